"""The settled-state cache: the wood at the start of a coupled bake, the bark's day-0 cracks
(:func:`wooddecay.sim.bark.initial`) and the rods after :func:`wooddecay.sim.mechanics.settle`,
stored by the hash of everything the rods depend on (``model.info.settle_hash``: the scene
without [time], [export], [climate], [bark] and its name and description), so bakes of the same
wood with other days, frames, schedules, climates or outputs, and re-bakes, skip both (settling is
0.2 s of mechanics, 2,000 substeps: 40% of an adaptive year of the log; the tree's bark cracks
14 s). The bark's cracks depend on the wood and the resolved [bark] section (``model.bark_setup``,
stored in the file): of another [bark] they are cracked again, the rods loaded.

The cache is a folder of ``<settle_hash>.npz`` files, each the mechanics arrays a checkpoint
holds plus the clock, and the bark's arrays (``bark_*``), written to a temporary name and renamed.
A file that cannot be read, of another version, hash or shape, or written by other code (the
hash of the package's sources, :func:`code_hash`), is settled again and replaced: a state that
older code settled would otherwise start a bake of newer code from other bits.
Loading gives the bits settling gives (every kernel is deterministic), so a bake is the same with
and without the cache.
"""
from __future__ import annotations

import functools
from dataclasses import asdict
import json
import os
from pathlib import Path
from typing import cast

import numpy as np

from ..wood import BarkSetup, WoodModel
from ..atomic import cache_home, read_archive, replace_with, tree_hash
from ..errors import InputError
from . import bark
from . import implicit, mechanics

VERSION = 5
#: environment variable naming the cache folder ("" or "off": no cache)
ENV = "WOODDECAY_CACHE"


@functools.cache
def code_hash() -> str:
    """:func:`~wooddecay.atomic.tree_hash` of this package's Python sources, once per process: the
    settled state depends on the code besides the scene."""
    return tree_hash(Path(__file__).resolve().parent.parent, "*.py")


def default_folder() -> Path | None:
    """``$WOODDECAY_CACHE``, else ``$XDG_CACHE_HOME/wooddecay/settled`` (``~/.cache/...``);
    None when the variable is "" or "off"."""
    value = os.environ.get(ENV)
    if value is not None:
        return None if value.strip() in ("", "off") else Path(value)
    return cache_home() / "settled"


def settle(model: WoodModel, state, folder: Path | None, run=None) -> str:
    """Crack the bark of ``state`` at day 0 (:func:`bark.initial`) and settle its rods
    (:func:`mechanics.settle` with the model's time and damping, chunks through ``run``, or
    :func:`implicit.settle` for ``mechanics.solver = "implicit"``), or load
    them from ``folder``; store what was computed there. Returns "cached" (the rods loaded) or
    "settled"."""
    path = None if folder is None else Path(folder) / f"{model.info.settle_hash}.npz"
    rods, cracks = _load(path, model, state) if path is not None else (False, False)
    if not cracks:
        state.bark = bark.initial(model, state)
    if not rods and model.mech.solver == "implicit":
        implicit.settle(model, state)
    elif not rods:
        mechanics.settle(model, state, model.time.settle, model.time.settle_damping, run=run)
    if path is not None and not (rods and cracks):
        _save(path, model, state)
    return "cached" if rods else "settled"


def _bark_key(model: WoodModel) -> str | None:
    """What the day-0 cracks depend on beyond the wood: the resolved [bark] section."""
    return None if model.bark is None else json.dumps(asdict(cast(BarkSetup, model.bark_setup)), sort_keys=True, default=str)


def _bark_arrays(bark_state) -> dict:
    """The bark's arrays as the file holds them (``bark_*``; none without a sheet)."""
    return {} if bark_state is None else {f"bark_{k}": v for k, v in bark_state.arrays().items()}


def _matches(arrays: dict, own: dict) -> bool:
    return all(k in arrays and arrays[k].shape == v.shape and arrays[k].dtype == v.dtype for k, v in own.items())


def _load(path: Path, model, state) -> tuple[bool, bool]:
    """Restore the rods and the bark from ``path`` where they match; (rods loaded, bark loaded)."""
    try:
        meta, arrays = read_archive(path)
    except ValueError:
        return False, False
    if (meta.get("version") != VERSION or meta.get("settle_hash") != model.info.settle_hash
            or meta.get("code") != code_hash() or not isinstance(meta.get("t_seconds"), float)
            or not isinstance(meta.get("failures"), int)):
        return False, False
    rods = state.mech.arrays()
    if not _matches(arrays, rods):
        return False, False
    state.mech.restore({k: arrays[k] for k in rods}, meta["t_seconds"], meta["failures"])
    bark_now = bark.uncracked(model, state)
    if bark_now is None:
        return True, True
    if meta.get("bark") != _bark_key(model) or not _matches(arrays, _bark_arrays(bark_now)):
        return True, False
    state.bark = bark.BarkState.from_arrays({k: arrays[f"bark_{k}"] for k in bark_now.arrays()})
    return True, True


def _save(path: Path, model, state) -> None:
    ms = state.mech
    meta = {"version": VERSION, "settle_hash": model.info.settle_hash, "code": code_hash(), "bark": _bark_key(model),
            "t_seconds": ms.t_seconds, "failures": ms.failures}

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as fh:
            np.savez(fh, meta=np.array(json.dumps(meta)), **ms.arrays(), **_bark_arrays(state.bark))

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        replace_with(path, write, "settled-state cache")
    except (OSError, InputError):
        return  # a cache that cannot be written only costs the next bake its settling
