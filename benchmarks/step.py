"""Seconds per Algorithm 1 iteration (N_mech mechanics substeps + one biology step + coupling)
on samples/tree.toml (or the scene given), split per stage.

Prints ``name value unit`` lines:
    elements, reg_edges, reg_colors
    seconds_per_iteration           one macro step (best of 3 after a warm-up)
    segment_substeps_per_s          elements x N_mech / seconds_per_iteration
    stage_<name>_seconds            per stage within one iteration: predict, stage1, stage2,
                                    contact (colliders + pairs), velocities, failure, biology,
                                    coupling
The paper (Table 1): 0.098 s per iteration on an RTX 3090 for 56,712 segments.
"""
from __future__ import annotations

import sys
import time
from collections import defaultdict

import numpy as np

import wooddecay as wd
from wooddecay.sim import biology, contact, coupling, failure, mechanics, rods

from timing import SAMPLES


def _instrument(totals: dict) -> None:
    """Wrap the stage functions so their time is summed into ``totals``."""
    for mod, name, stage in ((mechanics, "_predict", "predict"), (rods, "stretch_shear", "stage1"),
                             (rods, "bend_twist", "stage1"), (rods, "reg_pass", "stage2"),
                             (contact, "project_colliders", "contact"), (contact, "project_contacts", "contact"),
                             (mechanics, "refresh_pairs", "contact"), (mechanics, "_velocities", "velocities"),
                             (contact, "collider_velocities", "velocities"),
                             (contact, "contact_velocities", "velocities"), (failure, "update", "failure"),
                             (biology, "step", "biology"), (coupling, "step", "coupling")):
        fn = getattr(mod, name)

        def timed(*a, _fn=fn, _stage=stage, **k):
            t = time.perf_counter()
            out = _fn(*a, **k)
            totals[_stage] += time.perf_counter() - t
            return out
        setattr(mod, name, timed)


def main(path: str) -> None:
    scene = wd.load_scene(path)
    model = wd.build_model(scene)
    sim = wd.Simulation(model)
    print(f"elements {model.n_elements} 1")
    print(f"reg_edges {model.n_edges} 1")
    print(f"reg_colors {len(sim.model.mech.sweep.ptr) - 1} 1")
    sim.macro_step(scene.time.dt_bio)  # warm-up (compilation)
    best = np.inf
    for _ in range(3):
        t = time.perf_counter()
        sim.macro_step(scene.time.dt_bio)
        best = min(best, time.perf_counter() - t)
    totals: dict = defaultdict(float)
    _instrument(totals)
    sim.macro_step(scene.time.dt_bio)
    print(f"seconds_per_iteration {best:.4f} s")
    print(f"segment_substeps_per_s {model.n_elements * scene.mechanics.N_mech / best:.4g} 1/s")
    for stage, sec in totals.items():
        print(f"stage_{stage}_seconds {sec:.4f} s")
    print(f"failures_so_far {sim.state.mech.failures} 1")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else str(SAMPLES / "tree.toml"))
