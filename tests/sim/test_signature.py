"""The visible-decay signature (wooddecay.sim.signature) and crumbling (coupling + failure) on
the tiny log with hand-set health fields."""
from __future__ import annotations

import numpy as np

import wooddecay as wd
from wooddecay.sim import coupling, failure
from wooddecay.sim.signature import signature
from wooddecay.sim.state import initial_state
from wooddecay.strands.rings import TISSUES

from ..conftest import SAMPLES


def _decayed(H_c, H_l):
    model = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", {"bsp.elongation": 3.0}))
    state = initial_state(model, rods=True)
    state.H_c[:], state.H_l[:] = H_c(model), H_l(model)
    coupling.step(model, state)
    state.mech.limit_elem[:] = np.inf
    state.mech.limit_edge[:] = np.inf
    failure.update(model.mech, state.mech)
    return model, state


def test_signature_of_intact_brown_and_white_wood():
    """Intact: one piece, the whole wood, no block (purity 0), no cracks. Brown rot everywhere
    (H_c 0.1): many pure blocks, cracks of all orientations. White rot (H_l 0.1): no connection
    left, pieces are strand bits that run through several cells, so purity is lower."""
    one = lambda m: np.ones(m.n_elements)  # noqa: E731
    model, state = _decayed(one, one)
    s = signature(model, state)
    assert (s["pieces"], s["largest_piece_fraction"], s["block_purity"], s["crumbled_elements"]) == (1, 1.0, 0.0, 0)
    assert s["crack_orientation"] == [0.0, 0.0, 0.0] and s["mass_loss"] == 0.0
    assert 0.1 < s["debris_height_m"] < 0.2 and s["debris_footprint_m2"] > 0.01
    # an intact log lying as placed: its wood's mean height is about its radius (0.055-0.06 m)
    assert 0.05 < s["debris_centre_height_m"] < 0.065
    brown = signature(*_decayed(lambda m: np.full(m.n_elements, 0.1), one))
    white = signature(*_decayed(one, lambda m: np.full(m.n_elements, 0.1)))
    assert brown["pieces"] >= 20 and brown["block_purity"] == 1.0 and brown["largest_piece_fraction"] < 0.2
    assert abs(sum(brown["crack_orientation"]) - 1.0) < 1e-12 and min(brown["crack_orientation"]) > 0.0
    assert white["block_purity"] < brown["block_purity"]
    assert brown["mass_loss"] > 0.6 and 0.2 < white["mass_loss"] < 0.3


def test_consumed_heartwood_crumbles_into_a_hollow():
    """Heartwood with H_c = H_l = 0.05 (remaining mass 0.05 < m_crumble 0.15) crumbles: every such
    element fails with all its connections, its meshlet scale is 0, and the hollow fraction is 1;
    the sapwood around it keeps its connections."""
    heart = TISSUES.index("heartwood")
    low = lambda m: np.where(m.tissue == heart, 0.05, 1.0)  # noqa: E731
    model, state = _decayed(low, low)
    ms, hw = state.mech, model.tissue == heart
    assert hw.sum() > 20 and np.array_equal(ms.crumbled, hw)
    assert not ms.element_ok[hw].any()
    i, j = model.reg_edges[:, 0], model.reg_edges[:, 1]
    assert not ms.edge_ok[hw[i] | hw[j]].any() and ms.edge_ok[~hw[i] & ~hw[j]].all()
    assert np.all(coupling.crumble_scale(model.coupling, state.H_c, state.H_l)[hw] == 0.0)
    s = signature(model, state)
    assert s["hollow_fraction"] == 1.0 and s["crumbled_elements"] == hw.sum()
    assert s["crack_orientation"] == [0.0, 0.0, 0.0]  # consumed, not cracked


def test_a_check_along_the_fibre_is_one_crack():
    """Connections broken across the plane y = 0 over a length of the log form one crack (they
    join along the strands on either side of it); the same plane with a 10 cm gap, two; scattered
    single breaks, none."""
    from wooddecay.sim.signature import crack_clusters

    model = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml"))
    c = model.centers
    i, j = model.reg_edges[:, 0], model.reg_edges[:, 1]
    across = (c[i, 1] < 0) != (c[j, 1] < 0)
    x = 0.5 * (c[i, 0] + c[j, 0])
    assert crack_clusters(model, across) == 1
    assert crack_clusters(model, across & ((x < 0.1) | (x > 0.2))) == 2
    scattered = np.zeros(len(i), dtype=bool)
    scattered[np.random.default_rng(0).choice(np.flatnonzero(across), 4, replace=False)] = True
    assert crack_clusters(model, scattered) == 0
