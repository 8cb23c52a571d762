"""The scene: one TOML file -> a validated, frozen :class:`Scene` (SPEC §1).

A scene describes one simulation: the skeleton graph G (woodstock §3, Fig. 3a) and every
parameter of the paper's Table 3 (woodstock), each a key named after its symbol with the Table 3
typical value as default. The schema (keys, defaults, units, ranges, docs) lives in
:mod:`wooddecay.params`; ``wooddecay.params.describe()`` prints it.

Sections
--------
``[scene]``        name (default: file stem), seed (int >= 0), quality (``draft`` | ``final``),
                   description.
``[skeleton]``     inline ``[[skeleton.node]]`` or ``file = ...`` (see
                   :func:`wooddecay.strands.skeleton.load_skeleton`).
``[strands] [rings] [bsp] [weakpoints] [transport] [fungi] [moisture] [wood] [mechanics]
[time] [export]``  scalar parameters (:data:`wooddecay.params.PARAMS`).
``[tissue.<bark|sapwood|heartwood|pith>]``
                   per-tissue overrides of any key of [fungi], [moisture], [mechanics],
                   [transport], [wood] (bare names, e.g. ``alpha_w0 = 0.01``), validated against
                   that key's range.
``[[inoculation]]`` ``fungus`` (``white`` | ``brown``, required), ``activity`` in (0, 1]
                   (default 0.1), ``day`` >= 0 (default 0), ``region`` (required, below).
``[[load]]``       ``region``, ``force`` [x, y, z] N, ``days`` [start, end] with
                   0 <= start < end (all required).
``[[collider]]``   a solid obstacle for the rods (woodstock §5.1): ``kind`` = ``plane``
                   (``point``, ``normal``), ``box`` (axis-aligned ``min``, ``max``), ``sphere``
                   (``center``, ``radius``) or ``cylinder`` (axis ``a`` to ``b``, ``radius``).
                   The ground plane is ``[mechanics] ground`` / ``ground_height``.

A region is a table with ``kind`` and ``space`` (``world`` | ``wood``, default ``world``):
``box`` (``min``, ``max``: [x, y, z], min < max componentwise), ``sphere`` (``center``,
``radius`` > 0 m), ``node`` (``id`` of a skeleton node, ``radius`` > 0 m), ``end``
(``which`` = ``root`` | ``tip``, default ``root``; ``depth`` > 0 m) and ``wound`` (``position``,
``radius`` > 0 m, ``depth`` > 0 m). In ``wood`` space coordinates are wood-local (r, phi, s).

Resolution
----------
* Overrides (API ``overrides={"time.days": 30}`` or CLI ``--set key=value`` through
  :func:`parse_set_option`) are dotted keys (``strands.r_s``, ``tissue.heartwood.alpha_w0``,
  ``scene.seed``) applied to the parsed TOML *before* validation, so they are checked exactly like
  file values; errors about them name ``<overrides>`` / ``<--set>`` as the file.
* ``strands.connect_radius`` defaults to ``2.5 * r_s`` and must be >= ``2 * r_s``.
* Consistency: ``fungi.M_min < fungi.M_max``, ``moisture.M_2 < moisture.M_1`` and
  ``M_2 <= M_init <= M_1``, also for every tissue after its overrides.
* Quality: ``draft`` multiplies ``strands.r_s``, ``strands.rod_length`` and
  ``strands.connect_radius`` (given or defaulted) by 1.5 *after* validation, so downstream code
  reads one resolved value and the ratio connect_radius / r_s is kept; ``final`` leaves them.

Errors
------
Every bad input raises :class:`wooddecay.errors.InputError` ``(file, key, message)`` whose one
line names the file, the dotted key and what is allowed, e.g.
``samples/log.toml: strands.r_s: -1 is outside (0, 1] m`` or
``log.toml: fungi.alpah_w0: unknown key 'alpah_w0' in [fungi]; did you mean 'alpha_w0'?``.
Booleans are not numbers; NaN and infinities are rejected; TOML syntax errors carry tomllib's
line and column. No other exception type escapes for any input.
"""
from __future__ import annotations

import copy
import hashlib
import json
import os
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, Iterator

from wooddecay.errors import InputError
from wooddecay.params import (
    PARAMS,
    SECTIONS,
    TISSUE_KEYS,
    TISSUE_SECTIONS,
    TISSUES,
    did_you_mean,
    format_range,
    format_value,
    make_param,
    type_name,
    validate_value,
)

__all__ = [
    "Scene",
    "Section",
    "FrozenMap",
    "Overrides",
    "load_scene",
    "parse_scene",
    "parse_set_option",
    "DRAFT_SCALE",
    "REGION_KINDS",
]

#: Factor applied to strand lengths (r_s, rod_length, connect_radius) by ``quality = "draft"``.
DRAFT_SCALE = 1.5
#: Default connect_radius in units of r_s, and the smallest allowed.
CONNECT_FACTOR = 2.5
CONNECT_MIN_FACTOR = 2.0

_TOP_LEVEL = tuple(SECTIONS) + ("skeleton", "tissue", "inoculation", "load", "collider")


# ---------------------------------------------------------------------------------------------
# Read-only containers
# ---------------------------------------------------------------------------------------------
class FrozenMap(Mapping):
    """A read-only, picklable mapping."""

    __slots__ = ("_d",)

    def __init__(self, data: Mapping | Sequence = ()):
        object.__setattr__(self, "_d", dict(data))

    def __getitem__(self, key: str) -> Any:
        return self._d[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._d)

    def __len__(self) -> int:
        return len(self._d)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"{type(self).__name__} is read-only")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"{type(self).__name__} is read-only")

    def __reduce__(self):
        return (type(self), (self._d,))

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._d!r})"

    def as_dict(self) -> dict:
        """A plain, JSON-able copy (tuples become lists, nested maps become dicts)."""
        return {k: _jsonable(v) for k, v in self._d.items()}


class Section(FrozenMap):
    """One parameter section as a read-only attribute namespace: ``scene.strands.r_s``."""

    __slots__ = ("_name",)

    def __init__(self, name: str, data: Mapping):
        object.__setattr__(self, "_name", name)
        super().__init__(data)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._d[name]
        except KeyError:
            raise AttributeError(f"[{self._name}] has no parameter {name!r}"
                                 f"{did_you_mean(name, self._d)}") from None

    def __dir__(self):
        return list(super().__dir__()) + list(self._d)

    def __reduce__(self):
        return (type(self), (self._name, self._d))

    def __repr__(self) -> str:
        return f"Section[{self._name}]({self._d!r})"


class Overrides(dict):
    """A dict of dotted-key overrides that remembers where it came from (``<--set>``)."""

    def __init__(self, data: Mapping | None = None, source: str = "<overrides>"):
        super().__init__(data or {})
        self.source = source


def _jsonable(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, Path):
        return str(v)
    return v


# ---------------------------------------------------------------------------------------------
# The Scene
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Scene:
    """A validated scene; every value resolved (defaults, overrides, quality preset).

    Sections are read-only namespaces (``scene.fungi.alpha_w0``, ``scene.time.days``,
    ``scene.strands.as_dict()``). Compare scenes by :attr:`hash`.
    """

    name: str
    seed: int
    quality: str
    description: str
    path: Path | None
    base_dir: Path
    source: str
    skeleton: Any  # wooddecay.strands.skeleton.Skeleton
    strands: Section
    rings: Section
    bsp: Section
    weakpoints: Section
    transport: Section
    fungi: Section
    moisture: Section
    wood: Section
    mechanics: Section
    time: Section
    export: Section
    tissues: FrozenMap  # tissue -> FrozenMap of overrides (all four tissues present)
    inoculations: tuple[FrozenMap, ...]
    loads: tuple[FrozenMap, ...]
    colliders: tuple[FrozenMap, ...]

    def section(self, name: str) -> Section:
        """The :class:`Section` called ``name`` (``scene`` gives name/seed/quality/description)."""
        if name == "scene":
            return Section("scene", {"name": self.name, "seed": self.seed, "quality": self.quality,
                                     "description": self.description})
        if name not in SECTIONS:
            raise KeyError(name)
        return getattr(self, name)

    def param(self, key: str) -> Any:
        """Resolved value of a dotted key, e.g. ``scene.param("fungi.alpha_w0")``."""
        section, _, name = key.partition(".")
        try:
            return self.section(section)[name]
        except KeyError:
            raise KeyError(f"no parameter {key!r}") from None

    def tissue_param(self, tissue: str, name: str) -> Any:
        """Value of ``name`` (``alpha_w0`` or ``fungi.alpha_w0``) in ``tissue``: its override,
        else the section value."""
        if tissue not in self.tissues:
            raise KeyError(f"unknown tissue {tissue!r}; tissues are {', '.join(TISSUES)}")
        section, dot, bare = name.rpartition(".")
        if bare not in TISSUE_KEYS or (dot and TISSUE_KEYS[bare].section != section):
            raise KeyError(f"{name!r} is not a per-tissue parameter")
        over = self.tissues[tissue]
        if bare in over:
            return over[bare]
        return getattr(self, TISSUE_KEYS[bare].section)[bare]

    def to_dict(self) -> dict:
        """The resolved scene as plain JSON-able data (values after the quality preset; not meant
        to be fed back as a scene file)."""
        out: dict[str, Any] = {
            "scene": {"name": self.name, "seed": self.seed, "quality": self.quality,
                      "description": self.description},
            "skeleton": _skeleton_dict(self.skeleton),
        }
        for sec in SECTIONS:
            if sec != "scene":
                out[sec] = getattr(self, sec).as_dict()
        out["tissue"] = self.tissues.as_dict()
        out["inoculation"] = [m.as_dict() for m in self.inoculations]
        out["load"] = [m.as_dict() for m in self.loads]
        out["collider"] = [m.as_dict() for m in self.colliders]
        out["path"] = None if self.path is None else str(self.path)
        out["base_dir"] = str(self.base_dir)
        return out

    @cached_property
    def hash(self) -> str:
        """sha256 (hex) of the canonical JSON of :meth:`to_dict` without paths (scene path,
        base directory, skeleton source file)."""
        d = self.to_dict()
        d.pop("path", None)
        d.pop("base_dir", None)
        d["skeleton"].pop("source", None)
        text = json.dumps(d, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
        return hashlib.sha256(text.encode("ascii")).hexdigest()


def _skeleton_dict(skel: Any) -> dict:
    nodes = []
    ids = list(skel.ids)
    for i, nid in enumerate(ids):
        prof = skel.profiles[i]
        pd: dict[str, Any] = {"kind": prof.kind}
        pd.update({str(k): float(v) for k, v in prof.params})
        if prof.kind == "polygon":
            pd["points"] = [[float(a), float(b)] for a, b in prof.polygon]
        par = int(skel.parent[i])
        nodes.append({
            "id": nid,
            "position": [float(x) for x in skel.positions[i]],
            "parent": None if par < 0 else ids[par],
            "profile": pd,
            "anchored": bool(skel.anchored[i]),
        })
    return {"source": str(skel.source), "nodes": nodes}


# ---------------------------------------------------------------------------------------------
# Entry points
# ---------------------------------------------------------------------------------------------
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


# ---------------------------------------------------------------------------------------------
# Resolution
# ---------------------------------------------------------------------------------------------
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


def _belongs(name: str) -> str:
    """``"; it belongs in [x]"`` when ``name`` is a parameter of another section."""
    homes = [sec for sec, table in PARAMS.items() if name in table]
    return f"; it belongs in [{homes[0]}]" if homes else ""


def _unknown_key(file: str, section: str, name: Any, allowed) -> InputError:
    name_s = str(name)
    hint = did_you_mean(name_s, allowed) or _belongs(name_s)
    where = f"[{section}]" if section else "the scene"
    return InputError(file, f"{section}.{name_s}" if section else name_s,
                      f"unknown key {format_value(name_s)} in {where}{hint}")


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
        if head not in PARAMS:
            raise InputError(src, key, f"unknown section {format_value(head)}; overridable sections are "
                             f"{', '.join(SECTIONS)} and tissue{did_you_mean(head, tuple(SECTIONS) + ('tissue',))}")
        if len(parts) != 2:
            raise InputError(src, key, f"expected {head}.<key>")
        name = parts[1]
        if name not in PARAMS[head]:
            raise _unknown_key(src, head, name, PARAMS[head])
        table = data.setdefault(head, {})
        if not isinstance(table, dict):
            raise InputError(ctx.file, head, f"expected a table [{head}], got {type_name(table)}")
        table[name] = value
        ctx.origin[key] = src


def _resolve(data: dict, ctx: _Ctx, base_dir: Path, path: Path | None, default_name: str) -> Scene:
    file = ctx.file
    for k in data:
        if k not in _TOP_LEVEL:
            raise _unknown_key(file, "", k, _TOP_LEVEL)

    # -- scalar sections
    values: dict[str, dict[str, Any]] = {}
    given: dict[str, set[str]] = {}
    for sec, table in PARAMS.items():
        raw = data.get(sec, {})
        if not isinstance(raw, dict):
            raise InputError(file, sec, f"expected a table [{sec}], got {type_name(raw)} {format_value(raw)}")
        for k in raw:
            if k not in table:
                raise _unknown_key(ctx.src(f"{sec}.{k}"), sec, k, table)
        vals: dict[str, Any] = {}
        for name, p in table.items():
            key = p.key
            if name in raw:
                vals[name] = validate_value(p, raw[name], ctx.src(key), key)
            else:
                vals[name] = p.default
        values[sec] = vals
        given[sec] = set(raw)

    # -- consistency of the sections
    strands = values["strands"]
    if strands["connect_radius"] is None:
        strands["connect_radius"] = CONNECT_FACTOR * strands["r_s"]
    elif strands["connect_radius"] < CONNECT_MIN_FACTOR * strands["r_s"]:
        raise InputError(
            ctx.src("strands.connect_radius", "strands.r_s"), "strands.connect_radius",
            f"{format_value(strands['connect_radius'])} m is less than 2 * strands.r_s = "
            f"{format_value(CONNECT_MIN_FACTOR * strands['r_s'])} m; strands.connect_radius and strands.r_s "
            f"are inconsistent (need connect_radius >= 2 r_s)")
    _check_moisture(values["fungi"], values["moisture"], ctx, prefix="", given=None)

    # -- skeleton
    if "skeleton" not in data:
        raise InputError(file, "skeleton", "missing [skeleton] table (inline [[skeleton.node]] or file = \"...\")")
    from wooddecay.strands.skeleton import load_skeleton  # lazy: keeps params/scene import light

    skeleton = load_skeleton(data["skeleton"], base_dir, file)

    # -- tissues
    tissues = _resolve_tissues(data.get("tissue", {}), values, ctx)

    # -- inoculations and loads
    inoculations = _resolve_list(data, "inoculation", _inoculation, ctx, skeleton)
    loads = _resolve_list(data, "load", _load, ctx, skeleton)
    colliders = _resolve_list(data, "collider", _collider, ctx, skeleton)

    # -- quality preset (after validation)
    scene_vals = values["scene"]
    if scene_vals["quality"] == "draft":
        for name in ("r_s", "rod_length", "connect_radius"):
            strands[name] = strands[name] * DRAFT_SCALE
    name = scene_vals["name"] if scene_vals["name"] is not None else default_name

    sections = {sec: Section(sec, values[sec]) for sec in SECTIONS if sec != "scene"}
    return Scene(
        name=name,
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


def _check_moisture(fungi: Mapping, moisture: Mapping, ctx: _Ctx, prefix: str,
                    given: set[str] | None) -> None:
    """M_min < M_max; M_2 < M_1; M_2 <= M_init <= M_1. ``prefix``: '' or 'tissue.<t>.'."""

    def key(sec: str, name: str) -> str:
        if not prefix:
            return f"{sec}.{name}"
        return f"{prefix}{name}"

    def pick(*cands: tuple[str, str]) -> str:
        # name the key the user set (a tissue override) first
        for sec, n in cands:
            if given is not None and n in given:
                return key(sec, n)
        return key(*cands[0])

    def src(*cands: tuple[str, str]) -> str:
        return ctx.src(*(key(s, n) for s, n in cands))

    def fail(cands: tuple[tuple[str, str], ...], msg: str) -> InputError:
        both = " and ".join(key(s, n) for s, n in cands)
        return InputError(src(*cands), pick(*cands), f"{msg}; {both} are inconsistent")

    lo, hi = fungi["M_min"], fungi["M_max"]
    if not lo < hi:
        raise fail((("fungi", "M_min"), ("fungi", "M_max")),
                   f"M_min = {format_value(lo)} kg/kg must be < M_max = {format_value(hi)} kg/kg")
    m1, m2, mi = moisture["M_1"], moisture["M_2"], moisture["M_init"]
    if not m2 < m1:
        raise fail((("moisture", "M_2"), ("moisture", "M_1")),
                   f"M_2 = {format_value(m2)} kg/kg must be < M_1 = {format_value(m1)} kg/kg")
    if not m2 <= mi <= m1:
        raise fail((("moisture", "M_init"), ("moisture", "M_2"), ("moisture", "M_1")),
                   f"M_init = {format_value(mi)} kg/kg must lie in [M_2, M_1] = "
                   f"[{format_value(m2)}, {format_value(m1)}] kg/kg")
    rows = moisture.get("schedule") or ()
    if rows:  # the schedule replaces M_1, M_2: M_init must lie in its range
        lo_s, hi_s = min(r[2] for r in rows), max(r[1] for r in rows)
        if not lo_s <= mi <= hi_s:
            raise fail((("moisture", "M_init"), ("moisture", "schedule")),
                       f"M_init = {format_value(mi)} kg/kg must lie in the schedule's range "
                       f"[{format_value(lo_s)}, {format_value(hi_s)}] kg/kg")


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
            over[name] = validate_value(TISSUE_KEYS[name], v, ctx.src(key), key)
        if over:
            fungi = {**values["fungi"], **{k: v for k, v in over.items() if k in values["fungi"]}}
            moist = {**values["moisture"], **{k: v for k, v in over.items() if k in values["moisture"]}}
            _check_moisture(fungi, moist, ctx, prefix=f"tissue.{t}.", given=set(over))
        out[t] = FrozenMap(over)
    return FrozenMap(out)


# ---------------------------------------------------------------------------------------------
# Inoculations, loads and regions
# ---------------------------------------------------------------------------------------------
_P_FUNGUS = make_param("inoculation", "fungus", None, "", "", "Fungus kind.", "enum:white|brown")
_P_ACTIVITY = make_param("inoculation", "activity", 0.1, "", "(0, 1]", "Initial activity R_w or R_b.")
_P_DAY = make_param("inoculation", "day", 0.0, "day", "[0, inf)", "Day the inoculation happens.")
_P_KIND = make_param("region", "kind", None, "", "", "Region kind.", "enum:box|sphere|node|end|wound")
_P_SPACE = make_param("region", "space", "world", "", "", "Coordinates of the region.", "enum:world|wood")
_P_WHICH = make_param("region", "which", "root", "", "", "Which log end.", "enum:root|tip")
_P_LENGTH = make_param("region", "length", None, "m", "(0, inf)", "A positive length.", "float")
_P_VEC = make_param("region", "vec", None, "m", "", "A point.", "vec3")
_P_FORCE = make_param("load", "force", None, "N", "", "Force applied to the region.", "vec3")
_P_DAYNUM = make_param("load", "days", None, "day", "[0, inf)", "A day.", "float")

#: Region kind -> {key: (param or "id", required)}.
REGION_KINDS: dict[str, dict[str, tuple[Any, bool]]] = {
    "box": {"min": (_P_VEC, True), "max": (_P_VEC, True)},
    "sphere": {"center": (_P_VEC, True), "radius": (_P_LENGTH, True)},
    "node": {"id": ("id", True), "radius": (_P_LENGTH, True)},
    "end": {"which": (_P_WHICH, False), "depth": (_P_LENGTH, True)},
    "wound": {"position": (_P_VEC, True), "radius": (_P_LENGTH, True), "depth": (_P_LENGTH, True)},
}


def _resolve_list(data: dict, name: str, fn, ctx: _Ctx, skeleton: Any) -> tuple[FrozenMap, ...]:
    raw = data.get(name, [])
    if not isinstance(raw, list) or not all(isinstance(x, dict) for x in raw):
        raise InputError(ctx.file, name, f"expected an array of tables [[{name}]], got {type_name(raw)} "
                         f"{format_value(raw)}")
    return tuple(fn(item, f"{name}[{i}]", ctx.file, skeleton) for i, item in enumerate(raw))


def _check_table(table: dict, allowed: Sequence[str], required: Sequence[str], file: str, prefix: str,
                 what: str) -> None:
    for k in table:
        if k not in allowed:
            raise InputError(file, f"{prefix}.{k}", f"unknown key {format_value(str(k))} in {what}"
                             f"{did_you_mean(str(k), allowed)} (allowed: {', '.join(allowed)})")
    for k in required:
        if k not in table:
            raise InputError(file, f"{prefix}.{k}", f"missing required key {k!r} in {what}")


def _region(raw: Any, prefix: str, file: str, skeleton: Any) -> FrozenMap:
    if not isinstance(raw, dict):
        raise InputError(file, prefix, f"expected a region table {{kind = ..., ...}}, got {type_name(raw)} "
                         f"{format_value(raw)}")
    if "kind" not in raw:
        raise InputError(file, f"{prefix}.kind", f"missing required key 'kind' ({format_range(_P_KIND)})")
    kind = validate_value(_P_KIND, raw["kind"], file, f"{prefix}.kind")
    spec = REGION_KINDS[kind]
    allowed = ("kind", "space") + tuple(spec)
    _check_table(raw, allowed, [k for k, (_, req) in spec.items() if req], file, prefix, f"a {kind} region")
    out: dict[str, Any] = {"kind": kind, "space": validate_value(_P_SPACE, raw.get("space", "world"), file,
                                                                 f"{prefix}.space")}
    for k, (p, _) in spec.items():
        key = f"{prefix}.{k}"
        if p == "id":
            out[k] = _node_id(raw[k], skeleton, file, key)
        elif k in raw:
            out[k] = validate_value(p, raw[k], file, key)
        else:
            out[k] = p.default
    if kind == "box":
        lo, hi = out["min"], out["max"]
        for axis in range(3):
            if not lo[axis] < hi[axis]:
                raise InputError(file, f"{prefix}.max", f"box max {format_value(list(hi))} must exceed min "
                                 f"{format_value(list(lo))} in every component ({'xyz'[axis]} is not); "
                                 f"{prefix}.min and {prefix}.max are inconsistent")
    return FrozenMap(out)


def _node_id(v: Any, skeleton: Any, file: str, key: str) -> str:
    if isinstance(v, bool) or not isinstance(v, (int, str)):
        raise InputError(file, key, f"expected a skeleton node id (string or integer), got {type_name(v)} "
                         f"{format_value(v)}")
    nid = str(v)
    ids = tuple(skeleton.ids)
    if nid not in ids:
        listed = ", ".join(repr(i) for i in ids[:8]) + (", ..." if len(ids) > 8 else "")
        raise InputError(file, key, f"{format_value(nid)} is not a skeleton node id "
                         f"(ids: {listed}){did_you_mean(nid, ids)}")
    return nid


def _inoculation(raw: dict, prefix: str, file: str, skeleton: Any) -> FrozenMap:
    _check_table(raw, ("fungus", "activity", "day", "region"), ("fungus", "region"), file, prefix,
                 "[[inoculation]]")
    return FrozenMap({
        "fungus": validate_value(_P_FUNGUS, raw["fungus"], file, f"{prefix}.fungus"),
        "activity": validate_value(_P_ACTIVITY, raw.get("activity", _P_ACTIVITY.default), file,
                                   f"{prefix}.activity"),
        "day": validate_value(_P_DAY, raw.get("day", _P_DAY.default), file, f"{prefix}.day"),
        "region": _region(raw["region"], f"{prefix}.region", file, skeleton),
    })


def _load(raw: dict, prefix: str, file: str, skeleton: Any) -> FrozenMap:
    _check_table(raw, ("region", "force", "days"), ("region", "force", "days"), file, prefix, "[[load]]")
    region = _region(raw["region"], f"{prefix}.region", file, skeleton)
    force = validate_value(_P_FORCE, raw["force"], file, f"{prefix}.force")
    days = raw["days"]
    key = f"{prefix}.days"
    if not isinstance(days, list) or len(days) != 2:
        raise InputError(file, key, f"expected [start, end] in days with 0 <= start < end, got {type_name(days)} "
                         f"{format_value(days)}")
    start = validate_value(_P_DAYNUM, days[0], file, key)
    end = validate_value(_P_DAYNUM, days[1], file, key)
    if not start < end:
        raise InputError(file, key, f"start {format_value(start)} must be < end {format_value(end)} "
                         f"(0 <= start < end, days)")
    return FrozenMap({"region": region, "force": force, "days": (start, end)})


_P_COLLIDER = make_param("collider", "kind", None, "", "", "Collider kind.", "enum:plane|box|sphere|cylinder")
#: Collider kind -> its keys (all required).
COLLIDER_KINDS: dict[str, dict[str, Any]] = {
    "plane": {"point": _P_VEC, "normal": _P_VEC},
    "box": {"min": _P_VEC, "max": _P_VEC},
    "sphere": {"center": _P_VEC, "radius": _P_LENGTH},
    "cylinder": {"a": _P_VEC, "b": _P_VEC, "radius": _P_LENGTH},
}


def _collider(raw: dict, prefix: str, file: str, skeleton: Any) -> FrozenMap:
    if "kind" not in raw:
        raise InputError(file, f"{prefix}.kind", f"missing required key 'kind' ({format_range(_P_COLLIDER)})")
    kind = validate_value(_P_COLLIDER, raw["kind"], file, f"{prefix}.kind")
    spec = COLLIDER_KINDS[kind]
    _check_table(raw, ("kind",) + tuple(spec), tuple(spec), file, prefix, f"a {kind} collider")
    out: dict[str, Any] = {"kind": kind}
    for k, p in spec.items():
        out[k] = validate_value(p, raw[k], file, f"{prefix}.{k}")
    if kind == "plane" and not any(out["normal"]):
        raise InputError(file, f"{prefix}.normal", "the plane normal must not be [0, 0, 0]")
    if kind == "box" and not all(lo < hi for lo, hi in zip(out["min"], out["max"])):
        raise InputError(file, f"{prefix}.max", f"box max {format_value(list(out['max']))} must exceed min "
                         f"{format_value(list(out['min']))} in every component")
    if kind == "cylinder" and out["a"] == out["b"]:
        raise InputError(file, f"{prefix}.b", "the cylinder axis has zero length (a == b)")
    return FrozenMap(out)
