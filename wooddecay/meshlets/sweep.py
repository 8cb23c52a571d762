"""Per-element meshlets: each strand site's Voronoi cell swept along d_t over its rod element.

Woodstock §8.1 and Fig. 10; docs/model.md §5. Per branch, the strand sites P_i(d_t) and their ghost mirrors
(:mod:`wooddecay.meshlets.branch`) are carried along the branch by the kinetic Delaunay
triangulation of :mod:`wooddecay.meshlets.kinetic`. The meshlet of the rod element of strand i
over [a, b] is the sweep of site i's Voronoi cell over [a, b]:

* Voronoi vertices are the circumcentres c(t, d) of the Delaunay triangles t. A triangle's vertex is
  sampled at its birth and death events, at the branch's node sections (where the motion bends)
  and at every element boundary of its three sites, so consecutive samples are joined by straight
  segments ("trajectories").
* The side surface between sites p and q is a *strip*: the ladder between the trajectories of the
  triangles left and right of the Delaunay edge pq, cut by rungs at the element boundaries of p and
  q and triangulated by a zipper (merge by d_t) between consecutive rungs. Both meshlets take the
  same triangles with opposite orientation, so neighbours share their side faces exactly and the
  meshlets partition the wood. Every strip beside a triangle includes all its samples: no
  T-junctions, each meshlet is a closed 2-manifold.
* Events. At a flip the four circumcentres coincide (the dual Voronoi edge has length zero): they
  share one vertex, and the surfaces stay continuous. Where a strand begins or ends at a section
  (insert / delete; also a ``repair`` rebuild) the cells of its neighbours jump: each neighbour j
  whose cycle of triangles changes gets a horizontal face at d_t made of the removed run of its
  Voronoi vertices (before the event) and the added run (after it), and the strips beside the
  changed triangles carry the horizontal junction from the old to the new vertex. The strand's own
  element gets its cap.
* Bark: faces between a real and a ghost site (the cell ends at the bisector with its mirror, the
  tangent of the profile). Without bark (``model.bark_thickness`` 0: a sawn board) they are wood
  surface, tagged side with no neighbour. Faces against a ghost that is another branch's strand
  (past a fork, :mod:`wooddecay.meshlets.branch`) are side faces with that strand's element there
  as the neighbour.
* Caps close each element at its two ends: the cell polygon at d_t = a (facing -d) and at b (+d).

Forks: an element that straddles a fork belongs to the branch of its midpoint (``model.branch``)
and is clipped at the fork section; the next element of the strand covers the rest. Per-branch
sweeps overlap slightly near junctions (woodstock §8.1 leaves junction gaps and overlaps;
``docs/decisions.md``, "Forks and hull repair"); bark faces with another branch's wood right
behind them become walls to it, open end caps there with nothing behind them bark
(:mod:`wooddecay.meshlets.junction`). For a model built from a mesh or a scan, the bark is then
pulled into a band around the source surface (:mod:`wooddecay.meshlets.conform`).

Output: :class:`Meshlets`, disjoint closed shells (each meshlet owns copies of its vertices), faces
tagged bark / side (with the neighbouring element) / cap, rest wood-local coordinates and ring age
per vertex, and the rest skinning data used by :mod:`wooddecay.meshlets.skin`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
from scipy.spatial import ConvexHull

from ..wood import WoodModel
from .. import fmath as fm
from .branch import Branch, section_frame, setup_branch
from .checks import closed_oriented
from .conform import conform_bark
from .junction import junction_walls
from .kinetic import FLIP, REPAIR, SECTION, perturbation, sweep
from .skin import rest_skinning

#: face kinds (docs/architecture.md "USD stage": uniform int faceKind)
FACE_BARK, FACE_SIDE, FACE_CAP = 0, 1, 2


class SweepFace(NamedTuple):
    """One triangle the sweep emits, over global sweep vertex ids.

    The element of ``site`` at depth ``d`` is resolved later by :meth:`_BranchSweep.element`
    (``side`` -1: the element ending at d, +1: the one starting at d, 0: the one containing d);
    ``other``/``other_side`` name the site across the face the same way (-1: none).
    """

    v0: int
    v1: int
    v2: int
    site: int
    side: int
    d: float
    kind: int  # FACE_BARK / FACE_SIDE / FACE_CAP
    other: int
    other_side: int


_COL = {name: k for k, name in enumerate(SweepFace._fields)}


class _BranchMesh(NamedTuple):
    """One branch's sweep as arrays: vertices, their faces and skinning candidates."""

    xyz: np.ndarray  # (v, 3) float64, m: sweep vertices
    uv: np.ndarray  # (v, 2) float64, m: section coordinates
    d: np.ndarray  # (v,) float64, m: depth along the branch
    tri: np.ndarray  # (f, 3) int64: sweep vertex ids
    elem: np.ndarray  # (f,) int64: the face's element
    kind: np.ndarray  # (f,) int8: FACE_BARK / FACE_SIDE / FACE_CAP
    nbr: np.ndarray  # (f,) int64: the element across the face, -1 none
    cand_v: np.ndarray  # (c,) int64: skinning candidate pairs, vertex ...
    cand_e: np.ndarray  # (c,) int64: ... and element


@dataclass(frozen=True, eq=False)
class Meshlets:
    """All meshlets of a model as disjoint closed shells (structure of arrays).

    Meshlet e (one per rod element) owns vertices ``vertex_offsets[e]:vertex_offsets[e + 1]`` and
    faces ``face_offsets[e]:face_offsets[e + 1]`` (triangles, counter-clockwise seen from outside).
    ``face_neighbour`` is the element on the other side of a side or cap face (-1 for bark and for
    the caps at strand ends). ``skin_*`` (CSR over vertices): the elements that share the vertex in
    the rest partition, their weights and the vertex in each element's rest frame.
    """

    points: np.ndarray  # (V, 3) rest positions
    faces: np.ndarray  # (F, 3) vertex indices
    face_element: np.ndarray  # (F,)
    face_kind: np.ndarray  # (F,) FACE_BARK / FACE_SIDE / FACE_CAP
    face_neighbour: np.ndarray  # (F,)
    vertex_element: np.ndarray  # (V,) owner
    vertex_shared: np.ndarray  # (V,) the rest-partition vertex this copy is (shared by neighbours)
    vertex_offsets: np.ndarray  # (n + 1,)
    face_offsets: np.ndarray  # (n + 1,)
    wood: np.ndarray  # (V, 3) rest wood-local coordinates (r, phi, s)
    ring: np.ndarray  # (V,) ring age (years)
    skin_indptr: np.ndarray  # (V + 1,)
    skin_element: np.ndarray  # (K,)
    skin_weight: np.ndarray  # (K,) normalised per vertex
    skin_local: np.ndarray  # (K, 3) rest position in the element's rest frame (d1, d2, d3)
    stats: dict = field(default_factory=dict)

    @property
    def count(self) -> int:
        return len(self.vertex_offsets) - 1

    @property
    def n_faces(self) -> int:
        return len(self.faces)


# --------------------------------------------------------------------------------------------
# The sweep of one branch
# --------------------------------------------------------------------------------------------

def _edges(t):
    """Edges of a counter-clockwise triangle as canonical (low, high) pairs with the slot the
    triangle fills: 0 left of low -> high, 1 right."""
    a, b, c = t
    for u, v in ((a, b), (b, c), (c, a)):
        yield ((u, v), 0) if u < v else ((v, u), 1)


class OpenFanError(RuntimeError):
    """A real site on the hull of its branch's sites: its Voronoi cell is unbounded."""


def _cycle(star, j):
    """The triangles around site j in counter-clockwise order (a closed fan)."""
    nxt = {}
    for t in star:
        k = t.index(j)
        nxt[t[(k + 1) % 3]] = t
    start = min(star)
    out, t = [start], start
    while True:
        t = nxt.get(t[(t.index(j) + 2) % 3])
        if t is None or len(out) > len(star):
            raise OpenFanError(f"site {j} lies on the hull of its branch's sites (unbounded cell)")
        if t == start:
            return out
        out.append(t)


class _Strip:
    """The side surface of one Delaunay edge: vertex ids left and right of the canonical edge
    and rungs (index left, index right, d) at the element boundaries of its two sites."""

    __slots__ = ("side", "rungs")

    def __init__(self):
        self.side = ([], [])
        self.rungs = []

    def push(self, slot, v):
        s = self.side[slot]
        if not s or s[-1] != v:
            s.append(v)

    def rung(self, d):
        if not self.rungs or self.rungs[-1][2] != d:
            self.rungs.append((len(self.side[0]) - 1, len(self.side[1]) - 1, d))


class _BranchSweep:
    """Walks the kinetic events of one branch and emits faces over global vertex ids.

    Faces are :class:`SweepFace` rows.
    """

    def __init__(self, br: Branch):
        self.br, self.nr = br, br.n_real
        self.vkey: dict[tuple, int] = {}  # (triangle, d) -> vertex id
        self.vtri: list[tuple] = []  # sites, d and (at a flip) the fourth site
        self.vd: list[float] = []
        self.vfourth: list[int] = []
        self.star: dict[int, set[tuple]] = {}  # site -> set of live triangles with at least one real site
        self.tris: set[tuple] = set()  # all of them
        self.strips: dict[tuple, _Strip] = {}
        self.done: list[tuple[tuple, _Strip]] = []
        self.faces: list[SweepFace] = []
        self.unmatched = 0  # neighbour cells that changed beyond a single run at an event

    # ---- vertices and faces ----------------------------------------------------------------
    def vertex(self, t, d):
        """The id of the sweep vertex at triangle ``t`` and depth ``d`` (created on first use)."""
        v = self.vkey.get((t, d))
        if v is None:
            v = self.vkey[(t, d)] = len(self.vd)
            self.vtri.append(t)
            self.vd.append(d)
            self.vfourth.append(-1)
        return v

    def polygon(self, ids, site, side, d, kind, other, other_side):
        """Fan of a convex polygon of vertex ids (repeated ids dropped)."""
        ids = [v for k, v in enumerate(ids) if v != ids[k - 1]] if len(ids) > 1 else ids
        for k in range(1, len(ids) - 1):
            self.faces.append(SweepFace(ids[0], ids[k], ids[k + 1], site, side, d, kind, other, other_side))

    def cell(self, j, d):
        return [self.vertex(t, d) for t in _cycle(self.star[j], j)]

    # ---- triangulation updates ----------------------------------------------------------
    def apply(self, removed, added, d, kind):
        """Replace the ``removed`` triangles by the ``added`` ones at d: junctions on the strips
        beside them, strips that end or begin, caps of strands that end or begin, and the
        horizontal faces of the neighbours whose cells jump (any change but a single flip)."""
        nr = self.nr
        removed = [t for t in removed if t[0] < nr]  # canonical triangles start at their minimum
        added = [t for t in added if t[0] < nr]
        if not removed and not added:
            return
        flip = kind == FLIP
        if flip:  # the four circumcentres coincide: one vertex, skinned by all four sites
            v = self.vertex(removed[0], d)
            for t in removed[1:] + added:
                self.vkey[(t, d)] = v
            self.vfourth[v] = next(iter({s for t in removed + added for s in t} - set(removed[0])), -1)
        touched = {s for t in removed + added for s in t}
        had = {j for j in touched if self.star.get(j)}
        rem_set = set(removed)
        stays = {s for t in added for s in t}
        ended = {j for j in had if j not in stays and self.star[j] <= rem_set}
        before = {} if flip else {j: _cycle(self.star[j], j) for j in had if j < nr}
        for j in sorted(j for j in ended if j < nr):
            self.polygon([self.vertex(t, d) for t in before[j]], j, -1, d, FACE_CAP, -1, 0)
        hit = {}
        for t in removed:
            v = self.vertex(t, d)
            for e, slot in _edges(t):
                st = self.strips.get(e)
                if st is not None:
                    st.push(slot, v)
                    hit[e] = hit.get(e, 0) | (1 << slot)
            for s in t:
                self.star[s].discard(t)
        self.tris.difference_update(removed)
        # a strip that loses the triangles on both sides ends here (it may begin again with the
        # new ones): its old and new Voronoi edges are then separate edges of the event faces
        for e, sides in hit.items():
            if sides == 3:
                st = self.strips.pop(e)
                st.rung(d)
                self.done.append((e, st))
        for t in added:
            v = self.vertex(t, d)
            for e, slot in _edges(t):
                if e[0] >= nr:
                    continue
                st = self.strips.get(e)
                if st is None:
                    st = self.strips[e] = _Strip()
                st.push(slot, v)
            for s in t:
                self.star.setdefault(s, set()).add(t)
        self.tris.update(added)
        for t in removed:
            for e, _ in _edges(t):
                if e in self.strips and not any(e[1] in x for x in self.star.get(e[0], ())):
                    st = self.strips.pop(e)
                    st.rung(d)
                    self.done.append((e, st))
        for t in added:
            for e, _ in _edges(t):
                st = self.strips.get(e)
                if st is not None and not st.rungs:
                    st.rung(d)
        started = {j for j in touched if j not in had}
        for j in sorted(j for j in started if j < nr):
            self.polygon(self.cell(j, d)[::-1], j, +1, d, FACE_CAP, -1, 0)
        if before:
            self.event_faces(before, d, ended, started)

    def event_faces(self, before, d, ended, started):
        """Horizontal faces of the neighbours whose cells jump where strands begin or end: per
        changed run of j's Voronoi vertices, the removed run (before) and the added run (after,
        reversed) bound the region j gains or loses at d."""
        for j, B in before.items():
            if not self.star.get(j):
                continue
            A = _cycle(self.star[j], j)
            common = set(B) & set(A)
            if len(common) == len(B) == len(A):
                continue
            if not common:
                self.unmatched += 1
                kind, other, side = self._other(j, B + A, ended, started)
                self.polygon([self.vertex(t, d) for t in B], j, 0, d, kind, other, side)
                self.polygon([self.vertex(t, d) for t in A[::-1]], j, 0, d, kind, other, side)
                continue
            pos_a = {t: i for i, t in enumerate(A)}
            nb, na = len(B), len(A)
            for i in range(nb):
                if B[i] in common or B[i - 1] not in common:
                    continue
                run, m = [], i
                while B[m % nb] not in common:
                    run.append(B[m % nb])
                    m += 1
                a, arun = pos_a[B[i - 1]] + 1, []
                while A[a % na] != B[m % nb]:
                    arun.append(A[a % na])
                    a += 1
                kind, other, side = self._other(j, run + arun, ended, started)
                ids = [self.vertex(t, d) for t in run] + [self.vertex(t, d) for t in arun[::-1]]
                self.polygon(ids, j, 0, d, kind, other, side)

    def _other(self, j, tris, ended, started):
        """Kind, site and side of what lies across j's horizontal face: the strand that ended
        or began there (a ghost: bark)."""
        cand = sorted({s for t in tris for s in t if s != j and (s in ended or s in started)})
        if not cand:
            return FACE_SIDE, -1, 0
        real = [s for s in cand if s < self.nr]
        if not real:
            return FACE_BARK, -1, 0
        k = real[0]
        return FACE_SIDE, k, (-1 if k in ended else +1)

    # ---- samples between events -----------------------------------------------------------
    def _sides(self, e):
        p, q = e
        for t in self.star.get(p, ()):
            if q in t:
                i = t.index(p)
                yield (0 if t[(i + 1) % 3] == q else 1), t

    def sample_all(self, d):
        """Samples of every live triangle at a node section (the motion bends there)."""
        for e, st in self.strips.items():
            for slot, t in self._sides(e):
                st.push(slot, self.vertex(t, d))

    def boundary(self, j, d):
        """Element boundary of real site j at d: samples, rungs on j's strips, two caps."""
        for t in self.star[j]:
            v = self.vertex(t, d)
            for e, slot in _edges(t):
                st = self.strips.get(e)
                if st is not None:
                    st.push(slot, v)
        for t in self.star[j]:
            for e, _ in _edges(t):
                if j in e:
                    self.strips[e].rung(d)
        ids = self.cell(j, d)
        self.polygon(ids, j, -1, d, FACE_CAP, j, +1)
        self.polygon(ids[::-1], j, +1, d, FACE_CAP, j, -1)

    def close(self, d):
        """The branch's last section: top caps and the last rung of every strip."""
        for j in range(self.nr):
            if self.star.get(j):
                self.polygon(self.cell(j, d), j, -1, d, FACE_CAP, -1, 0)
        for e in list(self.strips):
            st = self.strips.pop(e)
            for slot, t in self._sides(e):
                st.push(slot, self.vertex(t, d))
            st.rung(d)
            self.done.append((e, st))

    def emit_strips(self):
        """Zipper each strip between consecutive rungs (merge of the two sides by d)."""
        vd, nr = self.vd, self.nr
        for (p, q), st in self.done:
            L, R = st.side
            for (l0, r0, d0), (l1, r1, d1) in zip(st.rungs[:-1], st.rungs[1:]):
                if d1 <= d0:
                    continue
                dm = 0.5 * (d0 + d1)
                i, k = l0, r0
                while i < l1 or k < r1:
                    if k >= r1 or (i < l1 and vd[L[i + 1]] <= vd[R[k + 1]]):
                        tri = (R[k], L[i], L[i + 1])
                        i += 1
                    else:
                        tri = (R[k], L[i], R[k + 1])
                        k += 1
                    if tri[0] == tri[1] or tri[1] == tri[2] or tri[0] == tri[2]:
                        continue
                    if q < nr:
                        self.faces.append(SweepFace(tri[0], tri[1], tri[2], p, 0, dm, FACE_SIDE, q, 0))
                        self.faces.append(SweepFace(tri[0], tri[2], tri[1], q, 0, dm, FACE_SIDE, p, 0))
                    elif q - nr < len(self.br.foreign) and self.br.foreign[q - nr] >= 0:
                        # another branch's strand: a wall to its element
                        self.faces.append(SweepFace(tri[0], tri[1], tri[2], p, 0, dm, FACE_SIDE, q, 0))
                    else:
                        self.faces.append(SweepFace(tri[0], tri[1], tri[2], p, 0, dm, FACE_BARK, -1, 0))

    def element(self, site, side, d):
        """Element of real ``site`` at d (see the class docstring); arrays in, array out."""
        br = self.br
        out = np.empty(len(site), dtype=np.int64)
        order = np.argsort(site, kind="stable")
        cuts = np.searchsorted(site[order], np.arange(self.nr + 1))
        for j in range(self.nr):
            rows = order[cuts[j]:cuts[j + 1]]
            if len(rows) == 0:
                continue
            b = br.bounds[j]
            lo = np.searchsorted(b, d[rows], side="left")
            hi = np.searchsorted(b, d[rows], side="right")
            out[rows] = br.elem0[j] + np.where(side[rows] < 0, lo, hi)
        return out


def sweep_branch(br: Branch):
    """Run the kinetic sweep of one branch and collect its faces (see the module docstring)."""
    kin = sweep(br.d, br.P, br.alive)
    bs = _BranchSweep(br)
    nr = br.n_real
    bd = np.concatenate(br.bounds) if nr else np.zeros(0)
    bsite = np.repeat(np.arange(nr), [len(b) for b in br.bounds])
    order = np.argsort(bd, kind="stable")
    bd, bsite = bd[order].tolist(), bsite[order].tolist()
    node_d = set(br.s_chain.tolist())
    ib = 0
    events = list(kin.iter_events())
    e = 0
    while e < len(events):
        de = events[e][1]
        g = e
        while g < len(events) and events[g][1] == de:
            g += 1
        while ib < len(bd) and bd[ib] < de:
            bs.boundary(bsite[ib], bd[ib])
            ib += 1
        group = events[e:g]
        if len(group) == 1 and group[0][3] is not None:
            _, _, kind, rem, add = group[0]
        else:  # several events at one d (or a snapshot): their net change
            kind = REPAIR
            cur0 = set(bs.tris)
            cur = set(cur0)
            for _, _, _, r, a in group:
                if r is None:
                    cur = {t for t in a if t[0] < nr}
                else:
                    cur.difference_update(r)
                    cur.update(t for t in a if t[0] < nr)
            rem, add = sorted(cur0 - cur), sorted(cur - cur0)
            if len(group) == 1 and group[0][2] == FLIP:
                kind = FLIP
        bs.apply(rem, add, de, kind)
        if de in node_d and any(ev[2] == SECTION for ev in group):
            bs.sample_all(de)
        e = g
    while ib < len(bd):
        bs.boundary(bsite[ib], bd[ib])
        ib += 1
    bs.close(float(br.d[-1]))
    bs.emit_strips()
    return kin, bs


# --------------------------------------------------------------------------------------------
# Geometry: Voronoi vertices in 3D, per-meshlet shells, skinning data
# --------------------------------------------------------------------------------------------

def _circumcentres(X):
    """Circumcentres of triangles X (m, 3, 2)."""
    A = X[:, 0]
    a, b = X[:, 1] - A, X[:, 2] - A
    D = 2.0 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    aa, bb = (a * a).sum(1), (b * b).sum(1)
    return A + np.stack([b[:, 1] * aa - a[:, 1] * bb, a[:, 0] * bb - b[:, 0] * aa], axis=1) / D[:, None]


def _vertex_uv(kin, T, d):
    """Voronoi vertex (circumcentre of the sites T at d) in the branch frame, computed from the
    sites as the predicates see them (perturbed, so coincident strands stay resolved)."""
    S = len(kin.d)
    k = np.clip(np.searchsorted(kin.d, d, side="right") - 1, 0, max(S - 2, 0))
    if S > 1:
        s = ((d - kin.d[k]) / (kin.d[k + 1] - kin.d[k]))[:, None, None]
        X = (1.0 - s) * kin.P[k[:, None], T] + s * kin.P[np.minimum(k + 1, S - 1)[:, None], T]
    else:
        X = kin.P[0][T]
    Xn = (X - kin.centre) / kin.scale + kin.eta * perturbation(kin.n_sites)[T]
    return kin.centre + kin.scale * _circumcentres(Xn)


def _embed(skel, topo, chain, s_chain, d, uv):
    """3D points at distance d along the branch with cross-section coordinates uv."""
    origin, U, V = section_frame(skel, topo, chain, s_chain, d)
    return origin + uv[:, :1] * U + uv[:, 1:] * V


def _strand_element(model: WoodModel, b: int, strand: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Element of each ``strand`` (one that leaves branch ``b`` at a fork, or enters it there) at
    distance ``s`` to the root in the branch it runs in past the fork: the element whose span
    holds s, or the next one where that one is b's (it straddles the fork and is clipped there)."""
    out = np.empty(len(strand), dtype=np.int64)
    for st in np.unique(strand):
        rows = np.flatnonzero(strand == st)
        es = np.arange(model.element_offsets[st], model.element_offsets[st + 1])
        ends = model.particle_s[model.first_particle[es] + 1]
        k = np.minimum(np.searchsorted(ends, s[rows], side="right"), len(es) - 1)
        k = np.minimum(k + (model.branch[es[k]] == b), len(es) - 1)
        out[rows] = es[k]
    return out


def _branch_arrays(model: WoodModel, b: int, br, kin, bs) -> _BranchMesh:
    """Vertices (3D, uv, d), face rows and each vertex's candidate skinning elements."""
    T = np.array(bs.vtri, dtype=np.int64).reshape(-1, 3)
    d = np.array(bs.vd, dtype=float)
    uv = _vertex_uv(kin, T, d)
    xyz = _embed(model.skeleton, model.topology, br.chain, br.s_chain, d, uv)
    F = np.array(bs.faces, dtype=float).reshape(-1, len(SweepFace._fields))
    tri = F[:, :3].astype(np.int64)
    site, side, fd = F[:, _COL["site"]].astype(np.int64), F[:, _COL["side"]].astype(np.int64), F[:, _COL["d"]]
    elem = bs.element(site, side, fd)
    other, oside = F[:, _COL["other"]].astype(np.int64), F[:, _COL["other_side"]].astype(np.int64)
    nbr = np.full(len(F), -1, dtype=np.int64)
    has = (other >= 0) & (other < br.n_real)
    nbr[has] = bs.element(other[has], oside[has], fd[has])
    far = other >= br.n_real
    nbr[far] = _strand_element(model, b, br.foreign[other[far] - br.n_real], fd[far])
    # skinning candidates: the elements of the vertex's real sites on both sides of d
    T4 = np.concatenate([T, np.array(bs.vfourth, dtype=np.int64)[:, None]], axis=1)
    vs = np.repeat(np.arange(len(d)), 8)
    ss = np.repeat(T4, 2, axis=1).ravel()
    sides = np.tile([-1, 1], 4 * len(d))
    real = (ss >= 0) & (ss < br.n_real)
    cand_v, cand_e = vs[real], bs.element(ss[real], sides[real], d[vs[real]])
    return _BranchMesh(xyz, uv, d, tri, elem, F[:, _COL["kind"]].astype(np.int8), nbr, cand_v, cand_e)


def build_meshlets(model: WoodModel) -> Meshlets:
    """Rest meshlets of every rod element of ``model`` (see the module docstring)."""
    t0 = time.perf_counter()
    counts: dict[str, float]
    parts, counts = [], {"flips": 0, "hull": 0, "inserts": 0, "deletes": 0, "repairs": 0,
                         "sections": 0, "unmatched": 0, "branches": 0}
    off = 0
    for b in range(model.n_branches):
        br = setup_branch(model, b)
        if br is None:
            continue
        kin, bs = sweep_branch(br)
        for k, v in kin.counts.items():
            counts[k] += v
        counts["unmatched"] += bs.unmatched
        counts["branches"] += 1
        part = _branch_arrays(model, b, br, kin, bs)
        parts.append(part._replace(tri=part.tri + off, cand_v=part.cand_v + off))
        off += len(part.d)
    gxyz, guv, gd, tri, elem, kind, nbr, cv, ce = (np.concatenate(col) for col in zip(*parts))
    n = model.n_elements
    # faces sorted by element; each meshlet gets its own copy of every vertex it uses
    order = np.argsort(elem, kind="stable")
    tri, elem, kind, nbr = tri[order], elem[order], kind[order], nbr[order]
    key = elem[:, None] * off + tri
    ukey, inv = np.unique(key.ravel(), return_inverse=True)
    faces = inv.reshape(-1, 3)
    v_elem, v_gid = ukey // off, ukey % off
    points = gxyz[v_gid]
    # skinning: candidates per global vertex (unique), then per copy
    ck = np.unique(cv * n + ce)
    cv, ce = ck // n, ck % n
    g_ptr = np.searchsorted(cv, np.arange(off + 1))
    cnt = g_ptr[v_gid + 1] - g_ptr[v_gid]
    skin_indptr = np.concatenate([[0], np.cumsum(cnt)])
    rows = np.repeat(g_ptr[v_gid], cnt) + (np.arange(skin_indptr[-1]) - np.repeat(skin_indptr[:-1], cnt))
    skin_element = ce[rows]
    skin_weight, skin_local, ring = rest_skinning(model, points, skin_indptr, skin_element)
    uvv = guv[v_gid]
    wood = np.stack([fm.hypot(uvv[:, 0], uvv[:, 1]), fm.arctan2(uvv[:, 1], uvv[:, 0]), gd[v_gid]], axis=1)
    mesh = Meshlets(
        points=points, faces=faces.astype(np.int64), face_element=elem, face_kind=kind,
        face_neighbour=nbr, vertex_element=v_elem, vertex_shared=v_gid,
        vertex_offsets=np.searchsorted(v_elem, np.arange(n + 1)),
        face_offsets=np.searchsorted(elem, np.arange(n + 1)), wood=wood, ring=ring,
        skin_indptr=skin_indptr, skin_element=skin_element, skin_weight=skin_weight,
        skin_local=skin_local, stats=counts,
    )
    mesh = junction_walls(model, hull_repair(mesh), FACE_BARK, FACE_SIDE, FACE_CAP)
    if model.skeleton.surface is not None:
        mesh = conform_bark(model, mesh, FACE_BARK)
    if model.bark_thickness == 0.0:
        mesh = replace(mesh, face_kind=np.where(mesh.face_kind == FACE_BARK, FACE_SIDE, mesh.face_kind).astype(mesh.face_kind.dtype))
    counts["seconds"] = time.perf_counter() - t0
    return mesh


def hull_repair(mesh: Meshlets) -> Meshlets:
    """Last resort for a meshlet the sweep left open (:func:`~wooddecay.meshlets.checks.closed_oriented`
    false; 3 of the tree's 54,675, where three sites pass through collinearity between two element
    boundaries): its faces are replaced by the convex hull of its vertices, tagged side faces with
    no neighbour (so they are always exported). The hull is closed and outward-oriented; it may
    overlap its neighbours slightly. Counted in ``stats['hull_repairs']``."""
    bad = np.flatnonzero(~closed_oriented(mesh))
    mesh.stats["hull_repairs"] = int(len(bad))
    if len(bad) == 0:
        return mesh
    fo, vo = mesh.face_offsets, mesh.vertex_offsets
    blocks, last = [], 0
    for e in bad:
        blocks.append(("keep", last, fo[e]))
        P = mesh.points[vo[e]:vo[e + 1]]
        tri = ConvexHull(P).simplices
        c = P.mean(axis=0)
        nrm = np.cross(P[tri[:, 1]] - P[tri[:, 0]], P[tri[:, 2]] - P[tri[:, 0]])
        flip = ((P[tri[:, 0]] - c) * nrm).sum(1) < 0
        tri[flip] = tri[flip][:, ::-1]
        blocks.append(("new", e, tri + vo[e]))
        last = fo[e + 1]
    blocks.append(("keep", last, len(mesh.faces)))
    parts: dict[str, list[np.ndarray]] = {k: [] for k in ("faces", "face_element", "face_kind", "face_neighbour")}
    for kind, a, b in blocks:
        if kind == "keep":
            for k in parts:
                parts[k].append(getattr(mesh, k)[a:b])
        else:
            parts["faces"].append(b)
            parts["face_element"].append(np.full(len(b), a, dtype=mesh.face_element.dtype))
            parts["face_kind"].append(np.full(len(b), FACE_SIDE, dtype=mesh.face_kind.dtype))
            parts["face_neighbour"].append(np.full(len(b), -1, dtype=mesh.face_neighbour.dtype))
    new = {k: np.concatenate(v) for k, v in parts.items()}
    new["face_offsets"] = np.searchsorted(new["face_element"], np.arange(mesh.count + 1))
    return replace(mesh, **new)
