"""Rigid pieces of the implicit step (docs/decisions.md, "Rigid pieces"): the tiny log broken into
its BSP blocks lies on the ground, and three backward Euler steps of 0.01 s go from rest with the
small loose blocks as rigid bodies (``rigid.RIGID_FRACTION`` as shipped) and with every block as
rods (fraction 0).

    python benchmarks/rigid.py

Prints ``name value unit`` lines per mode: ``rigid_pieces``, ``newton`` (iterations of the three
steps), ``residual`` (the last step's equilibrium residual), ``shape_change`` (largest change of a
distance between two particles of one rigid block, m) and ``seconds`` (the three steps, median of
3 with its spread), and finally ``speedup <v> x``: rods' seconds over rigid seconds.
"""
from __future__ import annotations

import statistics
import time

import numpy as np
from timing import SAMPLES, spread

import wooddecay as wd
from wooddecay.sim import equilibrium, implicit, mechanics, rigid
from wooddecay.studies import debris

REPEAT = 3
STEPS, H = 3, 0.01


def _broken():
    model = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", overrides={"mechanics.solver": "implicit"}))
    sim = wd.Simulation(model)
    debris.fragment(sim)
    mechanics.refresh_pairs(sim.model.mech, sim.state.mech)
    return sim.model.mech, sim.state.mech


def _shape_change(x0: np.ndarray, x1: np.ndarray, rb: rigid.Bodies) -> float:
    worst = 0.0
    for k in range(rb.n_pieces):
        p = np.flatnonzero(rb.particle == k)
        d0 = np.linalg.norm(x0[p][:, None] - x0[p][None], axis=2)
        d1 = np.linalg.norm(x1[p][:, None] - x1[p][None], axis=2)
        worst = max(worst, float(np.abs(d1 - d0).max()))
    return worst


def _run(fraction: float) -> tuple[int, int, float, float, float]:
    setup, ms = _broken()
    rb = rigid.bodies(setup, ms)  # the blocks rigid as shipped
    saved, rigid.RIGID_FRACTION = rigid.RIGID_FRACTION, fraction
    try:
        count = rigid.bodies(setup, ms).n_pieces
        x0 = ms.x.copy()
        t0 = time.perf_counter()
        newton = sum(implicit.step(setup, ms, H, tol=1e-3).newton for _ in range(STEPS))
        seconds = time.perf_counter() - t0
        return count, newton, equilibrium.equilibrium_residual(setup, ms), seconds, _shape_change(x0, ms.x, rb)
    finally:
        rigid.RIGID_FRACTION = saved


def main() -> None:
    medians = {}
    shipped = rigid.RIGID_FRACTION
    for name, fraction in (("rigid", shipped), ("rods", 0.0)):
        runs = [_run(fraction) for _ in range(REPEAT)]
        seconds = [r[3] for r in runs]
        medians[name] = statistics.median(seconds)
        count, newton, residual, _, change = runs[0]
        print(f"{name}.rigid_pieces {count} -")
        print(f"{name}.newton {newton} iterations")
        print(f"{name}.residual {residual:.4g} -")
        print(f"{name}.shape_change {change:.3g} m  (of the blocks rigid under fraction {shipped})")
        print(f"{name}.seconds {medians[name]:.3f} s  {spread(seconds)}")
    print(f"speedup {medians['rods'] / medians['rigid']:.2f} x")


if __name__ == "__main__":
    main()
