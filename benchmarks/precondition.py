"""The implicit step's linear solves: preconditioners of its Newton systems compared.

    python benchmarks/precondition.py [SCENE ...]
                      (default: samples/log.toml and samples/gallery/fig6.toml)

From each scene's settled rods (the settled-state cache, else settled first: the log lies free on
the ground, Fig. 6's section stands on its end), the first Newton system of a backward Euler step
of 1 s and of 0.01 s (:func:`wooddecay.sim.implicit.first_system`, diagonally scaled) is solved
by conjugate gradients to ``implicit.LINEAR_TOL`` with each preconditioner:

* ``jacobi``: none beyond the scaling (the solver's before the two-level one);
* ``strand_blocks``: each strand's couplings factored exactly, no coarse space;
* ``block_coarse``: 3x3 block Jacobi plus the aggregates' rigid modes;
* ``two_level``: strand blocks plus the aggregates' rigid modes (the solver's;
  :mod:`wooddecay.sim.precondition`);
* ``pyamg_sa``: pyamg's smoothed aggregation with the rigid-body modes as near-null space, only
  where pyamg is installed (it is not a dependency).

Prints ``name value unit`` lines per scene, step and preconditioner: ``iterations``, ``setup``
and ``solve`` seconds (medians of 3 with their spread), and per scene ``unknowns``.
"""
from __future__ import annotations

import statistics
import sys
import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from timing import SAMPLES, spread

import wooddecay as wd
from wooddecay.sim import implicit, precondition

REPEAT = 3
STEPS = (1.0, 0.01)


def _preconditioners(A, lay, modes) -> dict:
    """name -> a function building the preconditioner (None: plain CG)."""
    blocks = np.arange(len(lay.strand))
    none = sp.csr_matrix((A.shape[0], 0))
    out = {"jacobi": lambda: None,
           "strand_blocks": lambda: precondition.two_level(A, lay.strand, lay.position, none),
           "block_coarse": lambda: precondition.two_level(A, blocks, lay.position, modes),
           "two_level": lambda: precondition.two_level(A, lay.strand, lay.position, modes)}
    try:
        import pyamg
    except ImportError:
        return out
    rigid = modes.toarray()  # the aggregates' modes summed into the whole wood's six
    agg_modes = np.stack([rigid[:, k::6].sum(axis=1) for k in range(6)], axis=1)
    out["pyamg_sa"] = lambda: pyamg.smoothed_aggregation_solver(A, B=agg_modes).aspreconditioner()
    return out


def _solve(A, b, build) -> tuple[int, float, float]:
    t0 = time.perf_counter()
    M = build()
    setup = time.perf_counter() - t0
    count = [0]

    def tick(_):
        count[0] += 1

    t0 = time.perf_counter()
    spla.cg(A, b, rtol=implicit.LINEAR_TOL, maxiter=implicit.LINEAR_CAP, M=M, callback=tick)
    return count[0], setup, time.perf_counter() - t0


def run(scene_path) -> None:
    model = wd.build_model(wd.load_scene(scene_path))
    settled = wd.Simulation(model).state.mech
    name = model.info.name
    for h in STEPS:
        A, b, lay, modes = implicit.first_system(model.mech, settled, h)
        if h == STEPS[0]:
            print(f"{name}.unknowns {A.shape[0]} - ({model.n_elements} elements, {modes.shape[1] // 6} aggregates)")
        for pre, build in _preconditioners(A, lay, modes).items():
            runs = [_solve(A, b, build) for _ in range(REPEAT)]
            key = f"{name}.h_{h:g}.{pre}"
            print(f"{key}.iterations {runs[0][0]} -")
            for k, what in ((1, "setup"), (2, "solve")):
                xs = [r[k] for r in runs]
                print(f"{key}.{what} {statistics.median(xs):.3g} s {spread(xs)}", flush=True)


def main(*scenes: str) -> None:
    for path in scenes or (SAMPLES / "log.toml", SAMPLES / "gallery" / "fig6.toml"):
        run(path)


if __name__ == "__main__":
    main(*sys.argv[1:])
