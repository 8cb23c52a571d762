"""The failure test of the REG edges after an epoch (``failure._flag_moved_edges``: edges whose
ends moved and turned too little since the chunk's first, exact test are not tested) against
testing every edge in every substep, timed in one run, alternating, on the same states.

    python benchmarks/failure.py [SCENE] [PAIRS]      (default samples/tree.toml, 7)

Prints ``name value unit`` lines, medians over PAIRS alternating pairs with their spread, for
two states of the scene: ``rest`` (the wood settled on day 0, a relaxing solve) and ``falling``
(the wood cut into its BSP blocks, ``studies.debris.fragment``, 0.05 s into their fall):
    <state>_chunk_bounded_seconds / <state>_chunk_exact_seconds    N_mech substeps
    <state>_chunk_speedup                                          exact / bounded, per pair
    <state>_same_bits                                              1 when both chunks end equal
"""
from __future__ import annotations

import hashlib
import statistics
import sys
import time
from pathlib import Path

import numpy as np
from timing import SAMPLES, spread

import wooddecay as wd
from wooddecay.sim import failure, mechanics
from wooddecay.studies import debris


def _digest(ms) -> str:
    h = hashlib.sha256()
    for a in (ms.x, ms.v, ms.q, ms.omega, ms.edge_ok, ms.element_ok, ms.component):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def _chunk(sim, start, bounded: bool) -> tuple[float, str]:
    """Seconds of one chunk from a copy of ``start`` and the digest it ends with; without
    ``bounded`` no epoch is recorded, so every substep tests every edge."""
    model = sim.model
    sim.state.mech = start.copy()
    epoch = failure.epoch
    if not bounded:
        failure.epoch = lambda setup, ms: None
    try:
        t0 = time.perf_counter()
        mechanics.advance(model, sim.state, model.time.N_mech)
        seconds = time.perf_counter() - t0
    finally:
        failure.epoch = epoch
    return seconds, _digest(sim.state.mech)


def _compare(name: str, sim, pairs: int) -> None:
    start = sim.state.mech.copy()
    _chunk(sim, start, True), _chunk(sim, start, False)  # compile
    bounded, exact, same = [], [], True
    for _ in range(pairs):
        (tb, hb), (te, he) = _chunk(sim, start, True), _chunk(sim, start, False)
        bounded.append(tb)
        exact.append(te)
        same &= hb == he
    ratio = [e / b for b, e in zip(bounded, exact)]
    print(f"{name}_chunk_bounded_seconds {statistics.median(bounded):.4g} s {spread(bounded)}")
    print(f"{name}_chunk_exact_seconds {statistics.median(exact):.4g} s {spread(exact)}")
    print(f"{name}_chunk_speedup {statistics.median(ratio):.3g} x {spread(ratio)}")
    print(f"{name}_same_bits {int(same)} -")


def main() -> None:
    path = Path(sys.argv[1] if len(sys.argv) > 1 else SAMPLES / "tree.toml")
    pairs = int(sys.argv[2]) if len(sys.argv) > 2 else 7
    model = wd.build_model(wd.load_scene(path))
    print(f"elements {model.n_elements} -")
    print(f"reg_edges {len(model.mech.edges)} -")
    sim = wd.Simulation(model, crack_bark=False)
    _compare("rest", sim, pairs)
    debris.fragment(sim)
    mechanics.refresh_pairs(model.mech, sim.state.mech)
    mechanics.advance(model, sim.state, int(round(0.05 / model.mech.dt)))
    _compare("falling", sim, pairs)


if __name__ == "__main__":
    main()
