"""Batch bakes on Dask (``wooddecay batch``): many variants of base scenes, each an independent
:func:`wooddecay.bake.bake` in its own folder, run on ``dask.distributed``.

A batch file is TOML::

    [batch]
    scenes = ["log.toml"]            # relative to the batch file, else to the working folder
    [batch.set]                      # applied to every variant, as --set
    "time.days" = 200
    [batch.grid]                     # the cartesian product of these lists
    "scene.seed" = [1, 2, 3]

Every variant is a base scene with the ``set`` overrides and one combination of the grid; its
folder is named after the scene's stem and the grid values (``log__scene.seed=2``). The batch
file is checked whole before anything runs (one line, exit 2 at the command line); a variant
whose overrides make a bad scene, or whose bake fails, is reported with its one-line error and
the others go on.

The engine is a ``dask.distributed`` Client: a LocalCluster of one single-threaded process per
worker by default (each bake then runs its numba kernels on cores // workers threads, so workers
do not oversubscribe the machine), or any scheduler by address (a farm, dask-jobqueue, Kubernetes)
with no other change. A worker keeps the models it built and bakes the next variant of the same
wood (differing only in [time], [export] or its name) from it, not from a new build, and keeps
the rest meshlets for every variant of the same wood (``Scene.settle_hash``: differing also in
[climate], [bark] or its inoculations), which depend on the wood alone (14 s of a tree's bake). Each variant
is one task with retries: a worker that dies mid-bake has its
variant run again elsewhere, and a bake is deterministic, so the result is the same. ``resume``
skips variants whose ``summary.json`` exists with the scene hash of the resolved scene. At the
end ``batch.json`` and ``batch.csv`` list every variant (scene, overrides, status, seconds,
signature of the last frame, output folder).
"""
from __future__ import annotations

import csv
import io
import itertools
import json
import os
import re
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .atomic import write_bytes
from .errors import InputError

#: tries of a variant whose worker died (Dask ``retries``)
RETRIES = 2
#: the keys of a [batch] table
KEYS = ("scenes", "set", "grid")


@dataclass(frozen=True)
class Variant:
    """One bake of a batch: a base scene and its overrides."""

    scene: str  # path of the base scene
    overrides: dict = field(default_factory=dict)
    name: str = ""  # the variant's folder name


def _value_text(v: Any) -> str:
    return json.dumps(v, separators=(",", ":")) if isinstance(v, (list, dict)) else str(v)


def _folder_name(stem: str, grid: dict) -> str:
    parts = [stem] + [f"{k}={_value_text(v)}" for k, v in grid.items()]
    return re.sub(r"[^A-Za-z0-9._=,+-]", "_", "__".join(parts))


def load_batch(path: str | os.PathLike) -> list[Variant]:
    """The variants of the batch file ``path`` (module docstring); InputError naming the file and
    key for anything wrong with the file itself."""
    p = Path(path)
    label = str(path)
    if p.is_dir():
        raise InputError(label, "", "is a directory, not a batch file")
    try:
        raw = p.read_bytes()
    except FileNotFoundError:
        raise InputError(label, "", "no such batch file") from None
    except OSError as err:
        raise InputError(label, "", f"cannot read the batch file: {err.strerror or err}") from None
    try:
        data = tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise InputError(label, "", "is not UTF-8 text (a binary file?)") from None
    except tomllib.TOMLDecodeError as err:
        raise InputError(label, "", f"not valid TOML: {err}") from None
    batch = data.get("batch")
    if set(data) != {"batch"} or not isinstance(batch, dict):
        extra = sorted(set(data) - {"batch"})
        raise InputError(label, extra[0] if extra else "batch",
                         "a batch file holds one [batch] table (scenes, set, grid)")
    for key in batch:
        if key not in KEYS:
            raise InputError(label, f"batch.{key}", f"unknown key; allowed: {', '.join(KEYS)}")
    scenes = batch.get("scenes")
    if not isinstance(scenes, list) or not scenes or not all(isinstance(s, str) and s for s in scenes):
        raise InputError(label, "batch.scenes", "must be a non-empty list of scene file paths")
    common = batch.get("set", {})
    if not isinstance(common, dict):
        raise InputError(label, "batch.set", "must be a table of scene keys and values")
    grid = batch.get("grid", {})
    if not isinstance(grid, dict):
        raise InputError(label, "batch.grid", "must be a table of scene keys and lists of values")
    for key, values in grid.items():
        if not isinstance(values, list) or not values:
            raise InputError(label, f"batch.grid.{key}", "must be a non-empty list of values")
        if key in common:
            raise InputError(label, f"batch.grid.{key}", "is also in batch.set; give it in one of them")
    paths = []
    for k, s in enumerate(scenes):
        near = p.parent / s
        found = near if near.exists() else Path(s)
        if not found.is_file():
            raise InputError(label, f"batch.scenes[{k}]", f"no scene file {s!r} (next to the batch file or in the working folder)")
        paths.append(found)
    stems = [q.stem for q in paths]
    if len(set(stems)) != len(stems):
        raise InputError(label, "batch.scenes", "two scenes share a file name; their variants' folders would collide")
    out = []
    for scene in paths:
        for combo in itertools.product(*grid.values()):
            point = dict(zip(grid, combo))
            out.append(Variant(scene=str(scene), overrides={**common, **point}, name=_folder_name(scene.stem, point)))
    return out


#: built models a worker keeps for the next variants of the same wood (Scene.model_hash)
MODELS_KEPT = 2
_models: dict[str, Any] = {}


def _model_for(scene):
    """The scene's model: built, or retimed from a model this worker built for a variant of the
    same wood (:func:`wooddecay.model.retimed`)."""
    from .budget import check
    from .model import build_model, retimed

    key = scene.model_hash
    if key in _models:
        return retimed(_models[key], scene)
    check(scene)  # refuse an oversized scene before building it, as bake() does
    return _keep(_models, key, build_model(scene))


def _keep(store: dict, key: str, value):
    """``value`` kept in ``store`` under ``key``, the oldest entries dropped past MODELS_KEPT."""
    store[key] = value
    while len(store) > MODELS_KEPT:
        store.pop(next(iter(store)))
    return value


#: rest meshlets a worker keeps for the next variants of the same wood (Scene.settle_hash)
_meshlets: dict[str, Any] = {}


def _meshlets_for(scene, model):
    """The rest meshlets of ``model``: built, or those this worker built for a variant of the
    same wood."""
    from .meshlets.sweep import build_meshlets

    key = scene.settle_hash
    return _meshlets[key] if key in _meshlets else _keep(_meshlets, key, build_meshlets(model))


def bake_variant(variant: Variant, out: str, threads: int | None) -> dict:
    """Bake one variant into ``out`` (its folder) and return its row of ``batch.json``; a bad
    scene or a failed bake gives status "failed" with the one-line error. Runs on a worker."""
    from .bake import bake
    from .scene import load_scene

    t0 = time.perf_counter()
    row = {"scene": variant.scene, "overrides": variant.overrides, "output": out}
    try:
        scene = load_scene(variant.scene, overrides=variant.overrides)
        model = _model_for(scene)
        summary = bake(scene, out, threads=threads, model=model, meshlets=_meshlets_for(scene, model))
    except (InputError, ValueError, FloatingPointError, MemoryError) as err:
        return {**row, "status": "failed", "error": str(err).splitlines()[0], "seconds": time.perf_counter() - t0}
    last = summary["frames"][-1]
    return {**row, "status": "done", "seconds": time.perf_counter() - t0, "signature": last.get("signature"),
            "scene_hash": summary["scene_hash"]}


def finished(variant: Variant, out: Path) -> dict | None:
    """The summary of an earlier bake of ``variant`` in ``out`` when its scene hash matches the
    variant's resolved scene, else None."""
    from .bake import finished as finished_bake
    from .scene import load_scene

    try:
        scene = load_scene(variant.scene, overrides=variant.overrides)
    except (OSError, ValueError):
        return None
    return finished_bake(scene, out)


def client_for(scheduler: str | None, workers: int | None):
    """A dask.distributed Client: of the scheduler at ``scheduler``, else of a new LocalCluster of
    ``workers`` single-threaded processes (default: one per core)."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler, timeout="20s")
    n = workers or os.cpu_count() or 1
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0")
    return Client(cluster)


def run_batch(variants: list[Variant], out: Path, client, resume: bool = False, progress=None) -> list[dict]:
    """Bake ``variants`` into ``out/<name>`` on ``client`` (module docstring); writes and returns
    the rows of ``batch.json``. ``progress(row)`` is called as each variant ends."""
    from dask.distributed import as_completed

    out.mkdir(parents=True, exist_ok=True)
    workers = max(len(client.scheduler_info()["workers"]), 1)
    threads = max(1, (os.cpu_count() or 1) // workers)
    rows: dict[str, dict] = {}
    futures = {}
    for v in variants:
        folder = out / v.name
        done = finished(v, folder) if resume else None
        if done is not None:
            rows[v.name] = {"scene": v.scene, "overrides": v.overrides, "output": str(folder), "status": "skipped",
                            "seconds": 0.0, "signature": done["frames"][-1].get("signature"),
                            "scene_hash": done["scene_hash"]}
            if progress is not None:
                progress(rows[v.name])
            continue
        futures[client.submit(bake_variant, v, str(folder), threads, key=f"bake-{v.name}", retries=RETRIES,
                              pure=False)] = v
    for fut in as_completed(futures):
        v = futures[fut]
        try:
            rows[v.name] = fut.result()
        except Exception as err:  # the task itself failed (a worker died more than RETRIES times)
            rows[v.name] = {"scene": v.scene, "overrides": v.overrides, "output": str(out / v.name),
                            "status": "failed", "seconds": 0.0, "error": f"{type(err).__name__}: {err}".splitlines()[0]}
        if progress is not None:
            progress(rows[v.name])
    ordered = [rows[v.name] for v in variants]
    write_bytes(out / "batch.json", json.dumps(ordered, indent=2).encode("utf-8"), "batch summary")
    write_bytes(out / "batch.csv", _csv(ordered).encode("utf-8"), "batch summary")
    return ordered


def _csv(rows: list[dict]) -> str:
    sig_keys = sorted({k for r in rows for k in (r.get("signature") or {}) if not isinstance(r["signature"][k], list)})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["scene", "overrides", "status", "seconds", "output", "error"] + sig_keys)
    for r in rows:
        sig = r.get("signature") or {}
        w.writerow([r["scene"], json.dumps(r["overrides"], sort_keys=True), r["status"], round(r["seconds"], 3),
                    r["output"], r.get("error", "")] + [sig.get(k, "") for k in sig_keys])
    return buf.getvalue()
