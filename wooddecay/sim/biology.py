"""Rot, tissue health, defence and moisture on the rod-element graph (woodstock §6, Eqs. 8-15, 20).

One biology step advances, in the paper's order (Algorithm 1, lines 9-11), each update using the
newest values of the fields before it (explicit forward Euler):

    R_w  (Eq. 8)   alpha_w(M) R_w (1 - R_w) (lambda_l H_l + lambda_c H_c) H_c / (K_c + H_c)
                   - beta_w C R_w + div(D_w grad R_w)
    R_b  (Eq. 9)   alpha_b(M) R_b (1 - R_b) H_c - beta_b C R_b + div(D_b grad R_b)
    H_c  (Eq. 12)  -gamma_cw R_w H_c - gamma_cb R_b H_c + rho_c (1 - H_c) C
    H_l  (Eq. 13)  -gamma_lw R_w H_l + rho_l (1 - H_l) C
    C    (Eq. 14)  kappa (R_w + R_b) H_c H_l (1 - C) - delta C + div(D_C grad C)
    M    (Eq. 15)  div(D_M grad M) + (M_1 - M) k_in - (M - M_2) k_out,
                   k_in = w_in k_in0 max(0, 1 - k_r_in bd) H_c + w_ground k_ground g,
                   k_out = w_out k_out0 max(0, 1 - k_r_out H_c) max(0, bd_0 - bd),
                   D_M = D_M0 (1 + k_DM (1 - H)),  H = (H_l + k_H H_c) / (1 + k_H)   (Eq. 20)

with alpha(M) = alpha_0 psi((M - M_min) / s_t) psi((M_max - M) / s_t) (Eqs. 10, 11). The weak-point
field scales growth and transport by 1 + k_W (2 W - 1) (docs/model.md §3). The climate's seasonal factors
w_in, w_out, w_ground, the exposed-surface distance bd (bark or cut end) and the ground contact g
are those of :mod:`wooddecay.sim.climate`. Diffusion uses the anisotropic graph Laplacian of
:mod:`wooddecay.sim.transport`, for the two fungi with each weight scaled so that their fronts
keep the continuum's speed on a coarse graph (:mod:`wooddecay.sim.fronts`). Every parameter may
differ per tissue.

Stability: an explicit step keeps every field in its box [0, 1] / [M_2, M_1] (Appendix A)
when dt (S_i + r_i) <= 1 for every element and field, S_i the Gershgorin row sum of the diffusion
operator and r_i the largest reaction rate (the logistic gain plus the decay rate). ``dt_bio``
larger than that bound is split into the fewest equal substeps that satisfy it. Clamping to the
box remains as a safety net; every change above 1e-12 it makes is counted and reported.

The numba kernel runs every update as a parallel loop over elements, each writing only its own
entry (a gather over its CSR row): race-free and identical for any thread count. A rot field
that is zero everywhere stays zero, so its update is skipped. There is no serial build: numba's
parallel build runs the log's substep about twice as fast on one thread as the same code compiled
without ``parallel`` (docs/decisions.md, "Biology on one build").
:func:`step_reference` is the plain numpy version of the same step.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numba as nb
import numpy as np

from ..wood import WoodModel
from ..strands.rings import TISSUES
from . import climate as climate_mod
from . import fronts
from .climate import Climate
from .events import Events
from .state import SimState, inoculate
from .transport import TransportOperator, assemble

#: per-tissue parameters, in the column order of ``BioSetup.P``
BIO_PARAMS = (
    "alpha_w0", "alpha_b0", "D_w", "D_b", "lambda_l", "lambda_c", "K_c", "beta_w", "beta_b",
    "gamma_cw", "gamma_cb", "gamma_lw", "rho_c", "rho_l", "kappa", "delta", "D_C",
    "M_min", "M_max", "s_t", "D_M0", "k_DM", "k_H", "k_in0", "k_r_in", "k_out0", "k_r_out", "bd_0",
)
(ALPHA_W, ALPHA_B, D_W, D_B, LAMBDA_L, LAMBDA_C, K_C, BETA_W, BETA_B, GAMMA_CW, GAMMA_CB, GAMMA_LW,
 RHO_C, RHO_L, KAPPA, DELTA, D_C, M_MIN, M_MAX, S_T, D_M0, K_DM, K_H, K_IN0, K_R_IN, K_OUT0, K_R_OUT,
 BD_0) = range(len(BIO_PARAMS))

#: a clamp that changes a value by more than this is counted (docs/model.md §3)
CLAMP_TOL = 1e-12


@dataclass(frozen=True, eq=False)
class BioSetup:
    """Everything static a biology step needs, built once with the model (``model.bio``)."""

    op: TransportOperator
    P: np.ndarray  # (n_tissues, n_params) parameters per tissue, columns BIO_PARAMS
    tissue: np.ndarray  # (n,) int64
    wfac: np.ndarray  # (n,) 1 + k_W (2 W - 1)
    bd: np.ndarray  # (n,) distance to the nearest exposed surface, bark or cut end (climate.exposure_distance)
    kappa: np.ndarray  # (n, 3) diffusivities of R_w, R_b, C (with wfac)
    aniso: np.ndarray  # (n, 3) transport factors (a_r, a_t, a_l)
    rho_table: np.ndarray  # the fronts' diffusivity factor on its q grid (fronts.rho_table)
    schedules: tuple  # per tissue: (days, M_1, M_2) arrays, or constants as 1-row arrays
    box_M: np.ndarray  # (n_tissues, 2) the envelope [min M_2, max M_1] over tissues and schedules
    climate: Climate  # seasons and ground wetting of Eq. 15
    bound: float  # explicit-step stability bound in days (stability_bound)


def _schedule(materials, t: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rows = materials.per_tissue("schedule")[t]
    if len(rows) == 0:
        return (np.zeros(1), np.array([materials.per_tissue("M_1")[t]]),
                np.array([materials.per_tissue("M_2")[t]]))
    arr = np.asarray(rows, dtype=np.float64)
    return arr[:, 0], arr[:, 1], arr[:, 2]


def moisture_bounds(setup: BioSetup, t_days: float) -> np.ndarray:
    """(n_tissues, 2) [M_1, M_2] at ``t_days``: the seasonal keyframes interpolated linearly
    (held constant before the first and after the last)."""
    return np.array([[np.interp(t_days, d, m1), np.interp(t_days, d, m2)] for d, m1, m2 in setup.schedules])


def prepare(model: WoodModel, phi_pack: float, k_W: float, climate: Climate) -> BioSetup:
    """Transport operator, per-tissue parameters (``model.materials``) and static per-element
    factors; ``phi_pack`` is the strands' packing fraction (an element's volume is
    pi r_s^2 l / phi_pack), ``k_W`` the weak-point gain and ``climate`` the environment."""
    tissue = model.tissue.astype(np.int64)
    mat = model.materials
    aniso = mat.table(("a_r", "a_t", "a_l"))[tissue]
    kind = model.transport_kind[model.transport_edge_of]
    pa = model.particles[model.first_particle]
    pb = model.particles[model.first_particle + 1]
    op = assemble(model.centers, model.frames, pa, pb, np.pi * model.r_s**2 / phi_pack,
                  model.transport_indptr, model.transport_indices, kind == 1, aniso)
    P = mat.table(BIO_PARAMS)
    wfac = 1.0 + k_W * (2.0 * model.W - 1.0)
    kappa = np.stack([P[tissue, D_W], P[tissue, D_B], P[tissue, D_C]], axis=1) * wfac[:, None]
    schedules = tuple(_schedule(mat, t) for t in range(len(TISSUES)))
    # one envelope for every tissue: diffusion mixes tissues with different bounds, and only a
    # common box makes each explicit update a convex combination of values inside it
    envelope = [min(m2.min() for _, _, m2 in schedules), max(m1.max() for _, m1, _ in schedules)]
    box_M = np.tile(envelope, (len(schedules), 1))
    setup = BioSetup(op=op, P=P, tissue=tissue, wfac=wfac, bd=climate_mod.exposure_distance(model),
                     kappa=np.ascontiguousarray(kappa), aniso=np.ascontiguousarray(aniso),
                     rho_table=fronts.rho_table(), schedules=schedules, box_M=box_M,
                     climate=climate, bound=0.0)
    return replace(setup, bound=stability_bound(setup))


def stability_bound(setup: BioSetup) -> float:
    """Largest explicit step (days) that keeps every field in its box (module docstring)."""
    P, t, w = setup.P, setup.tissue, setup.wfac
    bd = setup.bd
    kappa_M = P[t, D_M0] * (1.0 + P[t, K_DM]) * w  # worst case H = 0
    growth_w = P[t, ALPHA_W] * w * (P[t, LAMBDA_L] + P[t, LAMBDA_C]) / (1.0 + P[t, K_C])
    w_in, w_out, w_ground = setup.climate.w_max
    k_in = w_in * P[t, K_IN0] * np.maximum(0.0, 1.0 - P[t, K_R_IN] * bd) + w_ground * setup.climate.k_ground
    k_out = w_out * P[t, K_OUT0] * np.maximum(0.0, P[t, BD_0] - bd)
    rates = np.stack([
        setup.op.row_sums(setup.kappa[:, 0]) + growth_w + P[t, BETA_W],
        setup.op.row_sums(setup.kappa[:, 1]) + P[t, ALPHA_B] * w + P[t, BETA_B],
        P[t, GAMMA_CW] + P[t, GAMMA_CB] + P[t, RHO_C],
        P[t, GAMMA_LW] + P[t, RHO_L],
        setup.op.row_sums(setup.kappa[:, 2]) + 2.0 * P[t, KAPPA] + P[t, DELTA],
        setup.op.row_sums(kappa_M) + k_in + k_out,
    ])
    worst = float(rates.max()) if rates.size else 0.0
    return np.inf if worst <= 0.0 else 1.0 / worst


def substeps(dt: float, bound: float) -> int:
    """Fewest equal substeps of ``dt`` that respect ``bound``."""
    return 1 if not np.isfinite(bound) else max(1, int(np.ceil(dt / bound * (1.0 - 1e-12))))


# ----------------------------------------------------------------------------- numba kernel


@nb.njit(cache=True, inline="always")
def _smoothstep(z):
    if z <= 0.0:
        return 0.0
    if z >= 1.0:
        return 1.0
    return z * z * (3.0 - 2.0 * z)


@nb.njit(cache=True, inline="always")
def _alpha(alpha0, M, M_min, M_max, s_t):
    """Moisture-gated growth rate, Eqs. 10-11."""
    return alpha0 * _smoothstep((M - M_min) / s_t) * _smoothstep((M_max - M) / s_t)


@nb.njit(cache=True, inline="always")
def _lap(i, u, kappa, indptr, indices, weight, volume):
    """(L_kappa u)_i: gather over row i of the CSR operator."""
    acc = 0.0
    ui = u[i]
    ki = kappa[i]
    for e in range(indptr[i], indptr[i + 1]):
        j = indices[e]
        acc += weight[e] * 0.5 * (ki + kappa[j]) * (u[j] - ui)
    return acc / volume[i]


@nb.njit(cache=True, inline="always")
def _lap_front(i, u, kappa, rho, share, indptr, indices, weight, volume):
    """(L_kappa u)_i with each entry's weight scaled by the fronts' correction (fronts module)."""
    acc = 0.0
    ui = u[i]
    ki = kappa[i]
    for e in range(indptr[i], indptr[i + 1]):
        j = indices[e]
        s = 0.0
        for k in range(3):
            s += share[e, k] * 0.5 * (rho[i, k] + rho[j, k])
        acc += s * weight[e] * 0.5 * (ki + kappa[j]) * (u[j] - ui)
    return acc / volume[i]


@nb.njit(cache=True, inline="always")
def _clamp(v, lo, hi, clamp, i):
    if v < lo:
        if lo - v > CLAMP_TOL:
            clamp[i] += 1
        return lo
    if v > hi:
        if v - hi > CLAMP_TOL:
            clamp[i] += 1
        return hi
    return v


@nb.njit(parallel=True, cache=True)
def _substep(h, indptr, indices, weight, share, spacing, volume, tissue, P, wfac, bd, kappa, aniso, table, M12,
             box_M, w, k_g, R_w, R_b, H_c, H_l, C, M, rotting, buf, growth, rho, kappa_M, clamp):
    """One forward-Euler substep of all six fields in the paper's order (module docstring);
    ``w``: the climate's (w_in, w_out), ``k_g``: w_ground k_ground g per element, ``rotting``:
    whether R_w and R_b hold any fungus (a field that is zero everywhere stays zero, bit for bit,
    so its update is skipped). A fungus' growth rate and its fronts' diffusivity factors
    (:mod:`.fronts`) are taken in one pass before its update, into ``growth`` and ``rho``. ``buf``
    is copied back element by element: a slice assignment compiles numba's shape-error formatting
    (docs/decisions.md, "Tests on two workers")."""
    n = len(R_w)
    kw = kappa[:, 0]
    kb = kappa[:, 1]
    kc = kappa[:, 2]
    if rotting[0]:
        for i in nb.prange(n):  # Eq. 8: growth at R_w -> 0
            p = P[tissue[i]]
            a = _alpha(p[ALPHA_W], M[i], p[M_MIN], p[M_MAX], p[S_T]) * wfac[i]
            growth[i] = a * (p[LAMBDA_L] * H_l[i] + p[LAMBDA_C] * H_c[i]) * H_c[i] / (p[K_C] + H_c[i])
            fronts.element_rho(i, growth[i] - p[BETA_W] * C[i], kw[i], spacing, aniso, table, rho)
        for i in nb.prange(n):  # Eq. 8
            r = R_w[i]
            f = growth[i] * r * (1.0 - r) - P[tissue[i], BETA_W] * C[i] * r
            lap = _lap_front(i, R_w, kw, rho, share, indptr, indices, weight, volume)
            buf[i] = _clamp(r + h * (f + lap), 0.0, 1.0, clamp, i)
        for i in nb.prange(n):
            R_w[i] = buf[i]
    if rotting[1]:
        for i in nb.prange(n):  # Eq. 9: growth at R_b -> 0
            p = P[tissue[i]]
            growth[i] = _alpha(p[ALPHA_B], M[i], p[M_MIN], p[M_MAX], p[S_T]) * wfac[i] * H_c[i]
            fronts.element_rho(i, growth[i] - p[BETA_B] * C[i], kb[i], spacing, aniso, table, rho)
        for i in nb.prange(n):  # Eq. 9
            r = R_b[i]
            f = growth[i] * r * (1.0 - r) - P[tissue[i], BETA_B] * C[i] * r
            lap = _lap_front(i, R_b, kb, rho, share, indptr, indices, weight, volume)
            buf[i] = _clamp(r + h * (f + lap), 0.0, 1.0, clamp, i)
        for i in nb.prange(n):
            R_b[i] = buf[i]
    for i in nb.prange(n):  # Eqs. 12, 13 (no transport: pointwise)
        p = P[tissue[i]]
        hc = H_c[i]
        hl = H_l[i]
        fc = -p[GAMMA_CW] * R_w[i] * hc - p[GAMMA_CB] * R_b[i] * hc + p[RHO_C] * (1.0 - hc) * C[i]
        fl = -p[GAMMA_LW] * R_w[i] * hl + p[RHO_L] * (1.0 - hl) * C[i]
        H_c[i] = _clamp(hc + h * fc, 0.0, 1.0, clamp, i)
        H_l[i] = _clamp(hl + h * fl, 0.0, 1.0, clamp, i)
    for i in nb.prange(n):  # Eq. 14
        p = P[tissue[i]]
        c = C[i]
        f = p[KAPPA] * (R_w[i] + R_b[i]) * H_c[i] * H_l[i] * (1.0 - c) - p[DELTA] * c
        buf[i] = _clamp(c + h * (f + _lap(i, C, kc, indptr, indices, weight, volume)), 0.0, 1.0, clamp, i)
    for i in nb.prange(n):
        C[i] = buf[i]
    for i in nb.prange(n):  # Eq. 20 with the newest health
        p = P[tissue[i]]
        H = (H_l[i] + p[K_H] * H_c[i]) / (1.0 + p[K_H])
        kappa_M[i] = p[D_M0] * (1.0 + p[K_DM] * (1.0 - H)) * wfac[i]
    for i in nb.prange(n):  # Eq. 15
        t = tissue[i]
        p = P[t]
        m = M[i]
        k_in = w[0] * p[K_IN0] * max(0.0, 1.0 - p[K_R_IN] * bd[i]) * H_c[i] + k_g[i]
        k_out = w[1] * p[K_OUT0] * max(0.0, 1.0 - p[K_R_OUT] * H_c[i]) * max(0.0, p[BD_0] - bd[i])
        f = (M12[t, 0] - m) * k_in - (m - M12[t, 1]) * k_out
        buf[i] = _clamp(m + h * (f + _lap(i, M, kappa_M, indptr, indices, weight, volume)),
                        box_M[t, 0], box_M[t, 1], clamp, i)
    for i in nb.prange(n):
        M[i] = buf[i]


def _advance(model: WoodModel, state: SimState, dt: float, n_sub: int, kernel) -> None:
    setup = model.bio
    h = dt / n_sub
    x = model.particles if state.mech is None else state.mech.x
    g = climate_mod.ground_contact(model, setup.climate, x)
    for k in range(n_sub):
        t = state.t_days + k * h
        w = setup.climate.factors(t)
        kernel(setup, state, h, moisture_bounds(setup, t), w[:2].copy(), w[2] * setup.climate.k_ground * g)
    state.t_days += dt


def _numba_kernel(setup: BioSetup, state: SimState, h: float, M12: np.ndarray, w: np.ndarray,
                  k_g: np.ndarray) -> None:
    op = setup.op
    n = len(state.R_w)
    clamp = np.zeros(n, dtype=np.int64)
    _substep(h, op.indptr, op.indices, op.weight, op.share, op.spacing, op.volume, setup.tissue, setup.P,
             setup.wfac, setup.bd, setup.kappa, setup.aniso, setup.rho_table, M12, setup.box_M, w, k_g,
             state.R_w, state.R_b, state.H_c, state.H_l, state.C, state.M,
             np.array([state.R_w.any(), state.R_b.any()]), np.empty(n), np.empty(n), np.empty((n, 3)),
             np.empty(n), clamp)
    state.clamp_count += int(clamp.sum())


def step(model: WoodModel, state: SimState, dt: float, n_sub: int | None = None) -> int:
    """Advance the biology of ``state`` by ``dt`` days (numba) with ``model.bio``. Substeps:
    ``n_sub`` if given (tests of the unstable regime), else the fewest that respect the stability
    bound. Returns the number of substeps taken."""
    n_sub = n_sub or substeps(dt, model.bio.bound)
    _advance(model, state, dt, n_sub, _numba_kernel)
    return n_sub


def advance(model: WoodModel, state: SimState, dt: float) -> Events:
    """The driver's biology solver (:mod:`~wooddecay.sim.events`): :func:`step` over ``dt`` days,
    then the inoculations whose day has come."""
    n_sub = step(model, state, dt)
    inoculate(model, state)
    return Events(substeps=n_sub)


# ----------------------------------------------------------------------------- numpy reference


def _smoothstep_np(z):
    z = np.clip(z, 0.0, 1.0)
    return z * z * (3.0 - 2.0 * z)


def _clamp_np(v, lo, hi, state: SimState):
    out = np.clip(v, lo, hi)
    state.clamp_count += int(np.sum(np.abs(out - v) > CLAMP_TOL))
    return out


def _reference_kernel(setup: BioSetup, s: SimState, h: float, M12: np.ndarray, w_env: np.ndarray,
                      k_g: np.ndarray) -> None:
    """Plain numpy version of :func:`_substep` (same order, same formulas)."""
    P = setup.P[setup.tissue]
    col = dict(zip(BIO_PARAMS, P.T))
    op, w, bd = setup.op, setup.wfac, setup.bd

    def alpha(a0):
        return a0 * _smoothstep_np((s.M - col["M_min"]) / col["s_t"]) * _smoothstep_np((col["M_max"] - s.M) / col["s_t"]) * w

    rows = op.rows

    def front_scale(g, kappa):
        rho = fronts.rho_reference(g, kappa, op.spacing, setup.aniso, setup.rho_table)
        return np.sum(op.share * 0.5 * (rho[rows] + rho[op.indices]), axis=1)

    growth = alpha(col["alpha_w0"]) * (col["lambda_l"] * s.H_l + col["lambda_c"] * s.H_c) * s.H_c / (col["K_c"] + s.H_c)
    scale = front_scale(growth - col["beta_w"] * s.C, setup.kappa[:, 0])
    f = growth * s.R_w * (1 - s.R_w) - col["beta_w"] * s.C * s.R_w
    s.R_w = _clamp_np(s.R_w + h * (f + op.apply(s.R_w, setup.kappa[:, 0], scale)), 0.0, 1.0, s)
    growth = alpha(col["alpha_b0"]) * s.H_c
    scale = front_scale(growth - col["beta_b"] * s.C, setup.kappa[:, 1])
    f = growth * s.R_b * (1 - s.R_b) - col["beta_b"] * s.C * s.R_b
    s.R_b = _clamp_np(s.R_b + h * (f + op.apply(s.R_b, setup.kappa[:, 1], scale)), 0.0, 1.0, s)
    fc = -col["gamma_cw"] * s.R_w * s.H_c - col["gamma_cb"] * s.R_b * s.H_c + col["rho_c"] * (1 - s.H_c) * s.C
    fl = -col["gamma_lw"] * s.R_w * s.H_l + col["rho_l"] * (1 - s.H_l) * s.C
    s.H_c = _clamp_np(s.H_c + h * fc, 0.0, 1.0, s)
    s.H_l = _clamp_np(s.H_l + h * fl, 0.0, 1.0, s)
    f = col["kappa"] * (s.R_w + s.R_b) * s.H_c * s.H_l * (1 - s.C) - col["delta"] * s.C
    s.C = _clamp_np(s.C + h * (f + op.apply(s.C, setup.kappa[:, 2])), 0.0, 1.0, s)
    H = (s.H_l + col["k_H"] * s.H_c) / (1 + col["k_H"])
    kappa_M = col["D_M0"] * (1 + col["k_DM"] * (1 - H)) * w
    k_in = w_env[0] * col["k_in0"] * np.maximum(0, 1 - col["k_r_in"] * bd) * s.H_c + k_g
    k_out = w_env[1] * col["k_out0"] * np.maximum(0, 1 - col["k_r_out"] * s.H_c) * np.maximum(0, col["bd_0"] - bd)
    m12 = M12[setup.tissue]
    f = (m12[:, 0] - s.M) * k_in - (s.M - m12[:, 1]) * k_out
    box = setup.box_M[setup.tissue]
    s.M = _clamp_np(s.M + h * (f + op.apply(s.M, kappa_M)), box[:, 0], box[:, 1], s)


def step_reference(model: WoodModel, state: SimState, dt: float, n_sub: int | None = None) -> int:
    """Plain numpy reference of :func:`step` (without inoculation)."""
    n_sub = n_sub or substeps(dt, model.bio.bound)
    _advance(model, state, dt, n_sub, _reference_kernel)
    return n_sub
