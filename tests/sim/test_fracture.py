"""Rot and fracture (woodstock §5.3, §7 Eqs. 16-21; Figs. 6, 7, 8, 12, 13, 16; Table 2), asserted
on counts of broken REG connections of the full coupled simulation (biology, coupling, XPBD).

The specimen is the tiny sample log (0.3 m, r = 6 cm) drying in the open: no uptake (k_in0 = 0),
loss at the bark (k_out0 = 2 / (day m)), moisture bounds M_1 / M_2 = 0.6 / 0.2 (Fig. 16a),
M_init = 0.6, shrinkage below M_0 = 0.5, D_M0 = 1e-4 m^2 / day (the top of Table 3's range, so
the section dries over its whole depth within two to three weeks), dt_bio = 0.1 day, and
Algorithm 1's fixed schedule (the paper's figures).

A broken edge's direction is its (n_r^2, n_t^2, n_l^2) (``model.reg_dir_weights``): broken
tangential edges separate neighbours around the ring, i.e. a radial crack; broken radial edges
separate rings, a circumferential crack (delamination).
"""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

import wooddecay as wd

from ..conftest import SAMPLES

DRYING = {
    "moisture.k_in0": 0.0, "moisture.k_out0": 2.0, "moisture.M_1": 0.6, "moisture.M_2": 0.2,
    "moisture.M_init": 0.6, "moisture.D_M0": 1e-4, "mechanics.M_0": 0.5, "time.dt_bio": 0.1,
    "time.days": 20, "time.frames": 1, "time.schedule": "fixed", "climate.preset": "constant",
}
EVERYWHERE = '{ kind = "box", min = [-1.0, -1.0, -1.0], max = [1.0, 1.0, 1.0] }'


def _scene(tmp_path, fungus=None, **overrides):
    """The tiny log without its inoculation, or rotting everywhere with ``fungus`` at full
    activity; ``overrides`` on top of DRYING (dotted keys with '__' for '.')."""
    text = (SAMPLES / "tiny.toml").read_text()
    text = text[: text.index("[[inoculation]]")]
    if fungus is not None:
        text += f'[[inoculation]]\nfungus = "{fungus}"\nactivity = 1.0\nregion = {EVERYWHERE}\n'
    path = tmp_path / f"log_{fungus}.toml"
    path.write_text(text)
    return wd.load_scene(path, overrides={**DRYING, **{k.replace("__", "."): v for k, v in overrides.items()}})


def _run(scene, days, min_broken=None):
    """Simulation run to ``days`` (or until ``min_broken`` REG connections have broken)."""
    sim = wd.Simulation(wd.build_model(scene))
    ms = sim.state.mech
    while sim.state.t_days < days - 1e-9:
        sim.macro_step(scene.time.dt_bio)
        if min_broken is not None and np.count_nonzero(~ms.edge_ok[:, 0]) >= min_broken:
            break
    return sim


def _broken(sim):
    return ~sim.state.mech.edge_ok[:, 0]


def _direction(sim):
    """Mean (n_r^2, n_t^2, n_l^2) of the broken connections."""
    return sim.model.reg_dir_weights[_broken(sim)].mean(axis=0)


@pytest.mark.slow
def test_shrinkage_ablation_gives_opposite_crack_orientations(tmp_path):
    """Fig. 6a, b / Table 2: S_R / S_T = 0.1 / 1 breaks tangential edges (radial splitting),
    1 / 0.1 breaks radial edges (circumferential delamination); measured on the first 25 broken
    connections."""
    out = {}
    for S_R, S_T in ((0.1, 1.0), (1.0, 0.1)):
        sim = _run(_scene(tmp_path, mechanics__S_R=S_R, mechanics__S_T=S_T), days=20, min_broken=25)
        w = _direction(sim)
        out[S_R, S_T] = w
        print(f"S_R/S_T {S_R}/{S_T}: {np.count_nonzero(_broken(sim))} broken by day {sim.state.t_days:.1f}, "
              f"direction r {w[0]:.2f} t {w[1]:.2f} l {w[2]:.2f}, "
              f"broken elements {np.count_nonzero(~sim.state.mech.element_ok)}")
        assert np.count_nonzero(_broken(sim)) >= 25
    r_t, t_t = out[0.1, 1.0][:2]
    r_r, t_r = out[1.0, 0.1][:2]
    assert t_t > 2.0 * r_t and np.argmax(out[0.1, 1.0]) == 1
    assert r_r > 2.0 * t_r and np.argmax(out[1.0, 0.1]) == 0


def _crack_clusters(sim):
    """Crack clusters (broken connections joined when they share an element) with, per cluster,
    its opening: the sum over its connections between two intact elements of
    |c_j - c_i| - dp (a connection of a cut strand end measures the strand, not the crack)."""
    st, ms = sim.model.mech, sim.state.mech
    b = _broken(sim)
    e = st.edges[b]
    n = st.n_elements
    g = sp.coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n))
    label = connected_components(g, directed=False)[1][e[:, 0]]
    _, label = np.unique(label, return_inverse=True)
    c = 0.5 * (ms.x[st.fp] + ms.x[st.fp + 1])
    gap = np.maximum(np.linalg.norm(c[e[:, 1]] - c[e[:, 0]], axis=1) - ms.rest_offset[b], 0.0)
    gap[~(ms.element_ok[e[:, 0]] & ms.element_ok[e[:, 1]])] = 0.0
    return label, np.bincount(label, weights=gap)


@pytest.mark.slow
def test_balanced_shrinkage_opens_a_few_dominant_radial_cracks(tmp_path):
    """Fig. 6c, d: with S_R = S_T = 1 many small cracks start at the drying surface, but crack
    competition and stress shielding let a few of them open wide and run inwards: the
    opening-weighted number of cracks (sum w)^2 / sum w^2 is a few, far below the number of crack
    clusters; the widest three are radial (narrow in phi) and the widest runs over a third of the
    radius deep. Measured on day 24: wood above M_0 keeps its full limits (Eq. 19's knee at M_0),
    so the outer wood must dry below M_0 = 0.5 first."""
    sim = _run(_scene(tmp_path, mechanics__S_R=1.0, mechanics__S_T=1.0), days=24)
    w = _direction(sim)
    label, opening = _crack_clusters(sim)
    effective = opening.sum() ** 2 / np.sum(opening**2)
    wood = sim.model.wood_coords
    i, j = sim.model.mech.edges[_broken(sim)].T
    z = np.exp(1j * wood[i, 1]) + np.exp(1j * wood[j, 1])
    r = 0.5 * (wood[i, 0] + wood[j, 0])
    widest = np.argsort(opening)[::-1][:3]
    spread = [np.degrees(np.mean(np.abs(np.angle(z[label == k] / np.mean(z[label == k]))))) for k in widest]
    depth = [np.ptp(r[label == k]) for k in widest]
    radius = wood[:, 0].max()
    print(f"1/1: {len(i)} broken by day {sim.state.t_days:.1f}, direction r {w[0]:.2f} t {w[1]:.2f} l {w[2]:.2f}; "
          f"{len(opening)} crack clusters, opening-weighted count {effective:.1f}, widest three hold "
          f"{opening[widest].sum() / opening.sum():.2f} of the opening, phi spread {np.round(spread, 1)} deg, "
          f"depth {np.round(depth, 3)} m (log radius {radius:.3f} m)")
    assert w[1] > 2.0 * w[0]  # radial cracks: broken edges run around the ring
    assert len(opening) >= 30 and effective <= 12.0 and len(opening) >= 4 * effective
    assert max(spread) < 30.0 and depth[0] > radius / 3


def _run_with_snapshot(scene, days, snapshot_day):
    """Simulation run to ``days``, with the broken-connection flags at ``snapshot_day``."""
    sim = wd.Simulation(wd.build_model(scene))
    sim.advance(snapshot_day)
    broken = _broken(sim).copy()
    sim.advance(days - snapshot_day)
    return sim, broken


def _loose_pieces(sim):
    """Sizes (elements) of the pieces that came loose (every component but the largest) and
    their BSP purity: the fraction of a piece's elements in its most common BSP leaf."""
    comp, leaf = sim.state.mech.component, sim.model.bsp_leaf
    sizes = np.bincount(comp)
    loose = np.delete(np.arange(len(sizes)), np.argmax(sizes))
    purity = np.array([np.bincount(leaf[comp == c]).max() / sizes[c] for c in loose])
    return sizes[loose], purity


@pytest.mark.slow
def test_brown_rot_breaks_bsp_boundaries_into_blocks_white_rot_does_not_and_wet_wood_breaks_less(tmp_path):
    """Figs. 7, 8, 12, 13 and Eq. 21: the same log rotting everywhere while it dries. Brown rot
    (carbohydrates only, gamma_cb 0.1 / day) lowers I = 1 - theta k_c (1 - H_c) on the BSP
    boundaries alone (REG pairs and strand links), so by day 10 most broken connections have
    theta = 1, and by day 22 blocks come loose along the BSP cells: a few pieces, each mostly
    inside one leaf. A lignin-selective white rot (gamma_lw 0.1, gamma_cw 0.02 / day) weakens every
    pair and strand through (1 - k_l (1 - H_l)): its broken connections have theta = 1 about as
    often as the REG as a whole, and the log frays into many small fragments instead. Fig. 16: the
    same brown-rotting log in a wetter environment (M_1 / M_2 = 0.6 / 0.4) breaks far fewer
    connections by day 10."""
    cells = {"bsp__elongation": 3.0}  # cells longer than an element along the grain (samples/log.toml)
    brown, brown10 = _run_with_snapshot(_scene(tmp_path, "brown", fungi__gamma_cb=0.1, **cells), 22.0, 10.0)
    white, white10 = _run_with_snapshot(_scene(tmp_path, "white", fungi__gamma_lw=0.1, fungi__gamma_cw=0.02, **cells),
                                        22.0, 10.0)
    wet = _run(_scene(tmp_path, "brown", fungi__gamma_cb=0.1, moisture__M_2=0.4, **cells), 10.0)
    theta = brown.model.reg_theta.astype(bool)
    base = theta.mean()
    frac = {"brown": theta[brown10].mean(), "white": theta[white10].mean()}
    n_wet = np.count_nonzero(_broken(wet))
    for name, b in (("brown", brown10), ("white", white10)):
        print(f"{name} day 10: broken {np.count_nonzero(b)} of {len(b)}, theta=1 among broken {frac[name]:.2f} "
              f"(all edges {base:.2f})")
    print(f"wet brown day 10: broken {n_wet}")
    pieces = {}
    for name, sim in (("brown", brown), ("white", white)):
        sizes, purity = _loose_pieces(sim)
        pieces[name] = sizes, purity
        blocks = sizes >= 5
        print(f"{name} day 22: H_c {sim.state.H_c.mean():.2f}, H_l {sim.state.H_l.mean():.2f}, loose pieces "
              f"{len(sizes)} ({np.count_nonzero(blocks)} of >= 5 elements, {np.count_nonzero(~blocks)} smaller), "
              f"BSP purity of those >= 5: {np.round(purity[blocks], 2)}")
    assert np.count_nonzero(brown10) >= 100 and np.count_nonzero(white10) >= 100
    assert frac["brown"] > base + 0.15
    assert abs(frac["white"] - base) < 0.08
    assert n_wet < np.count_nonzero(brown10) / 10
    (bs, bp), (ws, _) = pieces["brown"], pieces["white"]
    assert np.count_nonzero(bs >= 5) >= 4  # blocks came loose
    assert np.median(bp[bs >= 5]) >= 0.8  # each mostly one BSP cell
    assert np.count_nonzero(ws < 5) >= 5 * max(np.count_nonzero(bs < 5), 1)  # white rot frays
