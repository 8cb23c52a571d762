"""What a solver reports of one macro step: the shape every solver of the driver shares.

Each solver of :class:`wooddecay.sim.driver.Simulation` is ``advance(model, state, dt) ->
Events``: it advances ``state`` (whose clock ``state.t_days`` is where the step starts) by ``dt``
days, doing its own scheduling inside (the biology its stable substeps, the mechanics its chunks of
``N_mech`` XPBD substeps when they are due, the bark its crack search), and says what it did. One
time unit (days), one return type: a fixed-step solver and an event-driven one are called alike.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Events:
    """What happened in one solver's step; fields a solver does not touch keep their default.

    ``substeps``: the biology's explicit substeps; ``due``: why mechanics ran (a reason of
    :func:`wooddecay.sim.schedule.due`, ``"fixed"``, or None when it was skipped); ``chunks``: the
    chunks of N_mech substeps it ran; ``searched``: whether the bark searched for new cracks."""

    substeps: int = 0
    due: str | None = None
    chunks: int = 0
    searched: bool = False
