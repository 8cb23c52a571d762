"""The kinetic Delaunay triangulation of one branch and its sweep along d_t (woodstock §8.1; docs/model.md §5).

Convex hull: one symbolic vertex at infinity (index n, never a real site). Every hull edge u -> v
(outside on its left) carries the "infinite triangle" (u, v, inf), so the triangulation is always a
closed triangulated sphere and hull changes are ordinary flips of edges that touch inf. The
in-circle test degenerates to an orientation test when inf is one of the four points (the limit of
a far point, :mod:`.certificates`), so the reported real triangles are exactly DT(P(d_t)) with its
convex hull; no bounding sites are added.

Insert and delete (at sections, t = 0 of the piece) are local: insertion locates the site by a
visibility walk, splits its triangle (or attaches the visible hull edges when outside the hull) and
restores the Delaunay property by Lawson flips; deletion removes the site's star, fills the hole by
ear clipping (the hull pocket of a hull site likewise, keeping the new hull convex) and restores the
Delaunay property by Lawson flips. The first build at a section inserts the sites in Morton order.

* Virtual sections (:meth:`_KineticDelaunay.run_piece`). Strands that meet in the middle of a
  piece would again be resolved only from cancelling coefficients: where two Delaunay neighbours
  will pass closer than KAPPA h = 1e-6 h strictly inside the current segment, it is cut at their
  closest approach (:func:`~.certificates.close_pass`; nearest neighbours are Delaunay neighbours,
  so every close pass is seen before it happens). They are not events: the triangulation carries over.
* Repair (last resort). If a flip would still duplicate an edge or create a triangle inverted
  beyond rounding (both new triangles are checked before every flip; with positive old triangles
  they are positive: a resolved in-circle violation implies a convex quad, and a flatness flip
  moves the middle vertex into the neighbouring triangle), the structure is folded already: the
  flip is not done and the sites are re-triangulated from scratch at that time (an event of kind
  ``repair`` with a full snapshot; ``counts['repairs']``), as when a triangle is found inverted at
  a section; the triangulation may have been folded between the unresolved event and the repair.
* Three alive sites: the triangulation is one triangle; when the three become collinear all six
  certificates fire together and the triangle is re-oriented (counted as ``hull``). Fewer than three
  alive sites (or all collinear at a section, possible only with eta = 0): no triangles until a later
  section has three non-collinear sites.
* Safety: more than ``max_events`` events (or 100 repairs) in a piece raise ``RuntimeError``.
"""
from __future__ import annotations

import heapq

import numpy as np

from .certificates import TAU, cert_time, cert_times, cert_violated, close_pass, close_passes, flip_inverts
from .result import (DELETE, ETA, FLIP, HULL, INSERT, REPAIR, SECTION, KineticResult, canon_triangle,
                     perturbation)

#: relative distance below which two neighbours passing each other mid-piece cut the piece there
KAPPA = 1e-6


def _morton_order(xy):
    q = np.clip(((xy - xy.min(0)) / max(np.ptp(xy, axis=0).max(), 1e-300) * 1023).astype(np.int64), 0, 1023)
    key = np.zeros(len(xy), dtype=np.int64)
    for bit in range(10):
        key |= ((q[:, 0] >> bit) & 1) << (2 * bit)
        key |= ((q[:, 1] >> bit) & 1) << (2 * bit + 1)
    return np.argsort(key, kind="stable")


class _Degenerate(RuntimeError):
    """A flip that would break the triangulation: the predicates met an unresolvable configuration."""


class _KineticDelaunay:
    """Directed-edge map of a triangulated sphere: ``apex[u * N + v] = w`` for each ccw triangle (u, v, w)."""

    def __init__(self, n, tau, max_events):
        self.n = n
        self.INF = n
        self.N = n + 1
        self.tau = tau
        self.max_events = max_events
        self.apex = {}
        self.out = [-1] * (n + 1)
        self.sites = set()
        self.built = False
        self.journal = []
        self.X = np.zeros((n, 2))
        self.V = np.zeros((n, 2))
        self.NV = self.V
        self.X1 = self.X
        self.px = [0.0] * n
        self.py = [0.0] * n
        self.hint = -1
        self.cert_ver = {}
        self.version = 0

    # ---- motion --------------------------------------------------------------------------
    def set_motion(self, X, X1):
        """Sites at the start (X) and end (X1) of the piece; V = X1 - X."""
        self.X = np.ascontiguousarray(X, dtype=float)
        self.X1 = np.ascontiguousarray(X1, dtype=float)
        self.V = self.X1 - self.X
        self.NV = -self.V
        self.px = self.X[:, 0].tolist()
        self.py = self.X[:, 1].tolist()

    def _orient(self, a, b, c):
        px, py = self.px, self.py
        return (px[b] - px[a]) * (py[c] - py[a]) - (py[b] - py[a]) * (px[c] - px[a])

    # ---- primitive edits -----------------------------------------------------------------
    def _add(self, a, b, c):
        N, ap, out = self.N, self.apex, self.out
        ap[a * N + b] = c
        ap[b * N + c] = a
        ap[c * N + a] = b
        out[a] = b
        out[b] = c
        out[c] = a
        if a != self.INF and b != self.INF and c != self.INF:
            self.journal.append((1, canon_triangle(a, b, c)))
            self.hint = a * N + b

    def _remove(self, a, b, c):
        N, ap = self.N, self.apex
        del ap[a * N + b]
        del ap[b * N + c]
        del ap[c * N + a]
        if a != self.INF and b != self.INF and c != self.INF:
            self.journal.append((-1, canon_triangle(a, b, c)))

    def _flip(self, p, q, r, s):
        """Edge p -> q between (p, q, r) and (q, p, s) becomes r -> s: (r, p, s) and (s, q, r)."""
        if r * self.N + s in self.apex:
            raise _Degenerate(
                f"kinetic Delaunay: flip of edge {p}-{q} would duplicate edge {r}-{s}; the sites "
                "form a configuration the predicates cannot resolve (coincident strands away from "
                "a section?)")
        self._remove(p, q, r)
        self._remove(q, p, s)
        self._add(r, p, s)
        self._add(s, q, r)

    def take_journal(self):
        """Net (removed, added) real triangles since the last call."""
        j = self.journal
        self.journal = []
        if len(j) <= 4 and len({t for _, t in j}) == len(j):
            return [t for sgn, t in j if sgn < 0], [t for sgn, t in j if sgn > 0]
        net = {}
        for sgn, t in j:
            net[t] = net.get(t, 0) + sgn
        return sorted(t for t, v in net.items() if v < 0), sorted(t for t, v in net.items() if v > 0)

    def triangles(self):
        INF, N = self.INF, self.N
        res = []
        for key, w in self.apex.items():
            u, v = divmod(key, N)
            if u < v and u < w and v != INF and w != INF:
                res.append((u, v, w))
        return res

    def edges(self):
        """Undirected edges (u < v) with their apexes: rows (u, v, left apex, right apex)."""
        N, ap = self.N, self.apex
        rows = []
        for key, w in ap.items():
            u, v = divmod(key, N)
            if u < v:
                rows.append((u, v, w, ap[v * N + u]))
        return rows

    # ---- Lawson flips at the current positions (t = 0 of the piece) ---------------------
    def _violated(self, p, q, r, s):
        return cert_violated(self.X, self.V, p, q, r, s, self.INF, self.tau, 0.0)

    def _lawson(self, stack):
        N, ap = self.N, self.apex
        budget = 100 * (len(self.sites) + 10) + len(stack)
        while stack:
            u, v = stack.pop()
            r = ap.get(u * N + v)
            if r is None:
                continue
            s = ap[v * N + u]
            if r == s:
                continue
            if self._violated(u, v, r, s):
                self._flip(u, v, r, s)
                stack.extend(((u, s), (s, v), (v, r), (r, u)))
                budget -= 1
                if budget < 0:
                    raise RuntimeError("kinetic Delaunay: Lawson flips do not terminate (degenerate input?)")

    # ---- build / clear -------------------------------------------------------------------
    def _clear(self):
        for a, b, c in self.triangles():
            self.journal.append((-1, canon_triangle(a, b, c)))
        self.apex.clear()
        self.built = False
        self.hint = -1

    def _make_triangle(self, a, b, c):
        INF = self.INF
        self._add(a, b, c)
        self._add(b, a, INF)
        self._add(c, b, INF)
        self._add(a, c, INF)
        self.built = True

    def ensure_built(self):
        if self.built or len(self.sites) < 3:
            return
        ids = np.array(sorted(self.sites))
        xy = self.X[ids]
        ia = int(np.lexsort((ids, xy[:, 1], xy[:, 0]))[0])
        a = int(ids[ia])
        d2 = ((xy - xy[ia]) ** 2).sum(1)
        ib = int(np.argmax(d2))
        b = int(ids[ib])
        u = xy[ib] - xy[ia]
        w = xy - xy[ia]
        o = u[0] * w[:, 1] - u[1] * w[:, 0]
        ic = int(np.argmax(np.abs(o)))
        if not abs(o[ic]) > 1e-13 * d2[ib]:
            return                                  # all collinear: no triangulation at this section
        c = int(ids[ic])
        if o[ic] < 0:
            b, c = c, b
        self._make_triangle(a, b, c)
        rest = ids[_morton_order(xy)]
        for x in rest.tolist():
            if x not in (a, b, c):
                self._insert_point(x)

    # ---- insertion -----------------------------------------------------------------------
    def insert(self, x):
        self.sites.add(x)
        if not self.built:
            self.ensure_built()
            return
        self._insert_point(x)

    def _start_triangle(self):
        N, ap, INF = self.N, self.apex, self.INF
        h = self.hint
        if h in ap:
            u, v = divmod(h, N)
            w = ap[h]
            if INF not in (u, v, w):
                return u, v, w
        for a in self.sites:
            if self.out[a] < 0 or (a * N + self.out[a]) not in ap:
                continue
            w0 = self.out[a]
            w = w0
            for _ in range(len(self.sites) + 2):
                c = ap[a * N + w]
                if w != INF and c != INF:
                    return a, w, c
                w = c
                if w == w0:
                    break
        raise RuntimeError("kinetic Delaunay: no real triangle to start the point location")

    def _locate(self, x):
        """('in', a, b, c): x in real triangle (a, b, c); ('out', u, v): x beyond hull edge u -> v."""
        N, ap, INF = self.N, self.apex, self.INF
        orient = self._orient
        a, b, c = self._start_triangle()
        for step in range(4 * len(self.sites) + 16):
            tri = (a, b, c)
            moved = False
            for j in range(3):
                k = (j + step) % 3
                u, v = tri[k], tri[(k + 1) % 3]
                if orient(u, v, x) < 0.0:
                    w = ap[v * N + u]
                    if w == INF:
                        return ("out", v, u)
                    a, b, c = v, u, w
                    moved = True
                    break
            if not moved:
                return ("in", a, b, c)
        return self._locate_brute(x)

    def _locate_brute(self, x):
        orient = self._orient
        best, arg = -np.inf, None
        for a, b, c in self.triangles():
            m = min(orient(a, b, x), orient(b, c, x), orient(c, a, x))
            if m > best:
                best, arg = m, ("in", a, b, c)
        if best >= 0.0:
            return arg
        INF, N = self.INF, self.N
        best, arg = 0.0, arg
        for key, w in self.apex.items():
            if w == INF:
                u, v = divmod(key, N)
                if u != INF and v != INF and orient(u, v, x) > best:
                    best, arg = orient(u, v, x), ("out", u, v)
        return arg

    def _insert_point(self, x):
        loc = self._locate(x)
        N, ap, INF = self.N, self.apex, self.INF
        orient = self._orient
        if loc[0] == "in":
            _, a, b, c = loc
            self._remove(a, b, c)
            self._add(a, b, x)
            self._add(b, c, x)
            self._add(c, a, x)
            stack = [(a, b), (b, c), (c, a)]
        else:
            _, h0, h1 = loc
            chain = [h0, h1]
            for _ in range(len(self.sites)):
                z = ap[chain[0] * N + INF]              # hull vertex before chain[0]
                if z == chain[-1] or orient(z, chain[0], x) <= 0.0:
                    break
                chain.insert(0, z)
            for _ in range(len(self.sites)):
                w = ap[INF * N + chain[-1]]             # hull vertex after chain[-1]
                if w == chain[0] or orient(chain[-1], w, x) <= 0.0:
                    break
                chain.append(w)
            stack = []
            for j in range(len(chain) - 1):
                self._remove(chain[j], chain[j + 1], INF)
                self._add(chain[j], chain[j + 1], x)
                stack.append((chain[j], chain[j + 1]))
            self._add(chain[0], x, INF)
            self._add(x, chain[-1], INF)
            stack.extend(((chain[0], INF), (chain[-1], INF), (x, INF)))
        self._lawson(stack)

    # ---- deletion ------------------------------------------------------------------------
    def delete(self, v):
        self.sites.discard(v)
        if not self.built:
            return
        if len(self.sites) < 3:
            self._clear()
            return
        N, ap, INF = self.N, self.apex, self.INF
        ring = []
        w0 = self.out[v]
        w = w0
        while True:
            ring.append(w)
            w = ap[v * N + w]
            if w == w0:
                break
        m = len(ring)
        for i in range(m):
            self._remove(v, ring[i], ring[(i + 1) % m])
        if INF in ring:
            j = ring.index(INF)
            chain = ring[j + 1:] + ring[:j]
            new = self._clip_ears(chain, closed=False)
            for i in range(len(chain) - 1):
                self._add(chain[i], chain[i + 1], INF)
                new.append((chain[i], chain[i + 1], INF))
        else:
            new = self._clip_ears(ring, closed=True)
        stack = []
        for a, b, c in new:
            stack.extend(((a, b), (b, c), (c, a)))
        self._lawson(stack)

    def _clip_ears(self, poly, closed):
        """Triangulate the hole around a deleted site by ear clipping (edits ``poly`` in place).

        closed: the star polygon of an interior site (ccw), clipped down to one triangle.
        open: the chain of a hull site's neighbours; left turns (pocket ears) are clipped until the
        chain is convex, which is then the new hull.
        """
        orient = self._orient
        new = []

        def is_ear(i):
            k = len(poly)
            a, b, c = poly[(i - 1) % k], poly[i], poly[(i + 1) % k]
            if orient(a, b, c) <= 0.0:
                return False
            for p in poly:
                if p in (a, b, c):
                    continue
                if orient(a, b, p) >= 0.0 and orient(b, c, p) >= 0.0 and orient(c, a, p) >= 0.0:
                    return False
            return True

        while len(poly) > (3 if closed else 2):
            k = len(poly)
            cand = range(k) if closed else range(1, k - 1)
            ear = next((i for i in cand if is_ear(i)), None)
            if ear is None:
                if not closed:
                    break
                # float trouble: take the most convex corner
                ear = max(cand, key=lambda i: orient(poly[(i - 1) % k], poly[i], poly[(i + 1) % k]))
            a, b, c = poly[(ear - 1) % k], poly[ear], poly[(ear + 1) % k]
            self._add(a, b, c)
            new.append((a, b, c))
            del poly[ear]
        if closed:
            self._add(poly[0], poly[1], poly[2])
            new.append((poly[0], poly[1], poly[2]))
        return new

    # ---- validity and repair ---------------------------------------------------------------
    def invalid(self):
        """True when a real triangle is inverted at the current positions (beyond rounding)."""
        T = self.triangles()
        if not T:
            return False
        T = np.array(T)
        a, b, c = self.X[T[:, 0]], self.X[T[:, 1]], self.X[T[:, 2]]
        u, v = b - a, c - a
        o = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
        bound = np.linalg.norm(u, axis=1) * np.linalg.norm(v, axis=1)
        return bool(np.any(o < -1e-10 * bound))

    def rebuild(self):
        """Triangulate the current sites from scratch (incremental insertion at t = 0)."""
        self._clear()
        self.ensure_built()

    # ---- kinetic events --------------------------------------------------------------------
    def _schedule(self, heap, a, b, half, val):
        if a > b:
            a, b = b, a
        N, ap, INF = self.N, self.apex, self.INF
        key = a * N + b
        r = ap[key]
        s = ap[b * N + a]
        h, v = cert_time(self.X, self.X1, self.V, self.NV, a, b, r, s, INF, self.tau, half, val)
        self.version += 1
        self.cert_ver[key] = self.version
        if h < 2:
            heapq.heappush(heap, (h, v, key, self.version))
        if b != INF:
            sp = close_pass(self.X, self.V, a, b, val if half == 0 else 1.0 + val, KAPPA * KAPPA)
            if 0.0 <= sp < self.split:
                self.split = sp

    def _schedule_all(self):
        rows = self.edges()
        self.cert_ver = {}
        if not rows:
            return []
        Q = np.array(rows, dtype=np.int64)
        halves = np.empty(len(Q), dtype=np.int64)
        vals = np.empty(len(Q))
        cert_times(self.X, self.X1, self.V, Q, self.INF, self.tau, halves, vals)
        sp = close_passes(self.X, self.V, Q, self.INF, KAPPA * KAPPA)
        if sp < self.split:
            self.split = sp
        N = self.N
        heap = []
        for (u, v, _, _), h, val in zip(rows, halves.tolist(), vals.tolist()):
            self.version += 1
            key = u * N + v
            self.cert_ver[key] = self.version
            if h < 2:
                heap.append((h, val, key, self.version))
        heapq.heapify(heap)
        return heap

    def run_piece(self, log, snapshot, d0, d1, piece):
        """Process the flip and hull events of the piece [d0, d1] (local parameter t in [0, 1]).

        The piece is cut into segments at virtual sections: when two Delaunay neighbours will pass
        closer than KAPPA h in the middle of the current segment, the segment is shortened to end
        at their closest approach (positions there computed directly), so a cluster of strands
        meeting mid-piece sits at a segment end, where the end expansion resolves it. A flip that
        would still duplicate an edge is not done: the sites are re-triangulated from scratch at
        that time (a ``repair`` snapshot) and the piece goes on from there.
        """
        Xs, Xe = self.X, self.X1
        Vp = Xe - Xs

        def pos(t):
            if t <= 0.0:
                return Xs
            if t >= 1.0:
                return Xe
            return Xs + t * Vp if t <= 0.5 else Xe - (1.0 - t) * Vp

        def d_of(t):
            return d1 if t >= 1.0 else d0 + t * (d1 - d0)

        tA, tB = 0.0, 1.0
        stops = []
        self.count = 0
        repairs = 0
        while True:
            self.set_motion(pos(tA), pos(tB))
            try:
                out = self._run_segment(log, d_of(tA), d_of(tB), piece)
            except _Degenerate as exc:
                repairs += 1
                if repairs > 100:
                    raise RuntimeError(f"kinetic Delaunay: 100 repairs in piece {piece} (d = {d0}..{d1})") from exc
                if getattr(exc, "time", None) is None:
                    raise
                half, val = exc.time
                s_now = val if half == 0 else 1.0 + val
                tA = tA + s_now * (tB - tA)
                self.set_motion(pos(tA), pos(tB))
                self.rebuild()
                snapshot(REPAIR, d_of(tA))
                continue
            if out is None:                          # segment done
                if not stops:
                    return
                tA, tB = tB, stops.pop()
            else:                                    # cut the segment at a close pass
                s_now, s_cut = out
                stops.append(tB)
                tA, tB = tA + s_now * (tB - tA), tA + s_cut * (tB - tA)

    def _run_segment(self, log, d0, d1, piece):
        """Events of one segment (local parameter 0..1 between the positions X and X1).

        Returns None when done, or (now, cut) (segment parameters) to cut the segment at ``cut``.
        """
        if not self.built:
            return None
        self.split = np.inf
        heap = self._schedule_all()
        if self.split < np.inf:
            return 0.0, self.split
        N, ap, INF = self.N, self.apex, self.INF
        while heap:
            half, val, key, ver = heapq.heappop(heap)
            if self.cert_ver.get(key) != ver:
                continue
            self.count += 1
            if self.count > self.max_events:
                raise RuntimeError(
                    f"kinetic Delaunay: more than {self.max_events} events in piece {piece} "
                    f"(d = {d0}..{d1}); the input is too degenerate for the predicates")
            de = d0 + val * (d1 - d0) if half == 0 else d1 + val * (d1 - d0)
            if len(self.sites) == 3:
                # three sites passing through collinearity: the one triangle turns over
                a, b, c = self.triangles()[0]
                self._clear()
                self._make_triangle(a, c, b)
                log(HULL, de)
                heap = []
                self.cert_ver = {}
                for u, v, _, _ in self.edges():
                    self._schedule(heap, u, v, half, val)
            else:
                u, v = divmod(key, N)
                r = ap[u * N + v]
                s = ap[v * N + u]
                try:
                    if flip_inverts(self.X, self.X1, self.V, self.NV, u, v, r, s, INF, self.tau, half,
                                     val):
                        raise _Degenerate(
                            f"kinetic Delaunay: flip of edge {u}-{v} would leave an inverted triangle "
                            "(the triangulation is folded there)")
                    self._flip(u, v, r, s)
                except _Degenerate as exc:
                    exc.time = (half, val)
                    raise
                del self.cert_ver[key]
                log(HULL if INF in (u, v, r, s) else FLIP, de)
                self._schedule(heap, r, s, half, val)
                self._schedule(heap, u, s, half, val)
                self._schedule(heap, s, v, half, val)
                self._schedule(heap, v, r, half, val)
                self._schedule(heap, r, u, half, val)
            if self.split < np.inf:
                return (val if half == 0 else 1.0 + val), self.split
        return None


def _check_runs(alive):
    a = alive.astype(np.int8)
    starts = np.sum(np.diff(a, axis=0, prepend=0) == 1, axis=0)
    bad = np.nonzero(starts > 1)[0]
    if len(bad):
        raise ValueError(f"alive must be one contiguous run per site; sites {bad[:10].tolist()} have several")


class _EventLog:
    """The events of a sweep in the order they happen: their d_t, kinds, the real triangles each
    removed and added, and the whole triangulation at a ``section`` or ``repair`` event (its
    snapshot, :class:`~.result.KineticResult`)."""

    def __init__(self, kd: _KineticDelaunay):
        self.kd = kd
        self.d: list[float] = []
        self.kinds: list[int] = []
        self.removed: list = []
        self.added: list = []
        self.snapshots: dict[int, list] = {}

    def log(self, kind, de):
        """An event at ``de`` whose changes are those journaled by the triangulation since the last."""
        rem, add = self.kd.take_journal()
        self.d.append(de)
        self.kinds.append(kind)
        self.removed.append(rem)
        self.added.append(add)

    def snapshot(self, kind, de):
        """An event at ``de`` that stores the whole triangulation (its journal is dropped)."""
        self.kd.take_journal()
        self.snapshots[len(self.d)] = [canon_triangle(*t) for t in self.kd.triangles()]
        self.d.append(de)
        self.kinds.append(kind)
        self.removed.append([])
        self.added.append([])


def _checked_sites(d, P, alive, eta):
    """``d``, ``P`` and ``alive`` of :func:`sweep` as float and bool arrays, checked, and the
    positions with 0 where a site is not alive."""
    d = np.asarray(d, dtype=float)
    P = np.asarray(P, dtype=float)
    if d.ndim != 1 or P.ndim != 3 or P.shape[0] != len(d) or P.shape[2] != 2:
        raise ValueError(f"expected d (S,) and P (S, n, 2); got {d.shape} and {P.shape}")
    if len(d) < 1:
        raise ValueError("need at least one section")
    if np.any(np.diff(d) <= 0):
        raise ValueError("sections d must be strictly increasing")
    S, n = P.shape[:2]
    alive = np.isfinite(P).all(axis=2) if alive is None else np.asarray(alive, dtype=bool)
    if alive.shape != (S, n):
        raise ValueError(f"alive must be (S, n) = {(S, n)}; got {alive.shape}")
    if np.any(alive & ~np.isfinite(P).all(axis=2)):
        raise ValueError("alive sites must have finite positions")
    _check_runs(alive)
    Pc = np.where(alive[..., None], P, 0.0)
    if eta == 0.0:
        for k in range(S):
            pts = Pc[k][alive[k]]
            if len(np.unique(pts, axis=0)) < len(pts):
                raise ValueError(f"section {k} has coincident sites; they need the perturbation eta > 0")
    return d, P, alive, Pc


def _normalised(P, Pc, alive, eta):
    """The alive sites centred on their bounding box, scaled by its extent h and perturbed by index
    (eta, :func:`~.result.perturbation`), 0 where not alive; with the centre and h."""
    if alive.any():
        pts = P[alive]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre = 0.5 * (lo + hi)
        h = float(np.max(hi - lo))
        h = h if h > 0 else 1.0
    else:
        centre, h = np.zeros(2), 1.0
    Pn = (Pc - centre) / h + eta * perturbation(P.shape[1])[None]
    Pn = np.where(alive[..., None], Pn, 0.0)
    return Pn, centre, h


def _run_sections(kd, events, d, alive, Pn):
    """Sweep ``kd`` through the sections d and the pieces between them (woodstock §8.1), logging
    into ``events``: at section k the sites beginning there are inserted, a folded triangulation
    is rebuilt (``repair``), the section snapshot is taken and the sites ending there deleted, then
    the flip and hull events of piece k are run. Returns each section's event index and the
    numbers of inserts and deletes."""
    S = len(d)
    section_event = np.zeros(S, dtype=np.int64)
    n_insert = n_delete = 0
    for k in range(S):
        if k < S - 1:
            both = (alive[k] & alive[k + 1])[:, None]
            kd.set_motion(Pn[k], np.where(both, Pn[k + 1], Pn[k]))
        else:
            kd.set_motion(Pn[k], Pn[k])
        if k == 0:
            for i in np.nonzero(alive[0])[0].tolist():
                kd.sites.add(i)
            kd.ensure_built()
            kd.take_journal()
        else:
            for i in np.nonzero(alive[k] & ~alive[k - 1])[0].tolist():
                kd.insert(i)
                events.log(INSERT, float(d[k]))
                n_insert += 1
            kd.ensure_built()           # a section that first has three non-collinear sites
            if kd.journal:
                events.log(INSERT, float(d[k]))
        if kd.built and kd.invalid():       # an unresolved mid-piece cluster left a fold behind
            kd.rebuild()
            events.snapshot(REPAIR, float(d[k]))
        section_event[k] = len(events.d)
        events.snapshot(SECTION, float(d[k]))
        if k < S - 1:
            for i in np.nonzero(alive[k] & ~alive[k + 1])[0].tolist():
                kd.delete(i)
                events.log(DELETE, float(d[k]))
                n_delete += 1
            kd.run_piece(events.log, events.snapshot, float(d[k]), float(d[k + 1]), k)
    return section_event, n_insert, n_delete


def sweep(d, P, alive=None, *, eta: float = ETA, tau: float = TAU, max_events: int | None = None) -> KineticResult:
    """Kinetic Delaunay triangulation of one branch's moving sites along d_t (woodstock §8.1).

    Parameters
    ----------
    d : (S,) strictly increasing cross-section parameters d_t (distance to the root).
    P : (S, n, 2) site P_i(d_k) in the branch's cross-section frame (ignored where not alive).
    alive : (S, n) bool, one contiguous run per site (default: where P is finite).
    eta : relative index-based perturbation (:mod:`.result`; 0 disables it).
    tau : relative hysteresis of the certificates.
    max_events : bound on the events of one piece (default 2000 (n + 10)); beyond it RuntimeError.

    Returns
    -------
    KineticResult: events, their triangulations, ``triangles_at(t)`` and the event ``counts``
    (``flips``: in-circle flips, ``hull``: convex-hull flips, ``inserts`` / ``deletes``: strands
    beginning / ending at a section after the first / before the last, ``repairs``: rebuilds, see
    the module docstring, ``sections``).
    """
    d, P, alive, Pc = _checked_sites(d, P, alive, eta)
    S, n = P.shape[:2]
    Pn, centre, h = _normalised(P, Pc, alive, eta)
    kd = _KineticDelaunay(n, tau, max_events if max_events is not None else 2000 * (n + 10))
    events = _EventLog(kd)
    section_event, n_insert, n_delete = _run_sections(kd, events, d, alive, Pn)
    kinds_arr = np.array(events.kinds, dtype=np.int8)
    counts = {
        "flips": int(np.sum(kinds_arr == FLIP)),
        "hull": int(np.sum(kinds_arr == HULL)),
        "inserts": n_insert,
        "deletes": n_delete,
        "repairs": int(np.sum(kinds_arr == REPAIR)),
        "sections": S,
    }
    return KineticResult(
        d=d, P=Pc, alive=alive, d_events=np.array(events.d), kinds=kinds_arr,
        section_event=section_event, snapshot_event=np.array(sorted(events.snapshots), dtype=np.int64),
        counts=counts, eta=eta, tau=tau, centre=centre, scale=h,
        _removed=events.removed, _added=events.added, _snapshots=events.snapshots,
    )
