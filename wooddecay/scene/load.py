"""Reading a scene: TOML text -> overrides -> a validated, frozen :class:`Scene` (docs/model.md §1).

:func:`load_scene` reads a file, :func:`parse_scene` takes TOML text or the mapping it parses
to; both check every value against :mod:`wooddecay.scene.schema` through
:mod:`wooddecay.scene.validate` and resolve it. The skeleton is loaded by
:func:`wooddecay.strands.skeleton_loader.load_skeleton` (the scene depends on strands, never
the other way round).

* Overrides (API ``overrides={"time.days": 30}`` or CLI ``--set key=value`` through
  :func:`parse_set_option`) are dotted keys (``strands.r_s``, ``tissue.heartwood.alpha_w0``,
  ``scene.seed``) applied to the parsed TOML *before* validation, so they are checked exactly
  like file values; errors about them name ``<overrides>`` / ``<--set>`` as the file.
* ``[scene] format`` (:data:`~wooddecay.scene.schema.FORMAT`) is checked first: a scene of a
  newer format than this wooddecay reads is refused in one line; a file without it is format 1.
* ``strands.connect_radius`` defaults to ``2.5 * r_s`` and must be >= ``2 * r_s``.
* Consistency: ``fungi.M_min < fungi.M_max``, ``moisture.M_2 < moisture.M_1`` and
  ``M_2 <= M_init <= M_1``, also for every tissue after its overrides.
* Quality: ``draft`` multiplies ``strands.r_s``, ``strands.rod_length`` and
  ``strands.connect_radius`` (given or defaulted) by 1.5 *after* validation, so downstream code
  reads one resolved value and the ratio connect_radius / r_s is kept; ``final`` leaves them.

Every bad input raises :class:`wooddecay.errors.InputError`; TOML syntax errors carry
tomllib's line and column. No other exception type escapes for any input.
"""
from __future__ import annotations

import copy
import math
import os
import re
import tomllib
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from wooddecay.errors import InputError, did_you_mean, format_value, type_name
from wooddecay.scene.schema import (
    ARRAY_TABLES,
    BARK_SPECIES,
    CONNECT_FACTOR,
    DAYS_PER_YEAR,
    DRAFT_SCALE,
    PARAMS,
    SECTIONS,
    TABLES,
    TISSUE_KEYS,
    TISSUE_SECTIONS,
    TOP_LEVEL,
)
from wooddecay.scene.types import FrozenMap, Scene, Section
from wooddecay.scene.validate import (
    check_connect_radius,
    check_format,
    check_moisture,
    check_species,
    unknown_key,
    validate_table,
    validate_value,
)
from wooddecay.strands.rings import TISSUES
from wooddecay.strands.skeleton_loader import load_skeleton

#: an explicit ``scene.name``: it names the output files, so no path
_FILE_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


class Overrides(dict):
    """A dict of dotted-key overrides that remembers where it came from (``<--set>``)."""

    def __init__(self, data: Mapping | None = None, source: str = "<overrides>"):
        super().__init__(data or {})
        self.source = source


def load_scene(path: str | os.PathLike, overrides: Mapping[str, Any] | None = None) -> Scene:
    """Read, validate and resolve the scene file at ``path``.

    ``overrides`` maps dotted keys to values (see the module docstring); a mapping made by
    :func:`parse_set_option` names ``<--set>`` in its errors, any other ``<overrides>``.
    Raises :class:`InputError` for anything wrong, including a missing or unreadable file.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InputError("<path>", "", f"expected a file path, got {type_name(path)} {format_value(path)}")
    try:
        p = Path(path)
        label = str(path) if isinstance(path, str) else str(p)
    except (TypeError, ValueError) as err:
        raise InputError("<path>", "", f"not a usable path: {err}") from None
    try:
        raw = p.read_bytes()
    except (OSError, ValueError) as err:
        why = getattr(err, "strerror", None) or str(err)
        raise InputError(label, "", f"cannot read the scene file: {why}") from None
    text = _decode(raw, label)
    return _parse(text, label, p.parent, p, overrides)


def parse_scene(text: str | bytes | Mapping[str, Any], source: str = "<string>",
                base_dir: str | os.PathLike = Path("."), overrides: Mapping[str, Any] | None = None) -> Scene:
    """Validate and resolve a scene given as TOML text (``bytes`` must be UTF-8) or as the
    mapping TOML text parses to (``tomllib.loads``; copied, not changed).

    ``source`` names the text in messages (and gives the default scene name when it looks like a
    file name); relative skeleton files are looked up in ``base_dir``.
    """
    source = str(source)
    if isinstance(text, Mapping):
        return _resolve_data(copy.deepcopy(dict(text)), source, Path(base_dir), None, overrides)
    if isinstance(text, (bytes, bytearray, memoryview)):
        text = _decode(bytes(text), source)
    elif not isinstance(text, str):
        raise InputError(source, "", f"expected TOML text, got {type_name(text)}")
    return _parse(text, source, Path(base_dir), None, overrides)


def parse_set_option(items: Sequence[str]) -> Overrides:
    """Turn CLI ``--set key=value`` strings into an overrides dict (source ``<--set>``).

    The value is parsed as a TOML value (``0.01``, ``true``, ``"x"``, ``[0, 0, -9.81]``),
    falling back to the plain (stripped) string. A malformed item raises
    ``InputError("<--set>", item, ...)``. Later items win over earlier ones.
    """
    out = Overrides(source="<--set>")
    if isinstance(items, (str, bytes)) or not isinstance(items, Sequence):
        raise InputError("<--set>", "", f"expected a list of key=value strings, got {type_name(items)}")
    for item in items:
        if not isinstance(item, str):
            raise InputError("<--set>", "", f"expected key=value strings, got {type_name(item)} {format_value(item)}")
        key, eq, value = item.partition("=")
        key = key.strip()
        parts = key.split(".")
        if not eq or len(parts) < 2 or any(not part for part in parts) or any(c.isspace() for c in key):
            raise InputError("<--set>", _item_label(item),
                             "expected section.key=value, e.g. strands.r_s=0.005 or tissue.heartwood.alpha_w0=0.01")
        out[key] = _parse_toml_value(value.strip())
    return out


def _item_label(item: str) -> str:
    text = " ".join(item.split())
    return text if len(text) <= 60 else text[:57] + "..."


def _parse_toml_value(text: str) -> Any:
    try:
        doc = tomllib.loads(f"v = {text}\n")
    except (tomllib.TOMLDecodeError, RecursionError, ValueError):
        return text
    if list(doc) != ["v"]:
        return text
    return doc["v"]


def _decode(raw: bytes, label: str) -> str:
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(label, "", f"not UTF-8 text (byte 0x{raw[err.start]:02x} at offset {err.start})") from None
    if text.startswith("\ufeff"):
        text = text[1:]
    return text


class _Ctx:
    """Where values came from: the scene file, or an overrides source per dotted key."""

    def __init__(self, file: str):
        self.file = file
        self.origin: dict[str, str] = {}

    def src(self, *keys: str) -> str:
        for k in keys:
            if k in self.origin:
                return self.origin[k]
        return self.file


def _parse(text: str, label: str, base_dir: Path, path: Path | None,
           overrides: Mapping[str, Any] | None) -> Scene:
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise InputError(label, "", f"TOML syntax error: {err}") from None
    except RecursionError:
        raise InputError(label, "", "TOML syntax error: nesting too deep") from None
    return _resolve_data(data, label, base_dir, path, overrides)


def _resolve_data(data: dict, label: str, base_dir: Path, path: Path | None,
                  overrides: Mapping[str, Any] | None) -> Scene:
    ctx = _Ctx(label)
    if overrides is not None:
        _apply_overrides(data, overrides, ctx)
    if path is not None:
        default_name = path.stem
    else:
        stem = Path(label).stem if label and not label.startswith("<") else ""
        default_name = stem or "scene"
    return _resolve(data, ctx, base_dir, path, default_name)


def _override_entry(data: dict, parts: list[str], key: str, value: Any, src: str) -> None:
    """``<table>.<index>.<key>[.<key>]`` (``inoculation.0.fungus``, ``load.1.region.radius``): set a
    key of an existing entry of an array table or of its region; the entry is validated with the
    rest of the scene."""
    head = parts[0]
    entries = data.get(head, [])
    if len(parts) not in (3, 4) or not parts[1].isdigit():
        raise InputError(src, key, f"entries are overridden as {head}.<index>.<key> or {head}.<index>.region.<key>, "
                         f"e.g. {head}.0.{'fungus' if head == 'inoculation' else 'region.radius'}")
    index = int(parts[1])
    if not isinstance(entries, list) or index >= len(entries):
        count = len(entries) if isinstance(entries, list) else 0
        raise InputError(src, key, f"the scene has {count} [[{head}]] entr{'y' if count == 1 else 'ies'}"
                         f"{f' (indices 0 to {count - 1})' if count else ''}, no index {index}")
    table = entries[index]
    if len(parts) == 4:
        table = table.get(parts[2]) if isinstance(table, dict) else None
        if not isinstance(table, dict):
            raise InputError(src, key, f"[[{head}]] entry {index} has no table {format_value(parts[2])}")
    if isinstance(table, dict):
        table[parts[-1]] = value


#: the two ways to give the simulated time: overriding one drops the other from the scene file
DURATION_KEYS = {"time.days": "time.years", "time.years": "time.days"}


def _apply_overrides(data: dict, overrides: Mapping[str, Any], ctx: _Ctx) -> None:
    src = getattr(overrides, "source", "<overrides>")
    if not isinstance(overrides, Mapping):
        raise InputError(src, "", f"expected a mapping of dotted keys, got {type_name(overrides)}")
    for raw_key, value in overrides.items():
        if not isinstance(raw_key, str):
            raise InputError(src, format_value(raw_key), f"override keys are dotted strings, got {type_name(raw_key)}")
        key = raw_key.strip()
        parts = key.split(".")
        head = parts[0]
        if head == "tissue":
            if len(parts) != 3:
                raise InputError(src, key, "tissue overrides are written tissue.<tissue>.<key>, e.g. tissue.heartwood.alpha_w0")
            _, tissue, name = parts
            if tissue not in TISSUES:
                raise InputError(src, key, f"unknown tissue {format_value(tissue)}; tissues are "
                                 f"{', '.join(TISSUES)}{did_you_mean(tissue, TISSUES)}")
            if name not in TISSUE_KEYS:
                raise InputError(src, key, f"{format_value(name)} cannot be set per tissue (only keys of "
                                 f"{', '.join('[' + s + ']' for s in TISSUE_SECTIONS)}){did_you_mean(name, TISSUE_KEYS)}")
            tables = data.setdefault("tissue", {})
            if not isinstance(tables, dict):
                raise InputError(ctx.file, "tissue", f"expected a table of tissues, got {type_name(tables)}")
            table = tables.setdefault(tissue, {})
            if not isinstance(table, dict):
                raise InputError(ctx.file, f"tissue.{tissue}", f"expected a table, got {type_name(table)}")
            table[name] = value
            ctx.origin[key] = src
            continue
        if head in ARRAY_TABLES:
            _override_entry(data, parts, key, value, src)
            ctx.origin[f"{head}[{parts[1]}]." + ".".join(parts[2:])] = src
            continue
        if head not in PARAMS:
            names = tuple(SECTIONS) + ("tissue",) + ARRAY_TABLES
            raise InputError(src, key, f"unknown section {format_value(head)}; overridable sections are "
                             f"{', '.join(SECTIONS)}, tissue and {', '.join(ARRAY_TABLES)}{did_you_mean(head, names)}")
        if len(parts) != 2:
            raise InputError(src, key, f"expected {head}.<key>")
        name = parts[1]
        if name not in PARAMS[head]:
            raise unknown_key(src, head, name, PARAMS[head])
        table = data.setdefault(head, {})
        if not isinstance(table, dict):
            raise InputError(ctx.file, head, f"expected a table [{head}], got {type_name(table)}")
        table[name] = value
        ctx.origin[key] = src
        other = DURATION_KEYS.get(f"{head}.{name}")
        if other is not None and other not in overrides:
            table.pop(other.partition(".")[2], None)  # an override of the duration replaces the file's


def _resolve(data: dict, ctx: _Ctx, base_dir: Path, path: Path | None, default_name: str) -> Scene:
    file = ctx.file
    fmt = check_format(data, ctx.src("scene.format"))  # first: a newer scene may have keys this one lacks
    for k in data:
        if k not in TOP_LEVEL:
            raise unknown_key(file, "", k, TOP_LEVEL)

    # -- scalar sections
    values: dict[str, dict[str, Any]] = {}
    for sec, table in PARAMS.items():
        raw = data.get(sec, {})
        if not isinstance(raw, dict):
            raise InputError(file, sec, f"expected a table [{sec}], got {type_name(raw)} {format_value(raw)}")
        for k in raw:
            if k not in table:
                raise unknown_key(ctx.src(f"{sec}.{k}"), sec, k, table)
        vals: dict[str, Any] = {}
        for name, p in table.items():
            key = p.key
            if name in raw:
                vals[name] = validate_value(p, raw[name], ctx.src(key), key)
            else:
                vals[name] = p.default
        values[sec] = vals

    # -- consistency of the sections
    strands = values["strands"]
    if strands["connect_radius"] is None:
        strands["connect_radius"] = CONNECT_FACTOR * strands["r_s"]
    else:
        check_connect_radius(strands, ctx.src)
    bark = values["bark"]
    for name, value in BARK_SPECIES[bark["species"]].items():
        if bark[name] is None:
            bark[name] = value
    check_moisture(values["fungi"], values["moisture"], ctx.src, prefix="", given=None)
    time = values["time"]
    if time["years"] > 0.0:
        days = time["years"] * DAYS_PER_YEAR
        if "days" in data.get("time", {}) and not math.isclose(time["days"], days, rel_tol=1e-9):
            raise InputError(ctx.src("time.days", "time.years"), "time.days",
                             f"{format_value(time['days'])} days disagrees with time.years = "
                             f"{format_value(time['years'])} ({format_value(days)} days); give one of the two")
        time["days"] = days

    mech = values["mechanics"]
    check_species(values["wood"]["species"], mech, data.get("mechanics", {}), ctx.src)
    if mech["connection_shear"] > 0.0 and mech["solver"] != "implicit":
        raise InputError(ctx.src("mechanics.connection_shear", "mechanics.solver"), "mechanics.connection_shear",
                         f"{format_value(mech['connection_shear'])} acts only with mechanics.solver = 'implicit' "
                         "(XPBD projects the paper's central connection, Eq. 2): set it to 0 or choose the implicit solver")

    frames = int(time["frames"])
    if not -frames <= values["export"]["gltf_frame"] < frames:
        raise InputError(ctx.src("export.gltf_frame", "time.frames"), "export.gltf_frame",
                         f"{format_value(values['export']['gltf_frame'])} is not a frame of the bake: allowed "
                         f"[{-frames}, {frames - 1}] with time.frames = {frames} (negative counts from the end)")

    # -- skeleton
    if "skeleton" not in data:
        raise InputError(file, "skeleton", "missing [skeleton] table (inline [[skeleton.node]] or file = \"...\")")
    skeleton = load_skeleton(data["skeleton"], base_dir, file, resolution=strands["r_s"])

    # -- tissues
    tissues = _resolve_tissues(data.get("tissue", {}), values, ctx)

    # -- inoculations, loads and colliders
    inoculations, loads, colliders = (_resolve_list(data, name, ctx, skeleton.ids) for name in ARRAY_TABLES)

    # -- quality preset (after validation)
    scene_vals = values["scene"]
    if scene_vals["quality"] == "draft":
        for name in ("r_s", "rod_length", "connect_radius"):
            strands[name] = strands[name] * DRAFT_SCALE
    name = scene_vals["name"] if scene_vals["name"] is not None else default_name
    if scene_vals["name"] is not None and not _FILE_NAME.fullmatch(name):
        raise InputError(file, "scene.name", f"{format_value(name)} must be a file name: letters, digits, '.', "
                         "'_' and '-', starting with a letter or digit (it names the output files)")

    sections = {sec: Section(sec, values[sec]) for sec in SECTIONS if sec != "scene"}
    return Scene(
        name=name,
        format=fmt,
        seed=scene_vals["seed"],
        quality=scene_vals["quality"],
        description=scene_vals["description"],
        path=path,
        base_dir=base_dir,
        source=file,
        skeleton=skeleton,
        tissues=tissues,
        inoculations=inoculations,
        loads=loads,
        colliders=colliders,
        **sections,
    )


def _resolve_tissues(raw: Any, values: dict[str, dict[str, Any]], ctx: _Ctx) -> FrozenMap:
    if not isinstance(raw, dict):
        raise InputError(ctx.file, "tissue", f"expected tables [tissue.<{'|'.join(TISSUES)}>], "
                         f"got {type_name(raw)} {format_value(raw)}")
    for t in raw:
        if t not in TISSUES:
            raise InputError(ctx.src(*(f"tissue.{t}.{k}" for k in (raw[t] if isinstance(raw[t], dict) else ()))),
                             f"tissue.{t}", f"unknown tissue {format_value(t)}; tissues are "
                             f"{', '.join(TISSUES)}{did_you_mean(t, TISSUES)}")
    out: dict[str, FrozenMap] = {}
    for t in TISSUES:
        table = raw.get(t, {})
        if not isinstance(table, dict):
            raise InputError(ctx.file, f"tissue.{t}", f"expected a table [tissue.{t}], got "
                             f"{type_name(table)} {format_value(table)}")
        over: dict[str, Any] = {}
        for name, v in table.items():
            key = f"tissue.{t}.{name}"
            if name not in TISSUE_KEYS:
                hint = did_you_mean(str(name), TISSUE_KEYS)
                if not hint and name in PARAMS:
                    hint = f"; write the keys of [{name}] directly, e.g. {next(iter(PARAMS[name]))} = ..."
                raise InputError(ctx.src(key), key, f"unknown key {format_value(str(name))} in [tissue.{t}] "
                                 f"(allowed: keys of {', '.join('[' + s + ']' for s in TISSUE_SECTIONS)}){hint}")
            if name == "species":
                raise InputError(ctx.src(key), key, "a species is the whole wood's (its rods are calibrated on "
                                 "clear wood of one species): set [wood] species instead")
            over[name] = validate_value(TISSUE_KEYS[name], v, ctx.src(key), key)
        if over:
            fungi = {**values["fungi"], **{k: v for k, v in over.items() if k in values["fungi"]}}
            moist = {**values["moisture"], **{k: v for k, v in over.items() if k in values["moisture"]}}
            check_moisture(fungi, moist, ctx.src, prefix=f"tissue.{t}.", given=set(over))
        out[t] = FrozenMap(over)
    return FrozenMap(out)


def _resolve_list(data: dict, name: str, ctx: _Ctx, node_ids: Sequence[str]) -> tuple[FrozenMap, ...]:
    """The entries of the array table ``name`` (``[[inoculation]]``, ...), each validated."""
    raw = data.get(name, [])
    if not isinstance(raw, list) or not all(isinstance(x, dict) for x in raw):
        raise InputError(ctx.file, name, f"expected an array of tables [[{name}]], got {type_name(raw)} "
                         f"{format_value(raw)}")
    return tuple(validate_table(TABLES[name], item, ctx.src(*(k for k in ctx.origin if k.startswith(f"{name}[{i}]."))),
                                f"{name}[{i}]", node_ids) for i, item in enumerate(raw))
