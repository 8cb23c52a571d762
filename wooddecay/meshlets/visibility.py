"""Crack-face visibility: which meshlet faces an exporter writes (woodstock §8.3; DESIGN "USD stage").

Faces between meshlets that stay connected for the whole bake are never seen and are left out:
caps between consecutive elements of a strand, side faces across a REG connection that never
breaks, and side faces between unconnected neighbours that stay in one piece. Faces that a crack
exposes are kept from the first frame (their two sides coincide until it opens). Failures never
heal, so the rod state of the last frame says which connections broke during the bake.
"""
from __future__ import annotations

import numpy as np

from .sweep import BARK, CAP


def visible_faces(model, mesh, last) -> np.ndarray:
    """(F,) bool: the faces of ``mesh`` to export given the rod state ``last`` (``Frame.mech`` of
    the last frame: ``edge_ok``, ``component``); ``last`` None: no mechanics."""
    o, n, kind = mesh.face_element, mesh.face_neighbour, mesh.face_kind
    keep = (kind == BARK) | (n < 0)
    inner = (kind == CAP) & (n >= 0)  # between consecutive elements of a strand: never seen
    side = ~keep & ~inner
    if last is not None:
        e = model.reg_edges
        nn = model.n_elements
        keys = np.minimum(e[:, 0], e[:, 1]) * nn + np.maximum(e[:, 0], e[:, 1])
        order = np.argsort(keys)
        q = np.minimum(o[side], n[side]) * nn + np.maximum(o[side], n[side])
        pos = np.clip(np.searchsorted(keys[order], q), 0, len(keys) - 1)
        has = keys[order][pos] == q
        broken = np.where(has, ~last["edge_ok"][order[pos], 0],
                          last["component"][o[side]] != last["component"][n[side]])
        keep[np.flatnonzero(side)[broken]] = True
    return keep
