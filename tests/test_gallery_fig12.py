"""Fig. 12 in CI (``wooddecay gallery 12 --quick``, about 4 min on 2 cores, a file of its own so
that it runs beside tests/test_gallery.py): the direction of its claim on its quick logs. More
fungal activity from the ground breaks the log into more pieces and leaves a lower pile (the
mean height of its wood). The claim's third part, a median block no larger, is decided by the
full gallery: at quick size the blocks are one BSP cell in both logs and their medians differ by
half an element (9.5 against 10, 2026-11-27)."""
from __future__ import annotations

import pytest

from wooddecay.gallery import run_gallery


@pytest.fixture(scope="module")
def fig12(tmp_path_factory):
    return run_gallery(("fig12",), tmp_path_factory.mktemp("gallery"), quick=True, renders=False, log=print)["fig12"]


@pytest.mark.slow
def test_quick_fig12_one_sided_activity_gives_more_pieces_and_a_lower_pile(fig12):
    uniform, one_side = (fig12["variants"][k]["signature"] for k in ("uniform", "one_side"))
    assert uniform["pieces"] >= 5 and one_side["pieces"] > uniform["pieces"]
    assert one_side["debris_centre_height_m"] < uniform["debris_centre_height_m"]
    assert one_side["mass_loss"] > uniform["mass_loss"]
