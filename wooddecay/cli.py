"""Command line: ``wooddecay inspect`` and ``wooddecay init`` (docs/architecture.md "CLI").

Errors in the input are one line on stderr (file, key, allowed range) with exit code 2 and no
traceback unless ``--debug`` is given.
"""
from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import tempfile
import time
import tomllib
from importlib import resources
from pathlib import Path

import click
import numpy as np

from .wood import WoodModel
from . import budget
from .atomic import write_bytes
from .errors import InputError

TEMPLATES = ("board", "log", "tree")


class _Main(click.Group):
    """Turns InputError and click's own usage errors (a missing or unreadable SCENE, a directory,
    a bad option value) into one line and exit code 2 (``--debug`` keeps the traceback)."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode, **extra)
        try:
            code = super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        except click.exceptions.NoArgsIsHelpError as err:
            click.echo(err.ctx.get_help(), err=True)
            sys.exit(2)
        except click.ClickException as err:
            click.echo(f"error: {' '.join(err.format_message().split())}", err=True)
            sys.exit(2)
        except click.exceptions.Abort:
            click.echo("error: aborted", err=True)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except InputError as err:
            if ctx.obj and ctx.obj.get("debug"):
                raise
            click.echo(f"error: {err}", err=True)
            ctx.exit(2)


@click.group(cls=_Main)
@click.option("--debug", is_flag=True, help="Show tracebacks for input errors.")
@click.version_option(package_name="wooddecay")
@click.pass_context
def main(ctx: click.Context, debug: bool) -> None:
    """Simulate fungal decay of wood (Woodstock, SIGGRAPH 2026) and bake it into assets."""
    ctx.obj = {"debug": debug}


_UNITS = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40}


def parse_size(text: str) -> int:
    """Bytes of a size such as ``8G``, ``500M``, ``2.5g`` or ``1048576``."""
    t = text.strip().upper().removesuffix("B")
    unit = t[-1:] if t[-1:] in _UNITS else ""
    try:
        value = float(t[:len(t) - len(unit)])
    except ValueError:
        value = float("nan")
    if not value > 0 or value == float("inf"):
        raise InputError("--max-memory", "", f"{text!r} is not a size such as 8G, 500M or 1048576")
    return int(value * _UNITS[unit])


def _load(scene_path: str, set_items: tuple[str, ...]):
    from .scene import load_scene, parse_set_option

    return load_scene(scene_path, overrides=parse_set_option(set_items))


def inspect_report(model: WoodModel, estimate) -> dict:
    """The numbers ``wooddecay inspect`` prints (also its JSON), with the biology's explicit-step
    bound and substeps (``model.bio``) and the scene's size estimate (:mod:`wooddecay.budget`)."""
    deg = model.reg_degree
    stages = {k: round(v, 4) for k, v in model.build_seconds.items()}
    return {
        "scene": model.info.name,
        "seed": model.info.seed,
        "strands": model.n_strands,
        "elements": model.n_elements,
        "particles": int(len(model.particles)),
        "reg_edges": model.n_edges,
        "transport_edges": int(len(model.transport_edges)),
        "reg_degree": {"min": int(deg.min()), "mean": round(float(deg.mean()), 3), "max": int(deg.max())},
        "branches": model.n_branches,
        "bsp_cells": model.bsp_cells,
        "tissues": model.tissue_counts(),
        "estimate": estimate.as_dict(),
        "build_seconds": round(sum(model.build_seconds.values()), 4),
        "build_stages": stages,
        "biology": _bio_report(model),
        "notes": list(model.notes),
    }


def _bio_report(model: WoodModel) -> dict:
    from .sim.biology import substeps

    bio, dt_bio = model.bio, model.time.dt_bio
    return {
        "dt_bio_days": dt_bio,
        "stability_bound_days": float(bio.bound),
        "substeps": substeps(dt_bio, bio.bound),
        "transport_fit_error_p99": float(np.percentile(bio.op.fit_error, 99)),
        "transport_chain_saturated": bio.op.chain_saturated,
    }


def _print_report(rep: dict) -> None:
    d = rep["reg_degree"]
    lines = [
        f"scene            {rep['scene']} (seed {rep['seed']})",
        f"strands          {rep['strands']}",
        f"rod elements     {rep['elements']}  ({rep['particles']} particles)",
        f"REG edges        {rep['reg_edges']}  (degree min {d['min']} / mean {d['mean']} / max {d['max']})",
        f"transport edges  {rep['transport_edges']}  (strand chains + cross-strand pairs within transport_reach r_s)",
        f"branches         {rep['branches']}",
        f"BSP cells        {rep['bsp_cells']}",
        "tissues          " + ", ".join(f"{k} {v}" for k, v in rep["tissues"].items()),
        f"bake estimate    {rep['estimate']['elements']} elements, peak {rep['estimate']['peak_bytes'] / 2**20:.0f} MB,"
        f" outputs {rep['estimate']['output_bytes'] / 2**20:.0f} MB (from the scene alone)",
        f"build            {rep['build_seconds']:.3f} s  ("
        + ", ".join(f"{k} {v:.3f}" for k, v in rep["build_stages"].items()) + ")",
    ]
    b = rep["biology"]
    lines.append(f"biology step     dt_bio {b['dt_bio_days']:g} d, explicit bound {b['stability_bound_days']:.4g} d"
                 f" -> {b['substeps']} substep(s) per step")
    lines.append(f"transport fit    across-grain moment error p99 {b['transport_fit_error_p99']:.3g},"
                 f" {b['transport_chain_saturated']} element(s) with saturated chains")
    lines += [f"note             {n}" for n in rep["notes"]]
    click.echo("\n".join(lines))


def _inspect_bake(folder: Path, as_json: bool) -> None:
    """The per-frame signatures of the bake in ``folder`` (``summary.json``); a bake whose stage is
    of a newer format than this wooddecay reads is refused (:func:`wooddecay.export.usd.check_bake_format`)."""
    from .export.usd import check_bake_format

    check_bake_format(folder)
    path = folder / "summary.json"
    try:
        frames = json.loads(path.read_text())["frames"]
        rows = [{"frame": f["frame"], "t_days": f["t_days"], **f["signature"]} for f in frames]
    except (OSError, ValueError, KeyError, TypeError) as err:
        what = "no summary.json" if isinstance(err, FileNotFoundError) else f"not a bake summary ({type(err).__name__}: {err})"
        raise InputError(str(path), "", f"{what}; give a scene file or a folder written by wooddecay bake") from None
    if as_json:
        click.echo(json.dumps(rows, indent=2))
        return
    click.echo("frame      day  mass_loss  pieces  largest  purity  hollow  crumbled  height_m  footprint_m2  cracks  r/t/l")
    for r in rows:
        click.echo(f"{r['frame']:5d} {r['t_days']:8.1f} {r['mass_loss']:10.3f} {r['pieces']:7d} {r['largest_piece_fraction']:8.2f}"
                   f" {r['block_purity']:7.2f} {r['hollow_fraction']:7.2f} {r['crumbled_elements']:9d}"
                   f" {r['debris_height_m']:9.3f} {r['debris_footprint_m2']:13.3f} {r['crack_clusters']:7d}  "
                   + "/".join(f"{c:.2f}" for c in r["crack_orientation"]))


def _usd_path(ctx: click.Context, param: click.Parameter, value: str | None) -> Path | None:
    """Check ``--strands-usd`` (suffix, existing folder) before the model is built."""
    if value is None:
        return None
    from .export.strands_usd import check_usd_path

    return check_usd_path(value)


def _meshlets_usd_path(ctx: click.Context, param: click.Parameter, value: str | None) -> Path | None:
    """Check ``--meshlets-usd`` (suffix, existing folder) before the model is built."""
    if value is None:
        return None
    from .export.stage import check_usd_path

    return check_usd_path(value, "meshlets")


@main.command()
@click.argument("scene_path", metavar="SCENE|BAKE_DIR", type=click.Path())
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("--strands-usd", type=click.Path(dir_okay=False), callback=_usd_path,
              help="Write the strands as USD BasisCurves (.usda, .usdc or .usd, in an existing folder).")
@click.option("--meshlets", "with_meshlets", is_flag=True,
              help="Build the rest meshlets and report their count, closedness and volume error.")
@click.option("--meshlets-usd", type=click.Path(dir_okay=False), callback=_meshlets_usd_path,
              help="Write the rest meshlets coloured by element as USD (implies --meshlets).")
@click.option("--set", "set_items", multiple=True, metavar="KEY=VALUE", help="Override a scene key (repeatable).")
def inspect(scene_path: str, as_json: bool, strands_usd: Path | None, with_meshlets: bool,
            meshlets_usd: Path | None, set_items: tuple[str, ...]) -> None:
    """Build the wood model of SCENE and report its size, tissues, build time and the biology's
    explicit-step stability bound (and its meshlets with --meshlets); of a BAKE_DIR, print the
    visible-decay signature of every frame (summary.json)."""
    from .model import build_model

    if Path(scene_path).is_dir():
        _inspect_bake(Path(scene_path), as_json)
        return
    scene = _load(scene_path, set_items)
    est = budget.check(scene)
    model = build_model(scene)
    rep = inspect_report(model, est)
    if strands_usd:
        from .export.strands_usd import write_strands_usd

        t0 = time.perf_counter()
        write_strands_usd(strands_usd, model)
        rep["strands_usd"] = {"path": str(strands_usd), "seconds": round(time.perf_counter() - t0, 4)}
    if with_meshlets or meshlets_usd:
        rep["meshlets"] = _meshlets_report(model, meshlets_usd)
    if as_json:
        click.echo(json.dumps(rep, indent=2))
    else:
        _print_report(rep)
        if strands_usd:
            click.echo(f"strands USD      {strands_usd}")
        if "meshlets" in rep:
            r = rep["meshlets"]
            click.echo(f"meshlets         {r['count']} in {r['seconds']:.2f} s, closed fraction {r['closed_fraction']:.6f}, "
                       f"volume {r['volume']:.6g} m^3, volume error {r['volume_error']:.2e}, {r['faces']} faces"
                       + (f" -> {meshlets_usd}" if meshlets_usd else ""))
            if "source_mesh" in r:
                m = r["source_mesh"]
                click.echo(f"source mesh      volume {m['volume']:.6g} m^3 (meshlets {100 * m['volume_error']:+.2f} %), "
                           f"bark to mesh: mean {1e3 * m['bark_distance_mean']:.1f} mm, p99 "
                           f"{1e3 * m['bark_distance_p99']:.1f} mm, max {1e3 * m['bark_distance_max']:.1f} mm")


def _meshlets_report(model: WoodModel, usd_path: Path | None) -> dict:
    """``meshlets`` fields of the inspect report: count, closed fraction, volume error against
    the volume inside the bark surface, total volume, seconds (and the debug USD); for a skeleton
    built from a mesh, the meshlets against it (source_mesh: volumes, bark-to-mesh distances)."""
    from .meshlets import checks
    from .meshlets.sweep import FACE_BARK, build_meshlets

    mesh = build_meshlets(model)
    closed = checks.closed_oriented(mesh)
    vol = checks.volumes(mesh)
    rep = {
        "count": mesh.count,
        "faces": mesh.n_faces,
        "vertices": int(len(mesh.points)),
        "closed_fraction": float(closed.mean()) if mesh.count else 1.0,
        "positive_volume_fraction": float((vol > 0).mean()) if mesh.count else 1.0,
        "volume": float(vol.sum()),
        "volume_error": float(vol.sum() / checks.bark_volume(model) - 1.0),
        "seconds": round(mesh.stats["seconds"], 4),
        "events": {k: v for k, v in mesh.stats.items() if k != "seconds"},
    }
    surface = model.skeleton.surface
    if surface is not None:
        from .strands.mesh_input import surface_distance

        bark = np.unique(mesh.faces[mesh.face_kind == FACE_BARK])
        d = surface_distance(surface, mesh.points[bark], model.r_s)
        rep["source_mesh"] = {"volume": float(surface.volume), "volume_error": float(vol.sum() / surface.volume - 1.0),
                              "bark_distance_max": float(d.max()), "bark_distance_mean": float(d.mean()),
                              "bark_distance_p99": float(np.percentile(d, 99))}
    if usd_path:
        from .export.meshlets_usd import write_meshlets_usd

        write_meshlets_usd(usd_path, model, mesh)
        rep["usd"] = str(usd_path)
    return rep


@main.command()
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", type=click.Path(file_okay=False), default=None,
              help="Output folder (default: bake/<scene name>).")
@click.option("--days", type=float, default=None, help="Simulated days (overrides time.days and time.years).")
@click.option("--years", type=float, default=None, help="Simulated years of 365.25 days (overrides time.days and time.years).")
@click.option("--frames", type=int, default=None, help="Output frames (overrides time.frames).")
@click.option("--quality", type=click.Choice(["draft", "final"]), default="final", show_default=True,
              help="final: coupled mechanics (cracks, debris); draft: biology only, fast preview.")
@click.option("--resume", is_flag=True, help="Continue an interrupted bake in the same folder.")
@click.option("--threads", default=None, metavar="N|auto",
              help="Threads of the simulation kernels (default $WOODDECAY_THREADS, else auto: the faster of "
                   "one and all, measured while baking). Results are identical for any count.")
@click.option("--max-memory", default=None, metavar="SIZE",
              help="Refuse a scene whose estimated peak memory exceeds SIZE (e.g. 8G, 500M; default: the "
                   "memory available now).")
@click.option("--set", "set_items", multiple=True, metavar="KEY=VALUE", help="Override a scene key (repeatable).")
def bake(scene_path: str, out: str | None, days: float | None, years: float | None, frames: int | None,
         quality: str, resume: bool, threads: str | None, max_memory: str | None, set_items: tuple[str, ...]) -> None:
    """Simulate SCENE and write DIR/<name>.usdc, DIR/<name>.glb and DIR/summary.json."""
    from .bake import bake as run_bake
    from .sim.threads import requested_threads

    n_threads = requested_threads(threads)
    limit = None if max_memory is None else parse_size(max_memory)

    if days is not None and years is not None:
        raise InputError("--years", "", "give one of --days and --years")
    extra = tuple(f"time.{k}={v!r}" for k, v in (("days", days), ("years", years), ("frames", frames))
                  if v is not None)
    scene = _load(scene_path, set_items + extra)
    out_dir = Path(out) if out else Path("bake") / scene.name
    tty = sys.stderr.isatty()
    bar = click.progressbar(length=int(scene.time.frames), label=f"baking {scene.name}", file=sys.stderr) if tty else None

    def progress(fr, n):
        d = fr.diagnostics
        if bar is not None:
            bar.update(1)
        else:
            mech = d.get("mechanics", {})
            click.echo(f"frame {fr.index + 1}/{n}  day {fr.t_days:.2f}  mass loss {d['mass_loss']:.4f}"
                       + (f"  broken {mech['broken_connections']}  pieces {mech['components']}" if mech else ""),
                       err=True)

    try:
        with bar if bar is not None else contextlib.nullcontext():
            summary = run_bake(scene, out_dir, resume=resume, quality=quality, progress=progress,
                               threads=n_threads, max_memory=limit)
    except KeyboardInterrupt as err:  # click says only "aborted"; a traceback prints the note itself
        for note in getattr(err, "__notes__", ()):
            click.echo(f"note: {note}", err=True)
        raise
    sec = summary["seconds"]
    from .export.bark_texture import file_name, tile_number

    tiles = []
    for name, o in summary["outputs"].items():
        if tile_number(name, scene.name) is not None:
            tiles.append(o)
        else:
            click.echo(f"wrote {o['path']}  ({o['bytes'] / 2**20:.1f} MB)")
    if tiles:
        pattern = Path(tiles[0]["path"]).with_name(file_name(scene.name))
        click.echo(f"wrote {pattern}  ({len(tiles)} tiles, one per frame, "
                   f"{sum(o['bytes'] for o in tiles) / 2**20:.1f} MB)")
    click.echo(f"wrote {out_dir / 'summary.json'}")
    click.echo("seconds: " + ", ".join(f"{k} {v:.2f}" for k, v in sec.items()))
    used, held = summary["threads"]["steps"], summary["threads"].get("held_by_load", 0)
    click.echo("threads: " + ", ".join(f"{k} for {v} steps" for k, v in used.items())
               + (f" ({held} held to fewer threads by other processes' load)" if held else ""))
    for note in summary["notes"]:
        click.echo(f"note: {note}", err=True)
    conv = summary["convergence"]
    if conv is not None and not conv["converged"]:
        click.echo(f"warning: {conv['remedy']}", err=True)


@main.command()
@click.argument("batch_path", metavar="BATCH", type=click.Path(dir_okay=False))
@click.option("-o", "--output", "out", type=click.Path(file_okay=False), default=None,
              help="Output folder, one sub-folder per variant (default: bake/<batch file stem>).")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="A running dask scheduler (tcp://host:port); default: a LocalCluster on this machine.")
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="Worker processes of the LocalCluster (default: one per core).")
@click.option("--resume", is_flag=True, help="Skip variants whose summary.json exists with the same scene hash.")
def batch(batch_path: str, out: str | None, scheduler: str | None, workers: int | None, resume: bool) -> None:
    """Bake every variant of BATCH (base scenes x overrides x grid) on Dask; writes
    DIR/<variant>/ and DIR/batch.json, DIR/batch.csv. Exit 1 if a variant failed."""
    from . import batch as batch_mod

    variants = batch_mod.load_batch(batch_path)
    out_dir = Path(out) if out else Path("bake") / Path(batch_path).stem
    if scheduler is not None and not scheduler.strip():
        raise InputError("--scheduler", "", "give a scheduler address such as tcp://127.0.0.1:8786")
    try:
        client = batch_mod.client_for(scheduler, workers)
    except (OSError, TimeoutError) as err:
        raise InputError("--scheduler", "", f"cannot reach {scheduler}: {err}".splitlines()[0]) from None
    with client:
        click.echo(f"{len(variants)} variants on {len(client.scheduler_info()['workers'])} workers; "
                   f"dashboard {client.dashboard_link}", err=True)
        tty = sys.stderr.isatty()
        bar = click.progressbar(length=len(variants), label="batch", file=sys.stderr) if tty else None

        def progress(row):
            if bar is not None:
                bar.update(1)
            else:
                click.echo(f"{row['status']:8s} {Path(row['output']).name}  {row['seconds']:.1f} s"
                           + (f"  {row['error']}" if row.get("error") else ""), err=True)

        t0 = time.perf_counter()
        with bar if bar is not None else contextlib.nullcontext():
            rows = batch_mod.run_batch(variants, out_dir, client, resume=resume, progress=progress)
        if scheduler is None:
            client.cluster.close()
    counts = {k: sum(r["status"] == k for r in rows) for k in ("done", "skipped", "failed")}
    click.echo(f"wrote {out_dir / 'batch.json'} and {out_dir / 'batch.csv'}: "
               + ", ".join(f"{v} {k}" for k, v in counts.items()) + f" in {time.perf_counter() - t0:.1f} s")
    for r in rows:
        if r["status"] == "failed":
            click.echo(f"failed: {Path(r['output']).name}: {r['error']}", err=True)
    if counts["failed"]:
        sys.exit(1)


@main.command()
@click.argument("figures", metavar="[FIG]...", nargs=-1)
@click.option("-o", "--output", "out", type=click.Path(file_okay=False), default="gallery", show_default=True,
              help="Output folder: DIR/<fig>/<variant>/ bakes, DIR/<fig>/*.png panels, DIR/signatures.json.")
@click.option("--quick", is_flag=True, help="Reduced scenes (coarser strands, fewer days) that fit CI.")
@click.option("--render/--no-render", default=True, show_default=True,
              help="Render the panels through the add-on (needs the bpy wheel: wooddecay[render]).")
@click.option("--resume", is_flag=True,
              help="Reuse the finished bakes in DIR of variants whose scene is unchanged (same scene hash); "
                   "studies (figs. 17, 18, 20) run again.")
@click.option("--jobs", default="auto", show_default=True, metavar="N|auto",
              help="Processes that bake the figures' scenes ahead, each on cores // N threads (auto: one per "
                   "core, as memory allows); 1 bakes each scene when its figure is read.")
def gallery(figures: tuple[str, ...], out: str, quick: bool, render: bool, resume: bool, jobs: str) -> None:
    """Bake, render and measure the paper's figures (FIG: fig6, fig11, ..., fig19, or 6, 11, ...;
    default all) and write DIR/signatures.json with, per figure, whether its claim holds."""
    from .gallery.run import run_gallery, select
    from .sim.threads import parse_threads

    select(figures)  # a bad name fails before anything is written
    workers = parse_threads(jobs, "--jobs")
    t0 = time.perf_counter()
    result = run_gallery(figures, out, quick=quick, renders=render, log=lambda m: click.echo(m, err=True),
                         resume=resume, workers=workers)
    for key, e in result.items():
        click.echo(f"{key:6s} holds {str(e['holds']).lower():5s} {e['seconds']:7.0f} s  {e['title']}")
    click.echo(f"wrote {Path(out) / 'signatures.json'} in {time.perf_counter() - t0:.0f} s")


@main.command()
@click.argument("a", type=click.Path(dir_okay=False))
@click.argument("b", type=click.Path(dir_okay=False))
@click.option("--rtol", type=click.FloatRange(min=0), default=1e-6, show_default=True, help="Relative tolerance of numbers.")
@click.option("--atol", type=click.FloatRange(min=0), default=1e-9, show_default=True, help="Absolute tolerance of numbers.")
@click.pass_context
def diff(ctx: click.Context, a: str, b: str, rtol: float, atol: float) -> None:
    """Compare two USD stages: exit 0 equal, 1 different (each difference printed with its
    largest absolute and relative error), 2 error."""
    from .export.compare import compare_usd

    found = compare_usd(a, b, rtol=rtol, atol=atol)
    for d in found:
        click.echo(str(d))
    if found:
        click.echo(f"{len(found)} difference(s)")
        ctx.exit(1)
    click.echo("equal")


# --- wooddecay addon: the Blender extension (logic in wooddecay/addon.py) ---------------------
@main.group()
def addon() -> None:
    """The Blender add-on (shipped in the package, wooddecay/blender_addon/): build its installable extension zip."""


@addon.command("build")
@click.option("-o", "--output", "out", type=click.Path(file_okay=False), default="dist", show_default=True,
              help="Folder for the zip (created if missing).")
def addon_build(out: str) -> None:
    """Make <id>-<version>.zip, the zip Blender's `extension build` makes (no Blender or bpy needed):
    install it in Blender with Edit > Preferences > Get Extensions > Install from Disk."""
    from .addon import AddonError, build

    try:
        path = build(out)
    except AddonError as err:
        raise click.ClickException(str(err)) from None
    click.echo(f"wrote {path}")
# --- end of wooddecay addon -------------------------------------------------------------------


def template_text(template: str, name: str) -> str:
    """The sample scene of ``template`` with its [scene] name replaced by ``name``."""
    text = resources.files("wooddecay").joinpath("samples", f"{template}.toml").read_text("utf-8")
    lines = text.splitlines(keepends=True)
    for k, line in enumerate(lines):
        if line.strip().startswith("name") and "=" in line:
            lines[k] = f"name = {json.dumps(name)}\n"
            break
    return "".join(lines)


def mesh_template_text(template: str, name: str, key: str, ref: str, mi, scale: float, largest: bool,
                       up: str | None) -> str:
    """The log template with its [skeleton] replaced by ``key = ref`` (``mesh`` or ``points``;
    and ``scale``, ``largest``, ``up``) and its ground inoculation box fitted to the surface ``mi``:
    the bottom BOX_HEIGHT of it."""
    lines = template_text(template, name).splitlines(keepends=True)
    start = next(i for i, line in enumerate(lines) if line.strip() == "[skeleton]")
    end = next(i for i in range(start + 1, len(lines))
               if lines[i].startswith("[") and not lines[i].startswith(("[skeleton", "[[skeleton")))
    table = [f"[skeleton]\n# a centreline and its cross-sections, built from the file (wooddecay init --from-{key})\n",
             f"{key} = {json.dumps(ref)}\n"]
    table += [f"scale = {scale!r}\n"] if scale != 1.0 else []
    table += ["largest = true\n"] if largest else []
    table += [f"up = {json.dumps(up)}\n"] if up else []
    lo, hi = mi.mesh.bounds
    box = (f'region = {{ kind = "box", min = [{lo[0] - 0.1:.3f}, {lo[1] - 0.1:.3f}, {lo[2] - 0.1:.3f}], '
           f'max = [{hi[0] + 0.1:.3f}, {hi[1] + 0.1:.3f}, {lo[2] + BOX_HEIGHT * (hi[2] - lo[2]):.3f}] }}\n')
    rest = [box if line.startswith('region = { kind = "box"') else line for line in lines[end:]]
    return "".join(lines[:start] + table + ["\n"] + rest)


#: the ground inoculation of a log from a mesh: the bottom 13% of its height (as the sample log's)
BOX_HEIGHT = 0.13


@main.command()
@click.argument("name")
@click.option("--template", type=click.Choice(TEMPLATES), default="log", show_default=True)
@click.option("--from-mesh", "mesh_file", type=click.Path(dir_okay=False), default=None,
              help="Build the skeleton and profiles from this surface mesh (OBJ, PLY, STL, glTF/GLB, USD) of a log, "
                   "stump or branching wood; the log template only.")
@click.option("--scale", type=float, default=1.0, show_default=True,
              help="With --from-mesh: multiply the mesh's coordinates (e.g. 0.01 for centimetres).")
@click.option("--from-points", "points_file", type=click.Path(dir_okay=False), default=None,
              help="Build the skeleton and profiles from this scanned point cloud (PLY, XYZ, LAS); the log template only.")
@click.option("--largest", is_flag=True, help="With --from-mesh: keep the largest of several disjoint bodies.")
@click.option("--up", type=click.Choice(("y", "z")), default=None,
              help="The file's up axis (default: glTF y, USD its stage's, others z).")
@click.option("--force", is_flag=True, help="Overwrite existing files.")
def init(name: str, template: str, mesh_file: str | None, points_file: str | None, scale: float, largest: bool,
         up: str | None, force: bool) -> None:
    """Write a starting scene NAME.toml from a template (and its skeleton file, if any)."""
    target = Path(name if name.endswith(".toml") else f"{name}.toml")
    scene_name = target.stem
    if not target.parent.is_dir():
        raise InputError(str(target), "", f"folder {target.parent} does not exist")
    if mesh_file is not None and points_file is not None:
        raise InputError("--from-points", points_file, "give --from-mesh or --from-points, not both")
    if mesh_file is None and points_file is None:
        files = {target: template_text(template, scene_name)}
        samples = resources.files("wooddecay").joinpath("samples")
        for extra in sorted(p.name for p in samples.iterdir() if p.name.startswith(f"{template}_skeleton")):
            files[target.parent / extra] = samples.joinpath(extra).read_text("utf-8")
    else:
        key, surface_file = ("mesh", mesh_file) if mesh_file is not None else ("points", points_file)
        files = {target: _scene_from_surface(target, template, key, Path(surface_file), scale, largest, up)}
    existing = [str(p) for p in files if p.exists()]
    if existing and not force:
        raise InputError(existing[0], "", "already exists; use --force to overwrite")
    for path, text in files.items():
        write_bytes(path, text.encode("utf-8"), "scene")
        click.echo(f"wrote {path}")


def _scene_from_surface(target: Path, template: str, key: str, surface_file: Path, scale: float,
                        largest: bool, up: str | None) -> str:
    """The scene text of ``init --from-mesh`` (``key`` "mesh") or ``--from-points`` ("points"),
    after building its skeleton once (so a bad file fails here, in one line); prints what was
    found."""
    from .strands.mesh_skeleton import mesh_skeleton
    from .strands.skeleton_loader import load_surface

    option = f"--from-{key}"
    if template != "log":
        raise InputError("--template", template, f"{option} writes the log template's settings (a branching "
                         "mesh too): give --template log")
    if not (math.isfinite(scale) and scale > 0.0):
        raise InputError("--scale", str(scale), "must be a finite number > 0")
    if largest and key == "points":
        raise InputError("--largest", "", "applies to --from-mesh only")
    t0 = time.perf_counter()
    r_s = tomllib.loads(template_text(template, target.stem))["strands"]["r_s"]
    mi = load_surface(key, surface_file, scale, largest, up, r_s, option)
    skel = mesh_skeleton(mi, r_s)
    ref = os.path.relpath(surface_file.resolve(), target.parent.resolve())
    if ref.startswith(".."):  # outside the scene's folder: where it is
        ref = str(surface_file.resolve())
    text = mesh_template_text(template, target.stem, key, ref, mi, scale, largest, up)
    lo, hi = mi.mesh.bounds
    click.echo(f"{key:<17}{surface_file}: {len(mi.mesh.faces)} faces, volume {mi.mesh.volume:.6g} m^3, "
               f"box {np.round(lo, 3).tolist()} .. {np.round(hi, 3).tolist()} m")
    for note in mi.repairs:
        click.echo(f"repaired         {note}")
    click.echo(f"skeleton         {len(skel.ids)} nodes along {np.linalg.norm(np.diff(skel.positions, axis=0), axis=1).sum():.3f} m "
               f"in {time.perf_counter() - t0:.2f} s")
    return text


@main.group()
def chart() -> None:
    """Charts of the validation studies (PNG)."""


@chart.command("barrier")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="barrier.png", show_default=True)
@click.option("--days", type=click.FloatRange(min=10.0), default=1500.0, show_default=True)
def chart_barrier(output: str, days: float) -> None:
    """Fig. 18: mass loss and moisture content ratio over time for beta/kappa in {0, 0.5, 1, 2}."""
    from .studies.barrier import RATIOS, plot_barrier, run_barrier

    out = Path(output)
    if not out.parent.is_dir():
        raise InputError(output, "", f"folder {out.parent} does not exist")
    runs = [run_barrier(r, days=days) for r in RATIOS]
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        tmp_png = Path(tmp) / out.name
        plot_barrier(runs, tmp_png)
        os.replace(tmp_png, out)
    for r in runs:
        click.echo(f"beta/kappa {r.ratio:g}: plateau {r.plateau:.0f} days, mass loss at day {r.t[-1]:.0f} {r.mass_loss[-1]:.3f}")
    click.echo(f"wrote {out}")


@chart.command("mechanics")
@click.option("-o", "--output", type=click.Path(dir_okay=False), required=True, help="PNG to write.")
@click.option("--quick", is_flag=True, help="Fewer settings (dt in {1e-2, 1e-3, 2e-4} s x 2, 10 iterations).")
def chart_mechanics(output: str, quick: bool) -> None:
    """docs/model.md §7 "Speed": cantilever error against wall time over dt (substeps per simulated
    second = 1/dt) and iterations, with PyElastica's point on the same axes."""
    from .studies.mechanics_chart import (DTS, DTS_QUICK, ITERATIONS, ITERATIONS_QUICK, describe,
                                          plot_mechanics, run_mechanics)

    out = Path(output)
    if not out.parent.is_dir():
        raise InputError(output, "", f"folder {out.parent} does not exist")
    data = run_mechanics(DTS_QUICK if quick else DTS, ITERATIONS_QUICK if quick else ITERATIONS)
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        tmp_png = Path(tmp) / out.name
        plot_mechanics(data, tmp_png)
        os.replace(tmp_png, out)
    for p in data:
        click.echo(describe(p))
    if not any(p["solver"] == "pyelastica" for p in data):
        click.echo("PyElastica not installed (pip install pyelastica): no reference point")
    click.echo(f"wrote {out}")


@chart.command("solver")
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="solver.png", show_default=True)
@click.option("--quick", is_flag=True, help="A quarter of each bake's days, each bake cut at 120 s (600 s).")
def chart_solver(output: str, quick: bool) -> None:
    """Equilibrium residual against wall time for XPBD at 1-256 sweeps and the implicit solve at its
    tolerances, on the log and Fig. 6's section, with a lone strand's cantilever and the resting
    log's shape; rings the cheapest setting within residual 0.03 on both bakes."""
    from .studies.solver_chart import TARGET, plot_chart, run_chart

    out = Path(output)
    if not out.parent.is_dir():
        raise InputError(output, "", f"folder {out.parent} does not exist")
    runs, cantilever = run_chart(quick, report=click.echo)
    for p in cantilever:
        click.echo(f"cantilever {p['label']}: error {p['error']:.3g}, wall {p['seconds']:.2f} s")
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        tmp_png = Path(tmp) / out.name
        default = plot_chart(runs, cantilever, tmp_png)
        os.replace(tmp_png, out)
    click.echo(f"default: {default or f'no setting holds residual {TARGET:g} on both bakes'}")
    click.echo(f"wrote {out}")


@chart.command("schedule")
@click.argument("scene", required=False)
@click.option("-o", "--output", type=click.Path(dir_okay=False), default="schedule.png", show_default=True)
@click.option("--days", type=click.FloatRange(min=0.0, min_open=True), default=None,
              help="Simulated days (default: the scene's).")
def chart_schedule(scene: str | None, output: str, days: float | None) -> None:
    """Adaptive against fixed schedule: largest position difference against wall time over the
    schedule's tolerances (times 0.25, 1, 4), on SCENE (default: the log sample)."""
    from .studies.schedule import FACTORS, compare, describe, plot_schedule

    out = Path(output)
    if not out.parent.is_dir():
        raise InputError(output, "", f"folder {out.parent} does not exist")
    path = scene or str(resources.files("wooddecay").joinpath("samples", "log.toml"))
    name = _load(path, ()).name  # bad input fails here, before minutes of simulation
    fixed, runs = compare(path, FACTORS, overrides=None if days is None else {"time.days": days})
    with tempfile.TemporaryDirectory(dir=out.parent) as tmp:
        tmp_png = Path(tmp) / out.name
        plot_schedule(name, fixed, runs, tmp_png)
        os.replace(tmp_png, out)
    for r in (fixed, *runs):
        click.echo(describe(r, fixed))
    click.echo(f"wrote {out}")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
