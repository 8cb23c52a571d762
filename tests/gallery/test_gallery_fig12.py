"""Fig. 12 in CI (``wooddecay gallery 12 --quick``, about 2 min on 2 cores, a file of its own so
that it runs beside tests/gallery/test_gallery.py): sixteen times the fungal activity from the ground takes
more of the log's mass, breaks its wood finer (a smaller weight-average fragment,
``measures.fragment_share``) and leaves a lower pile (the mean height of its wood). The quick logs
on seeds 7 (the scene's), 2 and 3 (one bake each, 2026-12-05): fragment share 0.496 -> 0.371,
0.562 -> 0.452, 0.540 -> 0.390; pile 4.1, 8.0 and 33.5 mm lower; the full-size logs hold too
(docs/decisions.md, "Fig. 12: finer is the weight-average fragment"). The median loose block is printed, not decided: the loose blocks are
single BSP cells rotted to their lignin in both logs."""
from __future__ import annotations

import math

import numpy as np
import pytest

from wooddecay.arrays import best_rotation
from wooddecay.gallery import run_gallery
from wooddecay.gallery.bakes import SCENES, bake_scene
from wooddecay.scene import load_scene


@pytest.fixture(scope="module")
def fig12(tmp_path_factory):
    return run_gallery(("fig12",), tmp_path_factory.mktemp("gallery"), quick=True, renders=False, log=print)["fig12"]


@pytest.mark.slow
def test_quick_fig12_one_sided_activity_breaks_the_wood_finer_into_a_lower_pile(fig12):
    uniform, one_side = (fig12["variants"][k] for k in ("uniform", "one_side"))
    a, b = uniform["signature"], one_side["signature"]
    assert a["pieces"] >= 5
    assert b["mass_loss"] > a["mass_loss"]
    assert one_side["fragment_share"] < uniform["fragment_share"]
    assert b["debris_centre_height_m"] < a["debris_centre_height_m"]
    assert fig12["holds"]
    print(f"pieces: one side {b['pieces']}, uniform {a['pieces']}; median loose block: one side "
          f"{one_side['median_block_elements']} elements, uniform {uniform['median_block_elements']}")


def roll_degrees(x0: np.ndarray, x: np.ndarray) -> float:
    """Rotation about the x axis (the log's) of the best-fitting rigid motion of ``x0`` onto ``x``."""
    r = best_rotation(x0, x)
    return float(np.degrees(np.arctan2(r[2, 1], r[1, 1])))


@pytest.mark.slow
def test_fig12_log_lies_between_its_ridges_while_its_rotted_underside_bows_it(tmp_path):
    """The scene's two ridges of litter hold the log as placed through its first 1.2 years (3.5
    degrees at most, 2026-12-05); moved 5 m away, the log rolls as a whole (52.7 degrees):
    docs/decisions.md, "Fig. 12's log lies in its litter"."""
    year = {"time.years": 1.2, "time.frames": 12}
    ridges = load_scene(SCENES / "fig12.toml").colliders
    away = {f"collider.{i}.{end}": [c[end][0], c[end][1] + math.copysign(5.0, c[end][1]), c[end][2]]
            for i, c in enumerate(ridges) for end in ("a", "b")}
    rolls = {}
    for name, overrides in (("ridges", year), ("no ridges", {**year, **away})):
        frames = bake_scene("fig12.toml", overrides, tmp_path / name.replace(" ", "_")).frames
        rolls[name] = max(abs(roll_degrees(frames[0].mech["x"], f.mech["x"])) for f in frames)
    print(f"largest roll over 1.2 years: {rolls}")
    assert rolls["ridges"] < 10.0
    assert rolls["no ridges"] > 30.0
