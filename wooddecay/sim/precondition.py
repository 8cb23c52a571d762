"""The preconditioner of the implicit step's Newton systems (docs/decisions.md, "Implicit step").

The diagonally scaled matrix A of :mod:`~wooddecay.sim.implicit` couples a strand's particles and
element rotations stiffly (stretch, shear, bend-twist: 1e6-1e7 N/m on the log) and the strands
more weakly through the REG; the wood as a whole rests on a few contacts, so its lowest modes
are nearly rigid motions (a round log's roll). Two parts, added, take the two apart:

* strand blocks S: A's entries between the degrees of freedom of one strand (its particles and
  its elements' rotations, interleaved along the strand, so each block is banded), factored
  exactly once per Newton system;
* a coarse space P of the rigid-body modes (three translations, three rotations about the
  centroid) of aggregates: the elements of one piece within one cell of a grid sized for about
  AGGREGATE elements a cell, and the particles they hold.

M^-1 = S^-1 + P (P^T A P)^-1 P^T is symmetric positive definite, so conjugate gradients may use
it. Figure (the log in five pieces on the ground, day 635, 21,498 unknowns, steps of 1 s and
0.01 s, to 1e-3): 80-250 iterations against 265-2,400 of Jacobi, 3-4x less time a solve.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .mechanics import MechSetup, MechState

#: elements per aggregate of the coarse space (the grid's cell holds about this many)
AGGREGATE = 40
#: added to the strand blocks' unit diagonal: a strand that nothing else holds (no REG edge, no
#: contact, a static step) has rigid modes that make its block singular; the sum stays SPD
REGULAR = 1e-10


def strand_of_blocks(setup: MechSetup) -> tuple[np.ndarray, np.ndarray]:
    """The strand of each 3-DOF block (particles, then element rotations) and its position along
    the strands (particle p at 2 p, element e's rotation between its particles)."""
    per = np.diff(setup.strand_offsets)
    strand_e = np.repeat(np.arange(len(per)), per)
    strand_p = np.empty(setup.n_particles, np.int64)
    strand_p[setup.fp] = strand_e
    strand_p[setup.fp + 1] = strand_e
    position = np.concatenate([2.0 * np.arange(setup.n_particles), 2.0 * setup.fp + 1.0])
    return np.concatenate([strand_p, strand_e]), position


def aggregates(setup: MechSetup, ms: MechState) -> np.ndarray:
    """Aggregate of each element: its piece (``ms.component``) and its centre's cell in a grid of
    cubes holding about AGGREGATE elements each over the wood's bounding box."""
    c = 0.5 * (ms.x[setup.fp] + ms.x[setup.fp + 1])
    lo, hi = c.min(axis=0), c.max(axis=0)
    extent = np.maximum(hi - lo, 1e-9)
    cells = max(1.0, setup.n_elements / AGGREGATE)
    size = float(np.prod(extent) / cells) ** (1.0 / 3.0)
    size = max(size, float(extent.max()) / cells)  # a slender body: cells along its length
    cell = np.floor((c - lo) / size).astype(np.int64)
    key = np.stack([ms.component.astype(np.int64), cell[:, 0], cell[:, 1], cell[:, 2]], axis=1)
    return np.unique(key, axis=0, return_inverse=True)[1].ravel()


def rigid_modes(setup: MechSetup, ms: MechState, agg: np.ndarray) -> sp.csr_matrix:
    """(3 (P + n), 6 k) the rigid-body modes of the k aggregates ``agg`` (per element): a
    translation moves its particles, a rotation omega about its centroid c moves particle p by
    omega x (x_p - c) and turns its elements by omega. A particle goes with the last element of
    its strand that holds it."""
    P, n = setup.n_particles, setup.n_elements
    agg_p = np.empty(P, np.int64)
    agg_p[setup.fp] = agg
    agg_p[setup.fp + 1] = agg
    count = np.bincount(agg_p)
    centre = np.stack([np.bincount(agg_p, ms.x[:, c]) for c in range(3)], axis=1) / np.maximum(count, 1)[:, None]
    r = ms.x - centre[agg_p]
    p3, e3 = 3 * np.arange(P), 3 * (P + np.arange(n))
    entries = []  # (rows, columns, values)
    for k in range(3):
        entries.append((p3 + k, 6 * agg_p + k, np.ones(P)))
        t = np.cross(np.eye(3)[k], r)
        entries += [(p3 + m, 6 * agg_p + 3 + k, t[:, m]) for m in range(3)]
        entries.append((e3 + k, 6 * agg + 3 + k, np.ones(n)))
    rows, cols, vals = (np.concatenate(c) for c in zip(*entries))
    k_agg = int(agg.max()) + 1 if len(agg) else 0
    return sp.csr_matrix((vals, (rows, cols)), shape=(3 * (P + n), 6 * k_agg))


def two_level(A: sp.spmatrix, strand: np.ndarray, position: np.ndarray, modes: sp.csr_matrix
              ) -> spla.LinearOperator:
    """M^-1 (module docstring) for the scaled matrix ``A`` (3 b x 3 b) over b blocks whose strand
    and position along it are ``strand``, ``position``; ``modes`` the coarse basis in A's
    (scaled) unknowns (no columns: strand blocks alone; a strand per block: 3x3 block Jacobi)."""
    dof_strand = np.repeat(strand, 3)
    order = np.argsort(np.repeat(position, 3) * 3.0 + np.tile(np.arange(3.0), len(position)), kind="stable")
    coo = A.tocoo()
    same = dof_strand[coo.row] == dof_strand[coo.col]
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    S = sp.csc_matrix((coo.data[same], (rank[coo.row[same]], rank[coo.col[same]])), shape=A.shape)
    S += REGULAR * sp.identity(S.shape[0], format="csc")  # a strand free of all else has rigid modes
    lu = spla.splu(S, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    modes_t = modes.T.tocsr()
    coarse = (modes_t @ (A @ modes)).tocsc()
    d = coarse.diagonal()
    coarse.setdiag(np.where(d > 0.0, d * (1.0 + 1e-12), 1.0))
    # sparse: an aggregate's modes couple only its neighbours' (on the broken log's 1,104 modes,
    # 6% of the entries: 7 ms a factor and 0.13 ms a solve against 38 ms and 0.5 ms dense)
    factor = spla.splu(coarse, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True}) if len(d) else None

    def apply(r: np.ndarray) -> np.ndarray:
        z = lu.solve(r[order])[rank]
        return z if factor is None else z + modes @ factor.solve(modes_t @ r)

    return spla.LinearOperator(A.shape, apply, dtype=float)
