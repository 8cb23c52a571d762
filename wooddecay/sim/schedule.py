"""The adaptive schedule: mechanics only when the wood has changed enough to matter, and then for
as long as it moves (``time.schedule = "adaptive"``; ``"fixed"`` runs Algorithm 1's N_mech
substeps in every macro step).

Why (docs/decisions.md, "Adaptive schedule"): mechanics is 95-98% of a fixed-schedule iteration,
yet in a quiet year the coupling moves rest lengths, integrity and masses by fractions of a
percent per step and nothing fails, while a piece that does break loose needs 0.15 s of
mechanics (60 fixed macro steps) to fall 10 cm.

Rule, at the start of every macro step (:func:`due`), mechanics runs when, since its last solve
(:func:`mark`):

* a rest strain moved by more than ``time.strain_tolerance``: an element's |Delta l_r| / l_r
  (Eq. 17) or a REG pair's |Delta dp| / max(dp_0, r_s) (Eq. 16), the strain the solve would
  relax;
* an integrity I_ij (Eq. 21) changed by more than ``time.tolerance``, or an element mass by more
  than that fraction: the sag under gravity scales with mass over stiffness;
* the set of active ``[[load]]``s changed;
* the last solve ended with the wood still moving (it reached ``time.max_mechanics``);
* a constraint fails at the current positions against the current rest data and limits
  (:func:`failure.update`, the test every substep ends with) and that splits a piece (pieces
  count from ``MIN_PIECE`` elements here and below, :func:`big_pieces`): drying and
  decay lower the limits and shorten the rest lengths of wood that holds still, and that cracks
  it; decay separates BSP cells (``mechanics.I_fail``). A failure inside a piece is kept but
  starts no solve: the piece moves only once it splits or its rest data moved past the
  tolerances (a decaying log fails some connections on most macro steps, and solving each
  cost a chunk per step).

A solve (:func:`solve`) runs chunks of N_mech substeps (:func:`mechanics.macro_step`, sleeping
included), the first only :func:`relax_substeps` long when it relaxes rest data of wood at rest
(reasons ``RELAX``), until a chunk ends that split no piece and in which no piece is moving
(:func:`moving`): none whose centre of mass, faster than ``time.rest_speed`` on average or at its
end, is gaining speed (a piece released from rest falls g T^2 / 2 in a chunk of T, a mean speed of
g T / 2, and ends it at g T, which the chunk's length T puts above rest_speed) or carries a
kinetic energy share m_piece / m_wood v^2 above rest_speed^2 (a block that landed and rolls on at
a few cm/s does not keep the solve going: it held the collapsing log's solves at their cap), or
``time.max_mechanics`` seconds have run. Pieces, not particles: single elements next to a crack
swing in place at ~8e-2 m/s (docs/limits.md, "Single elements swing beside cracks") and kept every solve of a
drying log running to its cap (4.4x the fixed schedule's substeps), while a piece that falls,
rolls or rocks moves its centre of mass. A
failure that splits no piece does not extend a solve: a crack that opens moves its piece.
Skipped steps leave every rest-data change within the tolerances unrelaxed, so the failure test
sees strains at most ``strain_tolerance`` early and a resting shape lags by at most ``tolerance``
of its sag; ``benchmarks/schedule.py`` measures the difference to the fixed schedule.

Held pieces: after every chunk of a solve the pieces at rest (their centre of mass slower than
``time.hold_speed``) are held still for the next chunk (:func:`hold_still`), as a sleeping piece
is (zero weights, :mod:`~wooddecay.sim.sleep`), and the kernels skip every constraint of which
nothing can move (:func:`mechanics.stiffness`). A piece a moving one touches stays awake when
the mover's momentum could set it moving (m v > M hold_speed). Pieces held when a solve ends at its
cap stay held into the next ("moving") solve; a solve that ends quiet releases them, and so do
a failure in or beside them, a load, and rest data that changed past the tolerances (held
pieces keep the reference data of :func:`mark` they were held with). Why (docs/decisions.md,
"Held pieces"): in a collapse the solve goes on for the few pieces falling off the heap, and
the log they fall from took the substeps' time.

The reference rest data and the quiet flag live in the :class:`~wooddecay.sim.mechanics.MechState`
(``solved_*``, ``held``), so they are checkpointed and a resumed bake decides as the uninterrupted
one.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numba as nb
import numpy as np

from ..wood import Tolerances, WoodModel
from . import failure, implicit, mechanics, sleep
from .events import Events
from .signature import MIN_PIECE

#: a relaxing chunk brings a piece released from rest to this many times rest_speed (:func:`relax_substeps`)
CHUNK_MARGIN = 1.15
#: the reasons of :func:`due` that ask wood at rest to relax changed rest data
RELAX = ("strain", "integrity_mass")


def mark(model: WoodModel, ms: mechanics.MechState, t_days: float, quiet: bool) -> None:
    """Take the current rest data of the awake elements and of the REG pairs with an awake end
    as the state of the last solve, on day ``t_days``. A sleeping or held piece keeps the data
    it fell asleep or was held with, so its changes add up until they wake it
    (:func:`wake_changed`)."""
    awake = ~sleep.still(ms)
    edges = model.mech.edges
    pair_awake = awake[edges[:, 0]] | awake[edges[:, 1]]
    ms.solved_rest_length[awake] = ms.rest_length[awake]
    ms.solved_mass[awake] = ms.mass_e[awake]
    ms.solved_rest_offset[pair_awake] = ms.rest_offset[pair_awake]
    ms.solved_integrity[pair_awake] = ms.integrity[pair_awake]
    ms.solved_day = np.array([t_days])
    ms.quiet = np.array([quiet])


def active_loads(setup: mechanics.MechSetup, t_days: float) -> tuple[bool, ...]:
    """Which ``[[load]]``s act on ``t_days``."""
    return tuple(d0 <= t_days < d1 for d0, d1, _ in setup.loads)


#: the reasons of :func:`changed` by the code :func:`_changed` returns
CHANGE_REASONS = (None, "integrity_mass", "strain")


def changed(model: WoodModel, ms: mechanics.MechState, tol: Tolerances) -> tuple[str | None, np.ndarray]:
    """The elements whose rest data changed past the tolerances since the last solve (an element
    of a REG pair that did counts), and the first reason found: "strain" (a rest strain moved
    by more than ``tol.strain``), "integrity_mass" (an I_ij or a relative mass by more than
    ``tol.relative``) or None. One serial numba pass over the elements and the pairs
    (:func:`changed_reference` is its numpy twin). Why: the twin's temporaries over the tree's
    325,648 pairs took 2.9 ms a macro step (docs/decisions.md, "Adaptive schedule")."""
    over = np.zeros(len(ms.rest_length), dtype=np.bool_)
    code = _changed(model.mech.edges, model.mech.edge_length, ms.rest_length, ms.solved_rest_length, ms.mass_e,
                    ms.solved_mass, ms.rest_offset, ms.solved_rest_offset, ms.integrity, ms.solved_integrity,
                    float(tol.strain), float(tol.relative), over)
    return CHANGE_REASONS[code], over


@nb.njit(cache=True)
def _changed(edges, edge_length, rest_length, solved_rest_length, mass, solved_mass, rest_offset, solved_rest_offset,
             integrity, solved_integrity, strain, relative, over):
    """:func:`changed` into ``over``; returns 2 for "strain", 1 for "integrity_mass", 0 for none."""
    code = 0
    for e in range(len(rest_length)):
        if abs(rest_length[e] - solved_rest_length[e]) > strain * rest_length[e]:
            over[e] = True
            code = 2
        elif abs(mass[e] - solved_mass[e]) > relative * solved_mass[e]:
            over[e] = True
            code = max(code, 1)
    for k in range(len(edges)):
        if abs(rest_offset[k] - solved_rest_offset[k]) > strain * edge_length[k]:
            code = 2
        elif abs(integrity[k] - solved_integrity[k]) > relative:
            code = max(code, 1)
        else:
            continue
        over[edges[k, 0]] = True
        over[edges[k, 1]] = True
    return code


def changed_reference(model: WoodModel, ms: mechanics.MechState, tol: Tolerances) -> tuple[str | None, np.ndarray]:
    """Plain-numpy :func:`changed`."""
    edges = model.mech.edges
    strain_e = np.abs(ms.rest_length - ms.solved_rest_length) > tol.strain * ms.rest_length
    strain_k = np.abs(ms.rest_offset - ms.solved_rest_offset) > tol.strain * model.mech.edge_length
    rel_e = np.abs(ms.mass_e - ms.solved_mass) > tol.relative * ms.solved_mass
    rel_k = np.abs(ms.integrity - ms.solved_integrity) > tol.relative
    reason = "strain" if strain_e.any() or strain_k.any() else "integrity_mass" if rel_e.any() or rel_k.any() else None
    over = strain_e | rel_e
    over[edges[strain_k | rel_k].ravel()] = True
    return reason, over


def wake_changed(model: WoodModel, state, tol: Tolerances) -> str | None:
    """Wake the sleeping pieces whose rest data changed past the tolerances (:func:`changed`);
    returns the reason, or None."""
    reason, over = changed(model, state.mech, tol)
    if reason is not None:
        sleep.wake(model.mech, state.mech, over)
    return reason


def due(model: WoodModel, state, tol: Tolerances) -> str | None:
    """Why mechanics must run in the macro step starting at ``state.t_days``, or None (module
    docstring); wakes the sleeping and held pieces that changed. The failure test runs last, only
    when nothing else asks for a solve; failures it finds are kept and wake the pieces they touch
    (:func:`sleep.wake_failed`)."""
    ms, setup = state.mech, model.mech
    if not ms.quiet[0]:
        wake_changed(model, state, tol)  # held pieces whose rest data changed
        return "moving"
    if active_loads(setup, state.t_days) != active_loads(setup, float(ms.solved_day[0])):
        return "load"
    reason = wake_changed(model, state, tol)
    if reason is not None:
        return reason
    pieces, flags = big_pieces(ms), (ms.element_ok.copy(), ms.edge_ok.copy())
    if failure.update(setup, ms) and big_pieces(ms) != pieces:
        sleep.wake_failed(setup, ms, *flags, mechanics.refresh_pairs)
        return "failure"
    return None


def big_pieces(ms: mechanics.MechState) -> int:
    """Pieces of at least ``MIN_PIECE`` elements: a split that only frees a loose bit changes
    nothing the schedule waits for."""
    return int(np.count_nonzero(np.bincount(ms.component) >= MIN_PIECE))


class Motion(NamedTuple):
    """Each piece's element count, mass and centre-of-mass speeds over a chunk (:func:`motion`)."""

    count: np.ndarray  # type: ignore[assignment]  # a NamedTuple field may shadow tuple.count; kept for its callers
    mass: np.ndarray
    v_now: np.ndarray  # at the chunk's end
    v_mean: np.ndarray  # mean over the chunk


def motion(setup: mechanics.MechSetup, ms: mechanics.MechState, x0: np.ndarray, seconds: float,
           v0: np.ndarray | None = None) -> Motion:
    """:class:`Motion` of every piece: its centre of mass (intact element centres weighted by
    mass) now and on average since the positions ``x0``, ``seconds`` ago; given the velocities
    ``v0`` at the start (the implicit solver), the average is the mean of the start's and the
    end's velocities instead. Why: an implicit macro step leaves the bound wood's displacement
    through changed rest data as creep over the days it took (:func:`implicit.creep`), and its
    steps are seldom ``seconds`` long (a piece sliding steadily through steps of 0.01 s looked
    100x faster at its end than on average over the span, so gaining speed, and the log's solves
    never ended quiet)."""
    fp, n = setup.fp, int(ms.component.max(initial=-1)) + 1
    m_e = ms.mass_e * ms.element_ok
    mass = np.bincount(ms.component, weights=m_e, minlength=n)
    weight = np.divide(1.0, mass, out=np.zeros(n), where=mass > 0.0)

    def com_speed(a):
        v = np.stack([np.bincount(ms.component, weights=m_e * a[:, c], minlength=n) for c in range(3)], axis=1)
        return np.linalg.norm(v, axis=1) * weight

    now = 0.5 * (ms.v[fp] + ms.v[fp + 1])
    mean = (com_speed(0.5 * (ms.x[fp] + ms.x[fp + 1] - x0[fp] - x0[fp + 1])) / seconds if v0 is None
            else com_speed(0.5 * (0.5 * (v0[fp] + v0[fp + 1]) + now)))
    return Motion(np.bincount(ms.component, minlength=n), mass, com_speed(now), mean)


def moving(m: Motion, rest_speed: float) -> bool:
    """Whether a piece of at least ``MIN_PIECE`` elements still moves (module docstring): its
    centre of mass is gaining speed above ``rest_speed`` (its velocity at the chunk's end exceeds
    its mean velocity over the chunk: falling, tipping, sliding off), or it carries a kinetic
    energy share m_piece / m_wood v^2 above ``rest_speed``^2, v the larger of the two
    (:class:`Motion`). A small piece that rolls or rocks where it landed stops holding the solve
    open; a large one does as soon as it is slower than ``rest_speed``."""
    big = (m.count >= MIN_PIECE) & (m.mass > 0.0)
    v_now, v_mean = m.v_now[big], m.v_mean[big]
    v = np.maximum(v_now, v_mean)
    share = m.mass[big] / m.mass.sum()
    return bool(np.any((v > rest_speed) & ((v_now > v_mean) | (share * v * v > rest_speed * rest_speed))))


def hold_still(setup: mechanics.MechSetup, ms: mechanics.MechState, m: Motion, hold_speed: float) -> None:
    """Hold still, until the solve's next chunk, every awake piece (of any size) at rest: its
    centre of mass slower than ``hold_speed`` on average and at the end of the chunk
    (:class:`Motion`), unless a moving piece touches it whose momentum could set it moving at
    ``hold_speed`` (m v > M hold_speed: a block falling onto its like, not a stick sliding down
    the log). Release the others; ``hold_speed`` 0 holds nothing (module docstring, "Held
    pieces")."""
    if hold_speed <= 0.0:
        release(setup, ms)
        return
    v = np.maximum(m.v_now, m.v_mean)
    moves = v > hold_speed
    near = moves.copy()
    a, b = sleep.touching(setup, ms)
    push = m.mass * v
    near[a[moves[b] & (push[b] > m.mass[a] * hold_speed)]] = True
    near[b[moves[a] & (push[a] > m.mass[b] * hold_speed)]] = True
    held = ~near[ms.component] & ~ms.asleep
    if not np.array_equal(held, ms.held):
        ms.held = held
        sleep.hold(setup, ms)


def release(setup: mechanics.MechSetup, ms: mechanics.MechState) -> None:
    """Release every held piece."""
    if ms.held.any():
        ms.held[:] = False
        sleep.hold(setup, ms)


def relax_substeps(model: WoodModel) -> int:
    """Substeps of ``mechanics.dt_mech`` in the first chunk of a solve that relaxes rest data
    (``RELAX``): the fewest in which a piece released from rest reaches ``CHUNK_MARGIN``
    rest_speed (g T), so that :func:`moving` sees it fall, and at most N_mech (N_mech without
    gravity). 12 at the defaults (1.2 ms, 1.18 cm/s). Why: on the quiet steps of a drying year a
    solve is one chunk, and a shorter one relaxes the same rest data; a solve that goes on, or
    one for a failure, a load or wood still moving, runs chunks of N_mech, since shorter ones
    end a collapse's solves sooner with its pieces moving less (docs/decisions.md, "Adaptive
    schedule")."""
    g = float(np.linalg.norm(model.mech.gravity))
    n = int(model.time.N_mech)
    if g <= 0.0:
        return n
    return min(n, max(1, math.ceil(CHUNK_MARGIN * model.time.tolerances.rest_speed / (g * model.mech.dt))))


def _macro_step(model: WoodModel, state, n_sub: int) -> int:
    """``n_sub`` substeps' span of the rods by ``mechanics.solver``: XPBD
    (:func:`mechanics.macro_step`) or backward Euler (:func:`implicit.macro_step`)."""
    solver = implicit.macro_step if model.mech.solver == "implicit" else mechanics.macro_step
    return solver(model, state, n_sub)


def _budget(model: WoodModel, tol: Tolerances) -> float:
    """What :func:`solve` may spend: ``tol.max_seconds`` of XPBD substeps, or as many implicit
    steps (:func:`implicit.span` each, at least one) as fit in them."""
    if model.mech.solver == "xpbd":
        return tol.max_seconds - 1e-12
    return max(1, math.floor(tol.max_seconds / implicit.span(model.mech, model.time.N_mech)))


def solve(model: WoodModel, state, tol: Tolerances, reason: str | None = None) -> int:
    """Chunks of N_mech substeps, the first :func:`relax_substeps` long when ``reason`` (from
    :func:`due`) is in ``RELAX``, until the wood is quiet or the :func:`_budget` is spent (module
    docstring); marks the result as solved. Returns the number of chunks."""
    ms, dt = state.mech, model.mech.dt
    n_sub = relax_substeps(model) if reason in RELAX else model.time.N_mech
    chunks, substeps, quiet = 0, 0, False
    while not quiet and (substeps * dt if model.mech.solver == "xpbd" else chunks) < _budget(model, tol):
        x0, v0 = ms.x.copy(), (ms.v.copy() if model.mech.solver == "implicit" else None)
        pieces = big_pieces(ms)
        _macro_step(model, state, n_sub)
        chunks += 1
        substeps += n_sub
        m = motion(model.mech, ms, x0, n_sub * dt, v0)
        quiet = big_pieces(ms) == pieces and not moving(m, tol.rest_speed)
        hold_still(model.mech, ms, m, tol.hold_speed)
        n_sub = model.time.N_mech
    if quiet:
        release(model.mech, ms)
    mark(model, ms, state.t_days, quiet)
    return chunks


def advance(model: WoodModel, state, dt: float) -> Events:
    """The driver's mechanics solver (:mod:`~wooddecay.sim.events`), Algorithm 1 lines 4-8 under
    ``model.time.schedule``: "fixed" runs the N_mech substeps every macro step; "adaptive" runs
    the chunks of them :func:`due` finds due, until the pieces are at rest (:func:`solve`). The
    rods move in their own seconds; ``dt`` (days) is the biology's step they precede."""
    time = model.time
    if time.schedule == "fixed":
        wake_changed(model, state, time.tolerances)
        _macro_step(model, state, time.N_mech)
        mark(model, state.mech, state.t_days, quiet=True)
        return Events(due="fixed", chunks=1)
    due_now = due(model, state, time.tolerances)
    return Events(due=due_now, chunks=0 if due_now is None else solve(model, state, time.tolerances, due_now))
