"""Checking scene values against the schema, and saying what is wrong in one line (docs/model.md §1).

Unknown keys, wrong types, out-of-range values and inconsistent combinations raise
:class:`wooddecay.errors.InputError` ``(file, key, message)`` whose one line names the file, the
dotted key and what is allowed, e.g. ``samples/log.toml: strands.r_s: -1 is outside (0, 1] m`` or
``log.toml: fungi.alpah_w0: unknown key 'alpah_w0' in [fungi]; did you mean 'alpha_w0'?``.
Booleans are not numbers; NaN and infinities are rejected.

* :func:`validate_value`: one value against its :class:`~wooddecay.scene.schema.Param`.
* :func:`validate_table`: one entry of an entry table (``[[inoculation]]``, ``[[load]]``,
  ``[[collider]]``, a ``region``): its keys, values and consistency (box min < max, a plane
  normal and a cylinder axis that are not zero, load days start < end).
* :func:`check_format`: ``[scene] format`` first of all: a scene of a newer format than this
  wooddecay reads is refused (``scene.format: format 2 is newer than wooddecay 0.1.0 reads
  (formats [1, 1])...``).
* :func:`check_connect_radius`, :func:`check_moisture`: the consistency of the sections
  (connect_radius >= 2 r_s; M_min < M_max, M_2 < M_1, M_2 <= M_init <= M_1 and M_init within
  the moisture schedule), naming every key involved.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

from wooddecay.errors import InputError, did_you_mean, format_value, type_name
from wooddecay.scene.schema import (
    CONNECT_MIN_FACTOR,
    DAYS_PER_YEAR,
    PARAMS,
    TABLES,
    Param,
    Table,
    format_range,
)
from wooddecay.scene.types import FrozenMap
from wooddecay.species import SPECIES

#: ``src(*keys)``: the file (or overrides source) the first of ``keys`` that was set came from.
Source = Callable[..., str]


# ---------------------------------------------------------------------------------------------
# Values
# ---------------------------------------------------------------------------------------------
def _is_number(v: Any) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool) and type(v).__name__ != "bool_"


def _to_float(v: Any) -> float | None:
    """float(v) or None when not representable / not finite."""
    try:
        f = float(v)
    except (OverflowError, ValueError, TypeError):
        return None
    return f if math.isfinite(f) else None


def _in_range(p: Param, x: float) -> bool:
    if p.lo is not None and (x < p.lo or (p.lo_open and x == p.lo)):
        return False
    if p.hi is not None and (x > p.hi or (p.hi_open and x == p.hi)):
        return False
    return True


def _check_number(p: Param, v: Any, file: str, key: str, integer: bool) -> float | int:
    rng = format_range(p)
    if not _is_number(v):
        what = "an integer" if integer else "a number"
        raise InputError(file, key, f"expected {what} in {rng}, got {type_name(v)} {format_value(v)}")
    if integer:
        if isinstance(v, numbers.Integral):
            x: Any = int(v)
        else:
            f = _to_float(v)
            if f is None or f != int(f):
                raise InputError(file, key, f"expected an integer in {rng}, got {format_value(v)}")
            x = int(f)
        if not _in_range(p, x):
            raise InputError(file, key, f"{format_value(x)} is outside {rng}")
        return x
    f = _to_float(v)
    if f is None:
        if isinstance(v, numbers.Integral):  # an integer too large for a float
            raise InputError(file, key, f"{format_value(v)} is outside {rng}")
        raise InputError(file, key, f"{format_value(v)} is not a finite number; allowed {rng}")
    if not _in_range(p, f):
        raise InputError(file, key, f"{format_value(v)} is outside {rng}")
    return f


def _check_vec3(v: Any, file: str, key: str, what: str) -> tuple[float, float, float]:
    if hasattr(v, "tolist") and not isinstance(v, (str, bytes)):  # numpy arrays from the Python API
        try:
            v = v.tolist()
        except Exception:  # pragma: no cover - defensive
            pass
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise InputError(file, key, f"expected {what}, got {type_name(v)} {format_value(v)}")
    out = []
    for i, c in enumerate(v):
        if not _is_number(c):
            raise InputError(file, key, f"expected {what}, component {i} is {type_name(c)} {format_value(c)}")
        f = _to_float(c)
        if f is None:
            raise InputError(file, key, f"expected {what}, component {i} is not finite ({format_value(c)})")
        out.append(f)
    return (out[0], out[1], out[2])


def _keyframes(p: Param, v: Any, file: str, key: str, columns: str, day_max: float, days: str):
    """Rows of a keyframe list (the moisture schedule, the climate's seasons): yields each row's
    key and its finite values ``[day, ...]`` (``columns`` names them), days in [0, ``day_max``)
    (``days`` says so in words) and strictly increasing."""
    if not isinstance(v, (list, tuple)):
        raise InputError(file, key, f"expected {format_range(p)}, got {type_name(v)} {format_value(v)}")
    width = columns.count(",") + 1
    previous = None
    for i, row in enumerate(v):
        rkey = f"{key}[{i}]"
        if not isinstance(row, (list, tuple)) or len(row) != width:
            raise InputError(file, rkey, f"expected a row [{columns}], got {type_name(row)} {format_value(row)}")
        for j, c in enumerate(row):
            if not _is_number(c) or _to_float(c) is None:
                raise InputError(file, rkey, f"expected finite numbers [{columns}], item {j} is {type_name(c)} {format_value(c)}")
        vals = [float(c) for c in row]
        day = vals[0]
        if not 0.0 <= day < day_max:
            raise InputError(file, rkey, f"day {format_value(day)} is outside {days}")
        if previous is not None and day <= previous:
            raise InputError(file, rkey, f"day {format_value(day)} must be greater than the previous keyframe's day {format_value(previous)} (days strictly increasing)")
        previous = day
        yield rkey, vals


def _check_schedule(p: Param, v: Any, file: str, key: str) -> tuple[tuple[float, float, float], ...]:
    """The moisture schedule: rows [day, M_1, M_2], M_2 < M_1, each in its parameter's range."""
    m1 = PARAMS["moisture"]["M_1"]
    m2 = PARAMS["moisture"]["M_2"]
    rows: list[tuple[float, float, float]] = []
    for rkey, (day, hi, lo) in _keyframes(p, v, file, key, "day, M_1, M_2", math.inf, "[0, inf) day"):
        if not _in_range(m1, hi):
            raise InputError(file, rkey, f"M_1 {format_value(hi)} is outside {format_range(m1)}")
        if not _in_range(m2, lo):
            raise InputError(file, rkey, f"M_2 {format_value(lo)} is outside {format_range(m2)}")
        if not lo < hi:
            raise InputError(file, rkey, f"M_2 {format_value(lo)} must be < M_1 {format_value(hi)}")
        rows.append((day, hi, lo))
    return tuple(rows)


def _check_seasons(p: Param, v: Any, file: str, key: str) -> tuple[tuple[float, float, float, float], ...]:
    """The climate's keyframes: rows [day_of_year, w_in, w_out, w_ground], days in
    [0, DAYS_PER_YEAR), factors in [0, 100]."""
    rows: list[tuple[float, float, float, float]] = []
    for rkey, (day, *w) in _keyframes(p, v, file, key, "day_of_year, w_in, w_out, w_ground", DAYS_PER_YEAR,
                                      f"[0, {DAYS_PER_YEAR}) day of the year"):
        for name, f in zip(("w_in", "w_out", "w_ground"), w):
            if not 0.0 <= f <= 100.0:
                raise InputError(file, rkey, f"{name} {format_value(f)} is outside [0, 100]")
        rows.append((day, *w))
    return tuple(rows)


def _check_interval(p: Param, v: Any, file: str, key: str) -> tuple[float, float]:
    """``[start, end]``, each in ``p``'s range, start < end (a load's days)."""
    if not isinstance(v, list) or len(v) != 2:
        raise InputError(file, key, f"expected {format_range(p)}, got {type_name(v)} {format_value(v)}")
    end_point = replace(p, kind="float")
    start = _check_number(end_point, v[0], file, key, integer=False)
    end = _check_number(end_point, v[1], file, key, integer=False)
    if not start < end:
        raise InputError(file, key, f"start {format_value(start)} must be < end {format_value(end)} "
                         f"(0 <= start < end, days)")
    return (start, end)


def validate_value(p: Param, v: Any, file: str, key: str | None = None) -> Any:
    """Check ``v`` against ``p`` and return the resolved value.

    ints become floats for ``float`` parameters, integral floats become ints for ``int``
    parameters, ``vec3`` becomes a tuple of 3 floats, the schedule a tuple of 3-tuples and an
    ``interval`` a ``(start, end)`` pair. Booleans are not numbers here. Raises
    :class:`InputError` (``file``, ``key`` — default ``p.key`` —, a message with the allowed
    range and unit). Nested tables and node ids go through :func:`validate_table`.
    """
    key = p.key if key is None else key
    kind = p.kind
    if kind == "float":
        return _check_number(p, v, file, key, integer=False)
    if kind == "int":
        return _check_number(p, v, file, key, integer=True)
    if kind == "bool":
        if type(v).__name__ == "bool_":  # numpy.bool_ from the Python API
            v = bool(v)
        if not isinstance(v, bool):
            raise InputError(file, key, f"expected true or false, got {type_name(v)} {format_value(v)}")
        return v
    if kind == "str":
        if not isinstance(v, str):
            raise InputError(file, key, f"expected a string, got {type_name(v)} {format_value(v)}")
        return v
    if kind == "enum":
        if not isinstance(v, str) or v not in p.choices:
            hint = did_you_mean(v, p.choices) if isinstance(v, str) else ""
            raise InputError(file, key, f"{format_value(v)} is not {format_range(p)}{hint}")
        return v
    if kind == "vec3":
        return _check_vec3(v, file, key, format_range(p))
    if kind == "list":
        return _check_schedule(p, v, file, key)
    if kind == "seasons":
        return _check_seasons(p, v, file, key)
    if kind == "interval":
        return _check_interval(p, v, file, key)
    raise AssertionError(f"unknown kind {kind!r}")  # pragma: no cover


def check_format(raw: Any, file: str) -> int:
    """The scene file format of the parsed TOML ``raw`` (its ``[scene] format``, else the format of
    files written before the key existed). Checked before anything else in the file, so a scene
    written for a newer wooddecay is refused for that (one line naming the file, the key and the
    formats this one reads), not for the first key it does not know."""
    p = PARAMS["scene"]["format"]
    table = raw.get("scene") if isinstance(raw, Mapping) else None
    if not isinstance(table, Mapping) or "format" not in table:
        return p.default
    v = table["format"]
    f = _to_float(v) if _is_number(v) else None
    whole = _is_number(v) and (isinstance(v, numbers.Integral) or (f is not None and f.is_integer()))
    if whole and p.hi is not None and v > p.hi:
        from wooddecay.version import __version__

        raise InputError(file, p.key, f"format {format_value(v)} is newer than wooddecay {__version__} reads "
                         f"(formats {format_range(p)}); upgrade wooddecay to read this scene")
    return validate_value(p, v, file)


# ---------------------------------------------------------------------------------------------
# Keys
# ---------------------------------------------------------------------------------------------
def _belongs(name: str) -> str:
    """``"; it belongs in [x]"`` when ``name`` is a parameter of another section."""
    homes = [sec for sec, table in PARAMS.items() if name in table]
    return f"; it belongs in [{homes[0]}]" if homes else ""


def unknown_key(file: str, section: str, name: Any, allowed) -> InputError:
    """The error for key ``name`` that ``section`` (``""``: the top of the scene) lacks."""
    name_s = str(name)
    hint = did_you_mean(name_s, allowed) or _belongs(name_s)
    where = f"[{section}]" if section else "the scene"
    return InputError(file, f"{section}.{name_s}" if section else name_s,
                      f"unknown key {format_value(name_s)} in {where}{hint}")


def _check_keys(table: dict, allowed: Sequence[str], required: Sequence[str], file: str, prefix: str,
                what: str) -> None:
    for k in table:
        if k not in allowed:
            raise InputError(file, f"{prefix}.{k}", f"unknown key {format_value(str(k))} in {what}"
                             f"{did_you_mean(str(k), allowed)} (allowed: {', '.join(allowed)})")
    for k in required:
        if k not in table:
            raise InputError(file, f"{prefix}.{k}", f"missing required key {k!r} in {what}")


# ---------------------------------------------------------------------------------------------
# Entry tables
# ---------------------------------------------------------------------------------------------
def validate_table(table: Table, raw: dict, file: str, prefix: str, node_ids: Sequence[str]) -> FrozenMap:
    """Check one entry of ``table`` (keyed ``prefix``, e.g. ``inoculation[0]``) and resolve it.

    Keys are checked (unknown with a did-you-mean, missing required), then each value in schema
    order (defaults filled in), then the entry's consistency. ``node_ids``: the skeleton's node
    ids, which a ``node`` region must name.
    """
    kind = None
    if table.kinds:
        kind_param = table.keys["kind"]
        if "kind" not in raw:
            raise InputError(file, f"{prefix}.kind", f"missing required key 'kind' ({format_range(kind_param)})")
        kind = validate_value(kind_param, raw["kind"], file, f"{prefix}.kind")
    keys = table.keys_of(kind)
    what = f"[[{table.name}]]" if kind is None else f"a {kind} {table.name}"
    _check_keys(raw, tuple(keys), [k for k, p in keys.items() if p.default is None], file, prefix, what)
    out: dict[str, Any] = {}
    for k, p in keys.items():
        key = f"{prefix}.{k}"
        if k == "kind":
            out[k] = kind
        elif p.kind == "region":
            out[k] = _region(p, raw[k], file, key, node_ids)
        elif p.kind == "node_id":
            out[k] = _node_id(p, raw[k], file, key, node_ids)
        elif k in raw:
            out[k] = validate_value(p, raw[k], file, key)
        else:
            out[k] = p.default
    _check_entry(table.name, out, file, prefix)
    return FrozenMap(out)


def _region(p: Param, raw: Any, file: str, key: str, node_ids: Sequence[str]) -> FrozenMap:
    if not isinstance(raw, dict):
        raise InputError(file, key, f"expected {format_range(p)}, got {type_name(raw)} {format_value(raw)}")
    return validate_table(TABLES["region"], raw, file, key, node_ids)


def _node_id(p: Param, v: Any, file: str, key: str, node_ids: Sequence[str]) -> str:
    if isinstance(v, bool) or not isinstance(v, (int, str)):
        raise InputError(file, key, f"expected {format_range(p)}, got {type_name(v)} {format_value(v)}")
    nid = str(v)
    ids = tuple(node_ids)
    if nid not in ids:
        listed = ", ".join(repr(i) for i in ids[:8]) + (", ..." if len(ids) > 8 else "")
        raise InputError(file, key, f"{format_value(nid)} is not a skeleton node id "
                         f"(ids: {listed}){did_you_mean(nid, ids)}")
    return nid


def _check_entry(table: str, out: Mapping[str, Any], file: str, prefix: str) -> None:
    """Consistency of one resolved entry: boxes, plane normals, cylinder axes."""
    kind = out.get("kind")
    if table == "region" and kind == "box":
        lo, hi = out["min"], out["max"]
        for axis in range(3):
            if not lo[axis] < hi[axis]:
                raise InputError(file, f"{prefix}.max", f"box max {format_value(list(hi))} must exceed min "
                                 f"{format_value(list(lo))} in every component ({'xyz'[axis]} is not); "
                                 f"{prefix}.min and {prefix}.max are inconsistent")
    if table != "collider":
        return
    if kind == "plane" and not any(out["normal"]):
        raise InputError(file, f"{prefix}.normal", "the plane normal must not be [0, 0, 0]")
    if kind == "box" and not all(lo < hi for lo, hi in zip(out["min"], out["max"])):
        raise InputError(file, f"{prefix}.max", f"box max {format_value(list(out['max']))} must exceed min "
                         f"{format_value(list(out['min']))} in every component")
    if kind == "cylinder" and out["a"] == out["b"]:
        raise InputError(file, f"{prefix}.b", "the cylinder axis has zero length (a == b)")


# ---------------------------------------------------------------------------------------------
# Consistency of the sections
# ---------------------------------------------------------------------------------------------
def check_connect_radius(strands: Mapping[str, Any], src: Source) -> None:
    """``strands.connect_radius >= 2 * strands.r_s`` (REG edges reach past touching strands)."""
    if strands["connect_radius"] < CONNECT_MIN_FACTOR * strands["r_s"]:
        raise InputError(
            src("strands.connect_radius", "strands.r_s"), "strands.connect_radius",
            f"{format_value(strands['connect_radius'])} m is less than 2 * strands.r_s = "
            f"{format_value(CONNECT_MIN_FACTOR * strands['r_s'])} m; strands.connect_radius and strands.r_s "
            f"are inconsistent (need connect_radius >= 2 r_s)")


def check_moisture(fungi: Mapping, moisture: Mapping, src: Source, prefix: str,
                   given: set[str] | None) -> None:
    """M_min < M_max (Eq. 10); M_2 < M_1; M_2 <= M_init <= M_1 (Eq. 15), and M_init within the
    schedule's range. ``prefix``: '' or 'tissue.<t>.'; ``given``: the keys a tissue overrides."""

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

    def fail(cands: tuple[tuple[str, str], ...], msg: str) -> InputError:
        both = " and ".join(key(s, n) for s, n in cands)
        return InputError(src(*(key(s, n) for s, n in cands)), pick(*cands), f"{msg}; {both} are inconsistent")

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


def check_species(species: str, mech: dict[str, Any], given: Mapping[str, Any], src: Source) -> None:
    """``wood.species`` other than 'none' needs the implicit solver and sets mechanics.E, G and
    rho_dry (the species' calibrated strands and density, :mod:`wooddecay.species`) in ``mech``,
    the resolved ``[mechanics]``; ``given``: the keys the scene's ``[mechanics]`` sets."""
    if species == "none":
        return
    if mech["solver"] != "implicit":
        raise InputError(src("wood.species", "mechanics.solver"), "wood.species",
                         f"'{species}' gives the moduli of the converged bundle, which only mechanics.solver = "
                         "'implicit' reaches: choose the implicit solver or species = 'none'")
    for name in ("E", "G", "rho_dry", "connection_shear"):
        if name in given:
            raise InputError(src(f"mechanics.{name}", "wood.species"), f"mechanics.{name}",
                             f"set by wood.species = '{species}' (wooddecay/species.py): leave one of the two out")
    wood = SPECIES[species]
    rods = wood.rod_moduli()
    mech["E"], mech["G"], mech["rho_dry"] = rods.E, rods.G, wood.rho_dry
