"""Equilibrium residual against wall time for every setting of the rods' solver (docs/decisions.md,
"Solver chart"): XPBD at :data:`SWEEPS` sweeps a substep (``mechanics.iterations``) and the
implicit solve at :data:`TOLERANCES` (``mechanics.residual_tolerance``), on the log sample over its
first :data:`LOG_DAYS` days and on Fig. 6's section over its drying span, beside a lone strand's
cantilever and the resting log's shape.

Each bake runs in a child process (``spawn``) that builds the scene's model, then settles and runs
it frame by frame as ``wooddecay bake`` does (no meshing, no export) and sends after each frame the
wall time since the model was built and the frame's equilibrium residual
(:func:`~wooddecay.sim.equilibrium.equilibrium_residual`), with the settled particle positions at
frame 0. A child still running ``cap`` seconds after it built its model is killed: its run is
marked unfinished and keeps the frames it sent. A run's figures: ``residual`` the largest of its
frames' residuals (``summary.json``'s ``convergence.equilibrium_residual_max``), ``wall`` its last
frame's wall time (the cap when unfinished).

* The resting log's error: the settled log's deformation against the implicit solve at the
  tightest tolerance: each run's settled particles and the reference's are moved rigidly onto the
  rest shape (least squares) and |d - d_ref| / |d_ref| over all particles, d the displacement
  from the rest shape that remains (its sag and squash on the ground).
* The cantilever: :func:`wooddecay.studies.cantilever.cantilever` (a lone strand, 0.5 m, 20
  elements, clamped, under gravity) at the log's ``dt_mech`` for XPBD, and one static implicit
  solve to each tolerance; error |deflection / (q L^4 / 8 E I) - 1| (one process, numba compiled
  beforehand).

The default this measures (:func:`choose`): the cheapest setting, by its wall time summed over
the two bakes, whose residual is at most :data:`TARGET` in both and that finished.
"""
from __future__ import annotations

import multiprocessing as mp
import queue
import time
from dataclasses import dataclass, field
from importlib import resources

import numpy as np

from ..arrays import best_rotation

#: XPBD sweeps a substep charted
SWEEPS = (1, 4, 16, 64, 256)
#: implicit residual tolerances charted (the tightest is the resting log's reference)
TOLERANCES = (0.1, 0.03, 0.01, 0.003)
#: the residual every frame of a bake must hold (issue 81, item 6)
TARGET = 0.03
#: days of the log sample baked (one of its 24 frame intervals), in two frames
LOG_DAYS, LOG_FRAMES = 76.0, 2
#: seconds a bake may run after building its model (``--quick``: QUICK_CAP, a quarter of the days)
CAP, QUICK_CAP = 600.0, 120.0


def _sample(*parts: str) -> str:
    return str(resources.files("wooddecay").joinpath("samples", *parts))


def cases(quick: bool) -> dict[str, tuple[str, dict]]:
    """The two bakes charted: name -> (scene path, overrides)."""
    share = 0.25 if quick else 1.0
    return {"log": (_sample("log.toml"), {"time.days": share * LOG_DAYS, "time.frames": LOG_FRAMES}),
            "fig6": (_sample("gallery", "fig6.toml"), {"time.days": share * 40.0, "time.frames": 3 if quick else 11})}


def settings() -> list[tuple[str, dict]]:
    """(label, overrides) of every solver setting charted, XPBD first."""
    xpbd = [(f"xpbd {s}", {"mechanics.solver": "xpbd", "mechanics.iterations": s}) for s in SWEEPS]
    return xpbd + [(f"implicit {t:g}", {"mechanics.solver": "implicit", "mechanics.residual_tolerance": t})
                   for t in TOLERANCES]


@dataclass
class Run:
    """One bake of :func:`bake`."""

    case: str
    label: str
    walls: list[float] = field(default_factory=list)  # s since the model was built, per frame sent
    residuals: list[float] = field(default_factory=list)
    finished: bool = False
    cap: float = CAP
    settled: np.ndarray | None = None  # (P, 3) particles at frame 0
    rest: np.ndarray | None = None  # (P, 3) the built rest shape

    @property
    def residual(self) -> float:
        return max(self.residuals, default=np.nan)

    @property
    def wall(self) -> float:
        return self.walls[-1] if self.finished else self.cap

    def shape_error(self, reference: Run) -> float:
        """The resting log's error (module docstring) against ``reference``."""
        rest = self.rest
        if self.settled is None or reference.settled is None or rest is None:
            return np.nan

        def deformation(x: np.ndarray) -> np.ndarray:
            return (x - x.mean(axis=0)) @ best_rotation(rest, x) - (rest - rest.mean(axis=0))

        d, d_ref = deformation(self.settled), deformation(reference.settled)
        return float(np.linalg.norm(d - d_ref) / max(float(np.linalg.norm(d_ref)), 1e-300))


def _child(path: str, overrides: dict, out) -> None:
    from ..model import build_model
    from ..scene import load_scene
    from ..sim.driver import Simulation

    model = build_model(load_scene(path, overrides))
    out.put(("rest", model.particles.copy()))
    t0 = time.perf_counter()
    sim = Simulation(model)
    for frame in sim.run():
        out.put(("frame", time.perf_counter() - t0, frame.diagnostics["mechanics"]["equilibrium_residual"],
                 frame.mech["x"] if frame.index == 0 else None))
    out.put(("done",))


def bake(case: str, path: str, label: str, overrides: dict, cap: float) -> Run:
    """Bake ``path`` with ``overrides`` in a child process for at most ``cap`` seconds after its
    model is built (module docstring)."""
    ctx = mp.get_context("spawn")
    out = ctx.Queue()
    child = ctx.Process(target=_child, args=(path, overrides, out), daemon=True)
    child.start()
    run, deadline = Run(case, label, cap=cap), np.inf
    try:
        while True:
            try:
                msg = out.get(timeout=max(0.0, min(deadline - time.monotonic(), 60.0)))
            except queue.Empty:
                if time.monotonic() >= deadline:
                    break
                if not child.is_alive():
                    raise RuntimeError(f"{case} {label}: the bake's process ended with code {child.exitcode}")
                continue
            if msg[0] == "rest":
                run.rest, deadline = msg[1], time.monotonic() + cap
            elif msg[0] == "frame":
                run.walls.append(msg[1])
                run.residuals.append(msg[2])
                if msg[3] is not None:
                    run.settled = msg[3]
            else:
                run.finished = True
                break
    finally:
        if child.is_alive():
            child.kill()
        child.join()
    return run


def cantilever_points(dt: float) -> list[dict]:
    """The lone strand's cantilever under every setting (module docstring): label, error, wall."""
    from ..sim import implicit
    from . import cantilever

    cantilever.cantilever(dt=dt, iterations=1, seconds=10 * dt)  # compiles the kernels
    points = [{"label": f"xpbd {s}"} | cantilever.cantilever(dt=dt, iterations=s, seconds=1.5) for s in SWEEPS]
    for tol in TOLERANCES:
        s = cantilever.strand()
        t0 = time.perf_counter()
        implicit.step(s.setup, s.ms, np.inf, tol=tol)
        points.append({"label": f"implicit {tol:g}", "seconds": time.perf_counter() - t0, "error": s.deflection_error()})
    return points


def run_chart(quick: bool = False, report=print) -> tuple[list[Run], list[dict]]:
    """Every bake of :func:`cases` x :func:`settings` (``report`` told of each as it ends), then the
    cantilever's points."""
    from ..scene import load_scene

    runs = []
    cap = QUICK_CAP if quick else CAP
    for case, (path, overrides) in cases(quick).items():
        for label, setting in settings():
            runs.append(bake(case, path, label, overrides | setting, cap))
            report(describe(runs[-1]))
    dt = float(load_scene(_sample("log.toml")).mechanics["dt_mech"])
    return runs, cantilever_points(dt)


def choose(runs: list[Run]) -> str | None:
    """The cheapest setting with residual <= TARGET in every case, finished (module docstring)."""
    by_label: dict[str, list[Run]] = {}
    for r in runs:
        by_label.setdefault(r.label, []).append(r)
    ok = {label: sum(r.wall for r in rs) for label, rs in by_label.items()
          if all(r.finished and r.residual <= TARGET for r in rs)}
    return min(ok, key=ok.__getitem__) if ok else None


def describe(run: Run) -> str:
    state = "finished" if run.finished else f"killed at {run.cap:g} s after {len(run.walls)} frames"
    return (f"{run.case} {run.label}: residual_max {run.residual:.4g}, wall {run.wall:.1f} s ({state})")


def plot_chart(runs: list[Run], cantilever: list[dict], path) -> str | None:
    """Four panels (module docstring), the :func:`choose` default ringed; returns it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    default = choose(runs)
    fig, axes = plt.subplots(2, 2, figsize=(11.0, 8.5), dpi=110)
    colours = {"xpbd": "tab:blue", "implicit": "tab:red"}

    def draw(ax, points, title, ylabel, target=None):
        for solver, colour in colours.items():
            pts = [p for p in points if p[0].startswith(solver)]
            ax.plot([p[1] for p in pts], [p[2] for p in pts], "-", color=colour, alpha=0.5)
            groups: list[list] = []  # points within 3% of each other on both axes share one label
            for label, x, y, done in pts:
                ax.plot([x], [y], "o" if done else ">", color=colour, mfc=colour if done else "none", ms=7)
                if label == default:
                    ax.plot([x], [y], "o", ms=16, mfc="none", mec="k")
                near = next((g for g in groups if abs(g[1] / x - 1) < 0.03 and abs(g[2] / y - 1) < 0.03), None)
                name = label.split()[1] + ("" if done else " (killed)")
                if near is None:
                    groups.append([name, x, y])
                else:
                    near[0] += "/" + name
            for name, x, y in groups:
                ax.annotate(name, (x, y), textcoords="offset points", xytext=(5, 4), fontsize=7)
        if target is not None:
            ax.axhline(target, color="0.4", ls=":", label=f"residual {target:g}")
            ax.legend(fontsize=8, loc="lower left")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("wall time (s)")
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=10)

    for ax, case in zip(axes[0], ("log", "fig6")):
        pts = [(r.label, r.wall, r.residual, r.finished) for r in runs if r.case == case and r.residuals]
        draw(ax, pts, f"{case}: largest frame residual (xpbd: sweeps; implicit: tolerance)",
             "equilibrium residual", TARGET)
        top = max((p[2] for p in pts), default=1.0)
        for r in (r for r in runs if r.case == case and not r.residuals):  # killed before its first frame
            ax.plot([r.wall], [top], ">", color=colours[r.label.split()[0]], mfc="none", ms=7)
            ax.annotate(f"{r.label.split()[1]}: no frame in {r.cap:g} s", (r.wall, top), textcoords="offset points",
                        xytext=(-10, -12), fontsize=7, ha="right")
    draw(axes[1, 0], [(p["label"], p["seconds"], max(p["error"], 1e-6), True) for p in cantilever],
         "lone strand cantilever: deflection error", "|deflection / beam theory - 1|")
    log = [r for r in runs if r.case == "log"]
    reference = next(r for r in log if r.label == f"implicit {min(TOLERANCES):g}")
    draw(axes[1, 1], [(r.label, r.wall, r.shape_error(reference), r.finished) for r in log
                      if r is not reference and r.settled is not None],
         f"resting log: settled shape error against implicit {min(TOLERANCES):g}", "|d - d_ref| / |d_ref|")
    fig.suptitle(f"rods' solver: cost against accuracy; ringed: the default these measure ({default})", fontsize=11)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return default
