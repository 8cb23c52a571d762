"""An anchored root clamps every strand at one plane, ``[mechanics] clamp_depth`` along the wood
(to CLAMP_SPREAD of a rod length; docs/model.md §7), whatever the strand's rod phase."""
from __future__ import annotations

import numpy as np
import pytest

from wooddecay.model import build_model
from wooddecay.strands.elements import CLAMP_SPREAD, arc_positions
from wooddecay.studies import scene_template


def branch(length: float = 1.0, radius: float = 0.035, **overrides):
    """The model of a horizontal branch anchored at x = 0 (r_s 6 mm, rods 4 cm)."""
    profile = {"kind": "circle", "radius": radius}
    nodes = [{"id": "root", "position": [0.0, 0.0, 0.5], "anchored": True, "profile": profile},
             {"id": "tip", "position": [length, 0.0, 0.5], "parent": "root", "profile": profile}]
    return build_model(scene_template("cantilever", {"strands.r_s": 0.006, "strands.rod_length": 0.04,
                                                     **overrides}, nodes))


def clamp_edges(model) -> np.ndarray:
    """Per strand, the x of the last held particle (NaN for a strand with none held)."""
    held_p = np.zeros(len(model.particles), dtype=bool)
    held_p[model.first_particle[model.anchored] + 1] = True
    out = np.full(model.n_strands, np.nan)
    for k in range(model.n_strands):
        p = np.arange(model.particle_offsets[k], model.particle_offsets[k + 1])
        if held_p[p].any():
            out[k] = model.particles[p[held_p[p]].max(), 0]
    return out


@pytest.mark.parametrize("depth", [None, 0.03, 0.0071])
def test_every_strand_is_held_at_the_clamp_plane(depth):
    model = branch(**({} if depth is None else {"mechanics.clamp_depth": depth}))
    edges = clamp_edges(model)
    assert model.n_strands > 20 and np.isfinite(edges).all()
    beyond = edges - (0.05 if depth is None else depth)
    assert beyond.min() >= -1e-9 and beyond.max() <= CLAMP_SPREAD * 0.04 + 1e-9
    free = ~model.anchored
    assert model.rest_length[free].min() >= 0.5 * 0.04 * (1 - 1e-9)  # no short element outside the clamp


def test_wood_shorter_than_the_clamp_is_held_whole():
    model = branch(length=0.2, **{"mechanics.clamp_depth": 0.5})
    assert model.anchored.all()


def test_a_cut_is_a_particle_and_the_rods_beyond_it_keep_their_length():
    L = 0.04
    for phase in np.linspace(0.0, 0.99, 23):
        for cut in (0.001, 0.019, 0.04, 0.0613):
            arc = arc_positions(0.5, L, phase, cut)
            assert cut in arc and arc[0] == 0.0 and arc[-1] == 0.5
            beyond = np.diff(arc[arc >= cut])
            assert beyond.min() >= 0.5 * L - 1e-12 and beyond.max() <= 1.5 * L + 1e-12
    np.testing.assert_array_equal(arc_positions(0.5, L, 0.3, -1.0), arc_positions(0.5, L, 0.3))
