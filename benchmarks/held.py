"""A chunk of mechanics in a collapse with every piece awake and with the pieces at rest held
(:func:`wooddecay.sim.schedule.hold_still`): what the kernels save by skipping still wood.

    python benchmarks/held.py [BAKE_DIR] [PAIRS] [HOLD_SPEED]
                      (default: bakes samples/log.toml, 9 pairs, the scene's time.hold_speed)

From the last checkpoint of a bake of samples/log.toml (``BAKE_DIR/.bake/checkpoint.npz``;
without BAKE_DIR the log's five years are baked into a temporary folder first, about a minute),
one chunk of N_mech substeps runs awake and the schedule's rule picks the pieces to hold (at
HOLD_SPEED m/s); then
PAIRS pairs of chunks run alternately from that state with everything awake and with those
pieces held. Prints ``name value unit`` lines: elements, pieces, held_fraction, chunk_awake_ms,
chunk_held_ms (each with its spread), held_speedup (median of the pairs' ratios, with spread).
"""
from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import wooddecay as wd
from wooddecay.bake import bake
from wooddecay.sim import driver, mechanics, schedule, sleep

from timing import SAMPLES, spread


def main(folder: str | None = None, pairs: int = 9, hold_speed: float | None = None) -> None:
    scene = wd.load_scene(SAMPLES / "log.toml")
    with tempfile.TemporaryDirectory() as tmp:
        if folder is None:
            folder = tmp
            bake(scene, folder)
        model = wd.build_model(scene)
        sim = driver.Simulation.resume(model, Path(folder) / ".bake" / "checkpoint.npz")
    setup, ms, n_sub = model.mech, sim.state.mech, model.time.N_mech
    hold = model.time.tolerances.hold_speed if hold_speed is None else hold_speed
    sleep.wake_all(setup, ms)
    x0 = ms.x.copy()
    mechanics.macro_step(model, sim.state, n_sub)
    schedule.hold_still(setup, ms, schedule.motion(setup, ms, x0, n_sub * setup.dt), hold)
    held = ms.held.copy()
    print(f"elements {setup.n_elements} -")
    print(f"pieces {int(ms.component.max()) + 1} -")
    print(f"hold_speed {hold:g} m/s")
    print(f"held_fraction {held.mean():.3f} -")
    start = ms.copy()
    out = {True: [], False: []}
    for _ in range(pairs):
        for hold in (False, True):
            sim.state.mech = ms = start.copy()
            ms.held = held.copy() if hold else np.zeros_like(held)
            sleep.hold(setup, ms)
            t0 = time.perf_counter()
            mechanics.macro_step(model, sim.state, n_sub)
            out[hold].append(time.perf_counter() - t0)
    awake, still = (1e3 * np.array(out[k]) for k in (False, True))
    print(f"chunk_awake_ms {statistics.median(awake):.2f} ms {spread(awake)}")
    print(f"chunk_held_ms {statistics.median(still):.2f} ms {spread(still)}")
    ratio = awake / still
    print(f"held_speedup {statistics.median(ratio):.2f} x {spread(ratio)}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] != "-" else None,
         int(sys.argv[2]) if len(sys.argv) > 2 else 9, float(sys.argv[3]) if len(sys.argv) > 3 else None)
