"""Outward offset of a cross-section contour by the strand radius (woodstock §8.1; docs/model.md §5).

§8.1 bounds a branch's cross-section by the outer boundary of an alpha complex of its sites, offset
outwards by the strand radius r_s (docs/model.md §5). The meshlets bound the wood by mirror ghosts across the
node profiles instead (:mod:`wooddecay.meshlets.branch`); past a fork, where a branch's strands
fill only part of the fork's profile, the ghosts mirror across the convex hull of the branch's
sites (the alpha shape with alpha = inf) offset by r_s with :func:`offset_contour`.
"""
from __future__ import annotations

import numpy as np

from .. import fmath as fm


def offset_contour(points, r_s: float, join: str = "round", max_angle: float = np.pi / 8,
                   miter_limit: float = 4.0):
    """Offset a closed polygon (region on its left, e.g. a CCW contour) outwards by r_s.

    Every edge moves by r_s along its outward normal (to its right). At a convex corner ``join``
    decides: ``"round"`` inserts an arc of radius r_s about the corner, split into
    ceil(turn / max_angle) equal segments (its vertices lie exactly at r_s, its chords at least
    r_s cos(max_angle / 2)); ``"miter"`` extends both offset edges to their intersection (bevelled
    when the miter would exceed miter_limit r_s). At a reflex corner both joins take the
    intersection of the two offset edges (at distance r_s from both edges). The result is the
    boundary of the Minkowski sum of the polygon with a disk of radius r_s (up to the chords) as long
    as r_s stays below the local feature size: adjacent edges at a reflex corner longer than
    r_s tan(turn / 2) and non-adjacent parts more than 2 r_s apart; otherwise the curve
    self-intersects and is returned as is (no clipping).

    Returns (xy (k, 2), owner (k,)): the offset polygon (same orientation) and, for each of its
    vertices, the index of the input vertex it comes from.
    """
    if join not in ("round", "miter"):
        raise ValueError(f"join must be 'round' or 'miter', not {join!r}")
    P = np.asarray(points, float)
    m = len(P)
    if m < 2:
        raise ValueError("need a polygon of at least two vertices")
    r = float(r_s)
    e = np.roll(P, -1, axis=0) - P
    L = np.linalg.norm(e, axis=1)
    if np.any(L <= 0):
        raise ValueError("polygon has repeated consecutive vertices")
    tdir = e / L[:, None]
    nrm = np.stack([tdir[:, 1], -tdir[:, 0]], axis=1)        # right of each edge = outwards
    out, owner = [], []
    for i in range(m):
        n_in, n_out = nrm[i - 1], nrm[i]
        t_in, t_out = tdir[i - 1], tdir[i]
        turn = float(fm.arctan2(t_in[0] * t_out[1] - t_in[1] * t_out[0], float(t_in @ t_out)))
        v = P[i]
        if turn > 1e-12:                                      # convex corner
            if join == "round":
                k = max(1, int(np.ceil(turn / max_angle)))
                a0 = fm.arctan2(n_in[1], n_in[0])
                ang = a0 + turn * np.arange(k + 1) / k
                for a in ang:
                    out.append(v + r * np.array([fm.cos(a), fm.sin(a)]))
                    owner.append(i)
                continue
            if 1.0 / max(fm.cos(0.5 * turn), 1e-300) > miter_limit:
                out.extend((v + r * n_in, v + r * n_out))
                owner.extend((i, i))
                continue
        dot = float(n_in @ n_out)
        if dot <= -1.0 + 1e-12:                               # folds back on itself
            out.extend((v + r * n_in, v + r * n_out))
            owner.extend((i, i))
            continue
        out.append(v + r * (n_in + n_out) / (1.0 + dot))      # miter point: at r from both edges
        owner.append(i)
    return np.array(out), np.array(owner, dtype=np.int64)
