"""Bark in a band around the source surface: for a model built from a mesh or a scan
(``skeleton.surface``), a bark vertex of the rest partition farther than BAND r_s from that surface
moves towards its closest point on it until it is BAND r_s away, so the bake's silhouette is the
source mesh's wherever the sweep strays.

The partition's bark is the bisector between each outer site and its mirror across the section's
contour (woodstock §8.1); where strands run straight past a fork while the crotch's surface curves
it lies off the surface by more than r_s. Every vertex is not snapped onto the surface: a bark
face is a chord across an outer cell, about 2 r_s wide, so with all its vertices on a curved
surface it lies inside it, and the forked sample's meshlets lost 1.8% of their volume
(docs/decisions.md, "Bark on the source surface"). A vertex moves with every copy of it
(``vertex_shared``), so neighbours keep sharing their faces and the meshlets stay a partition. A
move that turns any face touching the vertex over (its normal against the rest normal) is
halved, HALVINGS times at most, then dropped: a cell is never turned inside out. The skinning is
recomputed for the moved points; the wood coordinates (r, phi, s) stay the sweep's.
``stats['conformed']`` counts the vertices moved all the way, ``stats['conform_held']`` those
held short, ``stats['conform_max']`` the largest move (m).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..wood import WoodModel
from .skin import rest_skinning

#: bark vertices farther than this many r_s from the surface move to this distance from it
BAND = 0.5
#: how often a move that turns a face over is halved before it is dropped
HALVINGS = 4


def _normals(P, F):
    return np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])


def conform_bark(model: WoodModel, mesh, bark: int):
    """``mesh`` with its bark vertices (on faces of kind ``bark``) within BAND r_s of
    ``model.skeleton.surface`` where that turns no face over (module docstring)."""
    from ..strands.mesh_input import surface_closest

    vs = mesh.vertex_shared
    on_bark = np.unique(vs[mesh.faces[mesh.face_kind == bark]])
    mesh.stats.update(conformed=0, conform_held=0, conform_max=0.0)
    if len(on_bark) == 0:
        return mesh
    first = np.full(vs.max() + 1, -1)
    first[vs[::-1]] = np.arange(len(vs))[::-1]
    p = mesh.points[first[on_bark]]
    move = np.zeros((len(first), 3))
    gap = surface_closest(model.skeleton.surface, p, model.r_s) - p
    dist = np.linalg.norm(gap, axis=1)
    move[on_bark] = gap * np.maximum(0.0, 1.0 - BAND * model.r_s / np.maximum(dist, 1e-300))[:, None]
    wanted = np.any(move != 0.0, axis=1)
    scale = wanted.astype(float)
    touched = np.flatnonzero(wanted[vs][mesh.faces].any(axis=1))
    F = mesh.faces[touched]
    rest = _normals(mesh.points, F)
    flat = np.einsum("ij,ij->i", rest, rest) == 0.0
    halved = 0
    while True:
        P = mesh.points + scale[vs, None] * move[vs]
        over = (np.einsum("ij,ij->i", _normals(P, F), rest) <= 0.0) & ~flat
        if not over.any():
            break
        turned = np.unique(vs[F[over]])
        scale[turned] = 0.5 * scale[turned] if halved < HALVINGS else 0.0
        halved += 1
    mesh.stats.update(conformed=int(np.count_nonzero(wanted & (scale == 1.0))),
                      conform_held=int(np.count_nonzero(wanted & (scale < 1.0))),
                      conform_max=float(np.linalg.norm(scale[:, None] * move, axis=1).max(initial=0.0)))
    weight, local, ring = rest_skinning(model, P, mesh.skin_indptr, mesh.skin_element)
    return replace(mesh, points=P, skin_weight=weight, skin_local=local, ring=ring)
