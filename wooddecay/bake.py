"""``wooddecay bake``: simulate, mesh and export a scene (docs/architecture.md "CLI").

:func:`bake` runs the model build, the coupled simulation (:class:`wooddecay.sim.driver.Simulation`),
the rest meshlets (:func:`wooddecay.meshlets.sweep.build_meshlets`) and the exporters, and writes
into ``out``:

* ``<name>.usdc`` (:func:`wooddecay.export.usd.export_usd`; unless ``export.usd`` is false) with
  the bark's crack map ``<name>_bark.<UDIM>.png`` beside it, a tile per frame
  (:mod:`wooddecay.export.bark_texture`), ``<name>.glb`` (the frame ``export.gltf_frame``, its
  pieces animated over every frame, :func:`wooddecay.export.gltf.export_gltf`; unless
  ``export.gltf`` is false; an output left out removes the earlier bake's) and ``summary.json``
  (counts, seconds per stage (the simulation's summed over the runs a resumed bake continues),
  threads, the schedule's macro steps, mechanics solves and seconds
  (:meth:`Simulation.schedule_summary`) and whether the settled rods came from the cache
  (:mod:`wooddecay.sim.settled`), the mechanics' convergence (:meth:`Simulation.convergence`),
  output sizes and ``bytes_per_element_frame`` (the stage's bytes over elements times frames), the build's notes
  (:attr:`WoodModel.notes`), and per frame the day, mass loss, moisture content ratio, crack
  statistics and strain excess);
* ``.bake/``: one small file per finished frame (fields and rod state) and the latest full
  simulation checkpoint. ``resume=True`` reloads the frames, continues the simulation from the
  checkpoint (bit-exact, see the driver) and gives the same outputs as an uninterrupted bake.

Every file is written to a temporary name and renamed, so a bake killed at any point leaves the
outputs of an earlier bake intact and never a half file. ``quality``: ``final`` runs the coupled
mechanics (cracks, breakage, debris); ``draft`` runs the biology alone on the rest geometry (a
fast preview of the decay fields; no cracks).
"""
from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path

import numpy as np

from . import budget
from .version import __version__
from .atomic import write_bytes
from .errors import InputError
from .export.gltf import export_gltf
from .export.usd import crack_map_files, export_usd
from .meshlets.sweep import build_meshlets
from .model import build_model
from .sim import settled
from .sim.driver import Frame, Simulation
from .sim.state import FIELDS
from .sim.threads import ThreadChoice

QUALITIES = ("draft", "final")
_MECH_KEYS = ("x", "q", "component", "element_ok", "edge_ok", "integrity")


def save_frame(path: Path, frame: Frame) -> None:
    """One frame's fields and rod state, atomically."""
    arrays = {f"field_{k}": v for k, v in frame.fields.items()}
    arrays.update({f"mech_{k}": v for k, v in frame.mech.items()})
    arrays.update({f"bark_{k}": v for k, v in frame.bark.items()})
    meta = {"index": frame.index, "t_days": frame.t_days, "diagnostics": frame.diagnostics}
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "wb") as fh:
        np.savez(fh, meta=np.array(json.dumps(meta)), **arrays)
    os.replace(tmp, path)


def load_frame(path: Path) -> Frame:
    with np.load(path) as z:
        meta = json.loads(str(z["meta"]))
        fields = {k: z[f"field_{k}"].copy() for k in FIELDS}
        mech = {k: z[f"mech_{k}"].copy() for k in _MECH_KEYS if f"mech_{k}" in z.files}
        bark = {k: z[f"bark_{k}"].copy() for k in ("cracked", "shed") if f"bark_{k}" in z.files}
    return Frame(index=meta["index"], t_days=meta["t_days"], fields=fields, mech=mech,
                 diagnostics=meta["diagnostics"], bark=bark)


def frame_summary(frame: Frame) -> dict:
    d = frame.diagnostics
    row = {"frame": frame.index, "t_days": round(frame.t_days, 6), "mass_loss": d["mass_loss"],
           "moisture_content_ratio": d["moisture_content_ratio"],
           "M_mean": float(np.mean(frame.fields["M"]))}
    if "mechanics" in d:
        row.update({k: d["mechanics"][k] for k in ("components", "broken_connections", "broken_elements",
                                                   "strain_excess", "equilibrium_residual")})
    if "signature" in d:
        row["signature"] = d["signature"]
    return row


def finished(scene, out) -> dict | None:
    """The ``summary.json`` of an earlier bake of ``scene`` in ``out`` (the same scene hash, a row
    per frame), else None. A bake writes its summary last, so a summary means the bake finished."""
    try:
        summary = json.loads((Path(out) / "summary.json").read_text("utf-8"))
    except (OSError, ValueError):
        return None
    if not (isinstance(summary, dict) and summary.get("scene_hash") == scene.hash):
        return None
    rows = summary.get("frames")
    return summary if isinstance(rows, list) and rows and all(isinstance(r, dict) for r in rows) else None


def bake(scene, out, resume: bool = False, quality: str = "final", progress=None, threads: int | None = None,
         max_memory: int | None = None, model=None, meshlets=None) -> dict:
    """Bake ``scene`` into the folder ``out`` (module docstring); returns the summary.

    ``progress(frame, n_frames)`` is called after every simulated frame. ``threads``: the numba
    thread count of the simulation, or None to pick it per macro step
    (:class:`wooddecay.sim.threads.ThreadChoice`). A scene whose estimated peak memory
    (:func:`wooddecay.budget.check`) exceeds ``max_memory`` bytes, or the memory available, is
    refused before anything is written. ``model``: the scene's built model, if the caller holds it
    (:func:`wooddecay.model.retimed`; a batch shares one between variants). ``meshlets``: the
    model's rest meshlets, if the caller holds them (they depend on the wood alone: a batch worker
    keeps them for the variants of the same ``Scene.settle_hash``).
    """

    if quality not in QUALITIES:
        raise InputError(str(out), "--quality", f"must be one of {', '.join(QUALITIES)}, not {quality!r}")
    budget.check(scene, max_memory)
    out = Path(out)
    created = not out.exists()
    started = time.time()
    try:
        return _bake(scene, out, resume, quality, progress, threads, model, meshlets)
    except BaseException as err:
        # a bake that fails before its first frame leaves nothing; a later failure keeps the frames
        # and the checkpoint for --resume, and says so
        ckpt = out / ".bake" / "checkpoint.npz"
        if created and not ckpt.exists():
            shutil.rmtree(out, ignore_errors=True)
        elif ckpt.exists() and (resume or ckpt.stat().st_mtime >= started - 1.0):
            done = len(list(ckpt.parent.glob("frame_*.npz")))
            err.add_note(f"the bake stopped after {done} of {int(scene.time.frames)} frames; its frames and "
                         f"checkpoint are kept in {ckpt.parent}: bake again with --resume to continue")
        raise


def _bake(scene, out: Path, resume: bool, quality: str, progress, threads: int | None, model=None,
          meshlets=None) -> dict:
    work = out / ".bake"
    try:
        work.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(str(out), "", f"cannot create the output folder: {err}") from None
    ckpt = work / "checkpoint.npz"
    seconds = {}
    choice = ThreadChoice(threads)  # before the build: its load monitor's first window
    t0 = time.perf_counter()
    if model is None:
        model = build_model(scene)
    elif model.info.hash != scene.hash:
        raise ValueError("the model given to bake() is not the scene's")
    if meshlets is not None and meshlets.count != model.n_elements:
        raise ValueError("the meshlets given to bake() are not the model's")
    seconds["build"] = time.perf_counter() - t0
    mechanics = quality == "final"

    t0 = time.perf_counter()
    frames: list[Frame] = []
    if resume and ckpt.exists():
        try:
            sim = Simulation.resume(model, ckpt, threads=choice)
        except ValueError as err:
            raise InputError(str(ckpt), "", f"{err}; bake without --resume to start over") from None
        frames = [load_frame(work / f"frame_{k:05d}.npz") for k in range(sim.last_frame + 1)]
    else:
        for stale in work.glob("*.npz"):
            stale.unlink()
        sim = Simulation(model, mechanics=mechanics, threads=choice, settle_cache=settled.default_folder())
    n_frames = int(scene.time.frames)
    before = sim.wall_seconds  # of the runs this one resumes
    for fr in sim.run():
        save_frame(work / f"frame_{fr.index:05d}.npz", fr)
        sim.wall_seconds = before + time.perf_counter() - t0
        sim.save_checkpoint(ckpt)
        frames.append(fr)
        if progress is not None:
            progress(fr, n_frames)
    seconds["simulation"] = before + time.perf_counter() - t0

    t0 = time.perf_counter()
    mesh = build_meshlets(model) if meshlets is None else meshlets
    seconds["meshing"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    ex = scene.export
    usd, glb = out / f"{scene.name}.usdc", out / f"{scene.name}.glb"
    written = []
    if ex.usd:
        export_usd(usd, model, mesh, frames, version=__version__, point_tolerance=ex.point_tolerance,
                   field_step=ex.field_step)
        written += [usd, *crack_map_files(usd)]
    else:  # an earlier bake's stage would pass for this one's
        for p in [usd, *crack_map_files(usd)]:
            p.unlink(missing_ok=True)
    if ex.gltf:
        written.append(export_gltf(glb, model, mesh, frames[ex.gltf_frame], version=__version__, frames=frames,
                                   point_tolerance=ex.point_tolerance))
    else:
        glb.unlink(missing_ok=True)
    seconds["export"] = time.perf_counter() - t0

    outputs = {p.name: {"path": str(p), "bytes": p.stat().st_size} for p in written}
    summary = {
        "wooddecay_version": __version__, "scene": scene.name, "seed": int(scene.seed),
        "scene_hash": scene.hash, "quality": quality, "threads": choice.summary(),
        "schedule": sim.schedule_summary(), "convergence": sim.convergence(frames),
        "counts": {"strands": model.n_strands, "elements": model.n_elements, "reg_edges": model.n_edges,
                   "meshlets": mesh.count, "meshlet_faces": mesh.n_faces, "frames": len(frames)},
        "seconds": {k: round(v, 3) for k, v in seconds.items()},
        "outputs": outputs,
        "bytes_per_element_frame": (round(usd.stat().st_size / max(model.n_elements * len(frames), 1), 1)
                                    if ex.usd else None),
        "frames": [frame_summary(f) for f in frames],
        "notes": list(model.notes),
    }
    write_bytes(out / "summary.json", json.dumps(summary, indent=2).encode("utf-8"), "summary")
    return summary
