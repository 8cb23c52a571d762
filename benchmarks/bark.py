"""Cost of the bark (wooddecay.bark, wooddecay.sim.bark) on samples/log.toml (or SCENE): building the sheet,
the growth cracks at day 0, one biology step of a drying log (dt_bio days) with and without the
bark step after it (its cracks growing), the export's crack fields and grooves of one frame, and
the crack kernels against their numpy references in the same run: the shadows of 600 crack edges
(face grid against KD-tree), the separation tensors of every vertex, the eigenpairs of every
face's tensor, the split of the first branch's bark into 16 plates (farthest-point sites), the
plates of the dried bark's cracks (union-find against scipy's components) and the step's pass over
the faces (loading, bonds; one kernel against the numpy twins), the faces of each plate (a
counting sort against a stable argsort) and the edges along which plates part (one pass against
numpy's gathers), with the ratio per pair.

    python benchmarks/bark.py [REPEAT] [SCENE]      (default 5, samples/log.toml)

Prints ``name value unit`` lines, each the median of REPEAT runs after a warm-up, with its spread.
"""
from __future__ import annotations

import statistics
import sys

import numpy as np

import wooddecay as wd
from wooddecay.bark import cracks, shedding
from wooddecay.export import bark_surface as surface
from wooddecay.bark.sheet import build_sheet
from wooddecay.meshlets.sweep import build_meshlets
from wooddecay.sim import bark, biology

from timing import SAMPLES, spread, times


def main() -> None:
    repeat = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    scene = wd.load_scene(sys.argv[2] if len(sys.argv) > 2 else SAMPLES / "log.toml", overrides={"climate.preset": "dry"})
    model = wd.build_model(scene)
    sim = wd.Simulation(model, mechanics=False)
    state = sim.state
    sheet = model.bark
    print(f"sheet_faces {sheet.n_faces}")
    recent = np.full(len(model.skeleton.ids), 0.1)
    t = times(lambda: build_sheet(model, model.bark_setup, recent, 0.15, np.random.default_rng(0)), repeat)
    print(f"sheet_build_s {statistics.median(t):.4f} s {spread(t)}")
    t = times(lambda: bark.initial(model, state), repeat)
    print(f"growth_cracks_s {statistics.median(t):.4f} s {spread(t)}")
    for _ in range(60):  # dry it for four months so that its steps crack
        sim.macro_step(model.time.dt_bio)
    snapshot = state.copy()

    def step(with_bark):
        s = snapshot.copy()
        biology.step(model, s, model.time.dt_bio)
        if with_bark:
            bark.step(model, s, model.time.dt_bio)

    both = times(lambda: step(True), repeat)
    bio = times(lambda: step(False), repeat)
    print(f"biology_step_s {statistics.median(bio):.4f} s {spread(bio)}")
    print(f"biology_and_bark_step_s {statistics.median(both):.4f} s {spread(both)}")
    print(f"bark_step_s {statistics.median(both) - statistics.median(bio):.4f} s (difference of the medians)")
    mesh = build_meshlets(model)
    frame = sim.frame(1)
    t = times(lambda: surface.frame_bark(model, mesh, frame), repeat)
    print(f"export_crack_fields_per_frame_s {statistics.median(t):.4f} s {spread(t)}")
    print(f"crack_length_m {bark.statistics(model, state.bark)['bark_crack_length_m']:.2f} m")
    rng = np.random.default_rng(0)
    new = np.unique(rng.integers(0, len(sheet.edges), 600))
    st = cracks.CrackState.empty(sheet)
    plus = rng.normal(size=(sheet.n_faces, 3))
    faces = np.flatnonzero(sheet.face_branch == 0)  # one plate over the first branch, in 16 pieces
    cut = rng.random(sheet.n_faces) < 0.01  # plates of the dried bark's cracks with 1% of the faces shed
    label = shedding.plates(sheet, state.bark.crack.cracked, cut)
    n_plates = int(label.max()) + 1
    split = label * 4 + rng.integers(0, 4, sheet.n_faces)  # each plate in four, half its faces off
    off, broke = (label >= 0) & (rng.random(sheet.n_faces) < 0.5), np.empty(len(sheet.edge_faces), dtype=bool)
    b = model.bark_setup
    face_args = (sheet.face_element, state.M, state.H_c, state.H_l, sheet.growth, float(b["drying"]), sheet.shrinkage,
                 sheet.M_0, float(b["shedding"]), model.time.dt_bio, state.bark.eps_seen, state.bark.bond.copy(),
                 state.bark.M_last.copy(), state.bark.shed, np.empty(sheet.n_faces))
    for name, fast, ref in (("shadows", lambda: cracks.cast_shadows(sheet, st, new, 0.02),
                             lambda: cracks.cast_shadows_reference(sheet, st, new, 0.02)),
                            ("separation", lambda: cracks.separation(sheet, plus),
                             lambda: cracks.separation_reference(sheet, plus)),
                            ("eig2", lambda: cracks.eig2(plus), lambda: cracks.eig2_reference(plus)),
                            ("partition", lambda: shedding.partition(sheet, faces, 16),
                             lambda: shedding.partition_reference(sheet, faces, 16)),
                            ("plates", lambda: shedding.plates(sheet, state.bark.crack.cracked, cut),
                             lambda: shedding.plates_reference(sheet, state.bark.crack.cracked, cut)),
                            ("faces", lambda: bark._faces(*face_args), lambda: bark.faces_reference(*face_args)),
                            ("members", lambda: shedding._members(label, n_plates),
                             lambda: shedding.members_reference(label, n_plates)),
                            ("broke", lambda: shedding._broke(sheet.edge_faces, label, split, off, broke),
                             lambda: shedding.broke_reference(sheet.edge_faces, label, split, off))):
        fast()
        pairs = [(times(fast, 1)[0], times(ref, 1)[0]) for _ in range(repeat)]
        a, b = [p[0] for p in pairs], [p[1] for p in pairs]
        print(f"{name}_s {statistics.median(a):.5f} s {spread(a)}")
        print(f"{name}_reference_s {statistics.median(b):.5f} s {spread(b)}")
        r = [y / x for x, y in pairs]
        print(f"{name}_speedup {statistics.median(r):.1f} x {spread(r)}")


if __name__ == "__main__":
    main()
