"""Figure statistics of the gallery: numbers a figure's claim is decided on, from a built model and
the rod state of a bake's frames (:class:`wooddecay.sim.driver.Frame`, ``mech``: x, component,
element_ok, edge_ok). The per-frame signature of ``summary.json`` (:mod:`wooddecay.sim.signature`)
is the common part; these add what one figure needs: the size and shape of the blocks that came
loose (Figs. 11, 12), how finely the wood is broken (Fig. 12), the opening-weighted number of
cracks (Fig. 6c) and the state of a part of the wood (Fig. 13's two ends).
"""
from __future__ import annotations

import numpy as np

from ..wood import WoodModel
from ..sim.diagnostics import mass_remaining
from ..sim.signature import MIN_PIECE


#: Fig. 6's crack orientation is read on the first frame with this many broken connections: later
#: breaks of the cracked section (along the grain, at the ends) blur it
FIRST_CRACKS = 25


def first_cracks(rows) -> int:
    """The first frame with FIRST_CRACKS broken connections (the last if none has)."""
    return next((i for i, f in enumerate(rows) if f["broken_connections"] >= FIRST_CRACKS), len(rows) - 1)



def crumbled(model: WoodModel, frame) -> np.ndarray:
    """Elements consumed by frame ``frame``: remaining mass (H_l + k_H H_c) / (1 + k_H) below
    m_crumble (:mod:`wooddecay.sim.coupling`; H only falls, so this is the bake's flag)."""
    cs, f = model.coupling, frame.fields
    return mass_remaining(f["H_c"], f["H_l"], cs.k_H) < cs.m_crumble


def loose_blocks(model: WoodModel, frame, mask: np.ndarray | None = None) -> dict:
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


def fragment_share(model: WoodModel, frame) -> float:
    """How finely the wood is broken: the weight-average fragment, sum_i w_i^2 / (sum_i w_i)^2 over
    the connected pieces of ``frame`` (every one, the largest and bits of one element included),
    w_i the remaining wood of piece i (volume times (H_l + k_H H_c) / (1 + k_H), crumbled elements
    left out), as a share of all the wood left. It is the share of the wood in the piece that a
    bit of wood picked at random lies in: 1 for the whole log, 1/n for n equal pieces."""
    left = np.where(crumbled(model, frame), 0.0, model.bio.op.volume * mass_remaining(
        frame.fields["H_c"], frame.fields["H_l"], model.coupling.k_H))
    w = np.bincount(frame.mech["component"], weights=left)
    return float(np.sum(w * w) / w.sum() ** 2)


#: sectors around the pith in which Fig. 6's radial cracks are counted (10 degrees each)
SECTORS = 36


def radial_cracks(model: WoodModel, first, frame) -> dict:
    """Radial cracks of ``frame`` (woodstock Fig. 6): the broken REG connections across the
    rings' tangent (their offset mostly along e_t, ``reg_dir_weights``), each with its opening,
    how far its two intact elements' centres lie beyond the rest offset dp of Eq. 16 at the frame's
    moisture (where the shrunk wood would hold them) less that excess at ``first``, summed in
    SECTORS sectors of the angle around the pith. Returns the total opening (m), the sectors
    holding at least a tenth of the widest one's, and the opening-weighted sector count
    (sum w)^2 / sum w^2: a few when a few wide radial cracks hold the opening, many when it is
    spread over hairlines all round."""
    e = model.reg_edges
    across = ~frame.mech["edge_ok"][:, 0] & (model.reg_dir_weights[:, 1] > 0.5)
    ok = frame.mech["element_ok"]
    across &= ok[e[:, 0]] & ok[e[:, 1]]
    e = e[across]
    fp, cs = model.mech.fp, model.coupling
    offset0, M_0, g = model.mech.offset0[across], cs.M_0_pair[across], cs.g_pair[across]

    def excess(f):
        c = 0.5 * (f.mech["x"][fp] + f.mech["x"][fp + 1])
        M = 0.5 * (f.fields["M"][e[:, 0]] + f.fields["M"][e[:, 1]])
        return np.linalg.norm(c[e[:, 1]] - c[e[:, 0]], axis=1) - offset0 * (1.0 - np.maximum(M_0 - M, 0.0) * g)

    gap = np.maximum(excess(frame) - excess(first), 0.0)
    phi = np.angle(np.exp(1j * model.wood_coords[e[:, 0], 1]) + np.exp(1j * model.wood_coords[e[:, 1], 1]))
    sector = np.floor((phi + np.pi) / (2.0 * np.pi) * SECTORS).astype(np.int64) % SECTORS
    opening = np.bincount(sector, weights=gap, minlength=SECTORS)
    total, widest = float(opening.sum()), float(opening.max(initial=0.0))
    return {"radial_crack_opening_m": total,
            "radial_crack_sectors": int(np.count_nonzero(opening >= 0.1 * widest)) if widest > 0 else 0,
            "effective_radial_cracks": total**2 / float(np.sum(opening**2)) if widest > 0 else 0.0}


def part(model: WoodModel, frame, mask: np.ndarray) -> dict:
    """The state of the elements in ``mask``: mass loss (volume-weighted, k_H as the signature),
    the crumbled share of their volume and their loose blocks (:func:`loose_blocks`)."""
    V, cs, f = model.bio.op.volume, model.coupling, frame.fields
    left = mass_remaining(f["H_c"], f["H_l"], cs.k_H)
    w = V * mask
    gone = crumbled(model, frame)
    return {"mass_loss": float(1.0 - np.sum(w * left) / w.sum()), "crumbled_share": float(np.sum(w * gone) / w.sum()),
            **loose_blocks(model, frame, mask)}
