"""The scene's ``[skeleton]`` table -> a :class:`~wooddecay.strands.skeleton.Skeleton` (docs/model.md §1).

The nodes of the skeleton graph G (woodstock §3, Fig. 3a) come inline (``[[skeleton.node]]``),
from a native TOML file with a ``[[node]]`` array, from a TreeQSM cylinder table
(:mod:`wooddecay.strands.qsm`), optionally scaled, from a surface mesh (``mesh = "FILE"``:
:mod:`wooddecay.strands.mesh_input`, :mod:`wooddecay.strands.mesh_skeleton`; ``scale`` scales the
mesh, ``largest`` keeps its largest body, ``spacing`` sets the node spacing in m) or from a
scanned point cloud (``points = "FILE"``, lofted into a mesh by :mod:`wooddecay.strands.point_cloud`). Errors about the table name the scene file,
errors inside a skeleton file name that file.
"""
from __future__ import annotations

import tomllib
from pathlib import Path

from wooddecay.errors import InputError, format_value, type_name
from wooddecay.strands.qsm import load_treeqsm
from wooddecay.strands.skeleton import Skeleton, check_keys, parse_nodes, positive, scale_skeleton

TABLE_KEYS = ("file", "format", "node", "mesh", "points", "scale", "largest", "spacing", "up")
SOURCES = ("file", "node", "mesh", "points")
FORMAT_BY_SUFFIX = {".toml": "native", ".csv": "treeqsm", ".txt": "treeqsm"}


def _read_native(path: Path) -> Skeleton:
    """Load a native skeleton TOML file (a ``[[node]]`` array)."""
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except tomllib.TOMLDecodeError as err:
        raise InputError(str(path), "", f"not valid TOML: {err}") from None
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(str(path), "", f"cannot read the skeleton file: {err}") from None
    check_keys(data, ("node",), ("node",), str(path), "")
    return parse_nodes(data["node"], str(path), "node")


def _format_of(table: dict, path: Path | None, source: str) -> str:
    """Resolve ``skeleton.format`` (explicit, or from the file extension)."""
    if "format" in table:
        fmt = table["format"]
        if fmt not in ("native", "treeqsm"):
            raise InputError(source, "skeleton.format", f"must be \"native\" or \"treeqsm\" (got {format_value(fmt)})")
        if path is None and fmt != "native":
            raise InputError(source, "skeleton.format", "inline skeleton.node tables are always \"native\"")
        return fmt
    if path is None:
        return "native"
    if path.suffix.lower() not in FORMAT_BY_SUFFIX:
        raise InputError(source, "skeleton.format", f"cannot tell the format of '{path.name}' from its extension "
                         "(.toml native, .csv/.txt treeqsm); set format = \"native\" or \"treeqsm\"")
    return FORMAT_BY_SUFFIX[path.suffix.lower()]


def _from_surface(table: dict, base_dir: Path, source: str, scale: float, resolution: float) -> Skeleton:
    """``skeleton.mesh`` (a surface mesh) or ``skeleton.points`` (a scan, lofted into one)."""
    from wooddecay.strands.mesh_skeleton import mesh_skeleton

    key = "mesh" if "mesh" in table else "points"
    if not isinstance(table[key], str) or not table[key].strip():
        raise InputError(source, f"skeleton.{key}", f"must be a path string (got {format_value(table[key])})")
    largest = table.get("largest", False)
    if not isinstance(largest, bool) or (largest and key == "points"):
        raise InputError(source, "skeleton.largest", f"must be true or false, with skeleton.mesh only (got "
                         f"{format_value(largest)})")
    spacing = positive(table["spacing"], source, "skeleton.spacing") if "spacing" in table else None
    up = table.get("up")
    if up not in (None, "y", "z"):
        raise InputError(source, "skeleton.up", f'must be "y" or "z" (got {format_value(up)})')
    path = Path(base_dir) / table[key]
    return mesh_skeleton(load_surface(key, path, scale, largest, up, resolution, f"{source}: skeleton.{key}"),
                         resolution, spacing)


def load_surface(key: str, path: Path, scale: float, largest: bool, up: str | None, resolution: float, where: str):
    """The closed surface of a ``mesh`` file (:func:`~wooddecay.strands.mesh_input.load_mesh`)
    or a ``points`` scan lofted at ``resolution`` (:mod:`wooddecay.strands.point_cloud`);
    ``where`` names the key or option in messages."""
    from wooddecay.strands.mesh_input import load_mesh
    from wooddecay.strands.point_cloud import loft, read_points

    if key == "mesh":
        return load_mesh(path, scale, largest, where, up)
    return loft(read_points(path, scale, where, up), resolution, str(path))


def load_skeleton(table, base_dir: Path, source: str, resolution: float = 0.005) -> Skeleton:
    """Load the skeleton described by the scene's ``[skeleton]`` table.

    Parameters
    ----------
    table : dict
        Keys ``file`` (path relative to the scene file), ``node`` (inline array of node
        tables), ``mesh`` (a surface mesh) or ``points`` (a scanned point cloud; both relative
        to the scene file), exactly one of them; ``format`` ("native" | "treeqsm", default
        from the file extension: .toml native, .csv/.txt treeqsm); ``scale`` (float > 0,
        default 1); with ``mesh``: ``largest`` (bool); with ``mesh`` or ``points``:
        ``spacing`` (m) and ``up`` ("y" | "z": the file's up axis, :mod:`.mesh_input`).
    base_dir : Path
        Directory of the scene file.
    source : str
        The scene file (for messages).
    resolution : float
        Point spacing of profiles sliced from a mesh (m): the strand radius r_s.

    Returns
    -------
    Skeleton

    Raises
    ------
    InputError
        For a bad table or a bad skeleton (file errors name the skeleton file).
    """
    if not isinstance(table, dict):
        raise InputError(source, "skeleton", f"must be a table (got {type_name(table)})")
    check_keys(table, TABLE_KEYS, (), source, "skeleton")
    if sum(k in table for k in SOURCES) != 1:
        raise InputError(source, "skeleton", "give exactly one of skeleton.file, [[skeleton.node]], skeleton.mesh "
                         "or skeleton.points")
    scale = positive(table.get("scale", 1.0), source, "skeleton.scale")
    if "mesh" in table or "points" in table:
        return _from_surface(table, base_dir, source, scale, resolution)
    for key in ("largest", "spacing", "up"):
        if key in table:
            raise InputError(source, f"skeleton.{key}", "applies to skeleton.mesh and skeleton.points only")
    if "node" in table:
        _format_of(table, None, source)
        return scale_skeleton(parse_nodes(table["node"], source, "skeleton.node"), scale, "skeleton.node")
    if not isinstance(table["file"], str) or not table["file"].strip():
        raise InputError(source, "skeleton.file", f"must be a path string (got {format_value(table['file'])})")
    path = Path(base_dir) / table["file"]
    if not path.is_file():
        raise InputError(source, "skeleton.file", f"'{table['file']}' is not a file (looked for {path})")
    if _format_of(table, path, source) == "treeqsm":
        return scale_skeleton(load_treeqsm(path), scale, "node")
    return scale_skeleton(_read_native(path), scale, "node")
