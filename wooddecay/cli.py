"""Command line: ``wooddecay inspect`` and ``wooddecay init`` (DESIGN "CLI").

Errors in the input are one line on stderr (file, key, allowed range) with exit code 2 and no
traceback unless ``--debug`` is given.
"""
from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from importlib import resources
from pathlib import Path

import click

from .errors import InputError

TEMPLATES = ("board", "log", "tree")


class _Main(click.Group):
    """Turns InputError into one line and exit code 2 (``--debug`` keeps the traceback)."""

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


def _load(scene_path: str, set_items: tuple[str, ...]):
    from .scene import load_scene, parse_set_option

    return load_scene(scene_path, overrides=parse_set_option(set_items))


def inspect_report(model, scene) -> dict:
    """The numbers ``wooddecay inspect`` prints (also its JSON)."""
    deg = model.reg_degree
    stages = {k: round(v, 4) for k, v in model.build_seconds.items()}
    return {
        "scene": scene.name,
        "seed": scene.seed,
        "strands": model.n_strands,
        "elements": model.n_elements,
        "particles": int(len(model.particles)),
        "reg_edges": model.n_edges,
        "transport_edges": int(len(model.transport_edges)),
        "reg_degree": {"min": int(deg.min()), "mean": round(float(deg.mean()), 3), "max": int(deg.max())},
        "branches": model.n_branches,
        "bsp_cells": model.bsp_cells,
        "tissues": model.tissue_counts(),
        "memory_estimate_mb": round(model.memory_estimate() / 2**20, 2),
        "build_seconds": round(sum(model.build_seconds.values()), 4),
        "build_stages": stages,
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
        f"memory estimate  {rep['memory_estimate_mb']} MB (model + simulation state)",
        f"build            {rep['build_seconds']:.3f} s  ("
        + ", ".join(f"{k} {v:.3f}" for k, v in rep["build_stages"].items()) + ")",
    ]
    click.echo("\n".join(lines))


@main.command()
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("--strands-usd", type=click.Path(dir_okay=False), help="Write the strands as USD BasisCurves.")
@click.option("--set", "set_items", multiple=True, metavar="KEY=VALUE", help="Override a scene key (repeatable).")
def inspect(scene_path: str, as_json: bool, strands_usd: str | None, set_items: tuple[str, ...]) -> None:
    """Build the wood model of SCENE and report its size, tissues and build time."""
    from .model import build_model

    scene = _load(scene_path, set_items)
    model = build_model(scene)
    rep = inspect_report(model, scene)
    if strands_usd:
        from .export.strands_usd import write_strands_usd

        t0 = time.perf_counter()
        write_strands_usd(strands_usd, model, scene)
        rep["strands_usd"] = {"path": str(strands_usd), "seconds": round(time.perf_counter() - t0, 4)}
    if as_json:
        click.echo(json.dumps(rep, indent=2))
    else:
        _print_report(rep)
        if strands_usd:
            click.echo(f"strands USD      {strands_usd}")


def template_text(template: str, name: str) -> str:
    """The sample scene of ``template`` with its [scene] name replaced by ``name``."""
    text = resources.files("wooddecay").joinpath("samples", f"{template}.toml").read_text("utf-8")
    lines = text.splitlines(keepends=True)
    for k, line in enumerate(lines):
        if line.strip().startswith("name") and "=" in line:
            lines[k] = f"name = {json.dumps(name)}\n"
            break
    return "".join(lines)


def write_atomic(path: Path, data: bytes) -> None:
    """Write to a temporary file in the same folder, then rename: never a half file."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


@main.command()
@click.argument("name")
@click.option("--template", type=click.Choice(TEMPLATES), default="log", show_default=True)
@click.option("--force", is_flag=True, help="Overwrite existing files.")
def init(name: str, template: str, force: bool) -> None:
    """Write a starting scene NAME.toml from a template (and its skeleton file, if any)."""
    target = Path(name if name.endswith(".toml") else f"{name}.toml")
    scene_name = target.stem
    files = {target: template_text(template, scene_name)}
    samples = resources.files("wooddecay").joinpath("samples")
    for extra in sorted(p.name for p in samples.iterdir() if p.name.startswith(f"{template}_skeleton")):
        files[target.parent / extra] = samples.joinpath(extra).read_text("utf-8")
    if not target.parent.is_dir():
        raise InputError(str(target), "", f"folder {target.parent} does not exist")
    existing = [str(p) for p in files if p.exists()]
    if existing and not force:
        raise InputError(existing[0], "", "already exists; use --force to overwrite")
    for path, text in files.items():
        write_atomic(path, text.encode("utf-8"))
        click.echo(f"wrote {path}")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
