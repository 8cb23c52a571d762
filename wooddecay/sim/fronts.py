"""Decay fronts at the continuum's speed on a coarse graph (woodstock Eqs. 8-9; docs/model.md §3).

White and brown rot spread into sound wood as pulled Fisher-KPP fronts, u_t = D u_xx + g u (1 - u),
whose continuum speed is 2 sqrt(g D). On a lattice of spacing h the leading edge
u ~ exp(-mu x / h) sees D (2 cosh mu - 2) / h^2 where the continuum has D mu^2 / h^2, and the front
runs at R(q) 2 sqrt(g D), q = h sqrt(g / D) the spacing in front widths (van Saarloos 2003, Phys.
Rep. 386, §2):

    R(q) = min over mu > 0 of (q / mu + 2 (cosh mu - 1) / (q mu)) / 2  >= 1,  R -> 1 as q -> 0.

A lattice whose diffusivity is scaled by rho runs at R(q / sqrt rho) 2 sqrt(g rho D), which is the
continuum's speed where R(Q) sqrt(rho) = 1 for Q = q / sqrt(rho): along Q, q = Q / R(Q) and
rho = 1 / R(Q)^2 (:func:`rho_table`).

On the rod graph, per element i, fungus and direction k in (e_r, e_t, e_l):

    q_ik = h_ik sqrt(g_i / (D_i a_ik)),   h_ik^2 = sum_j w_ij (d_ij . e_k)^4 / sum_j w_ij (d_ij . e_k)^2,

g_i the fungus' linear growth at R -> 0 on element i's current state (Eqs. 8-9: alpha(M) times the
substrate term, less the defence's beta C), D_i its diffusivity and h_ik the spacing of the 1D
lattice with the element's second and fourth moments along e_k (h on a lattice of spacing h: the
first two terms of the leading edge's cosh). Each edge's weight is scaled by
sum_k s_ijk (rho_ik + rho_jk) / 2, s_ijk = (d_ij . e_k)^2 / |d_ij|^2 its share along e_k
(:class:`wooddecay.sim.transport.TransportOperator`): symmetric, so diffusion still conserves the
fungus, and rho <= 1, so the explicit step's bound holds. Where g_i <= 0 rho is 1: the fungus only
diffuses. Measured on the rod graph: ``benchmarks/transport_accuracy.py``.
"""
from __future__ import annotations

import functools

import numba as nb
import numpy as np

#: rho(q) sampled on q = 0, Q_STEP, 2 Q_STEP, ... (:func:`rho_table`); beyond its end, its last value
Q_STEP = 0.01
Q_END = 40.0


def _ratio(q, mu, alpha_dt: float = 0.0):
    """The leading edge's speed over the continuum's at decay rate ``mu`` per spacing: q ln G /
    (2 mu alpha dt), G = 1 + alpha dt (1 + 2 (cosh mu - 1) / q^2) the growth of an explicit step,
    and at alpha dt -> 0 (q / mu + 2 (cosh mu - 1) / (q mu)) / 2 (module docstring)."""
    with np.errstate(over="ignore"):
        if alpha_dt == 0.0:
            return (q / mu + 2.0 * (np.cosh(mu) - 1.0) / (q * mu)) / 2.0
        return q * np.log1p(alpha_dt * (1.0 + 2.0 * (np.cosh(mu) - 1.0) / q**2)) / (2.0 * mu * alpha_dt)


def lattice_speed_ratio(q: float, alpha_dt: float = 0.0) -> float:
    """Speed of a pulled Fisher-KPP front on a 1D lattice (u_t = D (u_{i+1} - 2 u_i + u_{i-1}) / h^2
    + alpha u (1 - u), explicit Euler steps of dt) over the continuum's 2 sqrt(alpha D), at q =
    h sqrt(alpha / D) and ``alpha_dt`` = alpha dt (0: exact in time): the minimum of
    :func:`_ratio` over mu > 0, R(q) at alpha dt -> 0."""
    return float(np.min(_ratio(q, np.linspace(1e-4, 40.0, 400_001), alpha_dt)))


@functools.cache
def rho_table() -> np.ndarray:
    """rho on q = k Q_STEP, k = 0 .. Q_END / Q_STEP: the diffusivity factor that brings a 1D
    lattice's front at q to the continuum's speed (module docstring), from R(Q) on a geometric
    grid of Q, interpolated in q. One read-only table, shared by every model."""
    Q = np.geomspace(1e-3, 1e6, 1_000)
    R = np.min(_ratio(Q, np.geomspace(1e-5, 40.0, 6_000)[:, None]), axis=0)
    q = np.arange(0.0, Q_END + 0.5 * Q_STEP, Q_STEP)
    table = np.interp(q, np.concatenate([[0.0], Q / R]), np.concatenate([[1.0], 1.0 / R**2]))
    table.flags.writeable = False
    return table


def spacing(rows: np.ndarray, d: np.ndarray, weight: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) h_ik (module docstring) from the CSR entries' ``rows``, their displacements ``d``
    (nnz, 3) in the row element's frame (e_r, e_t, e_l) and their ``weight``; 0 where an element
    has no neighbour along e_k."""
    # float even where there is no entry at all (numpy's bincount of nothing is int64)
    m2 = np.stack([np.bincount(rows, weight * d[:, k] ** 2, minlength=n) for k in range(3)], axis=1).astype(float)
    m4 = np.stack([np.bincount(rows, weight * d[:, k] ** 4, minlength=n) for k in range(3)], axis=1).astype(float)
    return np.sqrt(np.divide(m4, m2, out=np.zeros_like(m4), where=m2 > 0.0))


def share(d: np.ndarray, reverse: np.ndarray) -> np.ndarray:
    """(nnz, 3) s_ijk = (d_ij . e_k)^2 / |d_ij|^2, averaged over the frames of i and j so that it
    is symmetric (``reverse``: the CSR position of (j, i))."""
    s = d**2 / np.maximum(np.sum(d**2, axis=1), 1e-300)[:, None]
    return np.ascontiguousarray(0.5 * (s + s[reverse]))


@nb.njit(cache=True, inline="always")
def rho_at(q, table):
    """rho(q) from :func:`rho_table` by linear interpolation."""
    x = q / Q_STEP
    if not x < len(table) - 1:  # beyond the table, and q = inf where D a is subnormal
        return table[-1]
    k = int(x)
    return table[k] + (x - k) * (table[k + 1] - table[k])


@nb.njit(cache=True, inline="always")
def element_rho(i, g, kappa_i, h, aniso, table, rho):
    """Fill rho[i, k] for element i whose fungus grows at g with diffusivity kappa_i."""
    for k in range(3):
        Da = kappa_i * aniso[i, k]
        rho[i, k] = 1.0 if g <= 0.0 or Da <= 0.0 else rho_at(h[i, k] * np.sqrt(g / Da), table)


def rho_reference(g: np.ndarray, kappa: np.ndarray, h: np.ndarray, aniso: np.ndarray,
                  table: np.ndarray) -> np.ndarray:
    """(n, 3) rho per element and direction, plain numpy (the reference of :func:`element_rho`)."""
    Da = kappa[:, None] * aniso
    ok = (g[:, None] > 0.0) & (Da > 0.0)
    q = h * np.sqrt(np.divide(np.maximum(g, 0.0)[:, None], Da, out=np.zeros_like(Da), where=ok))
    grid = np.arange(len(table)) * Q_STEP
    return np.where(ok, np.interp(q, grid, table), 1.0)
