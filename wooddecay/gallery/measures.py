"""Figure statistics of the gallery: numbers a figure's claim is decided on, from a built model and
the rod state of a bake's frames (:class:`wooddecay.sim.driver.Frame`, ``mech``: x, component,
element_ok, edge_ok). The per-frame signature of ``summary.json`` (:mod:`wooddecay.sim.signature`)
is the common part; these add what one figure needs: the size and shape of the blocks that came
loose (Figs. 11, 12), the opening-weighted number of cracks (Fig. 6c) and the state of a part of
the wood (Fig. 13's two ends).
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from ..sim.diagnostics import mass_remaining
from ..sim.signature import MIN_PIECE


def crumbled(model, frame) -> np.ndarray:
    """Elements consumed by frame ``frame``: remaining mass (H_l + k_H H_c) / (1 + k_H) below
    m_crumble (:mod:`wooddecay.sim.coupling`; H only falls, so this is the bake's flag)."""
    cs, f = model.coupling, frame.fields
    return mass_remaining(f["H_c"], f["H_l"], cs.k_H) < cs.m_crumble


def loose_blocks(model, frame, mask: np.ndarray | None = None) -> dict:
    """The pieces that came loose (every connected piece but the largest) of at least MIN_PIECE
    elements whose elements mostly lie in ``mask`` (default: anywhere): their count, median size
    (elements), median length along the grain and aspect (that length over the square root of the
    cross-section's two extents; at rest, in the frame of the piece's first element) and median
    BSP purity (share of the piece in its most common BSP cell)."""
    comp = frame.mech["component"]
    gone = crumbled(model, frame)
    size = np.bincount(comp, weights=~gone)
    keep = size >= MIN_PIECE
    keep[np.argmax(size)] = False
    if mask is not None:
        keep &= np.bincount(comp, weights=mask & ~gone, minlength=len(size)) > 0.5 * size
    sizes, lengths, aspects, purities = [], [], [], []
    for c in np.flatnonzero(keep):
        idx = np.flatnonzero((comp == c) & ~gone)
        local = model.centers[idx] @ model.frames[idx[0]].T  # (r, t, l) axes of the piece
        ext = np.ptp(local, axis=0) + 2.0 * model.r_s
        ext[2] += model.rest_length[idx].mean() - 2.0 * model.r_s
        sizes.append(len(idx))
        lengths.append(ext[2])
        aspects.append(ext[2] / np.sqrt(ext[0] * ext[1]))
        purities.append(np.bincount(model.bsp_leaf[idx]).max() / len(idx))
    med = (lambda v: float(np.median(v)) if v else 0.0)
    return {"blocks": len(sizes), "median_block_elements": med(sizes), "median_block_length_m": med(lengths),
            "median_block_aspect": med(aspects),
            "median_block_purity": med(purities)}


def crack_opening(model, first, frame) -> dict:
    """Cracks of ``frame`` (broken REG connections joined where they share an element) and their
    openings (the growth since ``first`` of the centre distance of each broken connection between
    two intact elements): the count and the opening-weighted count (sum w)^2 / sum w^2, a few when
    a few wide cracks hold the opening (woodstock Fig. 6c, d)."""
    broken = ~frame.mech["edge_ok"][:, 0]
    e = model.reg_edges[broken]
    if len(e) == 0:
        return {"cracks": 0, "effective_cracks": 0.0}
    n = model.n_elements
    _, label = connected_components(coo_matrix((np.ones(len(e)), (e[:, 0], e[:, 1])), shape=(n, n)), directed=False)
    _, label = np.unique(label[e[:, 0]], return_inverse=True)
    fp = model.mech.fp

    def distance(mech):
        c = 0.5 * (mech["x"][fp] + mech["x"][fp + 1])
        return np.linalg.norm(c[e[:, 1]] - c[e[:, 0]], axis=1)

    gap = np.maximum(distance(frame.mech) - distance(first.mech), 0.0)
    ok = frame.mech["element_ok"]
    gap[~(ok[e[:, 0]] & ok[e[:, 1]])] = 0.0
    opening = np.bincount(label, weights=gap)
    total = float(np.sum(opening**2))
    return {"cracks": int(len(opening)), "effective_cracks": float(opening.sum() ** 2 / total) if total > 0 else 0.0}


def part(model, frame, mask: np.ndarray) -> dict:
    """The state of the elements in ``mask``: mass loss (volume-weighted, k_H as the signature),
    the crumbled share of their volume and their loose blocks (:func:`loose_blocks`)."""
    V, cs, f = model.bio.op.volume, model.coupling, frame.fields
    left = mass_remaining(f["H_c"], f["H_l"], cs.k_H)
    w = V * mask
    gone = crumbled(model, frame)
    return {"mass_loss": float(1.0 - np.sum(w * left) / w.sum()), "crumbled_share": float(np.sum(w * gone) / w.sum()),
            **loose_blocks(model, frame, mask)}
