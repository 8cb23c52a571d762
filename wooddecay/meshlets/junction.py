"""Walls where branches meet: at a fork the sweeps of the parent and the side branch run into each
other inside the wood (woodstock §8.1 meshes each branch on its own), so some bark faces of one
branch have another branch's meshlet right behind them. Such a face is not the wood's surface: it
becomes a side face with that meshlet as its neighbour, hidden while the two stay connected and
shown as wood (not bark) once they part (:mod:`wooddecay.meshlets.visibility`).

A bark face of element e is a wall when the point OUTSIDE r_s beyond its centroid, along its
outward normal, lies inside a meshlet of another branch (a winding number over that meshlet's
closed shell above one half). Only faces within reach of a fork are tested: REACH times the
largest section radius at the fork and its children plus the longest meshlet's extent.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

#: how far beyond a bark face (in r_s) another branch's wood makes it a wall
OUTSIDE = 0.1
#: faces within this many section radii (plus a meshlet's extent) of a fork are tested
REACH = 3.0


def junction_walls(model, mesh, bark: int, side: int):
    """``mesh`` with the bark faces (kind ``bark``) that another branch's meshlet covers turned
    into ``side`` faces facing it (module docstring); ``stats['junction_walls']`` counts them."""
    topo, skel = model.topology, model.skeleton
    forks = [i for i, ch in enumerate(topo.children) if len(ch) > 1]
    mesh.stats["junction_walls"] = 0
    if not forks:
        return mesh
    vo = mesh.vertex_offsets
    has = np.diff(vo) > 0
    owner = np.repeat(np.arange(mesh.count), np.diff(vo))
    centre = np.zeros((mesh.count, 3))
    np.add.at(centre, owner, mesh.points)
    centre[has] /= np.diff(vo)[has, None]
    extent = np.zeros(mesh.count)
    np.maximum.at(extent, owner, np.linalg.norm(mesh.points - centre[owner], axis=1))

    faces = np.flatnonzero(mesh.face_kind == bark)
    tri = mesh.points[mesh.faces[faces]]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1)
    probe = tri.mean(axis=1) + OUTSIDE * model.r_s * normal / np.where(length > 0, length, 1.0)[:, None]
    radius = [max(float(np.abs(skel.profiles[j].polygon).max()) for j in (i, *topo.children[i])) for i in forks]
    near = cKDTree(skel.positions[forks]).query(probe, distance_upper_bound=REACH * max(radius) + extent.max())[0]
    faces, probe = faces[np.isfinite(near)], probe[np.isfinite(near)]

    pairs = cKDTree(probe).sparse_distance_matrix(cKDTree(centre[has]), extent.max(), output_type="ndarray")
    f, e = pairs["i"], np.flatnonzero(has)[pairs["j"]]
    keep = (model.branch[e] != model.branch[mesh.face_element[faces[f]]]) & (pairs["v"] <= extent[e])
    f, e = f[keep], e[keep]
    inside = _winding(mesh, e, probe[f]) > 0.5
    f, e = f[inside], e[inside]
    wall, first = np.unique(f, return_index=True)
    kind, neighbour = mesh.face_kind.copy(), mesh.face_neighbour.copy()
    kind[faces[wall]] = side
    neighbour[faces[wall]] = e[first]
    mesh.stats["junction_walls"] = int(len(wall))
    return replace(mesh, face_kind=kind, face_neighbour=neighbour)


def _winding(mesh, elements: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Winding number of each meshlet ``elements[k]``'s closed shell about ``points[k]``
    (van Oosterom and Strackee's solid angle per triangle, summed over 4 pi)."""
    fo = mesh.face_offsets
    count = fo[elements + 1] - fo[elements]
    pair = np.repeat(np.arange(len(elements)), count)
    face = np.repeat(fo[elements], count) + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
    a, b, c = (mesh.points[mesh.faces[face, k]] - points[pair] for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la + np.einsum("ij,ij->i", c, a) * lb
    return np.bincount(pair, weights=2.0 * np.arctan2(det, den), minlength=len(elements)) / (4.0 * np.pi)
