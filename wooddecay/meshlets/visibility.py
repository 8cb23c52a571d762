"""Crack-face visibility: which meshlet faces an exporter writes, and from which frame they show
(woodstock §8.3; docs/architecture.md "USD stage").

A face between two meshlets shows once the two no longer hold together or one of them dwindles:

* a side face across a REG connection, once the connection is broken;
* a side face between unconnected neighbours, once they lie in different pieces;
* a cap between consecutive elements of a strand, once the link between them is cut: the lower
  of the two has failed (its stretch is off; the skinning's rule, :mod:`.skin`);
* any of them, once either element dwindles (:func:`wooddecay.sim.coupling.crumble_scale` < 1):
  its meshlet draws in towards its centre and the faces round it become a cavity's walls.

Failures never heal, pieces never join and consumed wood never returns, so once shown a face
stays shown; until then it coincides with its neighbour's and is left out of that frame (the
stage's holes). Bark faces and faces without a neighbour show from the first frame.
"""
from __future__ import annotations

import numpy as np

from ..wood import WoodModel
from ..sim.coupling import crumble_scale
from ..strands.reg import edge_between
from .sweep import FACE_BARK, FACE_CAP

#: :func:`exposure` of a face that no frame shows
NEVER = -1


def exposure(model: WoodModel, mesh, frames) -> np.ndarray:
    """(F,) int: for each face of ``mesh`` the index into ``frames`` (frame order; each a
    :class:`~wooddecay.sim.driver.Frame`, or None for intact wood) of the first frame that shows it
    (module docstring), NEVER if none does."""
    frames = list(frames)
    o, n, kind = mesh.face_element, mesh.face_neighbour, mesh.face_kind
    first = np.where((kind == FACE_BARK) | (n < 0), 0, NEVER)
    if not frames:
        return first
    inner = np.flatnonzero(first == NEVER)
    edge, has = edge_between(model.reg_edges, model.n_elements, o[inner], n[inner])
    cap = kind[inner] == FACE_CAP
    # monotone: the last frame shows every face some frame shows; the rest is when each first does
    shown = _shown(model, frames[-1], o[inner], n[inner], cap, edge, has)
    inner, edge, has, cap = inner[shown], edge[shown], has[shown], cap[shown]
    first[inner] = len(frames) - 1
    for k, frame in enumerate(frames[:-1]):
        if not len(inner):
            break
        shown = _shown(model, frame, o[inner], n[inner], cap, edge, has)
        first[inner[shown]] = k
        inner, edge, has, cap = inner[~shown], edge[~shown], has[~shown], cap[~shown]
    return first


def visible_faces(model: WoodModel, mesh, frame) -> np.ndarray:
    """(F,) bool: the faces of ``mesh`` that ``frame`` shows (None: intact wood)."""
    return exposure(model, mesh, [frame]) != NEVER


def _shown(model: WoodModel, frame, o, n, cap, edge, has) -> np.ndarray:
    """Whether ``frame`` shows the faces between elements ``o`` and ``n`` (caps where ``cap``,
    side faces across REG edge ``edge`` where ``has``): module docstring."""
    shown = np.zeros(len(o), dtype=bool)
    if frame is None:
        return shown
    if frame.fields:
        scale = crumble_scale(model.coupling, frame.fields["H_c"], frame.fields["H_l"])
        shown |= (scale[o] < 1.0) | (scale[n] < 1.0)
    m = frame.mech
    if m:
        broken = m["component"][o] != m["component"][n]
        broken[has] = ~m["edge_ok"][edge[has], 0]  # wood without REG edges has none to index
        shown |= np.where(cap, ~m["element_ok"][np.minimum(o, n)], broken)
    return shown
