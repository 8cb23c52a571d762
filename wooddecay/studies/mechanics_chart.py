"""Cost against accuracy of the rod solver: the gravity cantilever over dt, substeps and
iterations, with PyElastica's point on the same axes (issue 4, item 7; docs/model.md §7 "Mechanics").

The case is :func:`wooddecay.studies.cantilever.cantilever`: one strand of the real pipeline,
L = 0.5 m free length, r_s = 6 mm, E = 1 GPa, 20 free elements, clamped at its root and sagging
under gravity for 1 s of simulated time. The error is |deflection / (q L^4 / (8 E I)) - 1|, the
cost the wall time of the time stepping only (numba compiled beforehand by a tiny warm-up run,
one run per setting). Numba runs on one thread (:data:`THREADS`): a 20-element strand has no
parallel work worth sharing, PyElastica is single-threaded too, and with two threads on a busy
2-core machine the many tiny parallel regions spin-wait on a descheduled worker (measured: the
same settings took 0.01-0.35 s on one thread and 1.3-10.8 s on two while another job ran).

Substeps are expressed by dt: every XPBD substep advances dt, so a setting makes 1 / dt substeps
per simulated second (``cantilever.cantilever``'s own ``substeps`` argument only splits
``dt_mech`` further and gives the same substep length dt / substeps). The sweep is therefore
dt in :data:`DTS` x solver iterations per substep in :data:`ITERATIONS`.

The reference is :func:`wooddecay.studies.elastica.elastica_cantilever` for the same rod (same L,
radius, E, G, rho_dry, elements): PositionVerlet at 0.9 of its stability limit (5.4 us), damped
near-critically and run until settled (10 / omega_1 = 0.16 s simulated). PyElastica is optional;
without it the chart says so and has no reference point.
"""
from __future__ import annotations

import inspect
import math

import numba
import numpy as np

from . import cantilever
from . import elastica as pe

#: substep lengths swept (s); substeps per simulated second = 1 / dt
DTS = (1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4)
#: solver iterations per substep swept
ITERATIONS = (1, 2, 5, 10)
#: the reduced sweep of ``--quick`` (includes a setting below the target: 2e-4 s, 2 iterations)
DTS_QUICK = (1e-2, 1e-3, 2e-4)
ITERATIONS_QUICK = (2, 10)
#: the accuracy target drawn as a horizontal line (3% of the analytic deflection)
TARGET = 0.03
#: errors above this, and non-finite ones (unstable settings), are drawn clipped at the top edge
Y_CAP = 100.0
#: simulated time of every run of ours (s)
SECONDS = 1.0
#: numba threads during the sweep (module docstring)
THREADS = 1
#: free length (m) and free elements of the strand
LENGTH = 0.5
N_ELEMENTS = 20


def case() -> dict:
    """The cantilever's parameters: length and elements from this module, the material and
    r_s from the defaults of :func:`wooddecay.studies.cantilever.strand` (so the title stays true)."""
    d = {k: p.default for k, p in inspect.signature(cantilever.strand).parameters.items()}
    return {"length": LENGTH, "n": N_ELEMENTS, "r_s": d["r_s"], "E": d["E"], "G": d["G"],
            "rho": d["rho"], "g": abs(d["g"]), "seconds": SECONDS}


def run_mechanics(dts=DTS, iterations=ITERATIONS, seconds: float = SECONDS,
                  elastica: bool = True, threads: int = THREADS) -> list[dict]:
    """Run the sweep (module docstring) on ``threads`` numba threads and, if ``elastica``,
    PyElastica's reference.

    Returns plain dicts, ours first in order of dt then iterations: ``solver`` ("wooddecay" or
    "pyelastica"), ``dt`` (s), ``substeps_per_second`` (1 / dt), ``iterations`` (None for
    PyElastica), ``error`` (relative, NaN when the run blew up), ``seconds`` (wall time of the
    stepping), ``simulated`` (s) and, for ours, ``threads``. The PyElastica entry is left out when it is not installed.
    """
    before = numba.get_num_threads()
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        return _sweep(dts, iterations, seconds, elastica)
    finally:
        numba.set_num_threads(before)


def _sweep(dts, iterations, seconds, elastica) -> list[dict]:
    c = case()
    cantilever.cantilever(length=c["length"], n=c["n"], dt=2e-3, iterations=1, seconds=0.01)  # compile numba
    out = []
    for dt in dts:
        for k in iterations:
            r = cantilever.cantilever(length=c["length"], n=c["n"], dt=dt, iterations=k, seconds=seconds)
            err = float(r["error"])
            out.append({"solver": "wooddecay", "dt": float(dt), "substeps_per_second": 1.0 / dt,
                        "iterations": int(k), "error": err if math.isfinite(err) else math.nan,
                        "seconds": float(r["seconds"]), "simulated": float(seconds),
                        "threads": numba.get_num_threads()})
    if elastica:
        try:
            pe.load_elastica()
        except ImportError:
            return out
        out.append(run_elastica(c))
    return out


def run_elastica(c: dict | None = None) -> dict:
    """PyElastica's point for the same rod, with its (default) step and run length made explicit."""
    c = case() if c is None else c
    dx = c["length"] / (c["n"] - 0.5)  # as elastica_cantilever lays the rod
    dt = pe.DT_SAFETY * pe.stable_dt(dx, c["r_s"], c["E"], c["G"], c["rho"])
    final = pe.OMEGA_T / pe.first_mode(c["length"], c["r_s"], c["E"], c["rho"])
    r = pe.elastica_cantilever(length=c["length"], radius=c["r_s"], E=c["E"], G=c["G"], rho=c["rho"],
                               g=c["g"], n_elements=c["n"], dt=dt, final_time=final)
    return {"solver": "pyelastica", "dt": dt, "substeps_per_second": 1.0 / dt, "iterations": None,
            "error": float(r["error"]), "seconds": float(r["seconds"]), "simulated": r["steps"] * dt}


def describe(p: dict) -> str:
    """One summary line per point (what ``wooddecay chart mechanics`` prints)."""
    if p["solver"] == "pyelastica":
        head = f"PyElastica  dt {p['dt']:.2e} s  ({p['simulated']:.2f} s simulated, settled)"
    else:
        head = f"wooddecay   dt {p['dt']:.0e} s  iterations {p['iterations']:>2}  ({p['simulated']:g} s simulated)"
    return f"{head}  error {p['error']:.4g}  seconds {p['seconds']:.3f}"


def plot_mechanics(data: list[dict], path) -> None:
    """Wall time (x) against relative error (y), log-log: one line per iteration count (colour),
    one marker shape per dt, PyElastica as a star, the 3% target as a dashed line. Errors above
    :data:`Y_CAP` and unstable (NaN) runs are drawn hollow in a grey band at the top edge."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    c = case()
    ours = [p for p in data if p["solver"] == "wooddecay"]
    threads = ours[0]["threads"] if ours else THREADS
    ref = [p for p in data if p["solver"] == "pyelastica"]
    dts = sorted({p["dt"] for p in ours}, reverse=True)
    its = sorted({p["iterations"] for p in ours})
    shapes = dict(zip(dts, "osDv^P<>h"))
    colors = dict(zip(its, plt.cm.viridis(np.linspace(0.05, 0.85, max(len(its), 1)))))

    finite = [p["error"] for p in data if math.isfinite(p["error"]) and p["error"] <= Y_CAP]
    y_lo = 0.4 * min(finite + [TARGET])
    y_clip = Y_CAP * 2.5  # where clipped points are drawn
    y_hi = Y_CAP * 6

    fig, ax = plt.subplots(figsize=(9.5, 5.2), dpi=110)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.axhspan(Y_CAP, y_hi, color="0.9", lw=0, zorder=0)
    ax.axhline(TARGET, color="crimson", ls="--", lw=1.2, zorder=1)
    ax.text(0.99, Y_CAP * 1.12, f"clipped: error > {Y_CAP:g} or unstable (NaN)", ha="right", va="bottom",
            transform=ax.get_yaxis_transform(), fontsize=7, color="0.4")

    clipped = unstable = False
    for k in its:
        pts = sorted((p for p in ours if p["iterations"] == k), key=lambda p: -p["dt"])  # along the dt sweep
        x = np.array([p["seconds"] for p in pts])
        bad = np.array([not (math.isfinite(p["error"]) and p["error"] <= Y_CAP) for p in pts])
        y = np.array([y_clip if b else p["error"] for p, b in zip(pts, bad)])
        ax.plot(x[~bad], y[~bad], color=colors[k], lw=1.4, zorder=2)
        for p, xi, yi, b in zip(pts, x, y, bad):
            nan = not math.isfinite(p["error"])
            clipped |= b and not nan
            unstable |= nan
            if nan:
                ax.scatter(xi, yi, marker="x", s=46, color=colors[k], linewidths=1.5, zorder=3)
            else:
                ax.scatter(xi, yi, marker=shapes[p["dt"]], s=46, facecolors="white" if b else colors[k],
                           edgecolors=colors[k], linewidths=1.3, zorder=3)
            if b and not nan:
                ax.annotate(f"{p['error']:.0f}", (xi, yi), textcoords="offset points", xytext=(0, -12),
                            ha="center", fontsize=7, color="0.3")
    for p in ref:
        ok = math.isfinite(p["error"])
        ax.scatter(p["seconds"], p["error"] if ok else y_clip, marker="*", s=240, color="black", zorder=4)
        ax.annotate("PyElastica", (p["seconds"], p["error"] if ok else y_clip), textcoords="offset points",
                    xytext=(-11, -3), ha="right", fontsize=8)

    ax.set_ylim(y_lo, y_hi)
    ax.set_xlabel("wall time of the time stepping (s)")
    ax.set_ylabel("relative tip deflection error |w / (q L⁴ / 8EI) − 1|")
    ax.set_title(f"Gravity cantilever: L = {c['length']:g} m, E = {c['E'] / 1e9:g} GPa, "
                 f"r_s = {c['r_s'] * 1e3:g} mm, {c['n']} elements, {c['seconds']:g} s simulated "
                 f"(numba on {threads} thread{'s' * (threads != 1)})",
                 fontsize=10)
    ax.grid(True, which="major", color="0.88", lw=0.6)

    h_it = [Line2D([], [], color=colors[k], lw=1.4, marker="o", ms=5, label=f"{k} iteration{'s' * (k != 1)}")
            for k in its]
    h_dt = [Line2D([], [], color="0.35", lw=0, marker=shapes[d], ms=6,
                   label=f"dt = {d:g} s ({1 / d:g} substeps/s)") for d in dts]
    h_more = [Line2D([], [], color="crimson", ls="--", lw=1.2, label=f"{TARGET:.0%} accuracy target")]
    for p in ref:
        h_more.append(Line2D([], [], color="black", lw=0, marker="*", ms=12,
                             label=f"PyElastica (dt {p['dt'] * 1e6:.1f} µs, {p['simulated']:.2f} s, settled)"))
    if not ref:
        h_more.append(Line2D([], [], lw=0, label="PyElastica not installed: no reference"))
    if clipped:
        h_more.append(Line2D([], [], color="0.35", lw=0, marker="o", mfc="white", ms=6,
                             label=f"error > {Y_CAP:g}, clipped (value written by it)"))
    if unstable:
        h_more.append(Line2D([], [], color="0.35", lw=0, marker="x", ms=6, label="unstable (NaN), at top"))
    leg1 = ax.legend(handles=h_it, title="solver iterations", fontsize=8, title_fontsize=8,
                     loc="upper left", bbox_to_anchor=(1.01, 1.0))
    ax.add_artist(leg1)
    leg2 = ax.legend(handles=h_dt, title="substep dt", fontsize=8, title_fontsize=8,
                     loc="upper left", bbox_to_anchor=(1.01, 0.68))
    ax.add_artist(leg2)
    ax.legend(handles=h_more, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 0.3))
    fig.tight_layout()
    fig.savefig(path, format="png")
    plt.close(fig)
