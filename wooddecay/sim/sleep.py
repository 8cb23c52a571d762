"""Sleeping pieces: a piece that has stopped moving is taken out of the solve until something
disturbs it (the deactivation of Box2D, Bullet and PhysX; woodstock §5.4 debris piles).

Why (docs/decisions.md, "Debris settles by sleeping"): an iterative penalty-contact solver never
holds a pile exactly still. With one Jacobi contact iteration per substep, every resting contact
is corrected a little differently in each substep, so a pile whose pieces have all stopped still
jitters by ~1e-7 m per substep, about 1e-3 m/s in the velocities x - x_old / dt. The jitter also
ratchets what rests on it: a single element lying on a quiet pile crept down it at 2 mm/s for six
seconds, and stopped within 0.4 s once the pile under it was held still.

Rule, evaluated at the end of every window of ``sleep_time`` seconds of :func:`macro_step`
(:func:`update`):

* a piece (connected component) whose every particle moved less than ``sleep_speed`` times the
  window since the window began is *quiet*; a quiet piece falls asleep unless it touches (a capsule
  pair overlapping beyond its rest overlap) an awake piece that moved faster than
  ``WAKE_FACTOR`` sleep_speed: an impact;
* a sleeping piece that such a *loud* piece touches wakes up;
* a sleeping piece has zero inverse mass and inertia, so the solver holds it like an anchored
  element: it does not move, and the pieces on it rest on a still support; its velocities are
  zero. The schedule holds pieces the same way within a solve (``held``,
  :func:`wooddecay.sim.schedule.hold_still`); :func:`still` is either.

Everything wakes (:func:`wake_all`, which restarts the window) when an external force acts on a
sleeping particle. A failure wakes the pieces it touched and those touching them
(:func:`wake_failed`; the window goes on). The coupling's new masses, rest data and
integrity after every biology step wake only the pieces where they changed past the schedule's
tolerances since those pieces fell asleep (:func:`wake`, called by
:func:`wooddecay.sim.schedule.wake_changed`): a small change leaves a piece asleep, holding the
shape it slept in, so pieces sleep in a coupled bake and a window outlasts macro steps (it counts
seconds of mechanics, which the adaptive schedule runs only when due). ``sleep_speed`` 0
switches sleeping off. Per piece and per particle in numpy, so deterministic; the state
(``asleep``, ``sleep_x``, ``sleep_t``) is checkpointed.
"""
from __future__ import annotations

import numpy as np

from .contact import pair_overlaps

#: an awake piece faster than this many times sleep_speed wakes the sleeping pieces it touches
WAKE_FACTOR = 10.0


def weights(setup, ms) -> tuple[np.ndarray, np.ndarray]:
    """Awake inverse particle masses and quaternion weights 1 / (4 I_rot) from ``ms.mass_p`` and
    ``ms.mass_e`` (zero where anchored or massless)."""
    w_p = np.where(setup.anchored_p | (ms.mass_p <= 0), 0.0, 1.0 / np.maximum(ms.mass_p, 1e-300))
    w_q = np.where(setup.anchored_e, 0.0, 1.0 / (4.0 * ms.mass_e * setup.inertia_factor))
    return w_p, w_q


def wake_all(setup, ms) -> None:
    """Wake every piece, release the held ones and start a new window at the current state."""
    ms.asleep[:] = False
    ms.held[:] = False
    ms.w_p, ms.w_q = weights(setup, ms)
    _restart(ms)


def wake(setup, ms, elements: np.ndarray) -> int:
    """Wake the sleeping or held pieces holding any of ``elements`` (a boolean mask); the window
    goes on. Returns the number of pieces woken."""
    pieces = np.unique(ms.component[elements & still(ms)])
    if len(pieces):
        woken = np.isin(ms.component, pieces)
        ms.asleep[woken] = False
        ms.held[woken] = False
        hold(setup, ms)
    return len(pieces)


def wake_failed(setup, ms, element_ok: np.ndarray, edge_ok: np.ndarray, refresh) -> int:
    """Wake the still pieces (:func:`still`) that hold an element or a REG edge whose flags
    differ from ``element_ok``, ``edge_ok`` (before the failures), then those touching such a
    piece (``refresh(setup, ms)`` rebuilds the contact list, which leaves out pairs of two still
    elements); the window goes on. Returns the number of pieces woken."""
    hit = element_ok != ms.element_ok
    hit[setup.edges[(edge_ok != ms.edge_ok).any(axis=1)].ravel()] = True
    if not (hit.any() and still(ms).any()):
        return 0
    near = np.zeros(int(ms.component.max(initial=-1)) + 1, dtype=bool)
    near[ms.component[hit]] = True
    woken = wake(setup, ms, near[ms.component])
    if woken:
        ms.pairs_x = None
        refresh(setup, ms)
    a, b = touching(setup, ms)
    touch = near[a] | near[b]
    near[a[touch]] = True
    near[b[touch]] = True
    return woken + wake(setup, ms, near[ms.component])


def substeps_left(setup, ms) -> int:
    """Substeps until the current window ends (0: it has ended)."""
    return max(int(round((ms.sleep_t[0] + setup.sleep_time - ms.t_seconds) / setup.dt)), 0)


def wake_loaded(setup, ms) -> None:
    """Wake everything if an external force (``ms.force``) acts on a sleeping particle."""
    if ms.asleep.any() and np.any(ms.force[ms.w_p == 0.0] != 0.0):
        wake_all(setup, ms)


def update(setup, ms) -> int:
    """End of a window (module docstring): put quiet pieces to sleep, wake the sleeping pieces a
    loud one touches, start the next window. Returns the number of sleeping pieces."""
    n_comp = int(ms.component.max(initial=-1)) + 1
    elapsed = ms.t_seconds - ms.sleep_t[0]
    moved = np.sqrt(np.sum((ms.x - ms.sleep_x) ** 2, axis=1))
    speed = np.zeros(n_comp)  # the fastest particle of each piece over the window
    np.maximum.at(speed, ms.component, np.maximum(moved[setup.fp], moved[setup.fp + 1]) / elapsed)
    loud = speed > WAKE_FACTOR * setup.sleep_speed
    hit = np.zeros(n_comp, dtype=bool)  # touched by a loud piece
    a, b = touching(setup, ms)
    np.logical_or.at(hit, a, loud[b])
    np.logical_or.at(hit, b, loud[a])
    asleep = (speed < setup.sleep_speed) & ~hit
    ms.asleep = asleep[ms.component]
    hold(setup, ms)
    _restart(ms)
    return int(asleep.sum())


def touching(setup, ms) -> tuple[np.ndarray, np.ndarray]:
    """Components of the two sides of every contact pair that overlaps beyond its rest overlap."""
    pairs = ms.pairs
    if len(pairs) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    on = pair_overlaps(ms.x, setup.fp, ms.radius, pairs) > ms.pairs_rest
    return ms.component[pairs[on, 0]], ms.component[pairs[on, 1]]


def still(ms) -> np.ndarray:
    """The elements the solver holds still: asleep, or held by the schedule for this solve
    (:mod:`~wooddecay.sim.schedule`, "held")."""
    return ms.asleep | ms.held


def hold(setup, ms) -> None:
    """Weights (from ``ms.mass_p``, ``ms.mass_e``) and velocities of the current ``asleep`` and
    ``held`` flags (:func:`still`): a particle is still when every element it belongs to is."""
    w_p, w_q = weights(setup, ms)
    stopped = still(ms)
    awake_p = np.zeros(setup.n_particles, dtype=bool)
    awake_p[setup.fp[~stopped]] = True
    awake_p[setup.fp[~stopped] + 1] = True
    ms.w_p = np.where(awake_p, w_p, 0.0)
    ms.w_q = np.where(stopped, 0.0, w_q)
    ms.v[~awake_p] = 0.0
    ms.omega[stopped] = 0.0


def _restart(ms) -> None:
    ms.sleep_x = ms.x.copy()
    ms.sleep_t = np.array([ms.t_seconds])
