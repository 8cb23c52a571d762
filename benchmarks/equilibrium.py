"""XPBD's distance from equilibrium against its sweeps a substep, and what measuring it costs.

    python benchmarks/equilibrium.py [SECONDS] [SCENE ...]
                      (default: 0.05 s of mechanics on samples/tiny.toml and samples/log.toml)

From each scene's settled rods (the settled-state cache, else settled first), SECONDS of mechanics
run at 1, 4, 16 and 64 sweeps a substep, the rest of ``[mechanics]`` as the scene says. The
residual (:func:`wooddecay.sim.equilibrium.equilibrium_residual`) is read at five points over the
last fifth of the span, since resting wood that XPBD has not converged still moves; then the same
span in backward Euler steps of 0.01 s and one static solve (:mod:`wooddecay.sim.implicit`). Prints
``name value unit`` lines per scene and sweep count: ``residual`` (median of the five, with their
range), ``strain_excess``, ``wall`` seconds and ``speed_max`` m/s at the end; per scene
``residual_ms`` (one evaluation, median with spread) and ``elements``; for the implicit steps
and the static solve ``residual`` at the end, ``newton`` iterations a step and ``wall``.
"""
from __future__ import annotations

import statistics
import sys
import time
from dataclasses import replace

import numpy as np

import wooddecay as wd
from wooddecay.sim import equilibrium, implicit, mechanics

from timing import SAMPLES, spread, times

SWEEPS = (1, 4, 16, 64)
READINGS = 5
#: the backward Euler step compared (s)
IMPLICIT_STEP = 0.01


def run(scene_path, seconds: float) -> None:
    model = wd.build_model(wd.load_scene(scene_path))
    settled = wd.Simulation(model).state.mech
    name = model.info.name
    print(f"{name}.elements {model.n_elements} -")
    cost = times(lambda: equilibrium.equilibrium_residual(model.mech, settled), 5)
    print(f"{name}.residual_ms {1e3 * statistics.median(cost):.2f} ms {spread([1e3 * c for c in cost])}")
    print(f"{name}.settled.residual {equilibrium.equilibrium_residual(model.mech, settled):.4g} -")
    for sweeps in SWEEPS:
        setup = replace(model.mech, iterations=sweeps)
        ms = settled.copy()
        n = max(READINGS, round(seconds / setup.dt))
        marks = set(np.linspace(n - n // 5, n, READINGS).round().astype(int))
        readings, wall = [], 0.0
        for k in range(1, n + 1):
            t0 = time.perf_counter()
            mechanics._substep(setup, ms, setup.dt, check=False)
            wall += time.perf_counter() - t0
            if k in marks:
                readings.append(equilibrium.equilibrium_residual(setup, ms))
        key = f"{name}.sweeps_{sweeps}"
        print(f"{key}.residual {statistics.median(readings):.4g} - (median of {len(readings)} over the last "
              f"fifth; range {min(readings):.4g}-{max(readings):.4g})")
        print(f"{key}.strain_excess {mechanics.strain_excess(setup, ms):.4g} -")
        print(f"{key}.wall {wall:.2f} s ({n} substeps of {setup.dt:g} s)")
        print(f"{key}.speed_max {np.linalg.norm(ms.v, axis=1).max():.4g} m/s", flush=True)
    run_implicit(name, model, settled, seconds)


def run_implicit(name: str, model, settled, seconds: float) -> None:
    """The same span in backward Euler steps of IMPLICIT_STEP s, and the static equilibrium
    (h = inf) from the settled rods (:mod:`wooddecay.sim.implicit`)."""
    for h, n in ((IMPLICIT_STEP, max(1, round(seconds / IMPLICIT_STEP))), (np.inf, 1)):
        ms = settled.copy()
        t0 = time.perf_counter()
        reports = [implicit.step(model.mech, ms, h, tol=1e-3) for _ in range(n)]
        wall = time.perf_counter() - t0
        newton = [r.newton for r in reports]
        key = f"{name}.implicit_{'static' if np.isinf(h) else f'{h:g}'}"
        print(f"{key}.residual {equilibrium.equilibrium_residual(model.mech, ms):.4g} - (after {n} steps; "
              f"converged {sum(r.converged for r in reports)} of {n})")
        print(f"{key}.newton {statistics.median(newton):g} - (median per step; max {max(newton)})")
        print(f"{key}.wall {wall:.2f} s", flush=True)


def main(seconds: float = 0.05, *scenes: str) -> None:
    for path in scenes or (SAMPLES / "tiny.toml", SAMPLES / "log.toml"):
        run(path, seconds)


if __name__ == "__main__":
    main(*([float(sys.argv[1]), *sys.argv[2:]] if len(sys.argv) > 1 else []))
