"""Crack-face visibility: which meshlet faces an exporter writes, and from which frame they show
(woodstock §8.3; DESIGN "USD stage").

Faces between meshlets that stay connected are never seen: caps between consecutive elements of
a strand, side faces across an intact REG connection, and side faces between unconnected
neighbours in one piece. A side face shows from the first frame at which its connection is broken
or its two elements lie in different pieces; failures never heal and pieces never join, so once
shown it stays shown. Bark faces and faces without a neighbour show from the first frame.
"""
from __future__ import annotations

import numpy as np

from .sweep import BARK, CAP

#: :func:`exposure` of a face that no frame shows
NEVER = -1


def exposure(model, mesh, mechs) -> np.ndarray:
    """(F,) int: for each face of ``mesh`` the index into ``mechs`` of the first rod state
    (``Frame.mech``: ``edge_ok``, ``component``; in frame order) that shows it, NEVER if none does.
    ``mechs`` empty or its states None (no mechanics): bark and open faces from 0, the rest NEVER."""
    o, n, kind = mesh.face_element, mesh.face_neighbour, mesh.face_kind
    first = np.where((kind == BARK) | (n < 0), 0, NEVER)
    side = np.flatnonzero((first == NEVER) & ~((kind == CAP) & (n >= 0)))
    if not len(side) or not any(mechs):
        return first
    e = model.reg_edges
    nn = model.n_elements
    keys = np.minimum(e[:, 0], e[:, 1]) * nn + np.maximum(e[:, 0], e[:, 1])
    order = np.argsort(keys)
    q = np.minimum(o[side], n[side]) * nn + np.maximum(o[side], n[side])
    pos = np.clip(np.searchsorted(keys[order], q), 0, len(keys) - 1)
    has = keys[order][pos] == q
    edge = order[pos]
    for k, mech in enumerate(mechs):
        if not mech:
            continue
        shown = np.where(has, ~mech["edge_ok"][edge, 0], mech["component"][o[side]] != mech["component"][n[side]])
        first[side[shown]] = k
        side = side[~shown]
        has, edge = has[~shown], edge[~shown]
        if not len(side):
            break
    return first


def visible_faces(model, mesh, last) -> np.ndarray:
    """(F,) bool: the faces of ``mesh`` shown by the rod state ``last`` (``Frame.mech`` of the
    last frame); ``last`` None: no mechanics."""
    return exposure(model, mesh, [last]) != NEVER
