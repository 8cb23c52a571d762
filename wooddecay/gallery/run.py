"""``wooddecay gallery``: bake each figure's variants, render the panels the paper shows through
the add-on, measure, decide and write ``DIR/signatures.json``.

``DIR/<fig>/<variant>/`` holds each bake (as ``wooddecay bake`` writes it), ``DIR/<fig>/*.png``
the panels (``<variant>_f<frame>.png``) or the study's chart. ``signatures.json`` is an object
keyed by figure: title, caption, claim, test, ``variants`` (label, overrides, the last frame's
signature, the per-frame signatures, the figure's statistic and ``reused``), ``panels``,
``seconds`` and ``holds`` (true/false). It is rewritten atomically after every figure, so an
interrupted gallery keeps the figures it finished, and so is ``DIR/gallery.md``
(:func:`markdown`), the page a user reads: per figure the caption, the panels, the statistic and
whether the claim holds. With ``resume`` a variant whose finished bake of the same scene is in its
folder is measured and rendered from it, not baked again (``reused``): a gallery stopped
mid-figure, or re-run to render, bakes only what is missing. The bakes (:func:`plan`) are made
ahead on a pool of processes (:mod:`.pool`) while the figures are read in order.
"""
from __future__ import annotations

import json
import time
from pathlib import Path

from .. import render
from ..atomic import write_bytes
from ..errors import InputError
from ..sim.threads import requested_threads
from . import pool
from .bakes import bake_scene, frame_rows, pending, render_panel, timed_bake
from .figures import FIGURES, Figure

def select(names) -> list[Figure]:
    """The figures named (``fig6`` or ``6``), all of them in order when none is."""
    if not names:
        return list(FIGURES.values())
    out = []
    for name in names:
        key = name if name.startswith("fig") else f"fig{name}"
        if key not in FIGURES:
            raise InputError("FIG", name, f"must be one of {', '.join(FIGURES)}")
        out.append(FIGURES[key])
    return out


def _bake_variant(fig: Figure, variant, folder: Path, quick: bool, resume: bool, log) -> tuple[dict, list, Path]:
    """Bake one variant into ``folder`` (with ``resume`` reusing a finished bake of the same
    scene there); its measurement, its frames and its USD file."""
    overrides = _overrides(fig, variant, quick)
    b = bake_scene(variant.scene or fig.scene, overrides, folder, resume)
    measured = {"label": variant.label, "overrides": overrides, "signature": b.summary["frames"][-1]["signature"],
                "frames": frame_rows(b.summary), "seconds": round(b.seconds, 1), "reused": b.reused}
    if fig.measure is not None:
        measured.update(fig.measure(b.model, b.frames))
    log(f"  {fig.key}/{variant.name}: {measured['seconds']:.0f} s{' (bake reused)' if b.reused else ''}, "
        f"{_brief(measured['signature'])}")
    return measured, b.frames, b.usd


def _overrides(fig: Figure, variant, quick: bool) -> dict:
    return {**variant.overrides, **(fig.quick if quick else {})}


def plan(figures: list[Figure], out: Path, quick: bool, resume: bool) -> list[pool.Job]:
    """The bakes of ``figures`` into ``out`` in the order they are read: each variant's and the
    studies' (:attr:`Figure.study_bakes`), those ``resume`` reuses left out (:func:`.bakes.pending`)."""
    jobs = []
    for fig in figures:
        for v in fig.variants:
            jobs.append(pool.Job(v.scene or fig.scene, _overrides(fig, v, quick), out / fig.key / v.name, resume))
        if fig.study_bakes is not None:
            jobs += fig.study_bakes(out / fig.key, quick, resume)
    return [job for job in jobs if pending(job)]


def _brief(sig: dict) -> str:
    r, t, l = sig["crack_orientation"]
    return (f"mass loss {sig['mass_loss']:.3f}, pieces {sig['pieces']}, largest {sig['largest_piece_fraction']:.2f}, "
            f"purity {sig['block_purity']:.2f}, cracks {sig['crack_clusters']} (r/t/l {r:.2f}/{t:.2f}/{l:.2f}), "
            f"hollow {sig['hollow_fraction']:.2f}, height {sig['debris_height_m']:.3f} m")


def run_figure(fig: Figure, out: Path, quick: bool, renders: bool, log=print, resume: bool = False) -> dict:
    """Bake (or study), render and decide one figure; its entry of signatures.json. ``resume``:
    reuse the finished bakes of variants whose scene is unchanged (a study's bakes too)."""
    t0 = time.perf_counter()
    folder = out / fig.key
    folder.mkdir(parents=True, exist_ok=True)
    panels = []
    if fig.study is not None:
        measured, charts = fig.study(folder, quick, renders, log, resume)
        panels += [str(Path(c).relative_to(out)) for c in charts]
    else:
        measured = {}
        for v in fig.variants:
            measured[v.name], frames, usd = _bake_variant(fig, v, folder / v.name, quick, resume, log)
            if renders:
                rows = measured[v.name]["frames"]
                picked = [p(rows) if callable(p) else p % len(rows) for p in fig.panels]
                for k in dict.fromkeys(picked):
                    png = folder / f"{v.name}_f{frames[k].index}.png"
                    render_panel(usd, png, frames[k].index, fig.render_options)
                    panels.append(str(png.relative_to(out)))
    holds = fig.decide(measured)
    entry = {"title": fig.title, "caption": fig.caption, "claim": fig.claim, "test": fig.test,
             "quick": quick, "variants": measured, "panels": panels,
             "seconds": round(time.perf_counter() - t0, 1), "holds": holds}
    log(f"{fig.key} {fig.title}: holds {str(holds).lower()} ({entry['seconds']:.0f} s)")
    return entry


def run_gallery(names, out, quick: bool = False, renders: bool = True, log=print, resume: bool = False,
                workers: int | None = 1) -> dict:
    """Run the figures ``names`` (all when empty) into ``out``; returns signatures.json's object.
    Figures already in an existing signatures.json are kept unless run again; ``resume``: see
    :func:`run_figure`. ``workers``: processes that make the bakes ahead (:mod:`.pool`; None: one
    per core), 1: every bake in this process when its figure reads it."""
    figures = select(names)
    requested_threads(None)  # a bad $WOODDECAY_THREADS is one line before anything is written
    out = Path(out)
    if renders and not render.available():
        raise InputError("--render", "bpy", 'rendering needs the bpy wheel: pip install "wooddecay[render]" '
                                            "(or give --no-render)")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(str(out), "", f"cannot create the output folder: {err}") from None
    path = out / "signatures.json"
    result = earlier(path)
    jobs = plan(figures, out, quick, resume)
    n = pool.workers_for(jobs, workers)
    if n > 1:
        log(f"baking {len(jobs)} scenes ahead on {n} processes")
    with pool.baking_ahead(jobs, n, timed_bake):
        for fig in figures:
            result[fig.key] = run_figure(fig, out, quick, renders, log, resume)
            write_bytes(path, json.dumps(result, indent=1).encode())
            write_bytes(out / "gallery.md", markdown(result).encode())
    return result


#: what gallery.md reads of every figure in signatures.json
ENTRY_KEYS = ("title", "caption", "claim", "test", "holds", "quick", "seconds", "panels", "variants")


def earlier(path: Path) -> dict:
    """The figures of an existing ``signatures.json`` (none when there is no file), checked for
    what :func:`markdown` reads before anything is baked: InputError for anything else."""
    if not path.is_file():
        return {}
    try:
        result = json.loads(path.read_text("utf-8"))
    except (OSError, ValueError) as err:
        raise InputError(str(path), "", f"not readable JSON ({err}); remove it or give another -o") from None
    for key, e in (result.items() if isinstance(result, dict) else [(None, None)]):
        if not (isinstance(e, dict) and all(k in e for k in ENTRY_KEYS) and isinstance(e["panels"], list)
                and isinstance(e["seconds"], (int, float)) and isinstance(e["variants"], dict)
                and all(isinstance(v, dict) for v in e["variants"].values())):
            where = "" if key is None else str(key)
            raise InputError(str(path), where, "not a figure of wooddecay gallery's signatures.json (keys "
                             f"{', '.join(ENTRY_KEYS)}); remove the file or give another -o")
    return result


#: statistics shown per variant in gallery.md (the signature's, then the figure's own)
SHOWN = ("mass_loss", "pieces", "largest_piece_fraction", "block_purity", "crack_clusters", "hollow_fraction",
         "debris_height_m", "debris_centre_height_m")


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, list):
        return "/".join(_fmt(x) for x in v)
    return str(v)


def markdown(result: dict, prefix: str = "") -> str:
    """gallery.md of a signatures.json object; panel paths get ``prefix`` in front."""
    lines = ["# Gallery: woodstock's figures baked, rendered and measured", "",
             "Made by `wooddecay gallery`; every number below is from `signatures.json` beside it.", "",
             "| figure | claim | holds | seconds |", "|---|---|---|---|"]
    lines += [f"| [{k}](#{k}) {e['title']} | {e['claim']} | {'yes' if e['holds'] else '**no**'} | {e['seconds']:.0f} |"
              for k, e in result.items()]
    for key, e in result.items():
        lines += ["", f"## {key}", "", f"**{e['title']}.** {e['caption']}", "",
                  f"Claim: {e['claim']} Test: {e['test']}. **Holds: {'yes' if e['holds'] else 'no'}**"
                  + (" (quick scenes)" if e["quick"] else "") + ".", ""]
        lines += [f"![{p}]({prefix}{p})" for p in e["panels"]]
        rows = {name: v for name, v in e["variants"].items()}
        own = sorted({k for v in rows.values() for k, x in v.items()
                      if isinstance(x, (int, float)) and not isinstance(x, bool) and k != "seconds"} - set(SHOWN))
        nested = sorted({k for v in rows.values() for k, x in v.items() if isinstance(x, dict) and k != "overrides"
                         and k != "signature"})
        cols = [c for c in SHOWN if any(c in v.get("signature", {}) for v in rows.values())] + own
        lines += ["", "| variant | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
        for name, v in rows.items():
            sig = v.get("signature", {})
            lines.append(f"| {name}: {v.get('label', '')} | " + " | ".join(_fmt(sig.get(c, v.get(c, ""))) for c in cols) + " |")
            for sub in nested:
                cells = [_fmt(v[sub].get(c, "")) for c in cols] if sub in v else []
                if any(cells):
                    lines.append(f"| {name} {sub} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
