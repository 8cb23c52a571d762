"""Walls where branches meet: at a fork the sweeps of the parent and the side branch run into each
other inside the wood (woodstock §8.1 meshes each branch on its own), so some bark faces of one
branch have another branch's meshlet right behind them. Such a face is not the wood's surface: it
becomes a side face with that meshlet as its neighbour, hidden while the two stay connected and
shown as wood (not bark) once they part (:mod:`wooddecay.meshlets.visibility`). The other way
round, a strand's open end cap there, or a face across a fork's section, with no meshlet behind
it (where the sweeps leave a notch between them; its own meshlet neither: a face folded inside its
own shell is not the surface) is the wood's surface: it becomes bark.

A face of element e is covered when the point OUTSIDE r_s beyond its centroid, along its outward
normal, lies inside another meshlet (a winding number over that meshlet's closed shell above one
half; for a bark face, one of another branch). Only faces within reach of a fork are tested:
REACH times the largest section radius at the fork and its children plus the longest meshlet's
extent.
"""
from __future__ import annotations

import math
from dataclasses import replace

import numba as nb
import numpy as np
from scipy.spatial import cKDTree

from ..wood import WoodModel
from .. import fmath as fm
from ..strands import profiles

#: how far beyond a bark face (in r_s) another branch's wood makes it a wall
OUTSIDE = 0.1
#: an uncovered face deeper than this many r_s below the profile faces a void, not the surface
SURFACE = 2.0
#: faces within this many section radii (plus a meshlet's extent) of a fork are tested
REACH = 3.0


def junction_walls(model: WoodModel, mesh, bark: int, side: int, cap: int):
    """``mesh`` with the bark faces (kind ``bark``) that another branch's meshlet covers turned
    into ``side`` faces facing it, and the open end caps (kind ``cap``, no neighbour) and faces
    across a fork's section that nothing covers turned into bark (module docstring);
    ``stats['junction_walls']`` and ``stats['junction_bark']`` count them."""
    topo, skel = model.topology, model.skeleton
    forks = [i for i, ch in enumerate(topo.children) if len(ch) > 1]
    mesh.stats["junction_walls"] = mesh.stats["junction_bark"] = 0
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

    d = mesh.wood[mesh.faces, 2]
    at_fork = np.isin(d[:, 0], topo.s[forks]) & (d[:, 0] == d[:, 1]) & (d[:, 0] == d[:, 2])
    faces = np.flatnonzero((mesh.face_kind == bark) | ((mesh.face_kind == cap) & (mesh.face_neighbour < 0)) | at_fork)
    tri = mesh.points[mesh.faces[faces]]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normal, axis=1)
    probe = tri.mean(axis=1) + OUTSIDE * model.r_s * normal / np.where(length > 0, length, 1.0)[:, None]
    radius = [max(float(np.linalg.norm(skel.profiles[j].polygon, axis=1).max()) for j in (i, *topo.children[i])) for i in forks]
    near = np.isfinite(cKDTree(skel.positions[forks]).query(probe, distance_upper_bound=REACH * max(radius) + extent.max())[0])
    faces, probe = faces[near], probe[near]

    pairs = cKDTree(probe).sparse_distance_matrix(cKDTree(centre[has]), extent.max(), output_type="ndarray")
    f, e = pairs["i"], np.flatnonzero(has)[pairs["j"]]
    own = mesh.face_element[faces[f]]
    is_bark = mesh.face_kind[faces[f]] == bark
    keep = (pairs["v"] <= extent[e]) & (e != own) & (~is_bark | (model.branch[e] != model.branch[own]))
    f, e = f[keep], e[keep]
    inside = _winding(mesh, e, probe[f]) > 0.5
    f, e = f[inside], e[inside]
    covered, first = np.unique(f, return_index=True)
    kind, neighbour = mesh.face_kind.copy(), mesh.face_neighbour.copy()
    wall = covered[mesh.face_kind[faces[covered]] == bark]
    kind[faces[wall]] = side
    neighbour[faces[wall]] = e[first][mesh.face_kind[faces[covered]] == bark]
    open_cap = np.setdiff1d(np.flatnonzero(mesh.face_kind[faces] != bark), covered)
    open_cap = open_cap[_at_surface(model, mesh, faces[open_cap])]
    open_cap = open_cap[_winding(mesh, mesh.face_element[faces[open_cap]], probe[open_cap]) < 0.5]
    kind[faces[open_cap]] = bark
    neighbour[faces[open_cap]] = -1
    mesh.stats["junction_walls"], mesh.stats["junction_bark"] = int(len(wall)), int(len(open_cap))
    return replace(mesh, face_kind=kind, face_neighbour=neighbour)


def _at_surface(model: WoodModel, mesh, faces: np.ndarray) -> np.ndarray:
    """Whether each face lies within SURFACE r_s of the wood's surface: its mean radius in its
    branch's section frame at least the profile's extent at its angle (the nearest node of the
    branch) less SURFACE r_s; deeper ones face a void inside the wood."""
    topo, skel = model.topology, model.skeleton
    w = mesh.wood[mesh.faces[faces]]
    r, d = w[:, :, 0].mean(axis=1), w[:, 0, 2]
    phi = fm.arctan2(fm.sin(w[:, :, 1]).mean(axis=1), fm.cos(w[:, :, 1]).mean(axis=1))  # circular mean
    branch = model.branch[mesh.face_element[faces]]
    order = np.lexsort((topo.s, topo.branch))  # nodes by branch, then along it
    key = topo.branch[order] * (topo.s.max() + 1.0) + topo.s[order]
    at = np.clip(np.searchsorted(key, branch * (topo.s.max() + 1.0) + d), 1, len(order) - 1)
    lo, hi = order[at - 1], order[at]
    node = np.where((topo.branch[lo] == branch) & ((topo.branch[hi] != branch) | (d - topo.s[lo] < topo.s[hi] - d)), lo, hi)
    extent = np.zeros(len(faces))
    for i in np.unique(node):
        extent[node == i] = profiles.ray_extent(skel.profiles[i].polygon, np.zeros(2), phi[node == i])
    return r >= extent - SURFACE * model.r_s


def _winding(mesh, elements: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Winding number of each meshlet ``elements[k]``'s closed shell about ``points[k]``
    (van Oosterom and Strackee's solid angle per triangle, summed over 4 pi): a numba kernel,
    parallel over k; :func:`_winding_reference` is its numpy twin."""
    out = np.empty(len(elements))
    _winding_kernel(mesh.face_offsets, mesh.faces, mesh.points, np.ascontiguousarray(elements, dtype=np.int64),
                    np.ascontiguousarray(points, dtype=np.float64), out)
    return out


@nb.njit(parallel=True, cache=True)
def _winding_kernel(fo, faces, P, elements, points, out):
    for k in nb.prange(len(elements)):
        e = elements[k]
        px, py, pz = points[k, 0], points[k, 1], points[k, 2]
        total = 0.0
        for f in range(fo[e], fo[e + 1]):
            i, j, m = faces[f, 0], faces[f, 1], faces[f, 2]
            ax, ay, az = P[i, 0] - px, P[i, 1] - py, P[i, 2] - pz
            bx, by, bz = P[j, 0] - px, P[j, 1] - py, P[j, 2] - pz
            cx, cy, cz = P[m, 0] - px, P[m, 1] - py, P[m, 2] - pz
            la = math.sqrt(ax * ax + ay * ay + az * az)
            lb = math.sqrt(bx * bx + by * by + bz * bz)
            lc = math.sqrt(cx * cx + cy * cy + cz * cz)
            det = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
            den = la * lb * lc + (ax * bx + ay * by + az * bz) * lc + (bx * cx + by * cy + bz * cz) * la \
                + (cx * ax + cy * ay + cz * az) * lb
            total += 2.0 * math.atan2(det, den)
        out[k] = total / (4.0 * math.pi)


def _winding_reference(mesh, elements: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Plain-numpy twin of :func:`_winding`."""
    fo = mesh.face_offsets
    count = fo[elements + 1] - fo[elements]
    pair = np.repeat(np.arange(len(elements)), count)
    face = np.repeat(fo[elements], count) + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
    a, b, c = (mesh.points[mesh.faces[face, k]] - points[pair] for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    det = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la + np.einsum("ij,ij->i", c, a) * lb
    return np.bincount(pair, weights=2.0 * fm.arctan2(det, den), minlength=len(elements)) / (4.0 * np.pi)
