"""wooddecay.fmath (the C library's transcendental functions as numba ufuncs) against numpy's own
loops, timed in one run: what the same bits under every numpy cost.

    python benchmarks/fmath.py [SCENE] [PAIRS]    (default: samples/tree.toml, 5 pairs)

Prints ``name value unit`` lines: ``<f>_fmath_over_numpy`` for sin, cos, arccos, arctan2, hypot,
exp and power on 10^6 values (medians of 9 alternating pairs, with their spread), and
``build_seconds_fmath`` / ``build_seconds_numpy`` / ``build_fmath_over_numpy``: SCENE's model
built with fmath as shipped and with numpy's ufuncs put in its place (alternating, PAIRS pairs).
"""
from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numpy as np
from timing import SAMPLES, spread

import wooddecay as wd
from wooddecay import fmath

NAMES = ("sin", "cos", "arccos", "arctan2", "hypot", "exp", "power")
TWO = ("arctan2", "hypot", "power")


def _pairs(a, b, n: int) -> tuple[list, list]:
    ta, tb = [], []
    a(), b()
    for _ in range(n):
        for fn, out in ((a, ta), (b, tb)):
            t0 = time.perf_counter()
            fn()
            out.append(time.perf_counter() - t0)
    return ta, tb


def main(path: Path, pairs: int) -> None:
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-1.0, 1.0, 10**6), rng.uniform(0.1, 3.0, 10**6)
    for name in NAMES:
        f, g = getattr(fmath, name), getattr(np, name)
        args = (y, x) if name in TWO else (x,)
        tf, tn = _pairs(lambda: f(*args), lambda: g(*args), 9)
        ratio = np.array(tf) / np.array(tn)
        print(f"{name}_fmath_over_numpy {statistics.median(ratio):.2f} x {spread(ratio)}")
    scene = wd.load_scene(path)
    shipped = {name: getattr(fmath, name) for name in NAMES}

    def build(numpy_loops: bool):
        for name in NAMES:
            setattr(fmath, name, getattr(np, name) if numpy_loops else shipped[name])
        try:
            wd.build_model(scene)
        finally:
            for name in NAMES:
                setattr(fmath, name, shipped[name])

    tf, tn = _pairs(lambda: build(False), lambda: build(True), pairs)
    print(f"build_seconds_fmath {statistics.median(tf):.3f} s {spread(tf)}")
    print(f"build_seconds_numpy {statistics.median(tn):.3f} s {spread(tn)}")
    ratio = np.array(tf) / np.array(tn)
    print(f"build_fmath_over_numpy {statistics.median(ratio):.3f} x {spread(ratio)}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else SAMPLES / "tree.toml", int(sys.argv[2]) if len(sys.argv) > 2 else 5)
