"""Speed against accuracy of the adaptive schedule (:mod:`wooddecay.sim.schedule`): a scene over
its days with the fixed schedule (Algorithm 1, the reference) and the adaptive one at tolerance
settings scaled by :data:`FACTORS`, in one process on the same thread count.

Every run starts from one settled state (settled once, then read from a settled-state cache:
:mod:`wooddecay.sim.settled`, the same bits), so the runs differ by their schedule alone. Per run:
the wall time of the simulation after settling (the model built beforehand and the kernels
compiled by a warm-up), the seconds of mechanics simulated, the solves and chunks of N_mech
substeps the schedule ran, the broken REG connections at the end, and against the fixed run the
largest particle position difference at the end (the meshlet vertices are skinned to the
particles). Used by ``benchmarks/schedule.py`` and ``wooddecay chart schedule``.
"""
from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass

import numpy as np

from ..wood import WoodModel
from ..arrays import best_rotation

#: adaptive settings: strain_tolerance, tolerance and rest_speed all times each factor
FACTORS = (0.25, 1.0, 4.0)
#: the ``[time]`` keys the factors scale
TOLERANCE_KEYS = ("strain_tolerance", "tolerance", "rest_speed")


@dataclass
class Run:
    """One simulation of :func:`run`."""

    label: str
    wall: float  # s, after settling
    mechanics_seconds: float  # simulated after settling
    solves: int
    chunks: int
    broken: int  # broken REG connections at the end
    x: np.ndarray  # (P, 3) particle positions at the end
    piece: np.ndarray  # (P,) the piece (component) of each particle at the end (:func:`particle_piece`)

    def error(self, reference: "Run") -> float:
        """Largest particle position difference to ``reference`` at the end (m)."""
        return float(np.sqrt(np.max(np.sum((self.x - reference.x) ** 2, axis=1), initial=0.0)))

    def shape_error(self, reference: "Run") -> float:
        """Largest particle position difference to ``reference`` at the end once each of the
        reference's pieces is moved rigidly onto this run's particles (least squares, Kabsch):
        how differently the wood deformed, without where its pieces rolled or slid to (m)."""
        worst = 0.0
        for k in np.unique(reference.piece):
            rows = np.flatnonzero(reference.piece == k)
            a, b = reference.x[rows], self.x[rows]
            a0, b0 = a - a.mean(axis=0), b - b.mean(axis=0)
            fitted = a0 @ best_rotation(a, b).T
            worst = max(worst, float(np.sqrt(np.max(np.sum((b0 - fitted) ** 2, axis=1)))))
        return worst


def run(path, schedule: str, factor: float = 1.0, overrides: dict | None = None, settle_cache=None) -> Run:
    """Simulate the scene at ``path`` to its last day with ``schedule`` ("fixed" or "adaptive",
    the latter with its tolerances times ``factor``) from the settled state in ``settle_cache``
    (settled there first if it is not); one output frame."""
    import wooddecay as wd

    model = wd.build_model(wd.load_scene(path, overrides=settings(path, schedule, factor, overrides)))
    sim = wd.Simulation(model, settle_cache=settle_cache)
    settled = sim.state.mech.t_seconds
    t0 = time.perf_counter()
    frame = list(sim.run())[-1]
    wall = time.perf_counter() - t0
    s = sim.schedule_summary()
    label = "fixed" if schedule == "fixed" else f"adaptive x{factor:g}"
    return Run(label=label, wall=wall, mechanics_seconds=s["mechanics_seconds"] - settled, solves=s["solves"],
               chunks=s["chunks"], broken=frame.diagnostics["mechanics"]["broken_connections"],
               x=frame.mech["x"], piece=particle_piece(model, frame.mech["component"]))


def particle_piece(model: WoodModel, component: np.ndarray) -> np.ndarray:
    """The piece of each particle: that of the element it starts, else of the one it ends."""
    fp = model.mech.fp
    piece = np.empty(model.mech.n_particles, dtype=np.int64)
    piece[fp + 1] = component
    piece[fp] = component
    return piece


def settings(path, schedule: str, factor: float = 1.0, overrides: dict | None = None) -> dict:
    """The scene overrides of a :func:`run`: ``overrides``, the schedule, one frame and, when
    adaptive, the tolerances (the scene's, or the ones ``overrides`` sets) times ``factor``."""
    import wooddecay as wd

    sets = {"time.schedule": schedule, "time.frames": 1, **(overrides or {})}
    if schedule == "adaptive":
        base = wd.load_scene(path, overrides=overrides)
        sets.update({f"time.{k}": float(base.time[k]) * factor for k in TOLERANCE_KEYS})
    return sets


def warm_up(path) -> None:
    """Compile every kernel a run uses (a two-step run of the scene) so no timing includes it."""
    run(path, "fixed", overrides={"time.days": 1.0})


def compare(path, factors=FACTORS, overrides: dict | None = None) -> tuple[Run, list[Run]]:
    """The fixed run and one adaptive run per factor of ``path`` (module docstring)."""
    warm_up(path)
    with tempfile.TemporaryDirectory(prefix="wooddecay-settled-") as cache:
        fixed = run(path, "fixed", overrides=overrides, settle_cache=cache)
        return fixed, [run(path, "adaptive", f, overrides=overrides, settle_cache=cache) for f in factors]


def pairs(path, n: int, overrides: dict | None = None) -> tuple[list[Run], list[Run]]:
    """``n`` fixed and ``n`` adaptive runs (tolerances as the scene has them) of ``path``,
    alternating, from one settled state: the wall-time ratio of each pair is measured under the
    same load of a shared machine. The runs of one schedule give the same bits."""
    warm_up(path)
    fixed, adaptive = [], []
    with tempfile.TemporaryDirectory(prefix="wooddecay-settled-") as cache:
        for _ in range(n):
            fixed.append(run(path, "fixed", overrides=overrides, settle_cache=cache))
            adaptive.append(run(path, "adaptive", overrides=overrides, settle_cache=cache))
    return fixed, adaptive


def describe(run_: Run, fixed: Run) -> str:
    return (f"{run_.label:>14}: {run_.wall:7.1f} s wall, {run_.mechanics_seconds:6.3f} s of mechanics in "
            f"{run_.chunks} chunks ({run_.solves} solves), {run_.broken} broken, "
            f"max position difference {run_.error(fixed):.2e} m ({run_.shape_error(fixed):.2e} m per piece moved "
            f"rigidly)")


def plot_schedule(name: str, fixed: Run, runs: list[Run], path) -> None:
    """Largest position difference to the fixed schedule against wall time, one point per
    tolerance factor, the fixed run's wall time as a vertical line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8.0, 4.8), dpi=110)
    err = [max(r.error(fixed), 1e-9) for r in runs]
    ax.plot([r.wall for r in runs], err, "o-", color="tab:blue", label="adaptive (tolerances x factor)")
    for r, e in zip(runs, err):
        ax.annotate(f"{r.label.split()[-1]}: {r.chunks} chunks, {r.broken} broken", (r.wall, e),
                    textcoords="offset points", xytext=(6, 4), fontsize=8)
    ax.axvline(fixed.wall, color="tab:red", ls="--", label=f"fixed (Algorithm 1): {fixed.chunks} chunks, "
                                                            f"{fixed.broken} broken")
    ax.axhline(1e-3, color="0.5", ls=":", label="1 mm")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the simulation (s)")
    ax.set_ylabel("largest particle position difference to fixed (m)")
    ax.set_title(f"{name}: adaptive schedule, error against wall time")
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
