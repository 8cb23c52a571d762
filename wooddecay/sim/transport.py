"""Anisotropic graph Laplacian on the transport graph (woodstock §6, Fig. 5; docs/model.md §3).

The diffusion terms D nabla^2 u of Eqs. 8, 9, 14 and div(D_M grad M) of Eq. 15 are discretised as

    (L_kappa u)_i = (1 / V_i) sum_j w_ij (kappa_i + kappa_j) / 2 (u_j - u_i),

V_i = A l_i the element's volume (A = pi r_s^2 / phi_pack), kappa the field's diffusivity per
element and w_ij = w_ji >= 0 the unit-diffusivity weights on the transport graph (strand chains
plus every cross-strand pair within ``transport_reach`` r_s; docs/decisions.md). Symmetric
weights make pure diffusion conserve sum_i V_i u_i; non-negative ones give a maximum principle.
The target is the tensor A_i = sum_k a_k e_k e_k^T in the wood frame (e_r, e_t, e_l), split:

* across the grain, the cross-strand pairs carry g_ij = psi_ij (s_ir n_r^2 + s_it n_t^2), with
  psi_ij = (overlap along the grain / l_i) exp(-sum_k (d . e_k)^2 / (2 h^2 a_k / max a)) for
  k in {r, t}, and s_i >= 0 (non-negative least squares over the 3 supports) so that the second
  moments match, sum_j g_ij (d_ij . e_k)^2 = 2 a_k for k in {r, t} ("second-moment
  renormalisation"); then w_ij = (V_i g_ij + V_j g_ji) / 2. The mixed (r, t) moment is not
  constrained; ``fit_error`` reports how well each element's two moments are met.
* along the grain, 1D finite volumes on the strand chain, w = a_l A / |d|, scaled by
  max(0, 1 - (f_i + f_j) / 2) where f is the share of the longitudinal moment 2 a_l that the
  cross pairs already carry through their stagger; ``chain_saturated`` counts elements with f > 1.

Measured on the real rod graph (benchmarks/transport_accuracy.py): heat-kernel variance growth
within 0.3% of 2 D a_k along e_l, e_r and e_t.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations

import numpy as np

from .. import fmath as fm
from . import fronts


def _supports(k: int) -> np.ndarray:
    """The non-empty supports of a k-vector, largest first (for the batched NNLS)."""
    return np.array([[i in c for i in range(k)] for n in range(k, 0, -1) for c in combinations(range(k), n)])


@dataclass(frozen=True, eq=False)
class TransportOperator:
    """CSR graph Laplacian with unit diffusivity (see module docstring)."""

    indptr: np.ndarray  # (n + 1,)
    indices: np.ndarray  # (nnz,)
    weight: np.ndarray  # (nnz,) w_ij, symmetric: weight[e] == weight[reverse[e]]
    reverse: np.ndarray  # (nnz,) CSR position of (j, i) for the entry (i, j)
    volume: np.ndarray  # (n,) V_i
    fit_error: np.ndarray  # (n,) relative residual of the across-grain moment fit
    chain_saturated: int  # elements whose cross pairs alone exceed the longitudinal moment
    share: np.ndarray  # (nnz, 3) the entry's share along (e_r, e_t, e_l) (fronts.share)
    spacing: np.ndarray  # (n, 3) lattice spacing h_ik along (e_r, e_t, e_l) (fronts.spacing)

    @property
    def rows(self) -> np.ndarray:
        return np.repeat(np.arange(len(self.volume)), np.diff(self.indptr))

    def apply(self, u: np.ndarray, kappa: np.ndarray, scale: np.ndarray | float = 1.0) -> np.ndarray:
        """(L_kappa u)_i, plain numpy (the reference the numba kernels are tested against), each
        entry's weight times ``scale`` (per entry: the fronts' correction, :mod:`.fronts`)."""
        rows = self.rows
        c = scale * self.weight * 0.5 * (kappa[rows] + kappa[self.indices])
        return np.bincount(rows, c * (u[self.indices] - u[rows]), minlength=len(u)) / self.volume

    def row_sums(self, kappa: np.ndarray) -> np.ndarray:
        """sum_j w_ij (kappa_i + kappa_j) / 2 / V_i: the Gershgorin radius of each row."""
        rows = self.rows
        c = self.weight * 0.5 * (kappa[rows] + kappa[self.indices])
        return np.bincount(rows, c, minlength=len(kappa)) / self.volume


def _nnls(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Batched non-negative least squares min ||A s - b||, s >= 0, for (n, k, k) A, (n, k) b,
    by trying every support and keeping the best feasible solution."""
    n, k = b.shape
    best = np.zeros((n, k))
    best_res = np.einsum("ni,ni->n", b, b)
    for sup in _supports(k):
        mask = sup.astype(float)
        M = A * mask[None, :, None] * mask[None, None, :] + np.diag(1.0 - mask)[None]
        s = np.einsum("nij,nj->ni", np.linalg.pinv(M), b * mask) * mask
        r = np.einsum("nij,nj->ni", A, s) - b
        res = np.einsum("ni,ni->n", r, r)
        ok = np.all(s >= 0.0, axis=1) & (res < best_res * (1.0 - 1e-12))
        best[ok], best_res[ok] = s[ok], res[ok]
    return best


def csr_reverse(indptr: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Position of (j, i) for every CSR entry (i, j) of a symmetric pattern with sorted rows."""
    n = len(indptr) - 1
    rows = np.repeat(np.arange(n), np.diff(indptr))
    keys = rows * n + indices
    return np.searchsorted(keys, indices * n + rows)


def segment_overlap(pa: np.ndarray, pb: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Length over which segments i and j overlap along the grain, averaged over measuring it on
    i's axis and on j's axis (so it is symmetric in i, j)."""

    def on_axis(a, b):
        length = np.linalg.norm(pb[a] - pa[a], axis=1)
        t = (pb[a] - pa[a]) / length[:, None]
        s0 = np.einsum("ni,ni->n", pa[b] - pa[a], t)
        s1 = np.einsum("ni,ni->n", pb[b] - pa[a], t)
        lo, hi = np.minimum(s0, s1), np.maximum(s0, s1)
        return np.maximum(0.0, np.minimum(hi, length) - np.maximum(lo, 0.0))

    return 0.5 * (on_axis(i, j) + on_axis(j, i))


def assemble(
    centers: np.ndarray,
    frames: np.ndarray,
    pa: np.ndarray,
    pb: np.ndarray,
    area: float,
    indptr: np.ndarray,
    indices: np.ndarray,
    chain: np.ndarray,
    aniso: np.ndarray,
) -> TransportOperator:
    """Build the operator for target tensors A_i = sum_k aniso[i, k] e_k e_k^T (module docstring).

    Parameters
    ----------
    centers : (n, 3) element centres
    frames : (n, 3, 3) wood frames, rows e_r, e_t, e_l
    pa, pb : (n, 3) element end particles
    area : cross-section area per strand, pi r_s^2 / phi_pack (V_i = area * l_i)
    indptr, indices : symmetric CSR of the transport graph, rows sorted
    chain : (nnz,) bool, True where the CSR entry is a strand-chain link
    aniso : (n, 3) principal (a_r, a_t, a_l) per element
    """
    n = len(centers)
    length = np.linalg.norm(pb - pa, axis=1)
    volume = area * length
    rows = np.repeat(np.arange(n), np.diff(indptr))
    cols = indices
    reverse = csr_reverse(indptr, indices)
    d = centers[cols] - centers[rows]
    dist = np.linalg.norm(d, axis=1)
    d_frame = np.einsum("mki,mi->mk", frames[rows], d)  # (d . e_r, d . e_t, d . e_l)
    weight = np.zeros(len(rows))
    # across the grain: REG edges weighted by their overlap along the grain, with the second
    # moment in the (e_r, e_t) plane renormalised per node (module docstring)
    reg = ~chain
    proj = d_frame[:, :2]
    perp2 = np.einsum("mk,mk->m", proj, proj)
    nk2 = proj**2 / np.maximum(perp2, 1e-300)[:, None]
    h2 = np.mean(perp2[reg]) if reg.any() else 1.0
    rel = aniso[rows, :2] / aniso[rows, :2].max(axis=1, keepdims=True)
    overlap = segment_overlap(pa, pb, rows, cols) / length[rows]
    psi = np.where(reg, overlap * fm.exp(-0.5 * np.sum(proj**2 / (h2 * rel), axis=1)), 0.0)
    A = np.zeros((n, 2, 2))
    for k in range(2):
        for m in range(k, 2):
            A[:, k, m] = np.bincount(rows, psi * perp2 * nk2[:, k] * nk2[:, m], minlength=n)
            A[:, m, k] = A[:, k, m]
    target = 2.0 * aniso[:, :2]
    s = _nnls(A, target)
    fit_error = np.linalg.norm(np.einsum("nij,nj->ni", A, s) - target, axis=1) / np.linalg.norm(target, axis=1)
    g = psi * np.einsum("mk,mk->m", s[rows], nk2)
    vg = volume[rows] * g
    weight[reg] = (0.5 * (vg + vg[reverse]))[reg]
    # along the grain: 1D finite volumes on the strand chain, w = a_l A / |d|, less the share of
    # the longitudinal second moment the REG edges already carry through their stagger
    along = d_frame[:, 2]
    m_l = np.bincount(rows, weight * along**2, minlength=n) / volume
    f = m_l / (2.0 * aniso[:, 2])
    a_l = 0.5 * (aniso[rows, 2] + aniso[cols, 2])
    weight[chain] = (a_l * area / dist * np.maximum(0.0, 1.0 - 0.5 * (f[rows] + f[cols])))[chain]
    return TransportOperator(indptr=indptr, indices=indices, weight=weight, reverse=reverse, volume=volume,
                             fit_error=fit_error, chain_saturated=int(np.sum(f > 1.0)),
                             share=fronts.share(d_frame, reverse), spacing=fronts.spacing(rows, d_frame, weight, n))
