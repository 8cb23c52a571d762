"""One bake of a gallery scene and its renders: what the figures (:mod:`.run`) and the sensitivity
study (:mod:`.sensitivity`) share."""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

from .. import render
from ..bake import bake, finished, load_frame
from ..errors import InputError
from ..model import build_model
from ..scene import load_scene
from ..sim.threads import requested_threads
from . import pool
from .pool import SCENES

#: the gallery's scenes
#: panels smaller and with fewer samples than render_bake's defaults: a gallery renders dozens
PANEL_OPTIONS = ("--width", "480", "--height", "270", "--samples", "12", "--max-kb", "90")


@dataclass
class Baked:
    """A gallery bake: its scene, ``summary.json``, the frames (:func:`wooddecay.bake.load_frame`),
    the USD path, the seconds it took (of the earlier bake where reused) and whether it was reused.
    Its model is built on first use: a bake made ahead or reused needs one only for a figure's
    own statistic (the tree figures and the sensitivity study read none; a tree's build is ~11 s)."""

    scene: object
    summary: dict
    frames: list
    usd: Path
    seconds: float
    reused: bool
    built: object = None  # the model, where the bake built it here

    @cached_property
    def model(self):
        return self.built if self.built is not None else build_model(self.scene)


def bake_scene(scene_file: str, overrides: dict, folder: Path, resume: bool = False, reuse: tuple = (),
               threads: int | None = None) -> Baked:
    """Bake ``samples/gallery/<scene_file>`` with ``overrides`` into ``folder`` on ``threads``
    (:func:`wooddecay.bake.bake`; None: ``$WOODDECAY_THREADS``, else auto), or take the bake made
    ahead into ``folder`` (:func:`.pool.take`). A finished bake of the same scene
    (:func:`wooddecay.bake.finished`, its frames and USD file there) in one of the folders
    ``reuse``, or with ``resume`` in ``folder``, is reused; with ``resume`` an unfinished one in
    ``folder`` is continued from its checkpoint."""
    scene = load_scene(SCENES / scene_file, overrides=overrides)
    ahead = pool.take(folder)
    t0 = time.perf_counter()
    if ahead is not None:
        done = finished_bake(scene, folder)
        if done is None:
            raise RuntimeError(f"the bake made ahead into {folder} is not a finished bake of its scene")
        summary, frames, usd = done
        return Baked(scene, summary, [load_frame(p) for p in frames], usd, ahead, False)
    for earlier in (*reuse, *((folder,) if resume else ())):
        done = finished_bake(scene, Path(earlier))
        if done is not None:
            summary, frames, usd = done
            seconds = sum(v for v in summary.get("seconds", {}).values() if isinstance(v, (int, float)))
            return Baked(scene, summary, [load_frame(p) for p in frames], usd, float(seconds), True)
    model = build_model(scene)
    threads = requested_threads(None) if threads is None else threads
    try:
        summary = bake(scene, folder, resume=resume, model=model, threads=threads)
    except InputError:
        if not resume:
            raise
        summary = bake(scene, folder, model=model, threads=threads)  # its checkpoint is of another scene: start over
    frames = sorted((folder / ".bake").glob("frame_*.npz"))
    return Baked(scene, summary, [load_frame(p) for p in frames], folder / f"{scene.name}.usdc",
                 time.perf_counter() - t0, False, model)


def pending(job: pool.Job) -> bool:
    """Whether ``job`` must bake: always without ``job.resume``, else unless ``job.folder`` holds
    a finished bake of its scene (:func:`finished_bake`)."""
    return not job.resume or finished_bake(load_scene(SCENES / job.scene_file, overrides=job.overrides),
                                           job.folder) is None


def finished_bake(scene, folder: Path) -> tuple[dict, list, Path] | None:
    """The summary, frame files and USD file of a finished final-quality bake of ``scene`` in
    ``folder``, else None."""
    summary = finished(scene, folder)
    if summary is None or summary.get("quality") != "final":
        return None
    frames = sorted((folder / ".bake").glob("frame_*.npz"))
    usd = folder / f"{scene.name}.usdc"
    return (summary, frames, usd) if len(frames) == len(summary["frames"]) and usd.is_file() else None


def frame_rows(summary: dict) -> list[dict]:
    """Per frame: day, broken connections and signature (of ``summary.json``)."""
    return [{"t_days": f["t_days"], "broken_connections": f["broken_connections"], "signature": f["signature"]}
            for f in summary["frames"]]


def render_panel(usd: Path, png: Path, frame: int, options=()) -> None:
    """One panel of ``usd`` at ``frame`` (PANEL_OPTIONS, then ``options``)."""
    render.render_bake(usd, png, frame=frame, options=(*PANEL_OPTIONS, *options))


def timed_bake(job: pool.Job, threads: int) -> float:
    """One job in a worker of :func:`.pool.baking_ahead`; its wall seconds."""
    t0 = time.perf_counter()
    bake_scene(job.scene_file, job.overrides, job.folder, job.resume, threads=threads)
    return time.perf_counter() - t0
