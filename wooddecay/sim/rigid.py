"""Rigid pieces of the implicit step (docs/decisions.md, "Rigid pieces").

Under ``mechanics.solver = "implicit"``, a piece (connected component,
:func:`~wooddecay.sim.failure.components`) that no anchor holds and that has fewer than
RIGID_FRACTION of the wood's elements intact moves as one rigid body in
:func:`~wooddecay.sim.implicit.step`: its particles and element rotations are replaced by six
unknowns, a translation t and a rotation omega about its centre of mass c. Its elements'
particles move by x_p <- c + t + R(omega) (x_p - c) and their orientations by
q_e <- exp(omega / 2) q_e, so its own energies (stretch, shear, bend-twist, its REG connections)
never change: the Newton system over its unknowns is B^T (H + M / h^2) B, the columns of B the
linearised motion (t; omega x (x_p - c) on a particle, omega on an element's rotation), and its
mass and inertia tensor those of its elements (B^T M B).

Why: a loose piece resting on others or on the ground couples its stiff strands to soft, nonlinear
contacts and friction, and the long steps of a decaying log stall on exactly that (docs/limits.md,
"The implicit solver is an option"); a small piece's own deformation shows nothing. A rigid piece
fails only by decay (its strains are referenced to its rigid shape each step,
:func:`freeze_strains`), not by stress. Pieces only split, so a rigid piece stays rigid.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from ..quaternion import exp_np, rotate_np
from . import failure
from .mechanics import MechSetup, MechState

#: a piece no anchor holds moves rigidly below this fraction of the wood's elements (intact ones)
RIGID_FRACTION = 0.05


def pieces(setup: MechSetup, ms: MechState) -> np.ndarray:
    """Rigid piece of each element, numbered from 0 in order of their components, or -1: its
    component is anchored or has at least RIGID_FRACTION of the elements intact, or the solver is
    XPBD (its pieces are rods). A failed element goes with its component (its REG connections may
    hold it)."""
    if setup.solver != "implicit":
        return np.full(setup.n_elements, -1, dtype=np.int64)
    comp = ms.component
    size = np.bincount(comp, weights=ms.element_ok.astype(float))
    held = np.zeros(len(size), dtype=bool)
    held[comp[setup.anchored_e]] = True
    rigid = (size > 0.0) & (size < RIGID_FRACTION * setup.n_elements) & ~held
    number = np.cumsum(rigid) - 1
    return np.where(rigid[comp], number[comp], -1)


class Bodies(NamedTuple):
    """The rigid pieces of a step: who moves with which, and about which centre."""

    element: np.ndarray  # (n,) int64: rigid piece of each element, or -1
    particle: np.ndarray  # (P,) int64: rigid piece of each particle, or -1
    centre: np.ndarray  # (k, 3) float64, m: each piece's centre of mass

    @property
    def n_pieces(self) -> int:
        return len(self.centre)

    @property
    def blocks(self) -> np.ndarray:
        """(P + n,) bool: the 3-DOF blocks (particles, then element rotations) that move rigidly."""
        return np.concatenate([self.particle >= 0, self.element >= 0])


def bodies(setup: MechSetup, ms: MechState) -> Bodies:
    """The :class:`Bodies` of ``ms``: :func:`pieces`, their particles and centres of mass."""
    element = pieces(setup, ms)
    particle = np.full(setup.n_particles, -1, dtype=np.int64)
    claimed = np.zeros(setup.n_particles, dtype=bool)
    for on in (ms.element_ok, ~ms.element_ok):  # a particle goes with the intact element holding it
        for end in (setup.fp[on], setup.fp[on] + 1):
            free = ~claimed[end]
            particle[end[free]] = element[on][free]
            claimed[end] = True
    k = int(element.max()) + 1 if len(element) else 0
    p = np.flatnonzero(particle >= 0)
    m = np.bincount(particle[p], ms.mass_p[p], minlength=k)
    moment = np.stack([np.bincount(particle[p], ms.mass_p[p] * ms.x[p, c], minlength=k) for c in range(3)], axis=1)
    centre = moment / np.where(m > 0.0, m, 1.0)[:, None]
    empty = m <= 0.0  # massless particles only: their mean
    if empty.any():
        count = np.bincount(particle[p], minlength=k)
        mean = np.stack([np.bincount(particle[p], ms.x[p, c], minlength=k) for c in range(3)], axis=1)
        centre[empty] = mean[empty] / count[empty, None]
    return Bodies(element, particle, centre)


def basis(setup: MechSetup, ms: MechState, rb: Bodies, free_blocks: np.ndarray) -> sp.csr_matrix:
    """B (3 free blocks, 3 kept + 6 k): the free DOFs as the kept blocks' own (free and not
    rigid, in block order) and each rigid piece's (t, omega), after them (module docstring)."""
    P = setup.n_particles
    kept = free_blocks & ~rb.blocks
    row_of = np.cumsum(free_blocks) - 1  # block -> free block
    col_of = np.cumsum(kept) - 1
    n_kept = int(kept.sum())
    rows, cols, vals = [], [], []
    kb = np.flatnonzero(kept)
    for c in range(3):
        rows.append(3 * row_of[kb] + c)
        cols.append(3 * col_of[kb] + c)
        vals.append(np.ones(len(kb)))
    p = np.flatnonzero(free_blocks[:P] & (rb.particle >= 0))
    r = ms.x[p] - rb.centre[rb.particle[p]]
    base = 3 * n_kept + 6 * rb.particle[p]
    for c in range(3):
        rows.append(3 * row_of[p] + c)
        cols.append(base + c)
        vals.append(np.ones(len(p)))
        turn = np.cross(np.eye(3)[c], r)  # omega_c e_c x r
        for m in range(3):
            rows.append(3 * row_of[p] + m)
            cols.append(base + 3 + c)
            vals.append(turn[:, m])
    e = np.flatnonzero(free_blocks[P:] & (rb.element >= 0))
    for c in range(3):
        rows.append(3 * row_of[P + e] + c)
        cols.append(3 * n_kept + 6 * rb.element[e] + 3 + c)
        vals.append(np.ones(len(e)))
    shape = (3 * int(free_blocks.sum()), 3 * n_kept + 6 * rb.n_pieces)
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=shape)


def motions(rb: Bodies, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each rigid piece's (t, omega) (k, 3) each, from the reduced unknowns ``d`` (its last 6 k)."""
    tail = d[len(d) - 6 * rb.n_pieces:].reshape(rb.n_pieces, 6)
    return tail[:, :3], tail[:, 3:]


def moved(x: np.ndarray, x0: np.ndarray, rb: Bodies, t: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """``x`` (P, 3) with the rigid pieces' particles moved exactly from ``x0``:
    c + t + R(omega) (x0_p - c)."""
    out = x.copy()
    p = np.flatnonzero(rb.particle >= 0)
    k = rb.particle[p]
    out[p] = rb.centre[k] + t[k] + rotate_np(exp_np(omega)[k], x0[p] - rb.centre[k])
    return out


def freeze_strains(setup: MechSetup, ms: MechState, rb: Bodies) -> None:
    """Reference the strains of the rigid pieces' intact elements and of the REG edges within them
    to their current shape, so that :func:`~wooddecay.sim.failure.update` breaks them by decay
    only (module docstring)."""
    if rb.n_pieces == 0:
        return
    elem, edge = failure.strains(setup, ms)
    e = rb.element >= 0
    ms.strain_ref_elem[e] = elem[e]
    a, b = rb.element[setup.edges[:, 0]], rb.element[setup.edges[:, 1]]
    k = (a >= 0) & (a == b)
    ms.strain_ref_edge[k] = edge[k]
