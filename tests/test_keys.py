"""Every key does what it says (issue 84): each key of the scene schema, moved away from its value
in a small bake, changes what the bake writes (its frames' fields and rods, the bark, the
signature, the files, the stage's wood, metadata and the glTF's buffer) by more than TOLERANCE.

The base is ``tests/data/keys.toml`` (the tiny log with both fungi, 6 days, 2 frames). A key that
acts only in some scenes says when in :data:`wooddecay.scene.schema.CONDITIONAL`, with the
overrides that make the base such a scene; the test moves it under those. A key is moved to each
value of :func:`away` in turn until one changes the bake; a value validation refuses is passed
over. The optional keys of the entry tables are moved in the base's white-rot inoculation.
"""
from __future__ import annotations

import json
import math
import struct
import tomllib
from pathlib import Path

import numpy as np
import pytest

from wooddecay.bake import bake, load_frame
from wooddecay.errors import InputError
from wooddecay.export.wood_read import wood_at
from wooddecay.scene import parse_scene
from wooddecay.scene import schema as S

BASE = Path(__file__).parent / "data" / "keys.toml"
#: a bake changes when an array of its outputs moves by more than this (m, or a field's unit)
TOLERANCE = 1e-9
#: entry-table keys with a default: (table, key) moved in the base's second inoculation
ENTRY_KEYS = (("inoculation", "activity"), ("inoculation", "day"), ("region", "which"), ("region", "space"))
#: the white-rot inoculation's region under which ``region.space`` can act: a sphere (an ``end``
#: region is placed along the skeleton whatever the space)
SPHERE = {"kind": "sphere", "center": [0.27, 0.0, 0.06], "radius": 0.04}
#: values for kinds :func:`away` cannot derive
OTHER = {"mechanics.gravity": [[0.0, 0.0, -5.0]], "moisture.schedule": [[[0.0, 1.0, 0.1], [3.0, 0.5, 0.3]]],
         "climate.seasons": [[[0.0, 1.0, 1.0, 1.0], [180.0, 0.2, 3.0, 0.2]]], "scene.name": ["other"],
         "scene.description": ["another description"]}


def away(p: S.Param, current) -> list:
    """Values of ``p`` other than ``current``, nearest first, within its range."""
    if p.key in OTHER:
        return OTHER[p.key]
    if p.kind == "bool":
        return [not current]
    if p.kind == "enum":
        return [c for c in p.choices if c != current]
    if p.kind not in ("int", "float"):
        raise AssertionError(f"{p.key}: kind {p.kind} has no away values")
    x = float(current)
    top = p.hi if p.hi is not None and math.isfinite(p.hi) else 1.0
    steps = [x * f for f in (1.5, 0.5, 0.1, 10.0, 0.01, 100.0, 0.001)] if x else [top * f for f in (0.01, 0.1, 0.5, 1)]
    if p.kind == "int":
        steps = [x + 1, x - 1, x * 2, x + 5]
    out = []
    for v in steps:
        v = int(round(v)) if p.kind == "int" else v
        lo_ok = p.lo is None or v > p.lo or (v == p.lo and not p.lo_open)
        hi_ok = p.hi is None or v < p.hi or (v == p.hi and not p.hi_open)
        if lo_ok and hi_ok and v != current and v not in out and math.isfinite(v):
            out.append(v)
    return out


def _data() -> dict:
    return tomllib.loads(BASE.read_text("utf-8"))


def _scene(data: dict, overrides: dict):
    """The scene of ``data`` with ``overrides``: dotted scene keys, or ``skeleton.node.<i>.<key>``
    (a node's key, which dotted scene keys do not reach)."""
    data = json.loads(json.dumps(data))
    for key in [k for k in overrides if k.startswith("skeleton.node.")]:
        _, _, i, name = key.split(".")
        data["skeleton"]["node"][int(i)][name] = overrides[key]
    scene_keys = {k: v for k, v in overrides.items() if not k.startswith("skeleton.node.")}
    return parse_scene(data, source=str(BASE), base_dir=BASE.parent, overrides=scene_keys)


def digest(out: Path) -> dict:
    """Everything a bake in ``out`` wrote that a user sees, as named arrays and values."""
    from pxr import Usd

    d: dict = {"files": sorted(p.name for p in out.iterdir() if not p.name.startswith("."))}
    for k, path in enumerate(sorted((out / ".bake").glob("frame_*.npz"))):
        fr = load_frame(path)
        d[f"frame{k}.t_days"] = np.array([fr.t_days])
        for group in ("fields", "mech", "bark"):
            for name, v in getattr(fr, group).items():
                d[f"frame{k}.{group}.{name}"] = np.asarray(v)
    summary = json.loads((out / "summary.json").read_text())
    d["signature"] = json.dumps([row.get("signature") for row in summary["frames"]], sort_keys=True)
    for usd in out.glob("*.usdc"):
        stage = Usd.Stage.Open(str(usd))
        d["usd.fps"] = np.array([stage.GetTimeCodesPerSecond()])
        d["usd.documentation"] = stage.GetRootLayer().documentation
        for t in range(int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode()) + 1):
            for name, v in wood_at(stage, t).items():
                d[f"usd{t}.{name}"] = v
    for glb in out.glob("*.glb"):
        raw = glb.read_bytes()
        n_json = struct.unpack_from("<I", raw, 12)[0]
        doc = json.loads(raw[20:20 + n_json])
        d["gltf.description"] = doc["asset"]["extras"]["description"]
        d["gltf.bin"] = np.frombuffer(raw[20 + n_json + 8:], dtype=np.uint8)
    return d


def difference(a: dict, b: dict) -> float:
    """The largest change between two digests (inf where a name, a shape or a string differs)."""
    if a.keys() != b.keys():
        return math.inf
    worst = 0.0
    for name, x in a.items():
        y = b[name]
        if isinstance(x, (str, list)) or isinstance(y, (str, list)):
            worst = max(worst, 0.0 if x == y else math.inf)
        elif x.shape != y.shape:
            return math.inf
        elif x.size:
            diff = np.abs(x.astype(np.float64) - y.astype(np.float64))
            worst = max(worst, float(np.nanmax(np.where(np.isnan(x) != np.isnan(y), np.inf, diff))))
    return worst


_BAKES: dict[str, dict] = {}


def baked(tmp: Path, data: dict, overrides: dict) -> dict | None:
    """The digest of a bake of ``data`` with ``overrides`` (cached); None when validation refuses."""
    key = json.dumps([data, overrides], sort_keys=True, default=str)
    if key not in _BAKES:
        try:
            scene = _scene(data, overrides)
        except InputError:
            return None
        out = tmp / f"bake{len(_BAKES)}"
        bake(scene, out, threads=1)
        _BAKES[key] = digest(out)
    return _BAKES[key]


def _scalar_keys() -> list[S.Param]:
    return [p for table in S.PARAMS.values() for p in table.values()]


def _changes(tmp: Path, data: dict, overrides: dict, moves: list[tuple[dict, dict]]) -> list[str]:
    """Bake the base (``data`` with ``overrides``) and each move (data, overrides) in turn until one
    changes it; the moves tried, each with its largest change."""
    base = baked(tmp, data, overrides)
    assert base is not None, "the base scene is refused"
    tried = []
    for move_data, move in moves:
        other = baked(tmp, move_data, {**overrides, **move})
        if other is None:
            tried.append(f"{move} refused")
            continue
        change = difference(base, other)
        tried.append(f"{move}: {change:.3g}")
        if change > TOLERANCE:
            return []
    return tried


@pytest.mark.slow
@pytest.mark.parametrize("p", _scalar_keys(), ids=lambda p: p.key)
def test_each_scene_key_changes_the_bake(tmp_path_factory, p):
    if p.key == "scene.format":  # how the file is read; one value is allowed
        assert (p.lo, p.hi) == (S.FORMAT_MIN, S.FORMAT) and S.FORMAT_MIN == S.FORMAT
        return
    tmp = tmp_path_factory.mktemp("keys")
    data = _data()
    when, overrides = S.CONDITIONAL.get(p.key, ("", {}))
    if p.key == "time.years":  # days in other units: the base gives days, this its years
        days = data["time"].pop("days")
        years = {**data, "time": dict(data["time"])}
        assert difference(baked(tmp, years, {**overrides, "time.years": days / 365.25}),
                          baked(tmp, _data(), overrides)) == 0
        moves = [(years, {"time.years": 2 * days / 365.25})]
        data = years
        overrides = {**overrides, "time.years": days / 365.25}
    else:
        scene = _scene(data, overrides)
        current = getattr(scene if p.section == "scene" else getattr(scene, p.section), p.name)
        moves = [(data, {p.key: v}) for v in away(p, current)]
    tried = _changes(tmp, data, overrides, moves)
    assert not tried, f"{p.key} changes nothing{' ' + when if when else ''}: {'; '.join(tried)}"


@pytest.mark.slow
@pytest.mark.parametrize("table,key", ENTRY_KEYS, ids=lambda v: v)
def test_each_entry_key_changes_the_bake(tmp_path_factory, table, key):
    tmp = tmp_path_factory.mktemp("keys")
    data = _data()
    if key == "space":
        data["inoculation"][1]["region"] = dict(SPHERE)
    entry = data["inoculation"][1] if table == "inoculation" else data["inoculation"][1]["region"]
    p = S.TABLES[table].keys_of(entry.get("kind") if table == "region" else None)[key]
    current = entry.get(key, p.default)
    moves = []
    for v in away(p, current):
        moved = json.loads(json.dumps(data))
        (moved["inoculation"][1] if table == "inoculation" else moved["inoculation"][1]["region"])[key] = v
        moves.append((moved, {}))
    tried = _changes(tmp, data, {}, moves)
    assert not tried, f"{table}.{key} changes nothing: {'; '.join(tried)}"
