"""Kinetic alpha shape of a branch's cross-sections (woodstock §8.1, Kerber and Edelsbrunner 2013; SPEC §5).

§8.1 bounds the otherwise unbounded Voronoi partition of P(d_t) by an alpha shape: "at each d_t, an
alpha-complex is obtained by pruning the Delaunay triangulation of P(d_t) using a fixed radius
threshold, and its outer polygonal boundary defines the cross-section contour", which is then offset
outwards by the strand radius r_s (SPEC §5). Here:

* alpha complex at d_t: the Delaunay triangles (from :class:`~wooddecay.meshlets.kinetic.KineticResult`)
  whose circumradius R <= alpha (:func:`alpha_complex`); alpha = inf keeps all of them (the
  convex hull). Edges and vertices that belong to no kept triangle are not part of the region.
* contours: the boundary of the union of kept triangles as closed loops of site indices with the
  region on their left: counter-clockwise ``outer`` loops and clockwise ``holes``
  (:func:`boundary_loops`, :func:`contours`). Where two kept fans touch at one site (a pinch) the
  loops are traced fan by fan, so every loop is a simple closed polygon.
* :func:`offset_contour`: the loop pushed outwards by r_s (module-level note there).
* :func:`alpha_events`: the kinetic part. Between two kinetic events a triangle (p, q, r) keeps its
  vertices, and on piece k the sites move linearly, x = X + s V, s in [0, 1]. With a = x_q - x_p,
  b = x_r - x_p, R = |a| |b| |b - a| / (2 |cross(a, b)|), so

      R <= alpha  <=>  h(s) = |a|^2 |b|^2 |b - a|^2 - 4 alpha^2 cross(a, b)^2 <= 0,

  a polynomial of degree <= 6 (three quadratics times each other minus a squared quadratic). Its
  sign-changing roots inside the triangle's lifetime are the membership events: ``+1`` the triangle
  enters the complex (h turns negative), ``-1`` it leaves. Together with the kinetic events
  (:func:`section_boundaries`) they split the branch into slabs in which the alpha complex is
  combinatorially constant. Alpha events use the unperturbed sites; like the kinetic certificates,
  each piece is expanded about its start on [0, 1/2] and about its end on [1/2, 1].
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from wooddecay.meshlets.kinetic import SECTION, KineticResult, _horner, _sign_change_roots


# --------------------------------------------------------------------------------------------
# Static alpha complex and its boundary
# --------------------------------------------------------------------------------------------

def circumradius2(points, tris) -> np.ndarray:
    """Squared circumradius of each triangle (rows of site indices into ``points``); inf if flat."""
    P = np.asarray(points, float)
    T = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    a = P[T[:, 1]] - P[T[:, 0]]
    b = P[T[:, 2]] - P[T[:, 0]]
    ab = b - a
    cr = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    num = (a * a).sum(1) * (b * b).sum(1) * (ab * ab).sum(1)
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = num / (4.0 * cr * cr)
    return np.where(cr != 0.0, r2, np.inf)


def alpha_complex(tris, points, alpha) -> np.ndarray:
    """The triangles of ``tris`` with circumradius <= alpha (alpha = inf: all of them)."""
    T = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    if not np.isfinite(alpha):
        return T.copy()
    return T[circumradius2(points, T) <= float(alpha) ** 2]


def boundary_loops(tris) -> list[np.ndarray]:
    """Boundary of the union of counter-clockwise triangles as closed loops, region on the left.

    A directed edge u -> v of a triangle is a boundary edge when v -> u belongs to no triangle. From
    u -> v the next boundary edge turns clockwise around v through the triangles of the same fan,
    so pinch sites (fans touching at one site) are passed through once per fan. Each loop starts at
    its smallest site index; loops are ordered by that index.
    """
    T = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    apex = {}
    for a, b, c in T.tolist():
        apex[(a, b)] = c
        apex[(b, c)] = a
        apex[(c, a)] = b
    nxt = {}
    for (u, v), _ in apex.items():
        if (v, u) in apex:
            continue
        x = apex[(u, v)]
        guard = 0
        while (x, v) in apex:
            x = apex[(x, v)]
            guard += 1
            if guard > len(T) + 3:
                raise RuntimeError("boundary_loops: triangles are not a consistent oriented set")
        nxt[(u, v)] = (v, x)
    loops = []
    seen = set()
    for start in sorted(nxt):
        if start in seen:
            continue
        loop = []
        e = start
        while e not in seen:
            seen.add(e)
            loop.append(e[0])
            e = nxt[e]
        i = int(np.argmin(loop))
        loops.append(np.array(loop[i:] + loop[:i], dtype=np.int64))
    loops.sort(key=lambda lp: int(lp[0]))
    return loops


def signed_area(xy) -> float:
    """Shoelace area of a closed polygon (positive when counter-clockwise)."""
    xy = np.asarray(xy, float)
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def contours(tris, points):
    """(outer, holes): counter-clockwise outer loops (largest area first) and clockwise hole loops."""
    P = np.asarray(points, float)
    outer, holes = [], []
    for lp in boundary_loops(tris):
        A = signed_area(P[lp])
        (outer if A > 0 else holes).append((A, lp))
    outer.sort(key=lambda x: -x[0])
    holes.sort(key=lambda x: x[0])
    return [lp for _, lp in outer], [lp for _, lp in holes]


@dataclass
class AlphaShape:
    """The alpha shape of one cross-section d_t: kept triangles, contours and the sites (n, 2)."""

    d: float
    alpha: float
    points: np.ndarray
    triangles: np.ndarray
    outer: list
    holes: list

    def outer_xy(self) -> list[np.ndarray]:
        return [self.points[lp] for lp in self.outer]


def alpha_shape(result: KineticResult, alpha: float, t: float) -> AlphaShape:
    """Alpha complex and contours of the branch's cross-section at d_t = t (§8.1)."""
    X = result.positions_at(t)
    T = alpha_complex(result.triangles_at(t), X, alpha)
    outer, holes = contours(T, X)
    return AlphaShape(d=float(t), alpha=float(alpha), points=X, triangles=T, outer=outer, holes=holes)


# --------------------------------------------------------------------------------------------
# Offset
# --------------------------------------------------------------------------------------------

def offset_contour(points, r_s: float, join: str = "round", max_angle: float = np.pi / 8,
                   miter_limit: float = 4.0):
    """Offset a closed polygon (region on its left, e.g. a CCW contour) outwards by r_s.

    Every edge moves by r_s along its outward normal (to its right). At a convex corner ``join``
    decides: ``"round"`` inserts an arc of radius r_s about the corner, split into
    ceil(turn / max_angle) equal segments (its vertices lie exactly at r_s, its chords at least
    r_s cos(max_angle / 2)); ``"miter"`` extends both offset edges to their intersection (bevelled
    when the miter would exceed miter_limit r_s). At a reflex corner both joins take the
    intersection of the two offset edges (at distance r_s from both edges). The result is the
    boundary of the Minkowski sum of the polygon with a disk of radius r_s (up to the chords) as long
    as r_s stays below the local feature size: adjacent edges at a reflex corner longer than
    r_s tan(turn / 2) and non-adjacent parts more than 2 r_s apart; otherwise the curve
    self-intersects and is returned as is (no clipping).

    Returns (xy (k, 2), owner (k,)): the offset polygon (same orientation) and, for each of its
    vertices, the index of the input vertex it comes from.
    """
    if join not in ("round", "miter"):
        raise ValueError(f"join must be 'round' or 'miter', not {join!r}")
    P = np.asarray(points, float)
    m = len(P)
    if m < 2:
        raise ValueError("need a polygon of at least two vertices")
    r = float(r_s)
    e = np.roll(P, -1, axis=0) - P
    L = np.linalg.norm(e, axis=1)
    if np.any(L <= 0):
        raise ValueError("polygon has repeated consecutive vertices")
    tdir = e / L[:, None]
    nrm = np.stack([tdir[:, 1], -tdir[:, 0]], axis=1)        # right of each edge = outwards
    out, owner = [], []
    for i in range(m):
        n_in, n_out = nrm[i - 1], nrm[i]
        t_in, t_out = tdir[i - 1], tdir[i]
        turn = float(np.arctan2(t_in[0] * t_out[1] - t_in[1] * t_out[0], float(t_in @ t_out)))
        v = P[i]
        if turn > 1e-12:                                      # convex corner
            if join == "round":
                k = max(1, int(np.ceil(turn / max_angle)))
                a0 = np.arctan2(n_in[1], n_in[0])
                ang = a0 + turn * np.arange(k + 1) / k
                for a in ang:
                    out.append(v + r * np.array([np.cos(a), np.sin(a)]))
                    owner.append(i)
                continue
            if 1.0 / max(np.cos(0.5 * turn), 1e-300) > miter_limit:
                out.extend((v + r * n_in, v + r * n_out))
                owner.extend((i, i))
                continue
        dot = float(n_in @ n_out)
        if dot <= -1.0 + 1e-12:                               # folds back on itself
            out.extend((v + r * n_in, v + r * n_out))
            owner.extend((i, i))
            continue
        out.append(v + r * (n_in + n_out) / (1.0 + dot))      # miter point: at r from both edges
        owner.append(i)
    return np.array(out), np.array(owner, dtype=np.int64)


# --------------------------------------------------------------------------------------------
# Kinetic alpha-membership events
# --------------------------------------------------------------------------------------------

@nb.njit(cache=True)
def _conv2(u0, u1, u2, v0, v1, v2, out):
    out[0] = u0 * v0
    out[1] = u0 * v1 + u1 * v0
    out[2] = u0 * v2 + u1 * v1 + u2 * v0
    out[3] = u1 * v2 + u2 * v1
    out[4] = u2 * v2


@nb.njit(cache=True)
def _alpha_poly(X, V, p, q, r, alpha2, h):
    """h(s) = |a|^2 |b|^2 |b-a|^2 - 4 alpha^2 cross(a, b)^2 (degree 6) into h[0:7]."""
    ax0 = X[q, 0] - X[p, 0]
    ax1 = V[q, 0] - V[p, 0]
    ay0 = X[q, 1] - X[p, 1]
    ay1 = V[q, 1] - V[p, 1]
    bx0 = X[r, 0] - X[p, 0]
    bx1 = V[r, 0] - V[p, 0]
    by0 = X[r, 1] - X[p, 1]
    by1 = V[r, 1] - V[p, 1]
    cx0, cx1, cy0, cy1 = bx0 - ax0, bx1 - ax1, by0 - ay0, by1 - ay1
    A = np.empty(5)
    _conv2(ax0 * ax0 + ay0 * ay0, 2.0 * (ax0 * ax1 + ay0 * ay1), ax1 * ax1 + ay1 * ay1,
           bx0 * bx0 + by0 * by0, 2.0 * (bx0 * bx1 + by0 * by1), bx1 * bx1 + by1 * by1, A)
    w0 = cx0 * cx0 + cy0 * cy0
    w1 = 2.0 * (cx0 * cx1 + cy0 * cy1)
    w2 = cx1 * cx1 + cy1 * cy1
    for j in range(7):
        h[j] = 0.0
    for j in range(5):
        h[j] += A[j] * w0
        h[j + 1] += A[j] * w1
        h[j + 2] += A[j] * w2
    k0 = ax0 * by0 - ay0 * bx0
    k1 = ax0 * by1 + ax1 * by0 - ay0 * bx1 - ay1 * bx0
    k2 = ax1 * by1 - ay1 * bx1
    K = np.empty(5)
    _conv2(k0, k1, k2, k0, k1, k2, K)
    for j in range(5):
        h[j] -= 4.0 * alpha2 * K[j]


@nb.njit(cache=True)
def _roots_in(h, lo, hi, buf, roots, kinds, e, cnt, flip):
    """Sign changes of h on (lo, hi) appended to row e; flip: h is in powers of u = 1 - t."""
    m = _sign_change_roots(h, 6, lo, hi, buf)
    for j in range(m):
        if flip:
            # u descending = t ascending; h just after the root in t = just below it in u
            jj = m - 1 - j
            below = buf[jj - 1] if jj > 0 else lo
            roots[e, cnt] = 1.0 - buf[jj]
            kinds[e, cnt] = 1 if _horner(h, 6, 0.5 * (below + buf[jj])) < 0.0 else -1
        else:
            above = buf[j + 1] if j + 1 < m else hi
            roots[e, cnt] = buf[j]
            kinds[e, cnt] = 1 if _horner(h, 6, 0.5 * (buf[j] + above)) < 0.0 else -1
        cnt += 1
    return cnt


@nb.njit(cache=True)
def _alpha_roots(P, T, piece, s0, s1, alpha2, roots, kinds):
    """Membership events of every interval: up to 12 roots each (NaN-padded) and their kinds.

    As for the kinetic certificates, [0, 1/2] of a piece is expanded about its start and [1/2, 1]
    about its end (in u = 1 - t), so sites meeting at a section are resolved from its coordinates.
    """
    h = np.empty(7)
    buf = np.empty(7)
    for e in range(T.shape[0]):
        k = piece[e]
        V = P[k + 1] - P[k]
        for j in range(roots.shape[1]):
            roots[e, j] = np.nan
            kinds[e, j] = 0
        cnt = 0
        if s0[e] < 0.5:
            _alpha_poly(P[k], V, T[e, 0], T[e, 1], T[e, 2], alpha2, h)
            cnt = _roots_in(h, s0[e], min(s1[e], 0.5), buf, roots, kinds, e, cnt, False)
        if s1[e] > 0.5:
            _alpha_poly(P[k + 1], -V, T[e, 0], T[e, 1], T[e, 2], alpha2, h)
            cnt = _roots_in(h, 1.0 - s1[e], 1.0 - max(s0[e], 0.5), buf, roots, kinds, e, cnt, True)


@dataclass
class AlphaEvents:
    """Alpha-membership events in order of d_t: ``kind`` +1 the triangle enters, -1 it leaves."""

    alpha: float
    d: np.ndarray
    triangles: np.ndarray
    kind: np.ndarray


def _lifetimes(result: KineticResult):
    """(triangles (m, 3), piece (m,), s0 (m,), s1 (m,)): each triangle's lifetime cut at sections."""
    d = result.d
    sec_of_event = {int(e): k for k, e in enumerate(result.section_event)}
    rows, piece, s0, s1 = [], [], [], []
    live = {}
    cur = -1

    def close(tri, start, end):
        if end > start and cur >= 0:
            span = d[cur + 1] - d[cur]
            rows.append(tri)
            piece.append(cur)
            s0.append((start - d[cur]) / span)
            s1.append(min((end - d[cur]) / span, 1.0))

    for e, de, kind, rem, add in result.iter_events():
        if rem is None:                                   # section or repair: full snapshot
            for tri, start in live.items():
                close(tri, start, de)
            if kind == SECTION:
                k = sec_of_event[e]
                cur = k if k < len(d) - 1 else -1
            live = {tri: de for tri in add}
        else:
            for tri in rem:
                start = live.pop(tri, None)
                if start is not None:
                    close(tri, start, de)
            for tri in add:
                live[tri] = de
    T = np.array(rows, dtype=np.int64).reshape(-1, 3)
    return T, np.array(piece, dtype=np.int64), np.array(s0), np.array(s1)


def alpha_events(result: KineticResult, alpha: float) -> AlphaEvents:
    """Alpha-membership change events of the kinetic triangulation (roots of h, module docstring).

    Every triangle's lifetime (between the kinetic events that create and destroy it, cut at the
    sections where the motion changes) is searched for sign changes of h; the events are returned
    in order of d_t (ties in lifetime order). alpha = inf: no events.
    """
    alpha = float(alpha)
    empty = AlphaEvents(alpha, np.zeros(0), np.zeros((0, 3), dtype=np.int64), np.zeros(0, dtype=np.int8))
    if not np.isfinite(alpha) or len(result.d) < 2:
        return empty
    T, piece, s0, s1 = _lifetimes(result)
    if len(T) == 0:
        return empty
    roots = np.empty((len(T), 12))
    kinds = np.empty((len(T), 12), dtype=np.int8)
    _alpha_roots(np.ascontiguousarray(result.P, float), T, piece, s0, s1, alpha * alpha, roots, kinds)
    e, j = np.nonzero(np.isfinite(roots))
    s = roots[e, j]
    d = result.d[piece[e]] + s * (result.d[piece[e] + 1] - result.d[piece[e]])
    order = np.lexsort((j, e, d))
    return AlphaEvents(alpha, d[order], T[e[order]], kinds[e[order], j[order]])


def section_boundaries(result: KineticResult, alpha: float) -> np.ndarray:
    """Sorted distinct d_t of all kinetic and alpha-membership events: between two consecutive ones
    the alpha complex (and the whole triangulation) is combinatorially constant."""
    return np.unique(np.concatenate([result.d_events, alpha_events(result, alpha).d]))
