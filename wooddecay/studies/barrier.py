"""The barrier-effect study of woodstock §9.4 and Fig. 18.

A small block of wood in full contact with mycelium (both fungi at a low uniform activity, the
lab-block setting of Bari et al. 2020 cited there) decays for ``days`` at a fixed moisture inside
the growth window, for inhibition-to-induction ratios beta/kappa in {0, 0.5, 1, 2}
(beta_w = beta_b = ratio * kappa). The run uses the real biology step on the block's rod graph.

Plateau (our definition, docs/model.md §7 asks for one): after the onset peak of the mass-loss rate, the
longest stretch during which the rate stays below ``FRAC`` (30%) of that peak while the mass loss
is still intermediate (below ``ML_MAX``, 50%). Exhaustion of the substrate at high mass loss is not a
plateau; a stall at intermediate mass loss, ended by renewed growth or the end of the run, is.
Appendix B explains it: defences pin the activity near a slow manifold whose residence time grows
with beta/kappa.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import build_model
from ..scene import Scene
from ..sim.driver import Simulation
from . import scene_template

#: fraction of the onset peak rate below which decay counts as stalled
FRAC = 0.3
#: mass loss above which a low rate is exhaustion, not a plateau
ML_MAX = 0.5
RATIOS = (0.0, 0.5, 1.0, 2.0)
#: fungi.kappa of the block; beta_w = beta_b = ratio * KAPPA
KAPPA = 0.036


@dataclass(frozen=True)
class BarrierRun:
    ratio: float
    t: np.ndarray  # days
    mass_loss: np.ndarray
    moisture_ratio: np.ndarray
    plateau: float  # days
    plateau_mask: np.ndarray  # bool per time sample


def plateau(t: np.ndarray, mass_loss: np.ndarray) -> tuple[float, np.ndarray]:
    """Length (days) and mask of the intermediate plateau: the longest contiguous stretch after
    the onset peak of the rate (the first local maximum above half the global one) during which
    the rate stays below FRAC of that peak with mass loss below ML_MAX (module docstring)."""
    rate = np.gradient(mass_loss, t)
    strong = np.flatnonzero(rate >= 0.5 * rate.max())
    onset = int(strong[0]) if len(strong) else 0
    while onset + 1 < len(rate) and rate[onset + 1] >= rate[onset]:
        onset += 1  # climb to the first peak
    low = np.zeros(len(t), dtype=bool)
    low[onset:] = (rate[onset:] < FRAC * rate[onset]) & (mass_loss[onset:] < ML_MAX)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], low.astype(np.int8), [0]])))
    mask = np.zeros(len(t), dtype=bool)
    if len(edges):
        starts, stops = edges[::2], edges[1::2]
        k = int(np.argmax(t[stops - 1] - t[starts]))
        mask[starts[k]:stops[k]] = True
        return float(t[stops[k] - 1] - t[starts[k]]), mask
    return 0.0, mask


def block_scene(ratio: float, days: float = 1500.0, dt: float = 1.0) -> Scene:
    """``scenes/barrier.toml`` with beta_w = beta_b = ratio * kappa, run for ``days`` in biology
    steps of ``dt`` days."""
    beta = ratio * KAPPA
    return scene_template("barrier", {"fungi.kappa": KAPPA, "fungi.beta_w": beta, "fungi.beta_b": beta,
                                      "time.days": days, "time.dt_bio": dt})


def run_barrier(ratio: float, days: float = 1500.0, dt: float = 1.0) -> BarrierRun:
    """Mass loss and moisture content ratio over time for one beta/kappa."""
    scene = block_scene(ratio, days, dt)
    sim = Simulation(build_model(scene), mechanics=False)
    for _ in sim.run():
        pass
    t = np.array([h["t_days"] for h in sim.history])
    ml = np.array([h["mass_loss"] for h in sim.history])
    mcr = np.array([h["moisture_content_ratio"] for h in sim.history])
    length, mask = plateau(t, ml)
    return BarrierRun(ratio=ratio, t=t, mass_loss=ml, moisture_ratio=mcr, plateau=length, plateau_mask=mask)


def plot_barrier(runs: list[BarrierRun], path) -> None:
    """Fig. 18: mass loss (solid) and moisture content ratio (dashed), plateaus shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 4.2), dpi=110)
    ax2 = ax.twinx()
    colors = plt.cm.viridis(np.linspace(0.1, 0.85, len(runs)))
    for run, c in zip(runs, colors):
        ax.plot(run.t, run.mass_loss, color=c, lw=2, label=f"beta/kappa = {run.ratio:g} (plateau {run.plateau:.0f} d)")
        ax2.plot(run.t, run.moisture_ratio, color=c, lw=1.2, ls="--")
        if run.plateau_mask.any():
            ax.fill_between(run.t, 0, 1, where=run.plateau_mask, color=c, alpha=0.12, lw=0,
                            transform=ax.get_xaxis_transform())
    ax.set_xlabel("time (days)")
    ax.set_ylabel("mass loss (solid)")
    ax2.set_ylabel("moisture content ratio (dashed)")
    ax.set_ylim(0, 1)
    ax.set_title("Barrier effect (woodstock Fig. 18): defence-induced plateau")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
