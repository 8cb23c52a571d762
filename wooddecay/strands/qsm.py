"""TreeQSM cylinder tables as skeletons (docs/model.md §1; woodstock §3, Fig. 3a).

TreeQSM (quantitative structure models reconstructed from terrestrial LiDAR) describes a tree
as cylinders. The table read here has one cylinder per line, nine columns::

    start_x start_y start_z axis_x axis_y axis_z length radius parent

separated by commas, whitespace or tabs, with ``#`` comments and an optional header line (the
first non-comment line, when none of its cells is a number).
``parent`` is the 1-based index of the parent cylinder, 0 for none (TreeQSM convention).

Each cylinder becomes a skeleton node at its end (a circle of the cylinder radius), whose
parent is the parent cylinder's end node; a cylinder without parent also makes a root node at
its start with the same radius. Node ids are ``c<k>`` (end of cylinder k) and ``c<k>_base``
(start of root cylinder k). Errors name the line number (key ``line <n>``).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from wooddecay.errors import InputError
from wooddecay.strands.skeleton import MIN_EDGE_LENGTH, Skeleton, parse_nodes, topological_order

COLUMNS = ("start_x", "start_y", "start_z", "axis_x", "axis_y", "axis_z", "length", "radius", "parent")


def _read_text(path: Path) -> str:
    """Read ``path`` as UTF-8 text (a BOM is allowed)."""
    try:
        return path.read_bytes().decode("utf-8-sig")
    except OSError as err:
        raise InputError(str(path), "", f"cannot read the TreeQSM table: {err.strerror or err}") from None
    except UnicodeDecodeError:
        raise InputError(str(path), "", "is not UTF-8 text; expected a TreeQSM cylinder table") from None


def _cells(line: str) -> list[str]:
    """Split a data line on commas (when present) or on whitespace."""
    if "," in line:
        return [c.strip() for c in line.split(",")]
    return line.split()


def _is_number(cell: str) -> bool:
    """Whether ``cell`` parses as a float."""
    try:
        float(cell)
    except ValueError:
        return False
    return True


def _rows(text: str, source: str) -> tuple[np.ndarray, list[int]]:
    """Parse the numeric rows of the table.

    Returns
    -------
    values : np.ndarray
        ``(m, 9)`` float64 cells.
    lines : list of int
        1-based line number of each row.
    """
    values, lines, header_seen = [], [], False
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        cells = _cells(line)
        if not values and not header_seen and not any(_is_number(c) for c in cells):
            header_seen = True
            continue
        key = f"line {number}"
        if len(cells) != len(COLUMNS):
            raise InputError(source, key, f"has {len(cells)} columns; expected {len(COLUMNS)}: {' '.join(COLUMNS)}")
        row = []
        for name, cell in zip(COLUMNS, cells):
            try:
                x = float(cell)
            except ValueError:
                raise InputError(source, key, f"{name} must be a number (got {cell[:40]!r})") from None
            if not math.isfinite(x):
                raise InputError(source, key, f"{name} must be a finite number (got {cell[:40]!r})")
            row.append(x)
        values.append(row)
        lines.append(number)
    if not values:
        raise InputError(source, "", f"no cylinders found; expected rows of {len(COLUMNS)} columns: {' '.join(COLUMNS)}")
    return np.array(values), lines


def _check_rows(values: np.ndarray, lines: list[int], source: str) -> np.ndarray:
    """Validate lengths, radii, axes and parents; return 0-based parent indices (-1 for none)."""
    n = len(values)
    with np.errstate(all="ignore"):
        axis_norm = np.sqrt(np.sum(values[:, 3:6] ** 2, axis=1))
    for i, row in enumerate(values):
        key = f"line {lines[i]}"
        if not row[7] > 0.0:
            raise InputError(source, key, f"radius must be > 0 m (got {row[7]:g})")
        if not row[6] >= MIN_EDGE_LENGTH:
            raise InputError(source, key, f"length must be >= {MIN_EDGE_LENGTH} m (got {row[6]:g})")
        if not (axis_norm[i] > 0.0 and math.isfinite(axis_norm[i])):
            raise InputError(source, key, "axis must be a non-zero finite vector")
        p = row[8]
        if p != int(p) or not 0 <= p <= n or p == i + 1:
            raise InputError(source, key, f"parent must be a cylinder index 1..{n} other than its own, or 0 for none (got {p:g})")
    return values[:, 8].astype(np.int64) - 1


def _check_parent_cycles(parent: np.ndarray, lines: list[int], source: str) -> None:
    """Reject parent chains that loop, naming the line of one cylinder in the loop."""
    _, cycle = topological_order(parent)
    if cycle:
        chain = " -> ".join(str(i + 1) for i in cycle + cycle[:1])
        raise InputError(source, f"line {lines[cycle[0]]}", f"parent cylinders form a cycle {chain}")


def _ends(values: np.ndarray, lines: list[int], parent: np.ndarray, source: str) -> np.ndarray:
    """Cylinder end points ``(m, 3)``; rejects non-finite ends and zero-length edges."""
    with np.errstate(all="ignore"):
        axis = values[:, 3:6] / np.sqrt(np.sum(values[:, 3:6] ** 2, axis=1))[:, None]
        ends = values[:, 0:3] + axis * values[:, 6:7]
        has = parent >= 0
        gap = np.full(len(values), np.inf)
        gap[has] = np.sqrt(np.sum((ends[has] - ends[parent[has]]) ** 2, axis=1))
    for i in range(len(values)):
        if not np.all(np.isfinite(ends[i])):
            raise InputError(source, f"line {lines[i]}", "cylinder end point is not finite")
        if not gap[i] >= MIN_EDGE_LENGTH:
            raise InputError(source, f"line {lines[i]}",
                             f"cylinder ends where its parent (cylinder {parent[i] + 1}) ends; zero-length edge")
    return ends


def _nodes(values: np.ndarray, parent: np.ndarray, ends: np.ndarray) -> list[dict]:
    """Native node tables for the cylinders (end nodes, plus base nodes of root cylinders)."""
    nodes = []
    for i, row in enumerate(values):
        profile = {"kind": "circle", "radius": float(row[7])}
        if parent[i] < 0:
            nodes.append({"id": f"c{i + 1}_base", "position": row[0:3].tolist(), "profile": dict(profile)})
            up = f"c{i + 1}_base"
        else:
            up = f"c{parent[i] + 1}"
        nodes.append({"id": f"c{i + 1}", "position": ends[i].tolist(), "parent": up, "profile": profile})
    return nodes


def load_treeqsm(path) -> Skeleton:
    """Load a TreeQSM cylinder table as a skeleton.

    Parameters
    ----------
    path : str or Path
        Text / CSV file with columns ``start_x start_y start_z axis_x axis_y axis_z length
        radius parent`` (comma, whitespace or tab separated; optional header; ``#`` comments).

    Returns
    -------
    Skeleton
        One node per cylinder end plus one root node per parentless cylinder start.

    Raises
    ------
    InputError
        For an unreadable or malformed table, naming the line (key ``line <n>``).
    """
    path = Path(path)
    source = str(path)
    values, lines = _rows(_read_text(path), source)
    parent = _check_rows(values, lines, source)
    _check_parent_cycles(parent, lines, source)
    ends = _ends(values, lines, parent, source)
    return parse_nodes(_nodes(values, parent, ends), source, "cylinder")
