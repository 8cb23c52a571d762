"""Build time and peak memory of the wood model.

Prints machine-readable lines ``name value unit``:
    build_seconds        first build in this process (includes loading numba's cached kernels)
    build_seconds_warm   a second build in the same process
    build_stage_<stage>  per-stage seconds of the first build
    peak_rss_mb          peak resident memory of the process
Usage: python benchmarks/build.py [SCENE]   (default samples/tree.toml)
"""
from __future__ import annotations

import resource
import sys
import time
from pathlib import Path

import wooddecay as wd

from timing import SAMPLES


def main() -> None:
    path = Path(sys.argv[1] if len(sys.argv) > 1 else SAMPLES / "tree.toml")
    scene = wd.load_scene(path)
    t0 = time.perf_counter()
    model = wd.build_model(scene)
    first = time.perf_counter() - t0
    t0 = time.perf_counter()
    wd.build_model(scene)
    warm = time.perf_counter() - t0
    print(f"scene {scene.name}")
    print(f"elements {model.n_elements} -")
    print(f"strands {model.n_strands} -")
    print(f"reg_edges {model.n_edges} -")
    print(f"build_seconds {first:.3f} s")
    print(f"build_seconds_warm {warm:.3f} s")
    for stage, sec in model.build_seconds.items():
        print(f"build_stage_{stage} {sec:.3f} s")
    print(f"model_mb {model.nbytes / 2**20:.1f} MB")
    print(f"peak_rss_mb {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.1f} MB")


if __name__ == "__main__":
    main()
