"""Debris settling (woodstock §5.4, Fig. 12; docs/model.md §4): a log falls apart into its BSP blocks,
is dropped onto the ground, and the pieces must come to rest without sinking into each other.

Used by ``benchmarks/debris.py`` and ``tests/studies/test_debris.py``; docs/decisions.md ("Debris")
gives reasons and figures.

* **Fragments** (:func:`fragment`): the log, settled on the ground by ``wd.Simulation``, falls
  apart the way advanced brown rot leaves it (Fig. 12): every theta = 1 REG connection and every
  element whose strand successor lies in another BSP leaf lose all strength and fail through
  :func:`wooddecay.sim.failure.update` (so the failure rules apply: an element next to a cut or
  at a strand end does not fail).
* **Drop** (:func:`drop`): the pieces are lifted by ``height`` and fall under gravity with the
  scene's contact, friction, damping and sleeping (:mod:`wooddecay.sim.sleep`), in macro steps
  of 0.1 s; each step is recorded (:class:`Record`).
* **Measures.** ``max_speed``: the largest particle speed; ``window_speed``: the largest
  displacement over the step divided by its length (what sleeping measures, blind to the
  solver's substep jitter); ``penetration``: the largest overlap of two intact capsules of
  different pieces beyond their overlap in the intact wood (:mod:`wooddecay.sim.contact`, "Rest
  overlap"), over r_s; ``asleep``: pieces asleep. The issue's target: afterwards max_speed
  < 1e-3 m/s and penetration < 0.1 r_s.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..sim import contact, failure
from ..sim import mechanics as mech

#: seconds of mechanics per recorded step
STEP = 0.1


@dataclass(frozen=True)
class Record:
    t: float  # seconds since the drop
    max_speed: float  # m/s
    p99_speed: float  # m/s
    window_speed: float  # m/s, over the last STEP
    penetration: float  # over r_s, beyond the rest overlap
    raw_overlap: float  # over r_s
    z_min: float  # m
    pieces: int
    asleep: int


def fragment(sim) -> None:
    """Fail the BSP-boundary connections and strand links of ``sim`` (module docstring)."""
    model, st, ms = sim.model, sim.model.mech, sim.state.mech
    leaf = model.bsp_leaf
    boundary = np.zeros(model.n_elements, dtype=bool)
    boundary[:-1] = leaf[:-1] != leaf[1:]
    ms.limit_edge[model.reg_theta.astype(bool)] = -np.inf
    ms.limit_elem[boundary] = -np.inf
    failure.update(st, ms)


def penetration(st, ms) -> tuple[float, float]:
    """Largest overlap of two intact capsules of different pieces beyond the overlap they had in
    the intact wood, and the largest raw one (m)."""
    pairs = contact.candidate_pairs(ms.x, st.fp, st.radius, ms.component, 0.0, active=ms.element_ok)
    phi = contact.pair_overlaps(ms.x, st.fp, st.radius, pairs)
    rest = contact.pair_overlaps(st.x_rest, st.fp, st.radius, pairs)
    return float(np.max(phi - rest, initial=0.0)), float(phi.max(initial=0.0))


def drop(sim, height: float, seconds: float):
    """Lift the pieces of ``sim`` by ``height`` and let them fall for ``seconds``; yields a
    :class:`Record` every :data:`STEP` seconds."""
    st, ms = sim.model.mech, sim.state.mech
    r_s = sim.model.r_s
    ms.x[:, 2] += height
    t0, per = ms.t_seconds, int(round(STEP / st.dt))
    while ms.t_seconds - t0 < seconds - 1e-9:
        x0 = ms.x.copy()
        mech.macro_step(sim.model, sim.state, per)
        speed = np.sqrt(np.sum(ms.v**2, axis=1))
        pen, raw = penetration(st, ms)
        yield Record(t=ms.t_seconds - t0, max_speed=float(speed.max()), p99_speed=float(np.percentile(speed, 99)),
                     window_speed=float(np.sqrt(np.sum((ms.x - x0) ** 2, axis=1)).max() / STEP),
                     penetration=pen / r_s, raw_overlap=raw / r_s, z_min=float(ms.x[:, 2].min()),
                     pieces=int(ms.component.max()) + 1, asleep=int(np.unique(ms.component[ms.asleep]).size))
