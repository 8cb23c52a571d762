"""Kinetic 2D Delaunay triangulation of a branch's strand sites along d_t (woodstock §8.1; SPEC §5).

For one branch, strand i crosses the cross-section at d_t in the site P_i(d_t) (branch frame, 2D),
sampled at the sections ``d[0] < d[1] < ... < d[S-1]`` and linear in d_t between two of them
(§8.1: "we represent each P_i(d_t) piecewise linearly between successive cross-sections"). The
paper tracks the Voronoi partition of P(d_t) with Guibas et al. [1992]; this module carries its dual,
the Delaunay triangulation DT(P(d_t)), along d_t with discrete events:

* ``flip``    four sites become co-circular: the in-circle certificate of an edge changes sign
              (roots of a polynomial of degree <= 4 in the local parameter of the piece, below);
* ``hull``    three consecutive hull sites become collinear: the convex hull changes (roots of an
              orientation polynomial of degree <= 2);
* ``insert``  a strand begins at a section; ``delete``: a strand ends at a section;
* ``section`` every input section is an event too (the motion changes there).

Motion. On piece k (d_k <= d_t <= d_{k+1}) with local parameter s = (d_t - d_k) / (d_{k+1} - d_k)
in [0, 1], x_i(s) = X_i + s V_i with X = P[k] and V = P[k+1] - P[k].

Convex hull: one symbolic vertex at infinity (index n, never a real site). Every hull edge u -> v
(outside on its left) carries the "infinite triangle" (u, v, inf), so the triangulation is always a
closed triangulated sphere and hull changes are ordinary flips of edges that touch inf. The
in-circle test degenerates to an orientation test when inf is one of the four points (the limit of a
far point, not a finite approximation), so the reported real triangles are exactly DT(P(d_t)) with
its convex hull; no bounding sites are added.

Certificates. An edge p -> q with left triangle (p, q, r) and right triangle (q, p, z) (both
counter-clockwise) is locally Delaunay while f(s) <= tau m(s) (the hysteresis bound below), with

    f = incircle(p, q, r; z) = w_a cross(b, c) + w_b cross(c, a) + w_c cross(a, b)
        a = x_p - x_z, b = x_q - x_z, c = x_r - x_z, w_u = |u|^2,  cross(u, v) = u_x v_y - u_y v_x

positive when z lies inside the circumcircle of (p, q, r). Each entry is exactly linear (a, b, c)
or quadratic (w) in s, so f is a quartic whose five coefficients are expanded in closed form from
X and V (:func:`incircle_coefficients`). With inf among the four points f is an orientation
(a quadratic): z = inf: f = -orient(p, q, r); r = inf: f = -orient(q, p, z); p = inf:
f = orient(z, q, r); q = inf: f = orient(r, p, z), where orient(a, b, c) = cross(x_b - x_a, x_c - x_a).

Flatness. Every real triangle (a, b, c) also carries the certificate orient(a, b, c) >= -tau m (a
quadratic, m its permanent bound; violated once the triangle is inverted beyond rounding), charged
to its longest edge at that time, i.e. the edge p -> q opposite the middle vertex r of the flattening
triangle; the event flips p-q, which moves r across it. In exact arithmetic this certificate never
fires first: when r reaches p-q the circumcircle of (p, q, r) has become the half-plane beyond p-q,
which holds the apex z across it, so the in-circle certificate of p-q is positive at the collinearity
(flipping p-q there is the exact Delaunay move, and r then lies inside (q, p, z), so both new
triangles are positive). With the hysteresis it is needed: that positive value is proportional to
z's distance to the line through p, q, r (times the sites' distances along it), and for four
nearly collinear sites (e.g. two pairs of nearly coincident sites: a strand on the profile and its
ghost mirror, passing another such pair) it can stay below tau m, the bound being inflated besides
by the expansion about a section where the four are far apart. The in-circle certificate then
fires only after the triangle has turned over, the structure is folded in between, and the flip
done then leaves an inverted triangle. The event time of an edge is therefore the earlier of its
in-circle (or hull) certificate and the flatness of those of its two real triangles whose longest
edge it is at their flatness time (all three edges of a triangle evaluate the same polynomial, from
its canonical rotation, and agree on the longest edge). A flatness flip lowers the lifted surface
too (the exact in-circle value is positive), and the new edge starts near -f, within the band, so
the no-cycling argument below still holds.

Roots. The event time of a certificate is the first s >= s_0 (the current time) with
g(s) = f(s) - tau m(s) > 0 in the piece. It is found without companion matrices: the
sign-changing roots of g', g'', ... split [s_0, 1] into intervals on which g is monotone
(recursively, from the linear derivative up), and bisection on the first monotone interval whose
end has g > 0 gives the time to the last bit. Tangencies (double roots, no sign change) are
therefore never events, and tiny leading coefficients do no harm.

Degeneracies (documented treatment):

* Hysteresis with an error bound. Each certificate is evaluated relative to the one of its points
  whose permanent bound is smallest at the expansion point (a point inside a tight cluster, so
  three nearly coincident sites and a far one still give an accurate sign), and it fires when
  f(s) > tau * m(s), with m(s) the permanent bound of f: the same expansion over absolute values
  (a polynomial with non-negative coefficients that bounds every rounded term for s in [0, 1]),
  tau = 1e-13 (the rounding error of expansion and evaluation is below ~5e-15 m). An edge flips
  only once f > +tau m; the flipped edge starts near -f, so float noise never flips an edge back
  and forth, and every flip lowers the lifted surface by a resolved amount (Lawson's argument), so
  simultaneous events cannot cycle. Both g = f - tau m and its roots are polynomial, as above.
* Two expansions per piece. [0, 1/2] is expanded about the piece's start (powers of t, positions
  of section k), [1/2, 1] about its end (powers of u = 1 - t, positions of section k + 1), and event
  times are kept as (half, t) or (half, -u) keys: strands that meet at a section (coincident
  sites there) are resolved from that section's own coordinates at full relative precision
  instead of from O(1) coefficients cancelling to 1e-18, and 1 - u never rounds u away.
* Symbolic-like perturbation. Coincident sites (two strands through one point), collinear and
  co-circular sets (grids, circles) are broken by a tiny deterministic index-based displacement:
  every predicate sees P_i(d) + eta h u_i, with h the extent of the branch's sites, eta = 1e-8
  (>> tau, so the perturbation is resolved by the predicates) and u_i = rho_i (cos(i phi), sin(i phi))
  with the golden angle phi and rho_i = 0.5 + 0.5 frac(i / golden ratio)
  (KineticResult.predicate_positions_at gives these positions). Coincident sites therefore become
  sites ~1e-8 h apart and never crash the structure; co-circular ties resolve the same way on
  every run. Coordinates are first centred and scaled by h (the DT is similarity-invariant).
* Degenerate configurations at a section (e.g. a grid exactly co-circular at d_k) are resolved by
  the motion: certificates already violated at s_0 are events at s_0 (processed first), and a
  certificate that is zero at s_0 fires as soon as the motion takes it past tau m.
* Virtual sections. Strands that meet in the middle of a piece would again be resolved only from
  cancelling coefficients. Whenever two Delaunay neighbours will pass closer than KAPPA h = 1e-6 h
  strictly inside the current segment of the piece, the segment is cut at their closest approach
  (positions there computed directly) and all certificates are re-expanded, so the meeting point
  becomes a segment end. (Nearest neighbours are Delaunay neighbours, so every close pass is seen
  before it happens.) Virtual sections are not events: the triangulation just carries over.
* Repair (last resort). If a flip would still duplicate an edge or create a triangle that is
  inverted beyond rounding (both new triangles are checked before every flip; with positive old
  triangles they are positive: a resolved in-circle violation implies a convex quad, and a
  flatness flip moves the middle vertex into the neighbouring triangle), the structure is folded
  already and the flip is not done: the sites are re-triangulated from scratch at that time by
  incremental insertion (an event of kind ``repair`` with a full snapshot; ``counts['repairs']``),
  as when a triangle is found inverted at a section; the triangulation may have been folded
  between the unresolved event and the repair.
* Three alive sites: the triangulation is one triangle; when the three become collinear all six
  certificates fire together and the triangle is re-oriented (counted as ``hull``). Fewer than three
  alive sites (or all collinear at a section, possible only with eta = 0): no triangles until a later
  section has three non-collinear sites.
* Safety: a piece with more than ``max_events`` events (or 100 repairs) raises ``RuntimeError``;
  the sweep never loops forever.

Insert and delete (at sections, t = 0 of the piece) are local: insertion locates the site by a
visibility walk, splits its triangle (or attaches the visible hull edges when outside the hull) and
restores the Delaunay property by Lawson flips; deletion removes the site's star, fills the hole by
ear clipping (the hull pocket of a hull site likewise, keeping the new hull convex) and restores the
Delaunay property by Lawson flips. The first build at a section inserts the sites in Morton order.

Cost: O(1) flips and five edge certificate recomputations (numba; each with the flatness of the
edge's two triangles) per event with a binary heap of event times (stale entries are skipped by
version numbers); O(n) per section (all certificates are recomputed because the velocities change
there, and the triangulation is snapshotted).
"""
from __future__ import annotations

import heapq
from bisect import bisect_right
from dataclasses import dataclass, field

import numba as nb
import numpy as np

#: relative hysteresis of the certificates (see module docstring)
TAU = 1e-13
#: relative index-based perturbation of the sites (see module docstring)
ETA = 1e-8
#: relative distance below which two neighbours passing each other mid-piece cut the piece there
KAPPA = 1e-6

KIND_NAMES = ("section", "flip", "hull", "insert", "delete", "repair")
SECTION, FLIP, HULL, INSERT, DELETE, REPAIR = range(6)
#: kinds whose event stores a full snapshot instead of the changes
SNAPSHOT_KINDS = (SECTION, REPAIR)

_GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))
_INV_PHI = (np.sqrt(5.0) - 1.0) / 2.0


# --------------------------------------------------------------------------------------------
# Polynomial kernels (numba): coefficients in ascending powers of the local parameter s.
# --------------------------------------------------------------------------------------------

@nb.njit(cache=True)
def _horner(c, deg, t):
    acc = c[deg]
    for j in range(deg - 1, -1, -1):
        acc = acc * t + c[j]
    return acc


@nb.njit(cache=True)
def _bisect_sign(c, deg, a, b, fa):
    """Sign-change root of c in (a, b) (c(a) = fa and c(b) of opposite strict signs)."""
    pos = fa > 0.0
    while True:
        m = 0.5 * (a + b)
        if m <= a or m >= b:
            break
        fm = _horner(c, deg, m)
        if (fm > 0.0) == pos and fm != 0.0:
            a = m
        else:
            b = m
    return 0.5 * (a + b)


@nb.njit(cache=True)
def _sign_change_roots(c, deg, lo, hi, out):
    """Roots of c in (lo, hi) where c changes sign, ascending, written to out; returns the count.

    Bottom-up over the derivatives: c^(k) is monotone between consecutive sign-change roots of
    c^(k+1), so each of those intervals holds at most one sign change of c^(k), found by bisection.
    """
    if deg <= 0:
        return 0
    D = np.zeros((deg + 1, deg + 1))
    for j in range(deg + 1):
        D[0, j] = c[j]
    for k in range(1, deg + 1):
        for j in range(deg - k + 1):
            D[k, j] = D[k - 1, j + 1] * (j + 1)
    prev = np.empty(deg + 1)
    cur = np.empty(deg + 1)
    m = 0
    for k in range(deg - 1, -1, -1):
        dk = deg - k
        row = D[k]
        cnt = 0
        a = lo
        fa = _horner(row, dk, a)
        for j in range(m + 1):
            b = prev[j] if j < m else hi
            fb = _horner(row, dk, b)
            if (fa < 0.0 and fb > 0.0) or (fa > 0.0 and fb < 0.0):
                cur[cnt] = _bisect_sign(row, dk, a, b, fa)
                cnt += 1
            a = b
            fa = fb
        for j in range(cnt):
            prev[j] = cur[j]
        m = cnt
    for j in range(m):
        out[j] = prev[j]
    return m


@nb.njit(cache=True)
def _bisect(c, deg, neg, pos):
    """Bisect between ``neg`` (c <= 0) and ``pos`` (c > 0), in either order, to adjacent floats;
    returns the end where c > 0."""
    while True:
        mid = 0.5 * (neg + pos)
        if mid == neg or mid == pos:
            return pos
        if _horner(c, deg, mid) > 0.0:
            pos = mid
        else:
            neg = mid


@nb.njit(cache=True)
def _first_positive(c, deg, t0, t1):
    """Smallest t in [t0, t1] with c(t) > 0 (to the last bit; c(t) > 0 holds there), inf if none."""
    if _horner(c, deg, t0) > 0.0:
        return t0
    if deg <= 0:
        return np.inf
    dc = np.empty(deg)
    for j in range(deg):
        dc[j] = c[j + 1] * (j + 1)
    crit = np.empty(deg)
    m = _sign_change_roots(dc, deg - 1, t0, t1, crit)
    a = t0
    for j in range(m + 1):
        b = crit[j] if j < m else t1
        if _horner(c, deg, b) > 0.0:      # c(a) <= 0 < c(b) and c monotone on [a, b]
            return _bisect(c, deg, a, b)
        a = b
    return np.inf


@nb.njit(cache=True)
def _last_positive(c, deg, lo, hi):
    """Largest u in [lo, hi] with c(u) > 0 (to the last bit; c(u) > 0 holds there), -inf if none."""
    if _horner(c, deg, hi) > 0.0:
        return hi
    if deg <= 0:
        return -np.inf
    dc = np.empty(deg)
    for j in range(deg):
        dc[j] = c[j + 1] * (j + 1)
    crit = np.empty(deg)
    m = _sign_change_roots(dc, deg - 1, lo, hi, crit)
    b = hi
    for j in range(m, -1, -1):
        a = crit[j - 1] if j > 0 else lo
        if _horner(c, deg, a) > 0.0:      # c(a) > 0 >= c(b) and c monotone on [a, b]
            return _bisect(c, deg, b, a)
        b = a
    return -np.inf


@nb.njit(cache=True)
def _lifted_det(X, V, o, i, j, k, sign, c, m):
    """sign * det3 of the lifted rows of x_i, x_j, x_k relative to x_o, for x = X + t V.

    det3(a, b, c) = w_a cross(b, c) + w_b cross(c, a) + w_c cross(a, b), w_u = |u|^2. Writes the
    quartic's coefficients to c[0:5] and those of its permanent bound (the same expansion over
    absolute values, so m(t) >= |every rounded term| for t in [0, 1]) to m[0:5].
    """
    ax0 = X[i, 0] - X[o, 0]
    ax1 = V[i, 0] - V[o, 0]
    ay0 = X[i, 1] - X[o, 1]
    ay1 = V[i, 1] - V[o, 1]
    bx0 = X[j, 0] - X[o, 0]
    bx1 = V[j, 0] - V[o, 0]
    by0 = X[j, 1] - X[o, 1]
    by1 = V[j, 1] - V[o, 1]
    cx0 = X[k, 0] - X[o, 0]
    cx1 = V[k, 0] - V[o, 0]
    cy0 = X[k, 1] - X[o, 1]
    cy1 = V[k, 1] - V[o, 1]
    # squared lengths (quadratics)
    wa0 = ax0 * ax0 + ay0 * ay0
    wa1 = 2.0 * (ax0 * ax1 + ay0 * ay1)
    wa2 = ax1 * ax1 + ay1 * ay1
    wb0 = bx0 * bx0 + by0 * by0
    wb1 = 2.0 * (bx0 * bx1 + by0 * by1)
    wb2 = bx1 * bx1 + by1 * by1
    wc0 = cx0 * cx0 + cy0 * cy0
    wc1 = 2.0 * (cx0 * cx1 + cy0 * cy1)
    wc2 = cx1 * cx1 + cy1 * cy1
    # cross(b, c), cross(c, a), cross(a, b) (quadratics)
    o0 = bx0 * cy0 - by0 * cx0
    o1 = bx0 * cy1 + bx1 * cy0 - by0 * cx1 - by1 * cx0
    o2 = bx1 * cy1 - by1 * cx1
    p0 = cx0 * ay0 - cy0 * ax0
    p1 = cx0 * ay1 + cx1 * ay0 - cy0 * ax1 - cy1 * ax0
    p2 = cx1 * ay1 - cy1 * ax1
    q0 = ax0 * by0 - ay0 * bx0
    q1 = ax0 * by1 + ax1 * by0 - ay0 * bx1 - ay1 * bx0
    q2 = ax1 * by1 - ay1 * bx1
    c[0] = sign * (wa0 * o0 + wb0 * p0 + wc0 * q0)
    c[1] = sign * (wa0 * o1 + wa1 * o0 + wb0 * p1 + wb1 * p0 + wc0 * q1 + wc1 * q0)
    c[2] = sign * (wa0 * o2 + wa1 * o1 + wa2 * o0 + wb0 * p2 + wb1 * p1 + wb2 * p0
                   + wc0 * q2 + wc1 * q1 + wc2 * q0)
    c[3] = sign * (wa1 * o2 + wa2 * o1 + wb1 * p2 + wb2 * p1 + wc1 * q2 + wc2 * q1)
    c[4] = sign * (wa2 * o2 + wb2 * p2 + wc2 * q2)
    # permanent bound
    ax0, ax1, ay0, ay1 = abs(ax0), abs(ax1), abs(ay0), abs(ay1)
    bx0, bx1, by0, by1 = abs(bx0), abs(bx1), abs(by0), abs(by1)
    cx0, cx1, cy0, cy1 = abs(cx0), abs(cx1), abs(cy0), abs(cy1)
    wa1 = 2.0 * (ax0 * ax1 + ay0 * ay1)
    wb1 = 2.0 * (bx0 * bx1 + by0 * by1)
    wc1 = 2.0 * (cx0 * cx1 + cy0 * cy1)
    o0 = bx0 * cy0 + by0 * cx0
    o1 = bx0 * cy1 + bx1 * cy0 + by0 * cx1 + by1 * cx0
    o2 = bx1 * cy1 + by1 * cx1
    p0 = cx0 * ay0 + cy0 * ax0
    p1 = cx0 * ay1 + cx1 * ay0 + cy0 * ax1 + cy1 * ax0
    p2 = cx1 * ay1 + cy1 * ax1
    q0 = ax0 * by0 + ay0 * bx0
    q1 = ax0 * by1 + ax1 * by0 + ay0 * bx1 + ay1 * bx0
    q2 = ax1 * by1 + ay1 * bx1
    m[0] = wa0 * o0 + wb0 * p0 + wc0 * q0
    m[1] = wa0 * o1 + wa1 * o0 + wb0 * p1 + wb1 * p0 + wc0 * q1 + wc1 * q0
    m[2] = (wa0 * o2 + wa1 * o1 + wa2 * o0 + wb0 * p2 + wb1 * p1 + wb2 * p0
            + wc0 * q2 + wc1 * q1 + wc2 * q0)
    m[3] = wa1 * o2 + wa2 * o1 + wb1 * p2 + wb2 * p1 + wc1 * q2 + wc2 * q1
    m[4] = wa2 * o2 + wb2 * p2 + wc2 * q2


@nb.njit(cache=True)
def _cross_lin(X, V, o, i, j, sign, c, m):
    """sign * cross(x_i - x_o, x_j - x_o) into c[0:3], its permanent bound into m[0:3]."""
    ux0 = X[i, 0] - X[o, 0]
    ux1 = V[i, 0] - V[o, 0]
    uy0 = X[i, 1] - X[o, 1]
    uy1 = V[i, 1] - V[o, 1]
    vx0 = X[j, 0] - X[o, 0]
    vx1 = V[j, 0] - V[o, 0]
    vy0 = X[j, 1] - X[o, 1]
    vy1 = V[j, 1] - V[o, 1]
    c[0] = sign * (ux0 * vy0 - uy0 * vx0)
    c[1] = sign * (ux0 * vy1 + ux1 * vy0 - uy0 * vx1 - uy1 * vx0)
    c[2] = sign * (ux1 * vy1 - uy1 * vx1)
    m[0] = abs(ux0 * vy0) + abs(uy0 * vx0)
    m[1] = abs(ux0 * vy1) + abs(ux1 * vy0) + abs(uy0 * vx1) + abs(uy1 * vx0)
    m[2] = abs(ux1 * vy1) + abs(uy1 * vx1)


@nb.njit(cache=True)
def _origin_score(m, deg):
    """Bound at the expansion point, ties broken by its mean over the half piece it serves."""
    acc = 0.0
    for j in range(deg + 1):
        acc += m[j] * 0.5 ** (j + 1) / (j + 1)
    return m[0] + 1e-3 * acc


@nb.njit(cache=True)
def _incircle_best(X, V, p, q, r, s, c, m):
    """incircle(p, q, r; s) = F(p, q, r, s) (alternating in its four points), evaluated relative to
    the point whose permanent bound is smallest at the expansion point (a point of a tight cluster):
    F = det3(p-s, q-s, r-s) = -det3(q-p, r-p, s-p) = det3(r-q, s-q, p-q) = -det3(s-r, p-r, q-r).
    """
    c2 = np.empty(5)
    m2 = np.empty(5)
    _lifted_det(X, V, s, p, q, r, 1.0, c, m)
    best = _origin_score(m, 4)
    for k in range(3):
        if k == 0:
            _lifted_det(X, V, p, q, r, s, -1.0, c2, m2)
        elif k == 1:
            _lifted_det(X, V, q, r, s, p, 1.0, c2, m2)
        else:
            _lifted_det(X, V, r, s, p, q, -1.0, c2, m2)
        b = _origin_score(m2, 4)
        if b < best:
            best = b
            for j in range(5):
                c[j] = c2[j]
                m[j] = m2[j]


@nb.njit(cache=True)
def _orient_best(X, V, a, b, cc, sign, c, m):
    """sign * orient(a, b, cc) (cyclic-invariant) relative to the vertex with the smallest bound."""
    c2 = np.empty(5)
    m2 = np.empty(5)
    for j in range(5):
        c[j] = 0.0
        m[j] = 0.0
        c2[j] = 0.0
        m2[j] = 0.0
    _cross_lin(X, V, a, b, cc, sign, c, m)
    best = _origin_score(m, 2)
    for k in range(2):
        if k == 0:
            _cross_lin(X, V, b, cc, a, sign, c2, m2)
        else:
            _cross_lin(X, V, cc, a, b, sign, c2, m2)
        bb = _origin_score(m2, 2)
        if bb < best:
            best = bb
            for j in range(3):
                c[j] = c2[j]
                m[j] = m2[j]


@nb.njit(cache=True)
def _certificate(X, V, p, q, r, s, inf, tau, g):
    """Certificate of edge p -> q (left apex r, right apex s) into g: violated when g(t) > 0.

    g = f - tau * bound (module docstring); returns the degree. One of p, q, r, s may be ``inf``.
    """
    m = np.empty(5)
    if s == inf:
        _orient_best(X, V, p, q, r, -1.0, g, m)
        deg = 2
    elif r == inf:
        _orient_best(X, V, q, p, s, -1.0, g, m)
        deg = 2
    elif p == inf:
        _orient_best(X, V, s, q, r, 1.0, g, m)
        deg = 2
    elif q == inf:
        _orient_best(X, V, r, p, s, 1.0, g, m)
        deg = 2
    else:
        _incircle_best(X, V, p, q, r, s, g, m)
        deg = 4
    for j in range(deg + 1):
        g[j] -= tau * m[j]
    return deg


@nb.njit(cache=True)
def _flatness(X, V, a, b, c, tau):
    """Flatness certificate of the real ccw triangle (a, b, c): the coefficients (g0, g1, g2) of
    g = -orient(a, b, c) - tau * bound, > 0 once the triangle is inverted beyond rounding. As
    :func:`_orient_best` (relative to the vertex with the smallest bound), from the triangle's
    canonical rotation, so each of its three edges gets the same polynomial; no allocation."""
    if b < a and b < c:
        a, b, c = b, c, a
    elif c < a and c < b:
        a, b, c = c, a, b
    best = np.inf
    g0 = g1 = g2 = 0.0
    for k in range(3):
        if k == 0:
            o, i, j = a, b, c
        elif k == 1:
            o, i, j = b, c, a
        else:
            o, i, j = c, a, b
        ux0 = X[i, 0] - X[o, 0]
        ux1 = V[i, 0] - V[o, 0]
        uy0 = X[i, 1] - X[o, 1]
        uy1 = V[i, 1] - V[o, 1]
        vx0 = X[j, 0] - X[o, 0]
        vx1 = V[j, 0] - V[o, 0]
        vy0 = X[j, 1] - X[o, 1]
        vy1 = V[j, 1] - V[o, 1]
        m0 = abs(ux0 * vy0) + abs(uy0 * vx0)
        m1 = abs(ux0 * vy1) + abs(ux1 * vy0) + abs(uy0 * vx1) + abs(uy1 * vx0)
        m2 = abs(ux1 * vy1) + abs(uy1 * vx1)
        score = m0 + 1e-3 * (0.5 * m0 + 0.125 * m1 + m2 * (0.125 / 3.0))     # _origin_score
        if score < best:
            best = score
            g0 = -(ux0 * vy0 - uy0 * vx0) - tau * m0
            g1 = -(ux0 * vy1 + ux1 * vy0 - uy0 * vx1 - uy1 * vx0) - tau * m1
            g2 = -(ux1 * vy1 - uy1 * vx1) - tau * m2
    return g0, g1, g2


@nb.njit(cache=True)
def _qbisect(g0, g1, g2, neg, pos):
    """:func:`_bisect` for the quadratic g0 + g1 t + g2 t^2."""
    while True:
        mid = 0.5 * (neg + pos)
        if mid == neg or mid == pos:
            return pos
        if (g2 * mid + g1) * mid + g0 > 0.0:
            pos = mid
        else:
            neg = mid


@nb.njit(cache=True)
def _quad_first_positive(g0, g1, g2, t0, t1):
    """:func:`_first_positive` for a quadratic (monotone pieces split at its vertex)."""
    if (g2 * t0 + g1) * t0 + g0 > 0.0:
        return t0
    a = t0
    if g2 != 0.0:
        tc = -g1 / (2.0 * g2)
        if t0 < tc < t1:
            if (g2 * tc + g1) * tc + g0 > 0.0:
                return _qbisect(g0, g1, g2, t0, tc)
            a = tc
    if (g2 * t1 + g1) * t1 + g0 > 0.0:
        return _qbisect(g0, g1, g2, a, t1)
    return np.inf


@nb.njit(cache=True)
def _quad_last_positive(g0, g1, g2, lo, hi):
    """:func:`_last_positive` for a quadratic: the first positive time of q(-s) on [-hi, -lo]."""
    return -_quad_first_positive(g0, -g1, g2, -hi, -lo)


@nb.njit(cache=True)
def _edge_key(X0, X1, V, NV, p, q, r, s, inf, tau, half, val):
    """First time key at or after (half, val) at which the edge certificate of p -> q is violated
    (see :func:`_cert_time`; (2, 0.0): never)."""
    g = np.empty(5)
    umax = 0.5
    if half == 0:
        deg = _certificate(X0, V, p, q, r, s, inf, tau, g)
        te = _first_positive(g, deg, val, 0.5)
        if te <= 0.5:
            return 0, te
    else:
        umax = -val
    deg = _certificate(X1, NV, p, q, r, s, inf, tau, g)
    u = _last_positive(g, deg, 0.0, umax)
    if u >= 0.0:
        return 1, -u
    return 2, 0.0


@nb.njit(cache=True)
def _flat_key(X0, X1, V, NV, a, b, c, tau, half, val, hmax, vmax):
    """First time key in [(half, val), (hmax, vmax)] at which the triangle (a, b, c) is inverted
    beyond rounding ((2, 0.0): none)."""
    umax = 0.5
    if half == 0:
        g0, g1, g2 = _flatness(X0, V, a, b, c, tau)
        t1 = vmax if hmax == 0 else 0.5
        te = _quad_first_positive(g0, g1, g2, val, t1)
        if te <= t1:
            return 0, te
        if hmax == 0:
            return 2, 0.0
    else:
        umax = -val
    ulo = -vmax if hmax == 1 else 0.0
    g0, g1, g2 = _flatness(X1, NV, a, b, c, tau)
    u = _quad_last_positive(g0, g1, g2, ulo, umax)
    if u >= ulo:
        return 1, -u
    return 2, 0.0


@nb.njit(cache=True)
def _is_longest(X0, X1, V, a, b, c, p, q, half, val):
    """Whether p-q is the longest edge of the triangle (a, b, c) at the key (half, val) (exactly one
    edge is: ties go to the first in the canonical rotation, so all three edges agree)."""
    if b < a and b < c:
        a, b, c = b, c, a
    elif c < a and c < b:
        a, b, c = c, a, b
    X = X0 if half == 0 else X1
    t = val                                     # half 1: x = X1 - u V with u = -val
    best = -1.0
    u0, v0 = a, b
    for k in range(3):
        i, j = (a, b) if k == 0 else ((b, c) if k == 1 else (c, a))
        dx = (X[j, 0] + t * V[j, 0]) - (X[i, 0] + t * V[i, 0])
        dy = (X[j, 1] + t * V[j, 1]) - (X[i, 1] + t * V[i, 1])
        l2 = dx * dx + dy * dy
        if l2 > best:
            best = l2
            u0, v0 = i, j
    return (u0 == p and v0 == q) or (u0 == q and v0 == p)


@nb.njit(cache=True)
def _cert_time(X0, X1, V, NV, p, q, r, s, inf, tau, half, val):
    """First time at or after (half, val) at which the edge p -> q must flip.

    That is the earlier of (a) its in-circle (or hull) certificate failing and (b) one of its two
    real triangles (p, q, r) or (q, p, s) turning over (inverted beyond rounding) while p-q is that
    triangle's longest edge (the flip then moves the middle vertex across p-q; module docstring).

    Times are keys (half, val): half 0: t = val in [0, 1/2], from the expansion about the piece's
    start (X0, powers of t); half 1: u = 1 - t = -val in [0, 1/2], from the expansion about its end
    (X1, powers of u); (2, 0.0): never. Near a section, where strands often meet, values thus come
    from that section's own positions (not from cancelling O(1) coefficients), and u keeps its full
    relative precision (1 - u would round it to 1e-16, more than such events are apart).
    Keys sort in time order as tuples.
    """
    h, v = _edge_key(X0, X1, V, NV, p, q, r, s, inf, tau, half, val)
    if p == inf or q == inf:
        return h, v
    if r != inf:
        h2, v2 = _flat_key(X0, X1, V, NV, p, q, r, tau, half, val, h, v)
        if h2 < 2 and (h2 < h or (h2 == h and v2 < v)) and _is_longest(X0, X1, V, p, q, r, p, q, h2, v2):
            h, v = h2, v2
    if s != inf:
        h2, v2 = _flat_key(X0, X1, V, NV, q, p, s, tau, half, val, h, v)
        if h2 < 2 and (h2 < h or (h2 == h and v2 < v)) and _is_longest(X0, X1, V, q, p, s, p, q, h2, v2):
            h, v = h2, v2
    return h, v


@nb.njit(cache=True)
def _flip_inverts(X0, X1, V, NV, p, q, r, s, inf, tau, half, val):
    """Whether flipping p -> q (left apex r, right apex s) at (half, val) would create a real
    triangle (r, p, s) or (s, q, r) that is inverted beyond rounding (a folded quad)."""
    if r == inf or s == inf:
        return False
    for k in range(2):
        a, b, c = (r, p, s) if k == 0 else (s, q, r)
        if a == inf or b == inf or c == inf:
            continue
        if half == 0:
            g0, g1, g2 = _flatness(X0, V, a, b, c, tau)
            t = val
        else:
            g0, g1, g2 = _flatness(X1, NV, a, b, c, tau)
            t = -val
        if (g2 * t + g1) * t + g0 > 0.0:
            return True
    return False


@nb.njit(cache=True)
def _cert_times(X0, X1, V, Q, inf, tau, halves, vals):
    NV = -V
    for e in range(Q.shape[0]):
        h, v = _cert_time(X0, X1, V, NV, Q[e, 0], Q[e, 1], Q[e, 2], Q[e, 3], inf, tau, 0, 0.0)
        halves[e] = h
        vals[e] = v


@nb.njit(cache=True)
def _cert_violated(X, V, p, q, r, s, inf, tau, t):
    g = np.empty(5)
    deg = _certificate(X, V, p, q, r, s, inf, tau, g)
    return _horner(g, deg, t) > 0.0


@nb.njit(cache=True)
def _close_pass(X, V, a, b, s0, kappa2):
    """Segment parameter of the closest approach of sites a and b when it is a close pass
    (distance < kappa) strictly inside (s0, 1) and not already at s0 or at 1 (there the distance
    is within 1e3 of the minimum); -1 otherwise."""
    dx0 = X[b, 0] - X[a, 0]
    dy0 = X[b, 1] - X[a, 1]
    dx1 = V[b, 0] - V[a, 0]
    dy1 = V[b, 1] - V[a, 1]
    vv = dx1 * dx1 + dy1 * dy1
    if vv == 0.0:
        return -1.0
    s = -(dx0 * dx1 + dy0 * dy1) / vv
    if not (s0 < s < 1.0):
        return -1.0
    ex, ey = dx0 + s * dx1, dy0 + s * dy1
    dmin2 = ex * ex + ey * ey
    if dmin2 >= kappa2:
        return -1.0
    ax, ay = dx0 + s0 * dx1, dy0 + s0 * dy1
    bx, by = dx0 + dx1, dy0 + dy1
    if ax * ax + ay * ay < 1e6 * dmin2 or bx * bx + by * by < 1e6 * dmin2:
        return -1.0
    return s


@nb.njit(cache=True)
def _close_passes(X, V, Q, inf, kappa2):
    best = np.inf
    for e in range(Q.shape[0]):
        if Q[e, 1] != inf:
            s = _close_pass(X, V, Q[e, 0], Q[e, 1], 0.0, kappa2)
            if 0.0 <= s < best:
                best = s
    return best


def incircle_coefficients(x0, v):
    """Coefficients (ascending powers of s) of incircle(p, q, r; z) for rows x0 + s v of (4, 2) arrays.

    Row order p, q, r, z; positive when z is inside the circumcircle of counter-clockwise (p, q, r).
    Exact expansion of the 3x3 lifted determinant about s = 0, relative to z (module docstring),
    degree <= 4.
    """
    c = np.empty(5)
    m = np.empty(5)
    _lifted_det(np.asarray(x0, float), np.asarray(v, float), 3, 0, 1, 2, 1.0, c, m)
    return c


def first_positive_time(coeffs, t0=0.0, t1=1.0):
    """Smallest t in [t0, t1] where the polynomial (ascending coefficients) is > 0; inf if none."""
    c = np.asarray(coeffs, float)
    return float(_first_positive(c, len(c) - 1, float(t0), float(t1)))


def sign_change_roots(coeffs, lo=0.0, hi=1.0):
    """Roots of the polynomial (ascending coefficients) in (lo, hi) where it changes sign."""
    c = np.asarray(coeffs, float)
    out = np.empty(max(len(c), 1))
    m = _sign_change_roots(c, len(c) - 1, float(lo), float(hi), out)
    return out[:m].copy()


# --------------------------------------------------------------------------------------------
# Result
# --------------------------------------------------------------------------------------------

def _canon(a, b, c):
    """Rotation of the counter-clockwise triangle (a, b, c) that starts at its smallest index."""
    if a < b and a < c:
        return (a, b, c)
    if b < c:
        return (b, c, a)
    return (c, a, b)


def _as_array(tris):
    if not tris:
        return np.zeros((0, 3), dtype=np.int64)
    return np.array(sorted(tris), dtype=np.int64)


@dataclass
class KineticResult:
    """Output of :func:`sweep`: the kinetic Delaunay triangulation of one branch (§8.1).

    Events are listed in order of d_t (``d_events``, non-decreasing) with their ``kinds`` (codes of
    :data:`KIND_NAMES`); every input section is an event of kind ``section`` whose triangulation is
    stored (``section_event[k]`` is its event index), as is that of a ``repair`` (a rebuild from
    scratch, see :func:`sweep`); any other event stores the real triangles it removed and added
    (``changes``), so a triangulation is the last snapshot plus a replay.

    Triangles are (T, 3) int arrays of site indices, counter-clockwise, rotated to start at their
    smallest index and sorted; triangles touching the infinite vertex are never reported. The
    combinatorial structure is constant between events.

    At a section d_k the sites alive at k are inserted first (``insert`` events), then the section
    snapshot (all sites alive at k), then the sites whose run ends at k are deleted (``delete``).
    """

    d: np.ndarray
    P: np.ndarray
    alive: np.ndarray
    d_events: np.ndarray
    kinds: np.ndarray
    section_event: np.ndarray
    snapshot_event: np.ndarray
    counts: dict
    eta: float
    tau: float
    centre: np.ndarray
    scale: float
    _removed: list = field(repr=False)
    _added: list = field(repr=False)
    _snapshots: dict = field(repr=False)

    @property
    def n_sites(self) -> int:
        return self.P.shape[1]

    @property
    def n_events(self) -> int:
        return len(self.d_events)

    def changes(self, e):
        """(removed, added) real triangles of event e, each (k, 3)."""
        return _as_array(self._removed[e]), _as_array(self._added[e])

    def triangulation(self, e) -> np.ndarray:
        """The triangulation right after event e (valid until event e + 1)."""
        e = int(e)
        if not 0 <= e < self.n_events:
            raise IndexError(f"event {e} out of range [0, {self.n_events})")
        k = int(np.searchsorted(self.snapshot_event, e, side="right")) - 1
        e0 = int(self.snapshot_event[k])
        cur = set(self._snapshots[e0])
        for j in range(e0 + 1, e + 1):
            cur.difference_update(self._removed[j])
            cur.update(self._added[j])
        return _as_array(cur)

    def event_at(self, t) -> int:
        """Index of the event whose triangulation is valid at d_t = t.

        At an input section exactly, its snapshot (all sites alive there); elsewhere the last event
        with d_e <= t.
        """
        t = float(t)
        if t < self.d[0] or t > self.d[-1]:
            raise ValueError(f"d_t = {t} outside the branch [{self.d[0]}, {self.d[-1]}]")
        k = int(np.searchsorted(self.d, t))
        if k < len(self.d) and self.d[k] == t:
            return int(self.section_event[k])
        return bisect_right(self.d_events, t) - 1

    def triangles_at(self, t) -> np.ndarray:
        """Delaunay triangles of the sites alive at d_t = t (counter-clockwise site indices)."""
        return self.triangulation(self.event_at(t))

    def alive_at(self, t) -> np.ndarray:
        """Boolean (n,) mask of the sites present at d_t = t (between sections: alive at both ends)."""
        k, s = self._piece(t)
        if s == 0.0:
            return self.alive[k].copy()
        return self.alive[k] & self.alive[k + 1]

    def positions_at(self, t) -> np.ndarray:
        """(n, 2) sites at d_t = t (linear between sections, unperturbed); NaN where not alive."""
        k, s = self._piece(t)
        if s == 0.0:
            X = self.P[k].astype(float).copy()
        else:
            X = (1.0 - s) * self.P[k] + s * self.P[k + 1]
        X[~self.alive_at(t)] = np.nan
        return X

    def predicate_positions_at(self, t) -> np.ndarray:
        """(n, 2) sites as the predicates see them: centred, scaled by the extent and perturbed by
        index (module docstring); NaN where not alive. The triangulation is exactly Delaunay for
        these (up to the hysteresis tau)."""
        X = (self.positions_at(t) - self.centre) / self.scale
        return X + self.eta * _perturbation(self.n_sites)

    def _piece(self, t):
        t = float(t)
        if t < self.d[0] or t > self.d[-1]:
            raise ValueError(f"d_t = {t} outside the branch [{self.d[0]}, {self.d[-1]}]")
        k = int(np.searchsorted(self.d, t, side="right")) - 1
        if k >= len(self.d) - 1 or self.d[k] == t:
            return min(k, len(self.d) - 1), 0.0
        return k, (t - self.d[k]) / (self.d[k + 1] - self.d[k])

    def iter_events(self):
        """Yield (e, d_e, kind, removed, added) in order; removed/added are lists of tuples.

        For a section or repair event, ``removed`` is None and ``added`` the full snapshot.
        """
        for e in range(self.n_events):
            if int(self.kinds[e]) in SNAPSHOT_KINDS:
                yield e, float(self.d_events[e]), int(self.kinds[e]), None, list(self._snapshots[e])
            else:
                yield e, float(self.d_events[e]), int(self.kinds[e]), self._removed[e], self._added[e]

    def iter_triangulations(self):
        """Yield (e, d_e, triangles) for every event by incremental replay (no per-event rebuild)."""
        cur = set()
        for e, de, kind, rem, add in self.iter_events():
            if rem is None:
                cur = set(add)
            else:
                cur.difference_update(rem)
                cur.update(add)
            yield e, de, _as_array(cur)


# --------------------------------------------------------------------------------------------
# The kinetic structure
# --------------------------------------------------------------------------------------------

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
            self.journal.append((1, _canon(a, b, c)))
            self.hint = a * N + b

    def _remove(self, a, b, c):
        N, ap = self.N, self.apex
        del ap[a * N + b]
        del ap[b * N + c]
        del ap[c * N + a]
        if a != self.INF and b != self.INF and c != self.INF:
            self.journal.append((-1, _canon(a, b, c)))

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
        return _cert_violated(self.X, self.V, p, q, r, s, self.INF, self.tau, 0.0)

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
            self.journal.append((-1, _canon(a, b, c)))
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
        h, v = _cert_time(self.X, self.X1, self.V, self.NV, a, b, r, s, INF, self.tau, half, val)
        self.version += 1
        self.cert_ver[key] = self.version
        if h < 2:
            heapq.heappush(heap, (h, v, key, self.version))
        if b != INF:
            sp = _close_pass(self.X, self.V, a, b, val if half == 0 else 1.0 + val, KAPPA * KAPPA)
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
        _cert_times(self.X, self.X1, self.V, Q, self.INF, self.tau, halves, vals)
        sp = _close_passes(self.X, self.V, Q, self.INF, KAPPA * KAPPA)
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
                    if _flip_inverts(self.X, self.X1, self.V, self.NV, u, v, r, s, INF, self.tau, half,
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


# --------------------------------------------------------------------------------------------
# Public entry point
# --------------------------------------------------------------------------------------------

def _perturbation(n):
    i = np.arange(n, dtype=float)
    rho = 0.5 + 0.5 * np.mod(i * _INV_PHI, 1.0)
    return np.stack([rho * np.cos(i * _GOLDEN_ANGLE), rho * np.sin(i * _GOLDEN_ANGLE)], axis=1)


def _check_runs(alive):
    a = alive.astype(np.int8)
    starts = np.sum(np.diff(a, axis=0, prepend=0) == 1, axis=0)
    bad = np.nonzero(starts > 1)[0]
    if len(bad):
        raise ValueError(f"alive must be one contiguous run per site; sites {bad[:10].tolist()} have several")


def sweep(d, P, alive=None, *, eta: float = ETA, tau: float = TAU, max_events: int | None = None) -> KineticResult:
    """Kinetic Delaunay triangulation of one branch's moving sites along d_t (woodstock §8.1).

    Parameters
    ----------
    d : (S,) strictly increasing cross-section parameters d_t (distance to the root).
    P : (S, n, 2) site P_i(d_k) in the branch's cross-section frame (ignored where not alive).
    alive : (S, n) bool, one contiguous run per site (default: where P is finite).
    eta : relative index-based perturbation (module docstring; 0 disables it).
    tau : relative hysteresis of the certificates.
    max_events : bound on the events of one piece (default 2000 (n + 10)); beyond it RuntimeError.

    Returns
    -------
    KineticResult: events, their triangulations, ``triangles_at(t)`` and the event ``counts``
    (``flips``: in-circle flips, ``hull``: convex-hull flips, ``inserts`` / ``deletes``: strands
    beginning / ending at a section after the first / before the last, ``repairs``: rebuilds, see
    the module docstring, ``sections``).
    """
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

    # normalise (centre, extent h) and perturb by index
    if alive.any():
        pts = P[alive]
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        centre = 0.5 * (lo + hi)
        h = float(np.max(hi - lo))
        h = h if h > 0 else 1.0
    else:
        centre, h = np.zeros(2), 1.0
    Pn = (Pc - centre) / h + eta * _perturbation(n)[None]
    Pn = np.where(alive[..., None], Pn, 0.0)

    kd = _KineticDelaunay(n, tau, max_events if max_events is not None else 2000 * (n + 10))
    d_ev, kinds, removed, added, snapshots = [], [], [], [], {}
    section_event = np.zeros(S, dtype=np.int64)

    def log(kind, de):
        rem, add = kd.take_journal()
        d_ev.append(de)
        kinds.append(kind)
        removed.append(rem)
        added.append(add)

    def snapshot(kind, de):
        kd.take_journal()
        snapshots[len(d_ev)] = [_canon(*t) for t in kd.triangles()]
        d_ev.append(de)
        kinds.append(kind)
        removed.append([])
        added.append([])

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
                log(INSERT, float(d[k]))
                n_insert += 1
            kd.ensure_built()           # a section that first has three non-collinear sites
            if kd.journal:
                log(INSERT, float(d[k]))
        if kd.built and kd.invalid():       # an unresolved mid-piece cluster left a fold behind
            kd.rebuild()
            snapshot(REPAIR, float(d[k]))
        section_event[k] = len(d_ev)
        snapshot(SECTION, float(d[k]))
        if k < S - 1:
            for i in np.nonzero(alive[k] & ~alive[k + 1])[0].tolist():
                kd.delete(i)
                log(DELETE, float(d[k]))
                n_delete += 1
            kd.run_piece(log, snapshot, float(d[k]), float(d[k + 1]), k)

    kinds_arr = np.array(kinds, dtype=np.int8)
    counts = {
        "flips": int(np.sum(kinds_arr == FLIP)),
        "hull": int(np.sum(kinds_arr == HULL)),
        "inserts": n_insert,
        "deletes": n_delete,
        "repairs": int(np.sum(kinds_arr == REPAIR)),
        "sections": S,
    }
    return KineticResult(
        d=d, P=Pc, alive=alive, d_events=np.array(d_ev), kinds=kinds_arr,
        section_event=section_event, snapshot_event=np.array(sorted(snapshots), dtype=np.int64),
        counts=counts, eta=eta, tau=tau, centre=centre, scale=h,
        _removed=removed, _added=added, _snapshots=snapshots,
    )
