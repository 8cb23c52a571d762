"""What a frame shows, in numbers (the visible-decay signature of ``summary.json``
``frames[i].signature``; woodstock Figs. 7-8, 12-15).

Of a state with rods (element volumes V from the transport operator, pieces = connected
components):

* ``mass_loss``: 1 - (H_l + k H_c) / (1 + k), volume-weighted (:mod:`~wooddecay.sim.diagnostics`);
* ``pieces``: pieces of at least ``MIN_PIECE`` elements; ``largest_piece_fraction``: the largest
  piece's share of the wood's volume;
* ``block_purity``: per piece of at least ``MIN_PIECE`` elements, the share of its elements in
  its most common BSP cell; the median over those pieces (1: every piece is one cell, a cube of
  brown rot's pattern, Fig. 7; low: fibres that run through many cells, Fig. 8). 1 for a single
  piece that is the whole wood is not a block, so with fewer than two such pieces it is 0;
* ``crack_orientation``: the shares (r, t, l) of the broken REG connections by the squared
  components of their rest direction in the local frame (``model.reg_dir_weights``), failed strand
  links counted as l, those of crumbled elements left out (consumed, not cracked): radial cracks (Fig. 6c) break tangential connections, delamination
  (Fig. 6a) radial ones, checks along the fibre (Fig. 15) both; zeros with none;
* ``crack_clusters``: the cracks, groups of at least ``MIN_CRACK`` broken REG connections (not of
  crumbled elements) joined where they share an element or touch consecutive elements of one
  strand, so a check that runs along the fibre between two strands is one crack;
* ``crumbled_elements``: elements consumed (:mod:`~wooddecay.sim.coupling`, ``m_crumble``);
  ``hollow_fraction``: the crumbled share of the heartwood's volume (0 without heartwood): white
  rot's hollow (Fig. 14);
* ``debris_footprint_m2``: the area of the convex hull of the element centres seen from above;
  ``debris_height_m``: from the lowest to the highest point of the wood (centre -+ radius): a
  log lying intact keeps its diameter, a pile is lower and wider; ``debris_centre_height_m``: the
  volume-weighted mean height of the element centres above that lowest point, crumbled elements
  left out: how low the wood lies, which one stick leaning up on a pile does not move.

The driver adds the bark's ``bark_crack_count``, ``bark_crack_length_m``, ``bark_crack_along_grain``
and ``bark_shed_fraction`` (:func:`wooddecay.sim.bark.statistics`).
"""
from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError

from ..wood import WoodModel
from ..strands.rings import TISSUES
from .diagnostics import mass_loss

#: pieces smaller than this (loose fibres, crumbs) are not counted as pieces
MIN_PIECE = 5
#: cracks of fewer broken connections than this are not counted
MIN_CRACK = 5


def signature(model: WoodModel, state) -> dict:
    """The signature of ``state`` (module docstring); ``state.mech`` must hold the rods."""
    ms, V = state.mech, model.bio.op.volume
    comp = ms.component
    size = np.bincount(comp)
    big = np.flatnonzero(size >= MIN_PIECE)
    volume = np.bincount(comp, weights=V)
    leaf = model.bsp_leaf
    purity = 0.0
    if len(big) >= 2:
        keys, counts = np.unique(comp * (int(leaf.max()) + 1) + leaf, return_counts=True)
        main = np.zeros(len(size))
        np.maximum.at(main, keys // (int(leaf.max()) + 1), counts)
        purity = float(np.median(main[big] / size[big]))
    i, j = model.reg_edges[:, 0], model.reg_edges[:, 1]
    broken = ~ms.edge_ok[:, 0] & ~ms.crumbled[i] & ~ms.crumbled[j]
    rtl = model.reg_dir_weights[broken].sum(axis=0)
    rtl[2] += np.count_nonzero(~ms.element_ok & ~ms.crumbled)
    total = rtl.sum()
    heart = model.tissue == TISSUES.index("heartwood")
    hollow = float(V[heart & ms.crumbled].sum() / V[heart].sum()) if heart.any() else 0.0
    fp = model.mech.fp
    c = 0.5 * (ms.x[fp] + ms.x[fp + 1])
    r = ms.radius
    bottom = np.min(c[:, 2] - r)
    solid = V * ~ms.crumbled
    return {
        "mass_loss": mass_loss(model, state),
        "pieces": int(len(big)),
        "largest_piece_fraction": float(volume.max() / volume.sum()),
        "block_purity": purity,
        "crack_orientation": [float(v) for v in (rtl / total if total > 0 else np.zeros(3))],
        "crack_clusters": crack_clusters(model, broken),
        "crumbled_elements": int(np.count_nonzero(ms.crumbled)),
        "hollow_fraction": hollow,
        "debris_footprint_m2": _hull_area(c[:, :2]),
        "debris_height_m": float(np.max(c[:, 2] + r) - bottom),
        "debris_centre_height_m": float(np.sum(solid * c[:, 2]) / solid.sum() - bottom) if solid.any() else 0.0,
    }


def crack_clusters(model: WoodModel, broken: np.ndarray) -> int:
    """Cracks of at least MIN_CRACK of the ``broken`` REG connections (module docstring)."""
    n = model.n_elements
    i, j = model.reg_edges[broken, 0], model.reg_edges[broken, 1]
    if len(i) < MIN_CRACK:
        return 0
    touched = np.zeros(n, dtype=bool)
    touched[i] = touched[j] = True
    e = np.flatnonzero(touched[:-1] & touched[1:] & (model.strand[:-1] == model.strand[1:]))
    a, b = np.concatenate([i, e]), np.concatenate([j, e + 1])
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    per_crack = np.bincount(label[i], minlength=n)
    return int(np.count_nonzero(per_crack >= MIN_CRACK))


def _hull_area(xy: np.ndarray) -> float:
    """Area of the convex hull of the points ``xy`` (0 when they span no area)."""
    try:
        return float(ConvexHull(xy).volume)
    except (QhullError, ValueError):
        return 0.0
