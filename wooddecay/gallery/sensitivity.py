"""Spatial and temporal sensitivity (woodstock §9.5, Fig. 20): the gallery's log (Fig. 12) and trunk
(Fig. 14) baked at the default step dt_bio and at dt_bio / 2, and with 2x and 4x sparser rods.

Timestep: the cracking state (the first frame with FIRST_CRACKS broken connections in the default
run, as Fig. 6 reads its cracks) and the degraded state (the last frame) of the runs in COMPARED
are rendered alike (one camera fitted to all of them, no captions, no quantisation) and compared by SSIM
(:mod:`.ssim`; the paper: 0.9984 and 0.9868, our targets SSIM_TARGET). The floor: the default run
against itself with the contact stiffness k_col changed by PERTURBATION (a change far below any
physical meaning), rendered and compared alike; where pieces fall and pile up this is the
most the timestep comparison can reach (docs/decisions.md, "Fig. 20's chaos floor"). Resolution:
strands 2x and 4x sparser (r_s x sqrt 2 and x 2, so 1/2 and 1/4 of the strands) keep the last
frame's signature within TOLERANCE of the default's (block purity where the default has come apart
into PURITY_PIECES pieces or more: :func:`within_tolerance`).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..scene import load_scene
from .bakes import SCENES, bake_scene, frame_rows, render_panel
from .measures import first_cracks
from .pool import Job
from .ssim import ssim_png

#: Fig. 12's log and Fig. 14's trunk (their --quick overrides are the figures')
STUDIED = ("fig12", "fig14")
#: SSIM the dt / 2 renders must reach: cracking state, degraded state
SSIM_TARGET = (0.99, 0.985)
#: largest absolute change of the last frame's signature under 2x and 4x sparser rods
TOLERANCE = {"mass_loss": 0.05, "hollow_fraction": 0.1, "largest_piece_fraction": 0.25, "block_purity": 0.2}
#: block purity is a median over the pieces: compared only where the default has this many
PURITY_PIECES = 5
#: relative change of mechanics.k_col in the ``perturbed`` run (the SSIM floor, module docstring)
PERTURBATION = 1e-7
#: the runs rendered for SSIM: the default, half the step (``ssim_*``) and the floor's (``floor_*``)
COMPARED = ("dt", "dt_half", "perturbed")
#: renders compared by SSIM: as the panels, without captions or quantisation
SSIM_OPTIONS = ("--no-labels", "--max-kb", "0")


def run(out: Path, quick: bool, renders: bool, log, resume: bool, figures: dict) -> tuple[dict, list]:
    """The study (module docstring) into ``out``; measured per scene, and the chart. ``resume``
    reuses the finished bakes in ``out`` (:func:`.bakes.bake_scene`); ``figures`` is the gallery's
    registry (:data:`.figures.FIGURES`), whose Fig. 12 and Fig. 14 entries the study reruns."""
    measured = {}
    for name in STUDIED:
        scene_file = figures[name].scene
        runs, frames, usds, summaries = {}, {}, {}, {}
        scene = load_scene(SCENES / scene_file, overrides=figures[name].quick if quick else {})
        for v, overrides in variants(name, quick, figures).items():
            reuse = own_bakes(name, out, figures) if v == "dt" else ()
            b = bake_scene(scene_file, overrides, out / name / v, resume, reuse)
            runs[v] = {"overrides": overrides, "signature": b.summary["frames"][-1]["signature"],
                       "seconds": round(b.seconds, 1), "elements": b.summary["counts"]["elements"], "reused": b.reused}
            frames[v], usds[v], summaries[v] = b.frames, b.usd, b.summary
            reused = f"{name}'s own bake" if v == "dt" else "its finished bake"
            log(f"  fig20/{name}/{v}: {b.seconds:.0f} s" + (f" ({reused})" if b.reused else ""))
        entry = {"runs": runs}
        ref = runs["dt"]["signature"]
        entry["within_tolerance"] = {v: within_tolerance(runs[v]["signature"], ref) for v in ("sparse2", "sparse4")}
        if renders:
            last = len(frames["dt"]) - 1
            for state, k in (("cracking", first_cracks(frame_rows(summaries["dt"]))), ("degraded", last)):
                ssim = ssim_at({v: frames[v] for v in COMPARED}, usds, k, out / name, state, 2.0 * scene.strands.r_s)
                entry[f"ssim_{state}"], entry[f"floor_{state}"] = ssim["dt_half"], ssim["perturbed"]
                entry[f"{state}_frame"] = int(frames["dt"][k].index)
        measured[name] = entry
    chart = out / "fig20.png"
    plot(measured, chart)
    return measured, [chart]


def variants(name: str, quick: bool, figures: dict) -> dict[str, dict]:
    """The overrides of figure ``name``'s scene for each run of the study: ``dt`` (the default
    step), ``dt_half``, ``perturbed`` (k_col changed by PERTURBATION), ``sparse2`` and
    ``sparse4`` (the figure's --quick ones under ``quick``)."""
    base = figures[name].quick if quick else {}
    scene = load_scene(SCENES / figures[name].scene, overrides=base)
    return {"dt": dict(base), "dt_half": {**base, "time.dt_bio": scene.time.dt_bio / 2},
            "perturbed": {**base, "mechanics.k_col": scene.mechanics.k_col * (1.0 + PERTURBATION)},
            "sparse2": {**base, "strands.r_s": scene.strands.r_s * math.sqrt(2.0)},
            "sparse4": {**base, "strands.r_s": scene.strands.r_s * 2.0}}


def jobs(out: Path, quick: bool, resume: bool, figures: dict) -> list[Job]:
    """The study's bakes that :mod:`.pool` can make ahead into ``out``: all but the runs at the
    default step, which are the figures' own bakes (:func:`own_bakes`)."""
    return [Job(figures[name].scene, overrides, out / name / v, resume)
            for name in STUDIED for v, overrides in variants(name, quick, figures).items() if v != "dt"]


def own_bakes(name: str, out: Path, figures: dict) -> tuple[Path, ...]:
    """The folders where the gallery bakes figure ``name``'s variants without overrides of its own
    (``DIR/<fig>/<variant>``, ``out`` being ``DIR/fig20``): the study's run at the default step
    is that bake, so a gallery that made it does not bake it again."""
    fig = figures[name]
    return tuple(out.parent / name / v.name for v in fig.variants if not v.overrides and v.scene in (None, fig.scene))


def ssim_at(frames: dict, usds: dict, k: int, folder: Path, state: str, pad: float) -> dict[str, float]:
    """SSIM against the ``dt`` run's frame ``k`` of every other run's (``frames`` and ``usds``
    keyed by run, ``dt`` among them), keyed by run: each rendered into ``folder/<run>_<state>.png``
    through one camera fitted to all (:func:`fit_box`, ``pad`` m wider)."""
    pngs = {v: folder / f"{v}_{state}.png" for v in frames}
    box = fit_box([f[k] for f in frames.values()], pad)
    for v, png in pngs.items():
        render_panel(usds[v], png, frames[v][k].index, (*SSIM_OPTIONS, "--fit-box", *box))
    return {v: ssim_png(pngs["dt"], png) for v, png in pngs.items() if v != "dt"}


def fit_box(frames, pad: float) -> list[str]:
    """``--fit-box`` for renders of ``frames`` through one camera: the box of their elements'
    centres, ``pad`` (m) wider on every side."""
    x = np.concatenate([f.mech["x"] for f in frames])
    return [f"{v:.4f}" for v in (*(x.min(0) - pad), *(x.max(0) + pad))]


def within_tolerance(signature: dict, ref: dict) -> bool:
    """Whether ``signature`` keeps ``ref``'s within TOLERANCE; block purity only where ``ref``'s
    wood has come apart into PURITY_PIECES pieces or more. Why: block purity is the median over
    the pieces, the largest included; over fewer, one piece decides it (a single piece has purity
    0 by definition, and Fig. 14's trunk read 1.0 in 3 pieces at dt_bio and 0.51 in 2 at dt_bio / 2)."""
    keys = [k for k in TOLERANCE if k != "block_purity" or ref["pieces"] >= PURITY_PIECES]
    return all(abs(signature[k] - ref[k]) <= TOLERANCE[k] for k in keys)


def decide(measured: dict) -> bool:
    """SSIM at both states reaches SSIM_TARGET and sparser rods stay within TOLERANCE, on both scenes."""
    return all(e.get("ssim_cracking", 0.0) >= SSIM_TARGET[0] and e.get("ssim_degraded", 0.0) >= SSIM_TARGET[1]
               and all(e["within_tolerance"].values()) for e in measured.values())


def plot(measured: dict, path: Path) -> None:
    """Per scene, the last frame's signature (TOLERANCE's keys) of every run, SSIM and its floor in
    the title."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(measured), figsize=(5.2 * len(measured), 3.8), dpi=110, squeeze=False)
    keys = list(TOLERANCE)
    for ax, (name, e) in zip(axes[0], measured.items()):
        runs = e["runs"]
        width = 0.8 / len(runs)
        for i, (v, r) in enumerate(runs.items()):
            ax.bar(np.arange(len(keys)) + (i - (len(runs) - 1) / 2) * width, [r["signature"][k] for k in keys], width,
                   label=f"{v} ({r['elements']} elements)")
        ax.set_xticks(np.arange(len(keys)), [k.replace("_", " ") for k in keys], fontsize=8)
        ssim_text = (f"SSIM dt/2: cracking {e['ssim_cracking']:.4f}, degraded {e['ssim_degraded']:.4f}\n"
                     f"floor (k_col x (1 + {PERTURBATION:g})): cracking {e['floor_cracking']:.4f}, "
                     f"degraded {e['floor_degraded']:.4f}"
                     if "ssim_cracking" in e else "SSIM: not rendered")
        ax.set_title(f"{name}\n{ssim_text}", fontsize=9)
        ax.set_ylim(0, 1.05)
        ax.legend(fontsize=7)
    fig.suptitle("Sensitivity (woodstock §9.5): timestep and rod density, last frame's signature")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
