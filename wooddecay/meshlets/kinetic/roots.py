"""Roots of the kinetic certificates' polynomials (woodstock §8.1; docs/model.md §5).

Coefficients are in ascending powers of the local parameter s of a piece (numba kernels, used by
:mod:`.certificates`). The event time of a certificate is the first s >= s_0 (the current time)
with g(s) = f(s) - tau m(s) > 0 in the piece. It is found without companion matrices: the
sign-changing roots of g', g'', ... split [s_0, 1] into intervals on which g is monotone
(recursively, from the linear derivative up), and bisection on the first monotone interval whose
end has g > 0 gives the time to the last bit. Tangencies (double roots, no sign change) are
therefore never events, and tiny leading coefficients do no harm.

:func:`first_positive_time` and :func:`sign_change_roots` are the same kernels on coefficient arrays.
"""
from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True)
def horner(c, deg, t):
    """c(t) of the coefficients c[0:deg + 1] (Horner's scheme)."""
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
        fm = horner(c, deg, m)
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
        fa = horner(row, dk, a)
        for j in range(m + 1):
            b = prev[j] if j < m else hi
            fb = horner(row, dk, b)
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
        if horner(c, deg, mid) > 0.0:
            pos = mid
        else:
            neg = mid


@nb.njit(cache=True)
def _critical_points(c, deg, lo, hi):
    """The roots of c' in [lo, hi] where it changes sign, ascending, and their count: c is
    monotone between consecutive ones."""
    dc = np.empty(deg)
    for j in range(deg):
        dc[j] = c[j + 1] * (j + 1)
    crit = np.empty(deg)
    return crit, _sign_change_roots(dc, deg - 1, lo, hi, crit)


@nb.njit(cache=True)
def first_positive(c, deg, t0, t1):
    """Smallest t in [t0, t1] with c(t) > 0 (to the last bit; c(t) > 0 holds there), inf if none."""
    if horner(c, deg, t0) > 0.0:
        return t0
    if deg <= 0:
        return np.inf
    crit, m = _critical_points(c, deg, t0, t1)
    a = t0
    for j in range(m + 1):
        b = crit[j] if j < m else t1
        if horner(c, deg, b) > 0.0:      # c(a) <= 0 < c(b) and c monotone on [a, b]
            return _bisect(c, deg, a, b)
        a = b
    return np.inf


@nb.njit(cache=True)
def last_positive(c, deg, lo, hi):
    """Largest u in [lo, hi] with c(u) > 0 (to the last bit; c(u) > 0 holds there), -inf if none."""
    if horner(c, deg, hi) > 0.0:
        return hi
    if deg <= 0:
        return -np.inf
    crit, m = _critical_points(c, deg, lo, hi)
    b = hi
    for j in range(m, -1, -1):
        a = crit[j - 1] if j > 0 else lo
        if horner(c, deg, a) > 0.0:      # c(a) > 0 >= c(b) and c monotone on [a, b]
            return _bisect(c, deg, b, a)
        b = a
    return -np.inf


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
def quad_first_positive(g0, g1, g2, t0, t1):
    """:func:`first_positive` for a quadratic (monotone pieces split at its vertex)."""
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
def quad_last_positive(g0, g1, g2, lo, hi):
    """:func:`last_positive` for a quadratic: the first positive time of q(-s) on [-hi, -lo]."""
    return -quad_first_positive(g0, -g1, g2, -hi, -lo)


def first_positive_time(coeffs, t0=0.0, t1=1.0):
    """Smallest t in [t0, t1] where the polynomial (ascending coefficients) is > 0; inf if none."""
    c = np.asarray(coeffs, float)
    return float(first_positive(c, len(c) - 1, float(t0), float(t1)))


def sign_change_roots(coeffs, lo=0.0, hi=1.0):
    """Roots of the polynomial (ascending coefficients) in (lo, hi) where it changes sign."""
    c = np.asarray(coeffs, float)
    out = np.empty(max(len(c), 1))
    m = _sign_change_roots(c, len(c) - 1, float(lo), float(hi), out)
    return out[:m].copy()
