"""Debris: fragments of the tiny log fall onto the ground and settle (woodstock §5.4, Fig. 12;
:mod:`wooddecay.studies.debris`).

    python benchmarks/debris.py [scene] [seconds] [k_col]

The settled log falls apart into its BSP blocks, is dropped from 5 cm and falls for ``seconds``
(default 8) with the scene's contact, friction, damping and sleeping; ``k_col`` overrides the
scene's contact stiffness (to see how robust the result is). Prints a line every 0.1 s, then
``name value unit`` lines: pieces, settled_at (first time from which every piece stays asleep),
the largest window_speed of the last 0.5 s before settled_at, and at the end max_speed,
p99_speed, window_speed, max_penetration_over_r_s (beyond the rest overlap; the largest over the
whole run after settled_at), max_raw_overlap_over_r_s, z_min, broken_connections, seconds
(wall). The target: afterwards max_speed < 1e-3 m/s and max_penetration_over_r_s < 0.1.
"""
from __future__ import annotations

import sys
import time

import numpy as np

import wooddecay as wd
from wooddecay.studies import debris

from timing import SAMPLES

SCENE = str(SAMPLES / "tiny.toml")
DROP = 0.05  # m
SECONDS = 8.0  # of mechanics after the drop


def main(path: str = SCENE, seconds: float = SECONDS, k_col: float | None = None) -> None:
    overrides = {} if k_col is None else {"mechanics.k_col": k_col}
    scene = wd.load_scene(path, overrides=overrides)
    sim = wd.Simulation(wd.build_model(scene))
    debris.fragment(sim)
    print(f"pieces {sim.state.mech.component.max() + 1} -")
    t0 = time.perf_counter()
    records = []
    for r in debris.drop(sim, DROP, seconds):
        records.append(r)
        print(f"t {r.t:.2f} s: max_speed {r.max_speed:.3e} m/s, p99_speed {r.p99_speed:.2e} m/s, window_speed "
              f"{r.window_speed:.2e} m/s, max_penetration_over_r_s {r.penetration:.3f} (raw {r.raw_overlap:.3f}), "
              f"z_min {r.z_min:.4f} m, pieces {r.pieces}, asleep {r.asleep}", flush=True)
    awake = [k for k, r in enumerate(records) if r.asleep < r.pieces]
    settled = awake[-1] + 1 if awake else 0
    last = records[-1]
    if settled < len(records):
        print(f"settled_at {records[settled].t:.1f} s")
        before = records[max(settled - 5, 0):settled]
        print(f"window_speed_before_settled {max((r.window_speed for r in before), default=0.0):.3e} m/s")
        print(f"max_penetration_after_settled_over_r_s {max(r.penetration for r in records[settled:]):.3f} -")
    else:
        print("settled_at never -")
    ms = sim.state.mech
    print(f"max_speed {last.max_speed:.3e} m/s")
    print(f"p99_speed {last.p99_speed:.3e} m/s")
    print(f"window_speed {last.window_speed:.3e} m/s")
    print(f"max_penetration_over_r_s {last.penetration:.3f} -")
    print(f"max_raw_overlap_over_r_s {last.raw_overlap:.3f} -")
    print(f"z_min {last.z_min:.4f} m")
    print(f"broken_connections {np.count_nonzero(~ms.edge_ok[:, 0])} -")
    print(f"seconds {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main(*sys.argv[1:2], *map(float, sys.argv[2:4]))
