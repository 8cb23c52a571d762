"""Bark that sheds: plates bounded by cracks come off when their bond to the wood is gone (docs/model.md §10).

Every face of the sheet has a bond b to the wood beneath, about 1 at first (with noise of a
plate's size, :mod:`.sheet`). Per step of dt days it weakens by ``shedding`` (per year) times the
decay of its element, (1 - (H_c + H_l) / 2) dt / 365.25, plus its wet/dry cycling,
|dM| / (2 M_0) (a full swing from dry to M_0 and back is one unit): bark loosens on rotting,
weathering wood.

A plate is a connected set of faces that no crack separates (nor a gap of one edge between two
cracks). One larger than ``plate_area`` is split into plates of about that area (sites spread by
farthest-point sampling, longer along the grain). A plate whose mean bond has reached 0 comes off,
unless it is smaller than an eighth of ``plate_area`` (a scale that small holds on); where it
broke from the rest of its plate the sheet gets new cracks. The elements of the bark layer under
it (:mod:`.sheet`) are cut from every other element: the REG pairs and the strand links between
them get integrity 0, so the failure pass separates them (:mod:`wooddecay.sim.failure`) and the
plate falls as a piece of debris.
"""
from __future__ import annotations

import numba as nb
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..wood import DAYS_PER_YEAR, WoodModel
from ..unionfind import labels, union
from .cracks import crack_degree

#: a loose plate smaller than plate_area / MIN_PLATE_SHARE holds on (too small to come off alone)
MIN_PLATE_SHARE = 8.0
#: plates a loose sheet breaks into are this much longer along the grain than across
ELONGATION = 2.0
#: fixed blocks of faces a farthest-point pass is split into (:func:`partition`; the result does
#: not depend on it)
CHUNKS = 64
#: passes that move elements cut at both their strand links into the run before them
MAX_REASSIGN = 16


def weaken(bond: np.ndarray, rate: float, dt_days: float, H_c: np.ndarray, H_l: np.ndarray, dM: np.ndarray,
           M_0: np.ndarray) -> np.ndarray:
    """The bonds after a step (module docstring); ``H_c``, ``H_l``, ``dM``, ``M_0`` per face."""
    decay = (1.0 - 0.5 * (H_c + H_l)) * dt_days / DAYS_PER_YEAR
    cycles = np.abs(dM) / (2.0 * np.maximum(M_0, 1e-6))
    return bond - rate * (decay + cycles)


def plates(sheet, cracked: np.ndarray, shed: np.ndarray) -> np.ndarray:
    """(F,) plate label of every face still on, -1 shed: faces connected across edges that no crack
    cuts and that do not bridge two crack vertices (a gap of one edge between cracks holds no
    plate together). A numba union-find (:func:`_plate_labels`), the labels of
    :func:`plates_reference` (scipy's components: a shed face takes a label of its own there, so
    it does here). Why: scipy's took 0.1 s a call on the sample tree's 830,660 faces (its sheet at 1 r_s), this 0.02 s
    (docs/decisions.md, "Components by union-find")."""
    return _plate_labels(sheet.n_faces, len(sheet.phi), sheet.edges, sheet.edge_faces, cracked, shed)


@nb.njit(cache=True)
def _plate_labels(n_faces, n_vertices, edges, edge_faces, cracked, shed):
    """:func:`plates` (serial: one pass over the edges, one over the faces)."""
    on_crack = np.zeros(n_vertices, dtype=np.bool_)
    for k in range(len(edges)):
        if cracked[k]:
            on_crack[edges[k, 0]] = True
            on_crack[edges[k, 1]] = True
    parent = np.arange(n_faces)
    for k in range(len(edges)):
        a, b = edge_faces[k, 0], edge_faces[k, 1]
        if (b >= 0 and not cracked[k] and not (on_crack[edges[k, 0]] and on_crack[edges[k, 1]])
                and not shed[a] and not shed[b]):
            union(parent, a, b)
    label = labels(parent)
    for f in range(n_faces):
        if shed[f]:
            label[f] = -1
    return label


def plates_reference(sheet, cracked: np.ndarray, shed: np.ndarray) -> np.ndarray:
    """:func:`plates` by scipy's connected components on the face graph."""
    ef = sheet.edge_faces
    on_crack = crack_degree(sheet, cracked) > 0
    bridge = on_crack[sheet.edges[:, 0]] & on_crack[sheet.edges[:, 1]]
    keep = (ef[:, 1] >= 0) & ~cracked & ~bridge
    a, b = ef[keep, 0], ef[keep, 1]
    on = ~shed[a] & ~shed[b]
    F = sheet.n_faces
    g = sp.coo_matrix((np.ones(int(on.sum())), (a[on], b[on])), shape=(F, F)).tocsr()
    _, label = connected_components(g, directed=False)
    return np.where(shed, -1, label)


def falling(sheet, label: np.ndarray, bond: np.ndarray, plate_area: float):
    """The plates that come off now (module docstring). A plate larger than ``plate_area`` is
    split into ceil(area / plate_area) plates (:func:`partition`) first; a plate comes off when its
    mean bond is <= 0 and it is at least ``plate_area`` / MIN_PLATE_SHARE (smaller scales hold
    on). Returns the plate labels (split plates relabelled), the faces that come off and the sheet
    edges along which they broke from the rest of their plate (new cracks)."""
    on = label >= 0
    if not on.any():
        return label, on, np.zeros(0, dtype=np.int64)
    n = int(label.max()) + 1
    area = np.bincount(label[on], weights=sheet.face_area[on], minlength=n)
    out = label.copy()
    top = n - 1  # the largest label in out
    ptr, members = _members(label, n)
    for p in np.flatnonzero(area > plate_area):
        faces = members[ptr[p]:ptr[p + 1]]
        if bond[faces].min() > 0.0:  # no part of it can come off yet
            continue
        piece = partition(sheet, faces, int(np.ceil(area[p] / plate_area)))
        out[faces] = top + 1 + piece
        top += 1 + int(piece.max())
    # the labels made dense in their order: np.unique's inverse without its sort (3 ms a step on the log)
    present = np.zeros(int(out.max()) + 1, dtype=bool)
    present[out[on]] = True
    out[on] = (np.cumsum(present) - 1)[out[on]]
    n = int(out.max()) + 1
    area = np.bincount(out[on], weights=sheet.face_area[on], minlength=n)
    mean_bond = np.bincount(out[on], weights=(bond * sheet.face_area)[on], minlength=n) / np.maximum(area, 1e-300)
    loose = (mean_bond <= 0.0) & (area >= plate_area / MIN_PLATE_SHARE)
    off = on & loose[np.maximum(out, 0)]
    broke = np.empty(len(sheet.edge_faces), dtype=np.bool_)
    _broke(sheet.edge_faces, label, out, off, broke)
    return out, off, np.flatnonzero(broke)


@nb.njit(parallel=True, cache=True)
def _broke(edge_faces, label, out, off, broke):
    """Per sheet edge: whether it joined two faces of one plate (``label``, -1 shed) that
    :func:`falling` parted (different ``out``, one of them coming ``off``). :func:`broke_reference`
    is its numpy twin; one pass instead of a dozen gathers over the tree's edges."""
    for k in nb.prange(len(edge_faces)):
        a, b = edge_faces[k, 0], edge_faces[k, 1]
        broke[k] = (b >= 0 and label[a] >= 0 and label[a] == label[b] and (off[a] or off[b])
                    and out[a] != out[b])


def broke_reference(edge_faces: np.ndarray, label: np.ndarray, out: np.ndarray, off: np.ndarray) -> np.ndarray:
    """Plain-numpy :func:`_broke`."""
    on = label >= 0
    a, b = edge_faces[:, 0], np.maximum(edge_faces[:, 1], 0)
    joined = (edge_faces[:, 1] >= 0) & on[a] & on[b] & (label[a] == label[b])
    return joined & (off[a] | off[b]) & (out[a] != out[b])


@nb.njit(cache=True)
def _members(label, n):
    """The faces of each label 0..n-1 (``label`` -1: none), in increasing order, as (ptr (n + 1,),
    faces): a counting sort, one serial pass to count and one to place. :func:`falling` took the
    faces of each plate it splits by a pass over all labels, on the tree one pass per plate
    (docs/decisions.md, "The bark's step in one pass"). :func:`members_reference` is its twin."""
    ptr = np.zeros(n + 1, dtype=np.int64)
    for f in range(len(label)):
        if label[f] >= 0:
            ptr[label[f] + 1] += 1
    for p in range(n):
        ptr[p + 1] += ptr[p]
    at = ptr[:-1].copy()
    faces = np.empty(ptr[n], dtype=np.int64)
    for f in range(len(label)):
        if label[f] >= 0:
            faces[at[label[f]]] = f
            at[label[f]] += 1
    return ptr, faces


def members_reference(label: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Plain-numpy :func:`_members` (a stable argsort)."""
    on = np.flatnonzero(label >= 0)
    faces = on[np.argsort(label[on], kind="stable")]
    return np.concatenate([[0], np.cumsum(np.bincount(label[on], minlength=n))]), faces


def partition(sheet, faces: np.ndarray, k: int) -> np.ndarray:
    """(len(faces),) piece in [0, k) of each face of one plate: the nearest of k sites spread by
    farthest-point sampling from its first face, distances along the grain counted 1 / ELONGATION
    (plates longer along the grain, as bark's are). A numba kernel (:func:`_farthest_sites`), the
    bits of :func:`partition_reference` for any thread count."""
    P = float(sheet.period[sheet.face_branch[faces[0]]])
    xy = np.ascontiguousarray(sheet.face_xy[faces])
    piece = np.zeros(len(faces), dtype=np.int64)
    _farthest_sites(xy, P, ELONGATION, min(k, len(faces)), piece, np.empty(len(faces)))
    return piece


def partition_reference(sheet, faces: np.ndarray, k: int) -> np.ndarray:
    """Plain-numpy twin of :func:`partition`."""
    P = sheet.period[sheet.face_branch[faces[0]]]
    xy = sheet.face_xy[faces]

    def dist(i):  # squared, around the branch the shorter way (x in [0, P))
        dx = xy[:, 0] - xy[i, 0]
        dx = np.where(dx >= 0.5 * P, dx - P, np.where(dx < -0.5 * P, dx + P, dx))
        dy = (xy[:, 1] - xy[i, 1]) / ELONGATION
        return dx * dx + dy * dy

    d = dist(0)
    near, piece = d.copy(), np.zeros(len(faces), dtype=np.int64)
    for j in range(1, min(k, len(faces))):
        i = int(np.argmax(near))
        d = dist(i)
        closer = d < near
        piece[closer], near[closer] = j, d[closer]
    return piece


@nb.njit(cache=True)
def _dist(xy, f, i, P, elongation):
    """Squared distance of faces f and i as :func:`partition_reference`'s ``dist``."""
    dx = xy[f, 0] - xy[i, 0]
    if dx >= 0.5 * P:
        dx -= P
    elif dx < -0.5 * P:
        dx += P
    dy = (xy[f, 1] - xy[i, 1]) / elongation
    return dx * dx + dy * dy


@nb.njit(parallel=True, cache=True)
def _farthest_sites(xy, P, elongation, k, piece, near):
    """Fill ``piece`` (zeros) with the nearest of ``k`` farthest-point sites; ``near`` is scratch.
    Per site one parallel pass over CHUNKS fixed blocks of faces, each keeping its first farthest
    face; the blocks' are compared in order, so the site is np.argmax's for any thread count."""
    n = len(near)
    size = (n + CHUNKS - 1) // CHUNKS
    far, best = np.zeros(CHUNKS, dtype=np.int64), np.full(CHUNKS, -1.0)
    i = 0
    for j in range(k):
        for c in nb.prange(CHUNKS):
            far[c], best[c] = 0, -1.0
            for f in range(c * size, min(n, (c + 1) * size)):
                d = _dist(xy, f, i, P, elongation)
                if j == 0 or d < near[f]:
                    near[f], piece[f] = d, j
                if near[f] > best[c]:
                    far[c], best[c] = f, near[f]
        top = -1.0
        for c in range(CHUNKS):
            if best[c] > top:
                i, top = far[c], best[c]


def cuts(model: WoodModel, sheet, label: np.ndarray, off: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """REG pairs (m,) and strand links (n,) to cut so that the plates of the faces ``off`` come
    loose, and the plate each element goes with (n,; -1: it stays on the wood): those between an
    element of such a plate and any element not in the same plate. A strand link is cut by
    failing the element before it, and two failures side by side separate nothing
    (:mod:`wooddecay.sim.failure`), so an element that would be cut at both its links goes with
    the element before it (a lone plate element stays on the wood, a lone element between two
    plates goes with the first)."""
    n = model.n_elements
    ef = sheet.element_face
    plate = np.full(n, -1, dtype=np.int64)
    on = ef >= 0
    plate[on] = np.where(off[ef[on]], label[ef[on]], -1)
    e = np.arange(n)
    e1 = model.coupling.link_next
    e0 = np.where((e > 0) & (model.strand[np.maximum(e - 1, 0)] == model.strand), e - 1, e)
    for _ in range(MAX_REASSIGN):
        cut_before = (e0 != e) & (plate[e0] != plate) & ((plate[e0] >= 0) | (plate >= 0))
        cut_after = (e1 != e) & (plate[e1] != plate) & ((plate[e1] >= 0) | (plate >= 0))
        both = cut_before & cut_after
        if not both.any():
            break
        plate[both] = plate[e0[both]]
    i, j = model.reg_edges[:, 0], model.reg_edges[:, 1]
    edge_cut = (plate[i] != plate[j]) & ((plate[i] >= 0) | (plate[j] >= 0))
    link_cut = (e1 != e) & (plate != plate[e1]) & ((plate >= 0) | (plate[e1] >= 0))
    return edge_cut, link_cut, plate
