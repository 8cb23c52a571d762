"""The simulation loop (woodstock §8.2, Algorithm 1) behind ``wd.Simulation``.

This version runs the biology only (Algorithm 1 lines 9-11: one biology step per macro step),
for years of decay on a static wood model; mechanics and coupling (lines 4-8, 12-13) come with
the mechanics module. Frames are yielded at ``scene.time.frames`` times evenly spaced over
[0, scene.time.days] (the first frame is the initial state when frames > 1).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import biology
from .diagnostics import diagnostics
from .state import FIELDS, SimState, initial_state, inoculate


@dataclass(frozen=True, eq=False)
class Frame:
    """A snapshot: frame index, time, copies of the fields and the diagnostics."""

    index: int
    t_days: float
    fields: dict
    diagnostics: dict


def frame_times(days: float, frames: int) -> np.ndarray:
    """Frame times in days: evenly spaced over [0, days], or just [days] for one frame."""
    return np.array([days]) if frames == 1 else np.linspace(0.0, days, frames)


class Simulation:
    """``Simulation(model, scene).run()`` yields :class:`Frame` objects.

    ``mechanics=False`` is the biology-only mode (the only mode until the mechanics module
    lands; asking for mechanics raises NotImplementedError rather than silently skipping it).
    ``history`` collects the diagnostics at day 0 and after every biology step.
    """

    def __init__(self, model, scene, mechanics: bool = False):
        if mechanics:
            raise NotImplementedError("mechanics are not implemented yet; use mechanics=False")
        self.model, self.scene = model, scene
        self.setup = biology.prepare(model, scene)
        self.state: SimState = initial_state(model, scene)
        self.history: list[dict] = [diagnostics(self.state, self.setup)]

    @property
    def substeps(self) -> int:
        """Biology substeps per ``dt_bio`` (1 when dt_bio is within the stability bound)."""
        return biology.substeps(self.scene.time.dt_bio, self.setup.bound)

    def advance(self, days: float) -> None:
        """Advance by ``days`` in biology steps of at most ``time.dt_bio``, equal between the
        days on which an inoculation falls (so it is applied on its day, not up to a step late)."""
        if days <= 0.0:
            return
        t0 = self.state.t_days
        stops = sorted({t0 + days} | {ino["day"] for ino in self.scene.inoculations
                                      if t0 + 1e-9 < ino["day"] < t0 + days - 1e-9})
        for stop in stops:
            span = stop - self.state.t_days
            n = max(1, int(np.ceil(span / self.scene.time.dt_bio - 1e-9)))
            for _ in range(n):
                biology.step(self.state, self.setup, span / n)
                inoculate(self.model, self.scene, self.state)
                self.history.append(diagnostics(self.state, self.setup))

    def frame(self, index: int) -> Frame:
        return Frame(index=index, t_days=self.state.t_days,
                     fields={f: getattr(self.state, f).copy() for f in FIELDS},
                     diagnostics=diagnostics(self.state, self.setup))

    def run(self):
        """Yield a frame at every frame time (module docstring)."""
        for k, t in enumerate(frame_times(self.scene.time.days, self.scene.time.frames)):
            self.advance(t - self.state.t_days)
            yield self.frame(k)
