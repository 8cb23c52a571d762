"""Fig. 12 in CI (``wooddecay gallery 12 --quick``, about 2.5 min on 2 cores, a file of its own
so that it runs beside tests/test_gallery.py): its claim decided on its quick logs. More fungal
activity from the ground breaks the log into more pieces, with a median block no larger, and
leaves a lower pile (the mean height of its wood). The quick logs keep the scene's 400 cells; their
blocks are about one cell: 7 against 8 elements, 58 against 54 pieces, a pile 5 mm lower (0.272
against 0.277 m), 2026-11-28 (docs/decisions.md, "Fig. 12 at quick size")."""
from __future__ import annotations

import pytest

from wooddecay.gallery import run_gallery


@pytest.fixture(scope="module")
def fig12(tmp_path_factory):
    return run_gallery(("fig12",), tmp_path_factory.mktemp("gallery"), quick=True, renders=False, log=print)["fig12"]


@pytest.mark.slow
def test_quick_fig12_one_sided_activity_gives_more_pieces_and_a_lower_pile(fig12):
    uniform, one_side = (fig12["variants"][k] for k in ("uniform", "one_side"))
    a, b = uniform["signature"], one_side["signature"]
    assert a["pieces"] >= 5 and b["pieces"] > a["pieces"]
    assert b["debris_centre_height_m"] < a["debris_centre_height_m"]
    assert b["mass_loss"] > a["mass_loss"]
    assert one_side["median_block_elements"] <= uniform["median_block_elements"]
    assert fig12["holds"] is True, fig12["test"]
