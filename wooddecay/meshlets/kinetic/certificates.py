"""Certificates of the kinetic Delaunay triangulation and their event times (woodstock §8.1; docs/model.md §5).

Motion. On piece k (d_k <= d_t <= d_{k+1}) with local parameter s = (d_t - d_k) / (d_{k+1} - d_k)
in [0, 1], x_i(s) = X_i + s V_i with X = P[k] and V = P[k+1] - P[k].

In-circle. An edge p -> q with left triangle (p, q, r) and right triangle (q, p, z) (both
counter-clockwise) is locally Delaunay while f(s) <= tau m(s) (the hysteresis bound below), with

    f = incircle(p, q, r; z) = w_a cross(b, c) + w_b cross(c, a) + w_c cross(a, b)
        a = x_p - x_z, b = x_q - x_z, c = x_r - x_z, w_u = |u|^2,  cross(u, v) = u_x v_y - u_y v_x

positive when z lies inside the circumcircle of (p, q, r). Each entry is exactly linear (a, b, c)
or quadratic (w) in s, so f is a quartic whose five coefficients are expanded in closed form from
X and V (:func:`incircle_coefficients`). With the vertex at infinity (``inf``, :mod:`.delaunay`)
among the four points f is an orientation (a quadratic): z = inf: f = -orient(p, q, r); r = inf:
f = -orient(q, p, z); p = inf: f = orient(z, q, r); q = inf: f = orient(r, p, z), where
orient(a, b, c) = cross(x_b - x_a, x_c - x_a).

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
the no-cycling argument below still holds. Event times are the roots of :mod:`.roots`.

* Hysteresis with an error bound. Each certificate is evaluated relative to the one of its points
  whose permanent bound is smallest at the expansion point (a point inside a tight cluster, so
  three nearly coincident sites and a far one still give an accurate sign), and it fires when
  f(s) > tau * m(s), with m(s) the permanent bound of f: the same expansion over absolute values
  (a polynomial with non-negative coefficients that bounds every rounded term for s in [0, 1]),
  tau = TAU = 1e-13 (the rounding error of expansion and evaluation is below ~5e-15 m). An edge
  flips only once f > +tau m; the flipped edge starts near -f, so float noise never flips an edge
  back and forth, and every flip lowers the lifted surface by a resolved amount (Lawson's
  argument), so simultaneous events cannot cycle. Both g = f - tau m and its roots are polynomial.
* Two expansions per piece. [0, 1/2] is expanded about the piece's start (powers of t, positions
  of section k), [1/2, 1] about its end (powers of u = 1 - t, positions of section k + 1), and event
  times are kept as (half, t) or (half, -u) keys: strands that meet at a section (coincident
  sites there) are resolved from that section's own coordinates at full relative precision
  instead of from O(1) coefficients cancelling to 1e-18, and 1 - u never rounds u away.
* Degenerate configurations at a section (e.g. a grid exactly co-circular at d_k) are resolved by
  the motion: certificates already violated at s_0 are events at s_0 (processed first), and a
  certificate that is zero at s_0 fires as soon as the motion takes it past tau m.
* Close passes (:func:`close_pass`): the closest approach of two Delaunay neighbours passing
  closer than a given distance strictly inside the current segment (the virtual sections of
  :mod:`.delaunay`).
"""
from __future__ import annotations

import numba as nb
import numpy as np

from .roots import first_positive, horner, last_positive, quad_first_positive, quad_last_positive

#: relative hysteresis of the certificates (see the module docstring)
TAU = 1e-13


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
def _edge_key(X0, X1, V, NV, p, q, r, s, inf, tau, half, val):
    """First time key at or after (half, val) at which the edge certificate of p -> q is violated
    (see :func:`cert_time`; (2, 0.0): never)."""
    g = np.empty(5)
    umax = 0.5
    if half == 0:
        deg = _certificate(X0, V, p, q, r, s, inf, tau, g)
        te = first_positive(g, deg, val, 0.5)
        if te <= 0.5:
            return 0, te
    else:
        umax = -val
    deg = _certificate(X1, NV, p, q, r, s, inf, tau, g)
    u = last_positive(g, deg, 0.0, umax)
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
        te = quad_first_positive(g0, g1, g2, val, t1)
        if te <= t1:
            return 0, te
        if hmax == 0:
            return 2, 0.0
    else:
        umax = -val
    ulo = -vmax if hmax == 1 else 0.0
    g0, g1, g2 = _flatness(X1, NV, a, b, c, tau)
    u = quad_last_positive(g0, g1, g2, ulo, umax)
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
def cert_time(X0, X1, V, NV, p, q, r, s, inf, tau, half, val):
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
def flip_inverts(X0, X1, V, NV, p, q, r, s, inf, tau, half, val):
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
def cert_times(X0, X1, V, Q, inf, tau, halves, vals):
    """:func:`cert_time` from the start of the segment of every edge row Q[e] = (p, q, left apex,
    right apex), into ``halves`` and ``vals``."""
    NV = -V
    for e in range(Q.shape[0]):
        h, v = cert_time(X0, X1, V, NV, Q[e, 0], Q[e, 1], Q[e, 2], Q[e, 3], inf, tau, 0, 0.0)
        halves[e] = h
        vals[e] = v


@nb.njit(cache=True)
def cert_violated(X, V, p, q, r, s, inf, tau, t):
    """Whether the certificate of edge p -> q (left apex r, right apex s) is violated at t."""
    g = np.empty(5)
    deg = _certificate(X, V, p, q, r, s, inf, tau, g)
    return horner(g, deg, t) > 0.0


@nb.njit(cache=True)
def close_pass(X, V, a, b, s0, kappa2):
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
def close_passes(X, V, Q, inf, kappa2):
    """Earliest :func:`close_pass` (from s0 = 0) of the edges Q[e, 0:2] that do not touch ``inf``;
    inf if none."""
    best = np.inf
    for e in range(Q.shape[0]):
        if Q[e, 1] != inf:
            s = close_pass(X, V, Q[e, 0], Q[e, 1], 0.0, kappa2)
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
