"""Skeleton topology: branches, arc length to the root, and node cross-section frames.

Woodstock §3 and Fig. 3a: the skeletal graph G carries planar cross-section profiles at its
nodes. A profile's 2D coordinates (u, v) live in the node frame (U, V, T): T is the branch
tangent, V the world up direction projected into the cross-section (so the profile's +v side is
"up", the y-hat of woodification Eq. 3), U = V x T. Frames are carried from parent to child by
parallel transport (minimal rotation), so (u, v) are continuous along the skeleton.

A *branch* is a maximal chain: at a fork, the child with the largest profile area continues the
parent's branch, the others start new branches one order higher.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .skeleton import Skeleton

UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True, eq=False)
class Topology:
    """Derived structure of a :class:`Skeleton` (all arrays indexed by node)."""

    children: tuple[tuple[int, ...], ...]
    frames: np.ndarray  # (n, 3, 3) rows U, V, T
    s: np.ndarray  # (n,) distance to the root along the skeleton
    branch: np.ndarray  # (n,) branch id of the edge parent -> node (root: its branch)
    branch_order: np.ndarray  # (n_branches,) 0 for a trunk / log, 1 for its branches, ...
    up2d: np.ndarray  # (n, 2) world up in each node's (u, v) plane (zero for vertical nodes)

    @property
    def n_branches(self) -> int:
        return len(self.branch_order)


def _normalize(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def _transport(n1: np.ndarray, t_from: np.ndarray, t_to: np.ndarray) -> np.ndarray:
    """Rotate ``n1`` by the minimal rotation taking unit ``t_from`` to unit ``t_to``."""
    axis = np.cross(t_from, t_to)
    c = float(np.dot(t_from, t_to))
    if np.linalg.norm(axis) < 1e-12:
        return n1 if c > 0 else -n1
    # Rodrigues with k = axis (unnormalised: |k| = sin), 1 / (1 + c) factor.
    return n1 * c + np.cross(axis, n1) + axis * np.dot(axis, n1) / (1.0 + c)


def _root_u(t: np.ndarray) -> np.ndarray:
    """U axis of a root frame: V = world up projected into the plane normal to ``t`` (world y
    projected instead when ``t`` is vertical), U = V x T."""
    v = UP - np.dot(UP, t) * t
    if np.linalg.norm(v) < 1e-6:
        v = np.array([0.0, 1.0, 0.0]) - t[1] * t
    v = _normalize(v)
    return _normalize(np.cross(v, t))


def build_topology(skel: Skeleton) -> Topology:
    """Branches, arc lengths and parallel-transported node frames of a skeleton."""
    n = len(skel.ids)
    pos = skel.positions
    parent = skel.parent
    children: list[list[int]] = [[] for _ in range(n)]
    for i in range(n):
        if parent[i] >= 0:
            children[parent[i]].append(i)
    areas = np.array([p.area for p in skel.profiles])

    def main_child(i: int) -> int:
        # largest area continues the branch; ties go to the smaller index (deterministic)
        return max(children[i], key=lambda c: (areas[c], -c))

    tangents = np.zeros((n, 3))
    for i in range(n):
        if parent[i] < 0:
            d = pos[main_child(i)] - pos[i] if children[i] else np.array([0.0, 0.0, 1.0])
        else:
            d = _normalize(pos[i] - pos[parent[i]])
            if len(children[i]) == 1:  # interior node of a chain: bisector plane
                d = d + _normalize(pos[children[i][0]] - pos[i])
        tangents[i] = _normalize(d)

    frames = np.zeros((n, 3, 3))
    s = np.zeros(n)
    branch = np.zeros(n, dtype=np.int64)
    orders: list[int] = []
    for i in range(n):  # parents come before children
        t = tangents[i]
        p = parent[i]
        if p < 0:
            u = _root_u(t)
            branch[i] = len(orders)
            orders.append(0)
        else:
            u = _transport(frames[p, 0], tangents[p], t)
            u = _normalize(u - np.dot(u, t) * t)
            s[i] = s[p] + np.linalg.norm(pos[i] - pos[p])
            if len(children[p]) > 1 and i != main_child(p):
                branch[i] = len(orders)
                orders.append(orders[branch[p]] + 1)
            else:
                branch[i] = branch[p]
        frames[i] = (u, np.cross(t, u), t)
    up2d = np.einsum("nij,j->ni", frames[:, :2, :], UP)
    return Topology(
        children=tuple(tuple(c) for c in children),
        frames=frames,
        s=s,
        branch=branch,
        branch_order=np.array(orders, dtype=np.int64),
        up2d=up2d,
    )
