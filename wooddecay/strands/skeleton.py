"""Skeleton graph G of the scene (docs/model.md §1; woodstock §3, Fig. 3a).

A skeleton is a forest of nodes, each with an id, a 3D position, an optional parent and a
planar cross-section profile (see :mod:`wooddecay.strands.profiles`). Roots may be anchored
(a stump held in place). This module holds the :class:`Skeleton` type and the validation of
native node tables (:func:`parse_nodes`), which every source of nodes goes through: the scene's
``[skeleton]`` table and the files it names (:mod:`wooddecay.strands.skeleton_loader`) and
TreeQSM cylinder tables (:mod:`wooddecay.strands.qsm`).

All bad input raises :class:`wooddecay.errors.InputError` naming the file, the key (e.g.
``skeleton.node[n3].profile.radius``) and what is allowed; nothing else escapes.
"""
from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from wooddecay.errors import InputError, did_you_mean, format_value, type_name
from wooddecay.strands import profiles
from wooddecay.strands.profiles import Profile

MIN_EDGE_LENGTH = 1e-9
"""Shortest allowed edge between a node and its parent (m)."""

NODE_KEYS = ("id", "position", "parent", "profile", "anchored")
PROFILE_KEYS = {
    "circle": ("kind", "radius"),
    "ellipse": ("kind", "a", "b", "angle"),
    "polygon": ("kind", "points"),
}


@dataclass(frozen=True, eq=False)
class Skeleton:
    """Validated skeleton forest, nodes in topological order (parents before children).

    Attributes
    ----------
    ids : tuple of str
        Node ids as given (integers become strings).
    positions : np.ndarray
        ``(n, 3)`` node positions in m.
    parent : np.ndarray
        ``(n,)`` int64 index of each node's parent, -1 for a root.
    profiles : tuple of Profile
        Cross-section of each node.
    anchored : np.ndarray
        ``(n,)`` bool, True for nodes held in place (stump).
    source : str
        File the nodes came from (for messages).
    surface : trimesh.Trimesh or None
        The surface mesh the skeleton was built from (:mod:`.mesh_skeleton`): the meshlets past a
        fork follow its sections (:mod:`wooddecay.meshlets.branch`); reports compare the bark with it.
    """

    ids: tuple[str, ...]
    positions: np.ndarray
    parent: np.ndarray
    profiles: tuple[Profile, ...]
    anchored: np.ndarray
    source: str
    surface: object = None

    def __len__(self) -> int:
        """Number of nodes."""
        return len(self.ids)

    def children(self, i: int) -> tuple[int, ...]:
        """Indices of the children of node ``i``, in node order."""
        return tuple(int(c) for c in np.flatnonzero(self.parent == i))


# ----------------------------------------------------------------------------- messages

def check_keys(table: dict, allowed, required, source: str, key: str) -> None:
    """Reject unknown keys (with a did-you-mean) and missing required keys."""
    prefix = f"{key}." if key else ""
    for name in table:
        if not isinstance(name, str) or name not in allowed:
            hint = did_you_mean(name, allowed) or f"; allowed keys: {', '.join(allowed)}"
            raise InputError(source, f"{prefix}{name}", "unknown key" + hint)
    for name in required:
        if name not in table:
            raise InputError(source, f"{prefix}{name}", "is required")


# ------------------------------------------------------------------------------- values

def _number(value, source: str, key: str) -> float:
    """Return ``value`` as a finite float (ints and floats only, not booleans).

    Raises
    ------
    InputError
        For any other type, NaN, infinities and integers too large for a float.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(source, key, f"must be a number (got {type_name(value)} {format_value(value)})")
    try:
        x = float(value)
    except OverflowError:
        raise InputError(source, key, f"must be a finite number (got {format_value(value)})") from None
    if not math.isfinite(x):
        raise InputError(source, key, f"must be a finite number (got {format_value(value)})")
    return x


def positive(value, source: str, key: str) -> float:
    """Return ``value`` as a finite float > 0 m."""
    x = _number(value, source, key)
    if x <= 0.0:
        raise InputError(source, key, f"must be > 0 m (got {format_value(value)})")
    return x


def _vector(value, size: int, source: str, key: str) -> np.ndarray:
    """Return ``value`` (an array of ``size`` finite numbers) as a float64 array."""
    if not isinstance(value, (list, tuple)) or len(value) != size:
        raise InputError(source, key, f"must be an array of {size} numbers (got {type_name(value)} {format_value(value)})")
    return np.array([_number(v, source, f"{key}[{i}]") for i, v in enumerate(value)])


def _node_id(value, source: str, key: str) -> str:
    """Return a node id (non-empty string or integer) as a string."""
    if isinstance(value, bool) or not isinstance(value, (str, int)):
        raise InputError(source, key, f"must be a string or an integer (got {type_name(value)} {format_value(value)})")
    try:
        text = str(value)
    except ValueError:  # an integer with more digits than str allows
        raise InputError(source, key, "integer id has too many digits") from None
    if not text.strip():
        raise InputError(source, key, "must be a non-empty string or an integer")
    return text


# ----------------------------------------------------------------------------- profiles

def _polygon_profile(points, source: str, key: str) -> Profile:
    """Validate ``points`` (>= 3 [u, v] pairs, simple, counter-clockwise) into a Profile."""
    if not isinstance(points, (list, tuple)) or len(points) < 3:
        raise InputError(source, key, f"must be an array of >= 3 [u, v] points (got {format_value(points)})")
    poly = np.array([_vector(p, 2, source, f"{key}[{i}]") for i, p in enumerate(points)])
    with np.errstate(all="ignore"):
        simple = profiles.is_simple(poly)
        area = profiles.polygon_area(poly)
    if not simple:
        raise InputError(source, key, "polygon is self-intersecting or repeats a vertex; a simple polygon is required")
    if not math.isfinite(area) or area == 0.0:
        raise InputError(source, key, "polygon has no finite non-zero area")
    if not profiles.is_ccw(poly):
        raise InputError(source, key, "polygon is clockwise; list the points counter-clockwise")
    return profiles.polygon(poly)


def _profile(value, source: str, key: str) -> Profile:
    """Validate a profile table ``{kind = circle|ellipse|polygon, ...}`` into a Profile."""
    if not isinstance(value, dict):
        raise InputError(source, key, f"must be a table with kind = circle | ellipse | polygon (got {type_name(value)})")
    kind = value.get("kind")
    if not isinstance(kind, str) or kind not in PROFILE_KEYS:
        raise InputError(source, f"{key}.kind", f"must be one of circle, ellipse, polygon (got {format_value(kind)})")
    allowed = PROFILE_KEYS[kind]
    required = tuple(k for k in allowed if k != "angle")
    check_keys(value, allowed, required, source, key)
    if kind == "circle":
        return profiles.circle(positive(value["radius"], source, f"{key}.radius"))
    if kind == "ellipse":
        a = positive(value["a"], source, f"{key}.a")
        b = positive(value["b"], source, f"{key}.b")
        angle = _number(value.get("angle", 0.0), source, f"{key}.angle")
        return profiles.ellipse(a, b, angle)
    return _polygon_profile(value["points"], source, f"{key}.points")


def scale_profile(profile: Profile, factor: float) -> Profile:
    """Return ``profile`` with every length multiplied by ``factor`` (> 0)."""
    if profile.kind == "circle":
        return profiles.circle(profile.param("radius") * factor)
    if profile.kind == "ellipse":
        return profiles.ellipse(profile.param("a") * factor, profile.param("b") * factor, profile.param("angle"))
    return profiles.polygon(profile.polygon * factor)


# -------------------------------------------------------------------------------- nodes

def _parse_node(node, index: int, source: str, key: str) -> tuple[str, str, np.ndarray, Profile, bool]:
    """Validate one node table.

    Returns
    -------
    tuple
        ``(id, parent id or "", position (3,), profile, anchored)``.
    """
    if not isinstance(node, dict):
        raise InputError(source, f"{key}[#{index}]", f"must be a table (got {type_name(node)} {format_value(node)})")
    if "id" not in node:
        raise InputError(source, f"{key}[#{index}].id", "is required")
    nid = _node_id(node["id"], source, f"{key}[#{index}].id")
    here = f"{key}[{nid}]"
    check_keys(node, NODE_KEYS, ("id", "position", "profile"), source, here)
    position = _vector(node["position"], 3, source, f"{here}.position")
    parent = node.get("parent", "")
    parent = "" if parent == "" else _node_id(parent, source, f"{here}.parent")
    profile = _profile(node["profile"], source, f"{here}.profile")
    anchored = node.get("anchored", False)
    if not isinstance(anchored, bool):
        raise InputError(source, f"{here}.anchored", f"must be true or false (got {format_value(anchored)})")
    if anchored and parent != "":
        raise InputError(source, f"{here}.anchored", "only a root node can be anchored")
    return nid, parent, position, profile, anchored


def _find_cycle(parent: np.ndarray, start: int) -> list[int]:
    """Follow parents from ``start`` (which does not reach a root) and return the cycle met."""
    seen: dict[int, int] = {}
    path: list[int] = []
    i = start
    while i not in seen:
        seen[i] = len(path)
        path.append(i)
        i = int(parent[i])
    return path[seen[i]:]


def topological_order(parent: np.ndarray) -> tuple[np.ndarray, list[int]]:
    """Order nodes parents-first, keeping the input order where the graph allows.

    Parameters
    ----------
    parent : np.ndarray
        ``(n,)`` parent index per node, -1 for roots.

    Returns
    -------
    order : np.ndarray
        ``(m,)`` node indices, each parent before its children (m < n when there is a cycle).
    cycle : list of int
        Node indices of one cycle in the parent chains, empty when there is none.
    """
    n = len(parent)
    kids: list[list[int]] = [[] for _ in range(n)]
    for i, p in enumerate(parent):
        if p >= 0:
            kids[p].append(i)
    heap = [i for i in range(n) if parent[i] < 0]
    heapq.heapify(heap)
    order = []
    while heap:
        i = heapq.heappop(heap)
        order.append(i)
        for c in kids[i]:
            heapq.heappush(heap, c)
    if len(order) == n:
        return np.array(order, dtype=np.int64), []
    reached = np.zeros(n, dtype=bool)
    reached[order] = True
    return np.array(order, dtype=np.int64), _find_cycle(parent, int(np.flatnonzero(~reached)[0]))


def _check_edges(positions: np.ndarray, parent: np.ndarray, ids, source: str, key: str) -> None:
    """Reject edges shorter than ``MIN_EDGE_LENGTH`` or of non-finite length (naming the child node)."""
    child = np.flatnonzero(parent >= 0)
    with np.errstate(all="ignore"):
        length = np.sqrt(np.sum((positions[child] - positions[parent[child]]) ** 2, axis=1))
    bad = np.flatnonzero(~((length >= MIN_EDGE_LENGTH) & np.isfinite(length)))
    if len(bad):
        i = int(child[bad[0]])
        raise InputError(source, f"{key}[{ids[i]}].position",
                         f"is {float(length[bad[0]]):g} m from its parent '{ids[parent[i]]}'; "
                         f"edges must be >= {MIN_EDGE_LENGTH} m and finite")


def _link(ids: list[str], parents: list[str], source: str, key: str) -> np.ndarray:
    """Map parent ids to indices, rejecting duplicate ids and dangling parents."""
    index: dict[str, int] = {}
    for i, nid in enumerate(ids):
        if nid in index:
            raise InputError(source, f"{key}[{nid}].id", f"duplicate id (nodes #{index[nid]} and #{i}); ids must be unique")
        index[nid] = i
    parent = np.full(len(ids), -1, dtype=np.int64)
    for i, p in enumerate(parents):
        if p == "":
            continue
        if p not in index:
            raise InputError(source, f"{key}[{ids[i]}].parent", f"'{p}' is not the id of any node")
        parent[i] = index[p]
    return parent


def _make_skeleton(ids, positions, parent, profs, anchored, source: str) -> Skeleton:
    """Build a Skeleton with read-only arrays."""
    for arr in (positions, parent, anchored):
        arr.flags.writeable = False
    return Skeleton(tuple(ids), positions, parent, tuple(profs), anchored, source)


def parse_nodes(nodes, source: str, key: str = "skeleton.node") -> Skeleton:
    """Validate native skeleton nodes and order them topologically.

    Parameters
    ----------
    nodes : list of dict
        ``{id, position = [x, y, z], parent = <id> (absent or "" for a root), profile = {...},
        anchored = false}``; profiles ``{kind = "circle", radius}``, ``{kind = "ellipse", a, b,
        angle = 0}`` or ``{kind = "polygon", points = [[u, v], ...]}``.
    source : str
        File the nodes came from (for messages).
    key : str
        Key prefix of the node array in messages.

    Returns
    -------
    Skeleton
        Nodes reordered parents-first.

    Raises
    ------
    InputError
        For any invalid node, naming its id.
    """
    if not isinstance(nodes, (list, tuple)) or not nodes:
        raise InputError(source, key, f"must be a non-empty array of node tables (got {format_value(nodes)})")
    parsed = [_parse_node(node, i, source, key) for i, node in enumerate(nodes)]
    ids = [p[0] for p in parsed]
    parent = _link(ids, [p[1] for p in parsed], source, key)
    order, cycle = topological_order(parent)
    if cycle:
        chain = " -> ".join(ids[i] for i in cycle + cycle[:1])
        root_note = "" if np.any(parent < 0) else "; there is no root node (a node without parent)"
        raise InputError(source, f"{key}[{ids[cycle[0]]}].parent", f"parents form a cycle {chain}{root_note}")
    new_index = np.empty(len(ids), dtype=np.int64)
    new_index[order] = np.arange(len(order))
    positions = np.array([parsed[i][2] for i in order])
    new_parent = np.array([new_index[parent[i]] if parent[i] >= 0 else -1 for i in order], dtype=np.int64)
    new_ids = [ids[i] for i in order]
    _check_edges(positions, new_parent, new_ids, source, key)
    if not (new_parent >= 0).any():
        raise InputError(source, key, f"has {len(ids)} node(s) and no edge: wood grows along edges, so give at "
                         "least two nodes, one the parent of the other")
    anchored = np.array([parsed[i][4] for i in order], dtype=bool)
    return _make_skeleton(new_ids, positions, new_parent, [parsed[i][3] for i in order], anchored, source)


def scale_skeleton(skel: Skeleton, factor: float, key: str) -> Skeleton:
    """Return ``skel`` with positions and profiles multiplied by ``factor`` (> 0).

    Edges that become too short are reported under ``key`` (the node array's key); positions that
    overflow under ``skeleton.scale``.
    """
    if factor == 1.0:
        return skel
    with np.errstate(all="ignore"):
        positions = skel.positions * factor
    if not np.all(np.isfinite(positions)):
        raise InputError(skel.source, "skeleton.scale", f"scaling by {factor} makes positions non-finite")
    profs = [scale_profile(p, factor) for p in skel.profiles]
    parent = skel.parent.copy()
    _check_edges(positions, parent, skel.ids, skel.source, key)
    return _make_skeleton(skel.ids, positions, parent, profs, skel.anchored.copy(), skel.source)
