"""The figures of the gallery: per figure of woodstock, its scene in ``samples/gallery/``, the
variants the paper compares (Table 2's parameter changes as scene overrides), the claim of its
caption in one sentence, the statistic and the test that decide whether our bake shows it, and
what ``--quick`` changes to fit CI.

A figure with ``study`` runs a study instead of bakes (Fig. 17's pull test, Fig. 18's barrier
curves); every other figure bakes each variant with :func:`wooddecay.bake.bake`.
``measure(model, frames)`` adds the figure's own statistic (:mod:`.measures`) to the last frame's
signature; ``decide(measured)`` takes the variants' measurements by name and returns whether the
claim holds.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..wood import WoodModel
from ..model import build_model
from ..studies import barrier, pull
from . import measures, sensitivity
from .measures import first_cracks


@dataclass(frozen=True)
class Variant:
    name: str  # folder and panel name
    label: str  # what differs, in the paper's terms
    overrides: dict = field(default_factory=dict)
    scene: str | None = None  # its own file in samples/gallery instead of the figure's


@dataclass(frozen=True)
class Figure:
    key: str  # "fig6"
    title: str
    caption: str  # the paper's caption in our words
    claim: str  # what must hold, one sentence
    test: str  # how ``decide`` reads the statistic
    decide: Callable[[dict], bool]
    scene: str | None = None  # file in samples/gallery
    variants: tuple[Variant, ...] = ()
    quick: dict = field(default_factory=dict)  # overrides of every variant under --quick
    measure: Callable | None = None  # (model, frames) -> dict
    #: frames rendered per variant: an index, or a function of the variant's frame rows
    #: (:func:`.bakes.frame_rows`) that picks the frame the claim is read on
    panels: tuple = (-1,)
    render_options: tuple = ()
    #: (out_dir, quick, renders, log, resume) -> (measured by variant, [chart paths]); ``resume``
    #: reuses the study's finished bakes (Fig. 20; the pull test and the barrier curves compute)
    study: Callable | None = None
    #: (out_dir, quick, resume) -> the study's bakes that can be made ahead (:mod:`.pool`)
    study_bakes: Callable | None = None


def _orientation(m):
    """(r, t) shares of the broken connections at the first frame with FIRST_CRACKS of them."""
    r, t, _ = m["frames"][first_cracks(m["frames"])]["signature"]["crack_orientation"]
    return r, t


#: Fig. 6 (c): "a few" dominant radial cracks hold the opening: at most this many sectors' worth
#: (opening-weighted, :func:`measures.radial_cracks`)
FEW_CRACKS = 6.0


def _fig6_measure(model: WoodModel, frames):
    return measures.radial_cracks(model, frames[0], frames[-1])


def fig6_orientations(m) -> bool:
    """The part of Fig. 6's claim on the first cracks' orientation (t > 2 r for 0.1/1 and 1/1,
    r > 2 t for 1/0.1)."""
    (ra, ta), (rb, tb), (rc, tc) = (_orientation(m[k]) for k in ("a", "b", "c"))
    return bool(ta > 2 * ra and rb > 2 * tb and tc > 2 * rc)


#: Fig. 6 (c) is baked on the scene's seed (None) and on seeds 2 and 3, and read on their median:
#: one section's count moves by 2-8 sectors from seed to seed (docs/decisions.md, "Shrinkage in the
#: cross-section's frame")
BALANCED_SEEDS = (None, 2, 3)


def _balanced(seed: int | None) -> Variant:
    """Fig. 6 (c), S_R/S_T = 1/1, on ``seed`` (None: the scene's)."""
    overrides = {"mechanics.S_R": 1.0, "mechanics.S_T": 1.0}
    if seed is None:
        return Variant("c", "S_R/S_T = 1/1", overrides)
    return Variant(f"c_seed{seed}", f"S_R/S_T = 1/1, seed {seed}", {**overrides, "scene.seed": seed})


def _fig6_decide(m):
    few = float(np.median([m[_balanced(s).name]["effective_radial_cracks"] for s in BALANCED_SEEDS]))
    return fig6_orientations(m) and 0 < few <= FEW_CRACKS


def _blocks(model: WoodModel, frames):
    return measures.loose_blocks(model, frames[-1])


def _fig11_decide(m):
    a, b, c, d = (m[k] for k in "abcd")
    return bool(a["blocks"] >= 3 and c["median_block_elements"] > a["median_block_elements"]
                and b["median_block_length_m"] > a["median_block_length_m"] and d["blocks"] < a["blocks"])


def _fig12_measure(model: WoodModel, frames):
    return {**measures.loose_blocks(model, frames[-1]), "fragment_share": measures.fragment_share(model, frames[-1])}


def _fig12_decide(m):
    a, b = m["uniform"], m["one_side"]
    return bool(a["signature"]["pieces"] >= 5 and b["fragment_share"] < a["fragment_share"]
                and b["signature"]["debris_centre_height_m"] < a["signature"]["debris_centre_height_m"])


def _halves(model: WoodModel, frames):
    s = model.wood_coords[:, 2]
    mid = 0.5 * (s.min() + s.max())
    return {"root_end": measures.part(model, frames[-1], s < mid), "far_end": measures.part(model, frames[-1], s >= mid)}


def _fig13_decide(m):
    brown, white = m["brown_white"]["root_end"], m["brown_white"]["far_end"]
    return bool(brown["blocks"] >= 3 and brown["median_block_purity"] >= 0.8
                and white["crumbled_share"] > max(2.0 * brown["crumbled_share"], 0.02))


def _sequence(sig_frames, key):
    return [f["signature"][key] for f in sig_frames]


def _fig14_decide(m):
    f = m["trunk"]["frames"]
    ml, cracks, hollow = (_sequence(f, k) for k in ("mass_loss", "crack_clusters", "hollow_fraction"))
    cracked = [i for i, c in enumerate(cracks) if c > 0]
    return bool(cracked and ml[cracked[0]] < 0.05 and max(hollow) >= 0.3 and ml[-1] > ml[len(ml) // 2] > 0.05)


def _checked(rows) -> list[int]:
    """Frames of Fig. 15's board with >= 3 crack clusters at mass loss < 0.02."""
    return [i for i, x in enumerate(rows) if x["signature"]["crack_clusters"] >= 3 and x["signature"]["mass_loss"] < 0.02]


def _most_checked(rows) -> int:
    """The checked frame (:func:`_checked`) with the most crack clusters (the first if none is)."""
    return max(_checked(rows), key=lambda i: rows[i]["signature"]["crack_clusters"], default=1)


def _fig15_decide(m):
    f = m["board"]["frames"]
    checked = _checked(f)
    return bool(checked and f[checked[0]]["signature"]["pieces"] <= 1 and f[-1]["signature"]["mass_loss"] >= 0.1)


def _fig16_decide(m):
    """Broken connections, not pieces: the quick dry tree crumbles into bits of fewer than
    MIN_PIECE elements, so it counts 1 or 2 pieces against the wet tree's 1 as the schedule's
    chunks change, its other figures equal to three digits (docs/decisions.md, "Adaptive schedule")."""
    dry, wet = m["dry"]["signature"], m["wet"]["signature"]
    broken = [m[k]["frames"][-1]["broken_connections"] for k in ("dry", "wet")]
    return bool(broken[0] > 2 * broken[1] and dry["largest_piece_fraction"] < wet["largest_piece_fraction"]
                and min(dry["hollow_fraction"], wet["hollow_fraction"]) > 0.05)


def _fig19_decide(m):
    def progresses(v):
        f = v["frames"]
        ml, hollow, largest = (_sequence(f, k) for k in ("mass_loss", "hollow_fraction", "largest_piece_fraction"))
        return ml[-1] > ml[1] and hollow[-1] > 0.05 and largest[-1] < largest[0] - 0.05
    return all(progresses(v) for v in m.values())


def _fig17_study(out, quick, renders, log, resume):
    scene = pull.specimen_scene(quality="draft")
    model = build_model(scene)
    rel = 0.25 if quick else 0.1
    measured = {}
    for name, decay, guess in (("severe", 0.5, (0.2, 0.4)), ("intermediate", 0.8, (1.0, 3.0))):
        healthy, decayed = pull.pull_cases(scene, model, decay=decay)
        if not measured:
            th = pull.threshold(healthy, 4.0, 8.0, rel=rel)
            measured["healthy"] = {"threshold_N": th.force, "bracket_N": [th.lo, th.hi]}
        td = pull.threshold(decayed, *guess, rel=rel)
        measured[name] = {"H": decay, "threshold_N": td.force, "bracket_N": [td.lo, td.hi]}
    return measured, []


def _fig17_decide(m):
    h, i, s = (m[k]["bracket_N"] for k in ("healthy", "intermediate", "severe"))
    return bool(h[0] >= 10.0 * s[1] and s[1] <= i[0] and i[1] <= h[0])


def _fig18_study(out, quick, renders, log, resume):
    days = 600.0 if quick else 1500.0
    runs = [barrier.run_barrier(r, days=days, dt=2.0 if quick else 1.0) for r in barrier.RATIOS]
    chart = out / "fig18.png"
    barrier.plot_barrier(runs, chart)
    return {f"beta_kappa_{r.ratio:g}": {"plateau_days": r.plateau, "mass_loss_end": float(r.mass_loss[-1])}
            for r in runs}, [chart]


def _fig20_study(out, quick, renders, log, resume):
    return sensitivity.run(out, quick, renders, log, resume, FIGURES)


def _fig20_bakes(out, quick, resume):
    return sensitivity.jobs(out, quick, resume, FIGURES)


def _fig20_decide(m):
    return sensitivity.decide(m)


def _fig18_decide(m):
    p = [v["plateau_days"] for v in m.values()]
    return bool(np.all(np.diff(p) >= 0) and p[-1] > p[0])


#: one view head-on onto the x = 0 end face, the section the paper shows: radial splits and
#: delamination rings read there and not from the side (docs/decisions.md, "Gallery")
END_VIEW = ("--azimuth", "-180", "--elevation", "6")
#: --quick: the log of Figs. 12-13 and the trees of Figs. 16, 19 with wider strands (log 1.3x,
#: trees 2.5x with rods twice as long: their twigs then hold no wood) and fewer cells; they and
#: Fig. 14's trunk rot for years at a 4-day biology step (the trees within their 7.6-day bound),
#: so that they bake in CI (docs/decisions.md, "Figures as scenes, claims as tests"); Fig. 13 runs
#: 3 of its 5 years (its brown end has 10 loose blocks by then, 1 after 2 years)
LOG_QUICK = {"strands.r_s": 0.012, "bsp.cells": 200, "time.frames": 4}
YEARS_QUICK = {"time.dt_bio": 4.0}
LOG_YEARS_QUICK = {**LOG_QUICK, **YEARS_QUICK}
#: Fig. 12's log breaks into blocks of about one BSP cell, so its quick log keeps the scene's 400
#: cells and its pieces are the full scene's cells (docs/decisions.md, "Fig. 12: finer is the
#: weight-average fragment")
FIG12_QUICK = {**LOG_YEARS_QUICK, "bsp.cells": 400}
TREE_QUICK = {"strands.r_s": 0.02, "strands.rod_length": 0.1, "bsp.cells": 100, **YEARS_QUICK}

FIGURES = {f.key: f for f in (
    Figure(
        "fig6", "Shrinkage ablation",
        "A fresh log section dries from its surface; the ratio of radial to tangential shrinkage "
        "decides how it cracks: S_R/S_T = 0.1/1 splits radially, 1/0.1 delaminates along the rings, "
        "1/1 opens many small surface cracks of which a few dominant radial ones run inwards.",
        "Radial shrinkage alone breaks radial connections (delamination), tangential alone "
        "tangential ones (radial splits), and balanced shrinkage concentrates the opening in a few cracks.",
        "on the first frame with >= 25 broken connections their shares t > 2 r for 0.1/1 and 1/1, "
        "r > 2 t for 1/0.1; for 1/1 on the last frame the opening of its radial cracks (broken "
        "tangential connections, summed in 10-degree sectors around the pith) is held by at most 6 "
        "sectors, opening-weighted, in the median of seeds 1, 2 and 3",
        _fig6_decide, scene="fig6.toml",
        variants=(Variant("a", "S_R/S_T = 0.1/1", {"mechanics.S_R": 0.1, "mechanics.S_T": 1.0}),
                  Variant("b", "S_R/S_T = 1/0.1", {"mechanics.S_R": 1.0, "mechanics.S_T": 0.1}),
                  *(_balanced(seed) for seed in BALANCED_SEEDS)),
        quick={"time.days": 24.0, "time.frames": 4}, measure=_fig6_measure, panels=(-1,),
        render_options=END_VIEW),
    Figure(
        "fig11", "BSP configurations",
        "The same brown-rotting log under four BSP partitions: (a) the default gives cubical "
        "blocks, (b) cells 2.5x longer along the grain bias the blocks along it, (c) 16x larger "
        "cells give coarser blocks, (d) without a BSP the structure is uniform and loses its blocks.",
        "Block size follows the cell size, block shape the cell shape, and no BSP gives no blocks.",
        "loose blocks (pieces of >= 5 elements but the largest): (a) at least 3, (c) larger median "
        "size than (a), (b) longer along the grain (median) than (a), (d) fewer than (a)",
        _fig11_decide, scene="fig11.toml",
        variants=(Variant("a", "default: 48 cells"),
                  Variant("b", "cells 2.5x along e_l: 19 cells", {"bsp.elongation": 5.0, "bsp.cells": 19}),
                  Variant("c", "cells 16x larger: 3 cells", {"bsp.cells": 3}), Variant("d", "no BSP", {"bsp.cells": 0})),
        measure=_blocks),
    Figure(
        "fig12", "Brown rot to a debris pile",
        "A log degraded by brown rot cracks into cubes, collapses and piles up as debris; more "
        "fungal activity on one side gives finer fragments and a lower, more compact pile.",
        "Brown rot takes the log apart into blocks that pile up; more activity on one side breaks "
        "the wood finer and leaves a lower pile.",
        "uniform: >= 5 pieces; one side: a smaller weight-average fragment (fragment_share: the share "
        "of the wood in the piece a random bit of wood lies in) and a lower pile (its wood's mean height "
        "above the ground, debris_centre_height_m)",
        _fig12_decide, scene="fig12.toml",
        variants=(Variant("uniform", "activity 0.05 from the ground"),
                  Variant("one_side", "activity 0.8 from the ground", {"inoculation.1.activity": 0.8})),
        quick=FIG12_QUICK, measure=_fig12_measure, panels=(0, -1)),
    Figure(
        "fig13", "Brown and white rot from opposite ends",
        "Brown rot from one end breaks the carbohydrate-rich wood into cubes; white rot from the "
        "other end hollows the lignin-rich heartwood with a diffuse front.",
        "The brown end comes apart in blocks of one BSP cell, the white end is consumed (crumbles).",
        "brown (root) half: >= 3 loose blocks of median BSP purity >= 0.8; white (far) half: "
        "crumbled share above 2x the brown half's and above 2%",
        _fig13_decide, scene="fig13.toml", variants=(Variant("brown_white", "brown at x = 0, white at x = 1 m"),),
        quick={**LOG_YEARS_QUICK, "time.years": 3.0}, measure=_halves, panels=(-1,)),
    Figure(
        "fig14", "Trunk: cracks, hollow, decomposition",
        "A cut trunk first cracks internally as it dries, then white rot hollows its weak heartwood, "
        "then brown rot from a wound decomposes the rest.",
        "Cracks come before decay, white rot leaves a hollow, and decay keeps going after it.",
        "the first frame with a crack has mass loss < 0.05; the hollow fraction reaches 0.3; mass "
        "loss rises from the middle frame (> 0.05) to the last",
        _fig14_decide, scene="fig14.toml", variants=(Variant("trunk", "as shipped"),),
        quick={"strands.r_s": 0.014, "bsp.cells": 100, "time.frames": 12, **YEARS_QUICK},
        panels=(1, -2, -1), render_options=("--elevation", "60")),
    Figure(
        "fig15", "Board: checks along the fibre, then decay",
        "A green board dries and checks along the fibre before any decay; fungi then take it apart "
        "from the inside.",
        "Drying opens several checks while the board is still whole and all but undecayed (< 2% mass "
        "loss); decay follows.",
        "a frame with >= 3 crack clusters at mass loss < 0.02 and the board in one piece; mass "
        "loss >= 0.1 at the end",
        _fig15_decide, scene="fig15.toml", variants=(Variant("board", "as shipped"),),
        quick={"strands.r_s": 0.006, "bsp.cells": 60, "time.frames": 12}, panels=(_most_checked, -1)),
    Figure(
        "fig16", "Moisture: dry tree against wet tree",
        "The same rotting tree at moisture bounds M_1/M_2 = 0.6/0.2 loses branches and partly "
        "collapses; at 0.6/0.4 it stays largely intact; both hollow.",
        "Drier wood breaks more: more broken connections and a smaller largest piece; both trees hollow.",
        "dry: more than twice the wet tree's broken connections and a smaller largest-piece share; hollow "
        "fraction > 0.05 in both",
        _fig16_decide, scene="fig16.toml",
        variants=(Variant("dry", "M_1/M_2 = 0.6/0.2", {"moisture.M_2": 0.2}),
                  Variant("wet", "M_1/M_2 = 0.6/0.4", {"moisture.M_2": 0.4})),
        quick={**TREE_QUICK, "time.frames": 3}, render_options=("--elevation", "15")),
    Figure(
        "fig17", "Pull test at three stages of health",
        "The same pull on a branch: severely decayed it fragments at once, at intermediate health "
        "it breaks early, healthy it needs at least 10x the force.",
        "The force that breaks the branch rises with its health, 10x or more from severe to healthy.",
        "thresholds (bisected brackets) severe < intermediate < healthy, healthy >= 10x severe",
        _fig17_decide, study=_fig17_study),
    Figure(
        "fig18", "Barrier effect",
        "Mass loss and moisture over time for beta/kappa in {0, 0.5, 1, 2}: stronger defence gives "
        "a longer intermediate plateau before decay resumes.",
        "The plateau lengthens with beta/kappa.",
        "plateau lengths non-decreasing in beta/kappa and longer at 2 than at 0",
        _fig18_decide, study=_fig18_study),
    Figure(
        "fig19", "Three trees after death",
        "Trees of different geometry and species settings go from intact through brittle, hollowed "
        "and broken to collapsed.",
        "Each tree loses mass, hollows and breaks apart over time.",
        "per tree: mass loss grows after the second frame, the last hollow fraction > 0.05 and the "
        "largest piece's share falls by > 0.05",
        _fig19_decide, scene="fig19_oak.toml",
        variants=(Variant("oak", "oak-like, the sample tree"),
                  Variant("spruce", "a taller, slimmer tree; brittle when dry: S 0.8, p_l 5, k_c 1.2",
                          {"mechanics.S": 0.8, "mechanics.p_l_bundle": 5.0, "mechanics.k_c": 1.2}, scene="fig19_spruce.toml"),
                  Variant("birch", "a low, wide tree; moisture-tolerant: M_0 0.15, s 0.01, k_l 0.6",
                          {"mechanics.M_0": 0.15, "mechanics.s": 0.01, "mechanics.k_l": 0.6}, scene="fig19_birch.toml")),
        quick={**TREE_QUICK, "time.frames": 4}, panels=(0, 1, 2, -1),
        render_options=("--elevation", "15")),
    Figure(
        "fig20", "Sensitivity to the timestep and the rod density",
        "The log of Fig. 12 and the trunk of Fig. 14 at half the timestep render alike (SSIM 0.9984 "
        "in the cracking state, 0.9868 degraded), and with 2x and 4x sparser rods they crack and "
        "rot in the same patterns.",
        "Halving dt_bio changes the renders little; sparser rods keep the signature.",
        "SSIM of the dt and dt/2 renders >= 0.99 (first frame with 25 broken connections) and "
        ">= 0.985 (last frame); with 2x and 4x sparser strands the last frame's mass loss within "
        "0.05, hollow fraction within 0.1, largest piece within 0.25 and, where the default has "
        "come apart into 5 pieces or more, block purity within 0.2 of the default's",
        _fig20_decide, study=_fig20_study, study_bakes=_fig20_bakes),
)}
