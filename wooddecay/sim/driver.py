"""The simulation loop (woodstock §8.2, Algorithm 1) behind ``wd.Simulation``.

Each macro step: ``N_mech`` mechanics substeps of ``dt_mech`` (lines 4-8,
:mod:`wooddecay.sim.mechanics`), one biology step of ``dt_bio`` (lines 9-11,
:mod:`wooddecay.sim.biology`), then the coupling of moisture and decay back to the rods
(lines 12-13, :mod:`wooddecay.sim.coupling`) and the bark (:mod:`wooddecay.sim.bark`: cracks,
bonds, plates that shed). ``mechanics=False`` runs the biology alone (years of
decay on a static model). Frames are yielded at ``model.time.frames`` times evenly spaced over
[0, model.time.days] (the first frame is the initial state when frames > 1). Every solver of a
macro step has the shape ``advance(model, state, dt) -> Events`` (:mod:`wooddecay.sim.events`,
``dt`` in days; :attr:`Simulation.solvers`): the model holds everything static (``model.bio``,
``model.mech``, ``model.coupling``, ``model.time``, ``model.inoculations``), the
:class:`~wooddecay.sim.state.SimState` everything that changes.

Settling: before the first step the rods settle under gravity (:func:`mechanics.settle`,
``model.time.settle`` seconds); failure strains are measured from the state they settle into.
With ``settle_cache`` (a folder) the settled rods are loaded from it when the same wood settled
before, and stored otherwise (:mod:`wooddecay.sim.settled`; the same bits either way).

Schedule: ``model.time.schedule`` "fixed" runs N_mech substeps in every macro step (Algorithm
1), "adaptive" only the chunks of them :mod:`wooddecay.sim.schedule` finds due; the history
records per step the chunks run and why.

Threads: with ``threads`` (a :class:`~wooddecay.sim.threads.ThreadChoice`) every macro step and
every settling chunk runs through :meth:`ThreadChoice.run` (the count it gives, its wall time
and the step's work reported back); without, numba's own setting is left alone.

Checkpoints: with ``checkpoint_dir`` and ``checkpoint_every = K`` the whole state is written
after every K-th frame (``frame_<k>.npz``, written to a temporary name and renamed).
:meth:`Simulation.resume` continues from one; the frames that follow are bit-identical to an
uninterrupted run (all kernels are deterministic and the contact list is rebuilt from the state at
the start of every macro step).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np

from ..wood import WoodModel
from ..atomic import read_archive
from . import bark, biology, coupling, schedule, settled
from .equilibrium import equilibrium_residual
from .mechanics import MechState, convergence, strain_excess
from .diagnostics import diagnostics, mech_diagnostics
from .signature import signature
from .state import FIELDS, SimState, initial_state
from .threads import ThreadChoice

CHECKPOINT_VERSION = 12


@dataclass(frozen=True, eq=False)
class Frame:
    """A snapshot: frame index, time, copies of the fields, of the rod state (``mech``: x, q,
    component, element_ok, edge_ok, integrity; empty without mechanics), the diagnostics and of
    the bark (``bark``: cracked sheet edges and shed faces; empty without a bark sheet)."""

    index: int
    t_days: float
    fields: dict
    mech: dict
    diagnostics: dict
    bark: dict = field(default_factory=dict)


def frame_times(days: float, frames: int) -> np.ndarray:
    """Frame times in days: evenly spaced over [0, days], or just [days] for one frame."""
    return np.array([days]) if frames == 1 else np.linspace(0.0, days, frames)


class Simulation:
    """``Simulation(model).run()`` yields :class:`Frame` objects (module docstring).
    ``history`` collects the diagnostics at day 0 and after every macro step."""

    def __init__(self, model: WoodModel, mechanics: bool = True, checkpoint_dir=None, checkpoint_every: int = 0,
                 settle: bool = True, threads: ThreadChoice | None = None, settle_cache=None,
                 crack_bark: bool = True):
        self.model = model
        self.threads = threads
        self.state: SimState = initial_state(model, rods=mechanics)
        self.mechanics = mechanics
        self.checkpoint_dir = None if checkpoint_dir is None else Path(checkpoint_dir)
        self.checkpoint_every = int(checkpoint_every)
        self.last_frame = -1
        #: wall seconds spent simulating this state, over every run that resumed it (the caller
        #: keeps it current; it is checkpointed)
        self.wall_seconds = 0.0
        self.settled = "no"  # "settled", or "cached" when loaded from ``settle_cache``
        if mechanics:
            coupling.step(model, self.state)
            if settle:  # the bark's day-0 cracks and the settled rods, or both from the cache
                self.settled = settled.settle(model, self.state, settle_cache,
                                              run=None if threads is None else threads.run)
            assert self.state.mech is not None  # initial_state(rods=True)
            schedule.mark(model, self.state.mech, self.state.t_days, quiet=settle)
        if self.settled == "no" and crack_bark:  # False: the caller restores a later bark (resume)
            self.state.bark = bark.initial(model, self.state)
        self.history: list[dict] = [self._diagnostics()]
        if mechanics:
            assert self.state.mech is not None
            self.history[0]["mechanics"] |= self._convergence()

    @property
    def substeps(self) -> int:
        """Biology substeps per ``dt_bio`` (1 when dt_bio is within the stability bound)."""
        return biology.substeps(self.model.time.dt_bio, self.model.bio.bound)

    def _diagnostics(self) -> dict:
        d = diagnostics(self.model, self.state)
        if self.mechanics:
            d["mechanics"] = mech_diagnostics(self.state.mech)
        return d

    @property
    def solvers(self) -> tuple:
        """The solvers of a macro step in Algorithm 1's order, each ``advance(model, state, dt) ->
        Events`` (:mod:`~wooddecay.sim.events`): mechanics under the schedule, biology (with the
        inoculations due), coupling, bark; without mechanics the biology and the bark."""
        if self.mechanics:
            return (schedule.advance, biology.advance, coupling.advance, bark.advance)
        return (biology.advance, bark.advance)

    def macro_step(self, dt_bio: float) -> None:
        """Algorithm 1 lines 4-13 with a biology step of ``dt_bio`` days."""
        if self.threads is None:
            self._macro_step(dt_bio)
        else:
            self.threads.run(lambda: self._macro_step(dt_bio), keyed=True)

    def _macro_step(self, dt_bio: float) -> tuple:
        """:meth:`macro_step`; returns what it did, the work under which ``threads`` compares its
        time: the schedule's reason and chunks and whether the bark searched for cracks."""
        events = [solver(self.model, self.state, dt_bio) for solver in self.solvers]
        d = self._diagnostics()
        self.history.append(d)
        if not self.mechanics:
            return None, None, events[-1].searched
        d["mechanics"].update({"chunks": events[0].chunks, "due": events[0].due})
        return events[0].due, events[0].chunks, events[-1].searched

    def schedule_summary(self) -> dict:
        """The schedule and, over the macro steps run so far (``history``), how many ran
        mechanics, the chunks of N_mech substeps, the seconds of mechanics and the solves by
        reason (:func:`schedule.due`), and whether the rods settled or came from the cache."""
        steps = [h["mechanics"] for h in self.history[1:] if "chunks" in h.get("mechanics", {})]
        reasons: dict[str, int] = {}
        for h in steps:
            if h["due"] is not None:
                reasons[h["due"]] = reasons.get(h["due"], 0) + 1
            if h.get("frame_solve"):
                reasons["frame"] = reasons.get("frame", 0) + 1
        return {"schedule": self.model.time.schedule, "macro_steps": len(steps),
                "solves": sum(reasons.values()), "chunks": sum(h["chunks"] for h in steps),
                "mechanics_seconds": cast(MechState, self.state.mech).t_seconds if self.mechanics else 0.0, "due": reasons,
                "settled": self.settled}

    def _convergence(self) -> dict:
        """The rods' :func:`strain_excess` and :func:`equilibrium_residual` now."""
        ms, setup = cast(MechState, self.state.mech), self.model.mech
        return {"strain_excess": strain_excess(setup, ms) if setup.solver == "xpbd" else None,
                "equilibrium_residual": equilibrium_residual(setup, ms)}

    def convergence(self, frames) -> dict | None:
        """:func:`mechanics.convergence` of the settled rods and ``frames`` (None without
        mechanics)."""
        if not self.mechanics:
            return None
        rows = [self.history[0]["mechanics"]] + [f.diagnostics["mechanics"] for f in frames]
        ms = cast(MechState, self.state.mech)
        return convergence(self.model.mech, [r["strain_excess"] for r in rows],
                           [r["equilibrium_residual"] for r in rows], int(ms.unconverged[0]), int(ms.resolves[0]))

    def advance(self, days: float) -> None:
        """Advance by ``days`` in macro steps of at most ``time.dt_bio``, equal between the days
        on which an inoculation falls (so it is applied on its day, not up to a step late)."""
        if days <= 0.0:
            return
        t0 = self.state.t_days
        stops = sorted({t0 + days} | {ino.day for ino in self.model.inoculations
                                      if t0 + 1e-9 < ino.day < t0 + days - 1e-9})
        for stop in stops:
            span = stop - self.state.t_days
            n = max(1, int(np.ceil(span / self.model.time.dt_bio - 1e-9)))
            for _ in range(n):
                self.macro_step(span / n)

    def _frame_solve(self) -> None:
        """Under the implicit solver, solve the rods against the rest data the last macro step's
        coupling changed, so a frame shows wood in equilibrium (docs/decisions.md, "Implicit
        frames"); counted in the last macro step's chunks and as a "frame" solve (the settled
        rods of frame 0 are solved already)."""
        last = self.history[-1]["mechanics"]
        last["chunks"] += schedule.solve(self.model, self.state, self.model.time.tolerances, "frame")
        last["frame_solve"] = True

    def frame(self, index: int) -> Frame:
        rods = {}
        if self.mechanics:
            ms = self.state.mech
            rods = {k: getattr(ms, k).copy() for k in ("x", "q", "component", "element_ok", "edge_ok", "integrity")}
        d = self._diagnostics()
        if self.mechanics:
            d["signature"] = signature(self.model, self.state) | bark.statistics(self.model, self.state.bark)
            assert self.state.mech is not None
            d["mechanics"] |= self._convergence()
        sheet = {} if self.state.bark is None else {"cracked": self.state.bark.crack.cracked.copy(),
                                                      "shed": self.state.bark.shed.copy()}
        return Frame(index=index, t_days=self.state.t_days,
                     fields={f: getattr(self.state, f).copy() for f in FIELDS}, mech=rods, diagnostics=d, bark=sheet)

    def run(self):
        """Yield a frame at every frame time after the last one yielded (module docstring)."""
        for k, t in enumerate(frame_times(self.model.time.days, self.model.time.frames)):
            if k <= self.last_frame:
                continue
            self.advance(t - self.state.t_days)
            if self.mechanics and self.model.mech.solver == "implicit" and "chunks" in self.history[-1]["mechanics"]:
                self._frame_solve()
            self.last_frame = k
            if self.checkpoint_dir is not None and self.checkpoint_every > 0 and k % self.checkpoint_every == 0:
                self.save_checkpoint(self.checkpoint_dir / f"frame_{k:05d}.npz")
            yield self.frame(k)

    # ------------------------------------------------------------------ checkpoints
    def save_checkpoint(self, path) -> Path:
        """Write the whole state (fields, clock, rods, history) atomically to ``path``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        s = self.state
        arrays = {f"field_{f}": getattr(s, f) for f in FIELDS}
        if self.mechanics:
            assert s.mech is not None
            arrays.update({f"mech_{k}": v for k, v in s.mech.arrays().items()})
        if s.bark is not None:
            arrays.update({f"bark_{k}": v for k, v in s.bark.arrays().items()})
        meta = {"version": CHECKPOINT_VERSION, "scene_hash": self.model.info.hash, "mechanics": self.mechanics,
                "frame": self.last_frame, "t_days": s.t_days, "clamp_count": s.clamp_count,
                "applied": sorted(s.applied), "history": self.history,
                "t_seconds": cast(MechState, s.mech).t_seconds if self.mechanics else 0.0,
                "failures": cast(MechState, s.mech).failures if self.mechanics else 0, "wall_seconds": self.wall_seconds}
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "wb") as fh:
            np.savez(fh, meta=np.array(json.dumps(meta)), **arrays)
        os.replace(tmp, path)
        return path

    @classmethod
    def resume(cls, model, path, **kwargs) -> "Simulation":
        """A simulation continuing from the checkpoint ``path`` of the same scene; ValueError for a
        file that is not one (unreadable, of another scene or version)."""
        try:
            meta, arrays = read_archive(path)
        except ValueError as err:
            raise ValueError(f"{err}; cannot resume") from None
        if meta.get("version") != CHECKPOINT_VERSION or meta.get("scene_hash") != model.info.hash:
            raise ValueError(f"{path}: checkpoint of another scene or version; cannot resume")
        sim = cls(model, mechanics=meta["mechanics"], settle=False, crack_bark=False, **kwargs)
        s = sim.state
        for f in FIELDS:
            setattr(s, f, arrays[f"field_{f}"])
        s.t_days, s.clamp_count, s.applied = meta["t_days"], meta["clamp_count"], set(meta["applied"])
        if sim.mechanics:
            assert s.mech is not None
            s.mech.restore({k: arrays[f"mech_{k}"] for k in s.mech.arrays()}, meta["t_seconds"], meta["failures"])
        sheet = bark.uncracked(model, s)
        if sheet is not None:
            s.bark = bark.BarkState.from_arrays({k: arrays[f"bark_{k}"] for k in sheet.arrays()})
        sim.history = meta["history"]
        sim.last_frame = meta["frame"]
        sim.wall_seconds = float(meta["wall_seconds"])
        return sim
