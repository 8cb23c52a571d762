"""Seconds per Algorithm 1 iteration (N_mech mechanics substeps + one biology step + coupling;
the fixed schedule) on samples/tree.toml (or the scene given), split per stage, against this machine's memory
bandwidth measured in the same run.

    python benchmarks/step.py [SCENE] [ITERATIONS]      (default samples/tree.toml, 7)

Prints ``name value unit`` lines, each timing the median over ITERATIONS macro steps after a
warm-up, followed by its quartiles and extremes (these machines are shared: the spread says how
far to trust a difference):
    elements, reg_edges, reg_colors, threads
    seconds_per_iteration           one macro step
    segment_substeps_per_s          elements x N_mech / seconds_per_iteration
    stage_<name>_seconds            per stage within one iteration: predict, stage1, stage2,
                                    contact (colliders + pairs), velocities, failure, biology,
                                    coupling
    stream_triad_gb_s               a = b + s c over 3 x 160 MB arrays (all threads)
    stage2_gb_s                     Stage 2's compulsory traffic (model below) / its time
    stage2_bandwidth_fraction       stage2_gb_s / stream_triad_gb_s
Stage 2 traffic model, per REG edge and sweep: it streams its edge pair, dp, k_conn, the rest
Darboux vector, lever, bend and twist stiffness and reads and writes its four multipliers (152 B)
and gathers the first-particle ids, the four particles' positions (read and written) and
inverse masses and the two elements' quaternions (read and written) and inverse inertias
(384 B): 536 B, counting each touched value once (cache lines and reuse ignored).
The paper (Table 1): 0.098 s per iteration on an RTX 3090 for 56,712 segments.
"""
from __future__ import annotations

import statistics
import sys
import time
from collections import defaultdict

import numba as nb

import wooddecay as wd
from wooddecay.sim import biology, contact, coupling, failure, mechanics, rods

from timing import SAMPLES, spread, stream_triad

STAGES = ((mechanics, "_predict", "predict"), (rods, "stretch_shear", "stage1"), (rods, "bend_twist", "stage1"),
          (rods, "reg_pass", "stage2"), (contact, "project_colliders", "contact"),
          (contact, "project_contacts", "contact"), (mechanics, "refresh_pairs", "contact"),
          (mechanics, "_velocities", "velocities"), (contact, "collider_velocities", "velocities"),
          (contact, "contact_velocities", "velocities"), (failure, "update", "failure"),
          (biology, "step", "biology"), (coupling, "step", "coupling"))
#: bytes Stage 2 touches per REG edge and sweep (module docstring)
STAGE2_BYTES_PER_EDGE = 536


def _instrument(totals: dict) -> None:
    """Wrap the stage functions so their time is summed into ``totals``."""
    for mod, name, stage in STAGES:
        fn = getattr(mod, name)

        def timed(*a, _fn=fn, _stage=stage, **k):
            t = time.perf_counter()
            out = _fn(*a, **k)
            totals[_stage] += time.perf_counter() - t
            return out
        setattr(mod, name, timed)


def main(path: str, iterations: int = 7) -> None:
    scene = wd.load_scene(path, {"time.schedule": "fixed"})  # every macro step runs N_mech substeps
    model = wd.build_model(scene)
    sim = wd.Simulation(model)
    print(f"elements {model.n_elements} 1")
    print(f"reg_edges {model.n_edges} 1")
    print(f"reg_colors {len(model.mech.sweep.ptr) - 1} 1")
    print(f"threads {nb.get_num_threads()} 1")
    totals: dict = defaultdict(float)
    _instrument(totals)
    sim.macro_step(scene.time.dt_bio)  # warm-up (compilation)
    per_iteration, per_stage = [], defaultdict(list)
    for _ in range(iterations):
        totals.clear()
        t = time.perf_counter()
        sim.macro_step(scene.time.dt_bio)
        per_iteration.append(time.perf_counter() - t)
        for stage, sec in totals.items():
            per_stage[stage].append(sec)
    sec = statistics.median(per_iteration)
    print(f"seconds_per_iteration {sec:.4f} s {spread(per_iteration)}")
    rate = [model.n_elements * scene.mechanics.N_mech / s for s in per_iteration]
    print(f"segment_substeps_per_s {statistics.median(rate):.4g} 1/s {spread(rate)}")
    for stage, xs in per_stage.items():
        print(f"stage_{stage}_seconds {statistics.median(xs):.4f} s {spread(xs)}")
    triad = stream_triad()
    sweeps = scene.mechanics.N_mech * model.mech.iterations
    stage2 = [STAGE2_BYTES_PER_EDGE * model.n_edges * sweeps / s for s in per_stage["stage2"]]
    print(f"stream_triad_gb_s {triad / 1e9:.2f} GB/s")
    print(f"stage2_gb_s {statistics.median(stage2) / 1e9:.2f} GB/s {spread([b / 1e9 for b in stage2])}")
    print(f"stage2_bandwidth_fraction {statistics.median(stage2) / triad:.3f} -")
    print(f"failures_so_far {sim.state.mech.failures} 1")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else str(SAMPLES / "tree.toml"), *map(int, sys.argv[2:3]))
