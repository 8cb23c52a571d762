"""docs/scene.md, written from the schema: every table and key of a scene file with its default,
unit, allowed range and meaning.

:func:`scene_docs` returns the page; ``python scripts/write_scene_docs.py`` writes it (and
``--check`` says whether the committed page is current). tests/scene/test_scene_docs.py fails when
the schema changes and the page was not regenerated. The scalar sections, entry tables and tissue
defaults come from :mod:`wooddecay.scene.schema`; the ``[skeleton]`` table is read by
:mod:`wooddecay.strands.skeleton_loader`, whose keys are described here (:data:`SKELETON_ROWS`)
and checked against that module's key lists, so a new skeleton key without a row fails too.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from wooddecay.errors import format_value
from wooddecay.export.usd import FORMAT as STAGE_FORMAT
from wooddecay.export.usd import FORMAT_KEY as STAGE_FORMAT_KEY
from wooddecay.export.usd import FORMAT_UNDECLARED as STAGE_FORMAT_UNDECLARED
from wooddecay.scene.schema import (
    ARRAY_TABLES,
    BARK_SPECIES,
    CONDITIONAL,
    DRAFT_SCALE,
    FORMAT,
    FORMAT_MIN,
    FORMAT_UNDECLARED,
    PARAMS,
    TABLES,
    TISSUE_DEFAULTS,
    TISSUE_KEYS,
    TISSUE_SECTIONS,
    Param,
    _num,
    default_text,
    format_range,
)

#: where the page lives, relative to the repository root
DOCS_PATH = Path("docs") / "scene.md"
#: the command that regenerates it (named by the test that fails when it is stale)
COMMAND = "python scripts/write_scene_docs.py"

#: ``(table, key, default, unit, allowed, meaning)`` of the ``[skeleton]`` table, its nodes and
#: their profiles (:mod:`wooddecay.strands.skeleton_loader`, :mod:`wooddecay.strands.skeleton`).
SKELETON_ROWS: tuple[tuple[str, str, str, str, str, str], ...] = (
    ("skeleton", "node", "", "", "an array of node tables",
     "Inline nodes, written `[[skeleton.node]]` (keys below). Exactly one of `node`, `file`, `mesh` and "
     "`points` is given."),
    ("skeleton", "file", "", "", "a path string",
     "A skeleton file, relative to the scene file: a native TOML file of `[[node]]` tables (the keys of "
     "`[[skeleton.node]]`) or a TreeQSM cylinder table (.csv, .txt)."),
    ("skeleton", "format", "from the file's extension", "", "one of 'native', 'treeqsm'",
     "Format of `file`: .toml is native, .csv and .txt TreeQSM; inline nodes are always native."),
    ("skeleton", "mesh", "", "", "a path string",
     "A closed surface mesh (OBJ, PLY, STL, glTF/GLB, USD), relative to the scene file: the centreline "
     "and cross-sections are built from it."),
    ("skeleton", "points", "", "", "a path string",
     "A scanned point cloud (PLY, XYZ, LAS), relative to the scene file, lofted into a closed surface "
     "and built as `mesh`."),
    ("skeleton", "scale", "1", "", "(0, inf)",
     "Factor on the coordinates of the nodes or of the mesh (0.01 for a mesh in centimetres)."),
    ("skeleton", "largest", "false", "", "true or false",
     "With `mesh`: keep the largest of several disjoint bodies."),
    ("skeleton", "spacing", "mean radius of the surface", "m", "(0, inf)",
     "With `mesh` or `points`: the spacing of the nodes along the centreline."),
    ("skeleton", "up", "glTF y, USD the stage's, others z", "", "one of 'y', 'z'",
     "With `mesh` or `points`: the file's up axis."),
    ("skeleton.node", "id", "required", "", "a non-empty string or an integer",
     "Node id, unique in the skeleton (inoculation and load regions of kind `node` name it)."),
    ("skeleton.node", "position", "required", "m", "a list of 3 finite numbers [x, y, z]",
     "Position of the node (world frame, Z up)."),
    ("skeleton.node", "parent", "none (a root)", "", "the id of another node",
     "The node this one grows from; the nodes form a forest without cycles, no edge shorter than 1e-9 m."),
    ("skeleton.node", "profile", "required", "", "a profile table {kind = ..., ...}",
     "Cross-section at the node, in the plane across the wood (keys below)."),
    ("skeleton.node", "anchored", "false", "", "true or false",
     "Hold a root node in place (a stump); only a root can be anchored."),
    ("profile", "kind", "required", "", "one of 'circle', 'ellipse', 'polygon'", "Profile kind."),
    ("profile", "radius", "required", "m", "(0, inf)", "`circle`: radius."),
    ("profile", "a", "required", "m", "(0, inf)", "`ellipse`: semi-axis along the rotated u axis."),
    ("profile", "b", "required", "m", "(0, inf)", "`ellipse`: semi-axis along the rotated v axis."),
    ("profile", "angle", "0", "rad", "any finite number",
     "`ellipse`: rotation of the `a` axis from u, counter-clockwise."),
    ("profile", "points", "required", "m", "a list of [u, v] points",
     "`polygon`: at least 3 points, counter-clockwise, a simple polygon with non-zero area."),
)


def allowed_text(p: Param) -> str:
    """:func:`~wooddecay.scene.schema.format_range` without the unit (the page has a unit column)."""
    return format_range(replace(p, unit=""))


def _cell(text: str) -> str:
    """One table cell: one line, ``|`` escaped, ``<``/``>`` escaped outside code spans (so that
    ``<name>.usdc`` is not taken for an HTML tag)."""
    parts = " ".join(str(text).split()).replace("|", "\\|").split("`")
    for k in range(0, len(parts), 2):
        parts[k] = parts[k].replace("<", "&lt;").replace(">", "&gt;")
    return "`".join(parts)


def _table(rows: list[tuple[str, ...]]) -> list[str]:
    lines = ["| key | default | unit | allowed | meaning |", "|---|---|---|---|---|"]
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in rows]
    return lines + [""]


def _param_rows(params, required: bool = False) -> list[tuple[str, ...]]:
    return [(f"`{p.name}`", default_text(p, required), p.unit, allowed_text(p), p.doc + _when(p)) for p in params]


def _when(p) -> str:
    """" Acts only ..." for a key of :data:`~wooddecay.scene.schema.CONDITIONAL`."""
    return f" *Acts only {CONDITIONAL[p.key][0]}.*" if p.key in CONDITIONAL else ""


def _check_skeleton_rows() -> None:
    """The rows of :data:`SKELETON_ROWS` are exactly the keys the skeleton loader reads."""
    from wooddecay.strands.skeleton import NODE_KEYS, PROFILE_KEYS
    from wooddecay.strands.skeleton_loader import TABLE_KEYS

    want = {"skeleton": set(TABLE_KEYS), "skeleton.node": set(NODE_KEYS),
            "profile": {k for keys in PROFILE_KEYS.values() for k in keys}}
    have: dict[str, set[str]] = {}
    for table, key, *_ in SKELETON_ROWS:
        have.setdefault(table, set()).add(key)
    if have != want:
        raise AssertionError(f"wooddecay/scene_docs.py SKELETON_ROWS {have} != the skeleton loader's keys {want}")


_INTRO = f"""\
# Scene files

<!-- Generated from wooddecay/scene/schema.py by `{COMMAND}`; do not edit by hand. -->

A scene is one TOML file that describes one simulation: the skeleton of the wood and every
parameter of the model (docs/model.md). Every key is optional unless marked *required*; a key left
out takes its default. Units are SI: lengths in m, biology time in days, mechanics time in s,
moisture content in kg/kg. `wooddecay init NAME` writes a starting scene; the scenes in `samples/`
are examples.

Any key can be overridden at the command line with `--set section.key=value` (a TOML value:
`--set strands.r_s=0.005`, `--set tissue.heartwood.alpha_w0=0.01`, `--set inoculation.0.fungus=brown`,
`--set load.0.region.radius=0.1`), through the Python API with `overrides={{"time.days": 30}}`, and in
a batch file's `[batch.set]` and `[batch.grid]`. Overrides are checked exactly like file values.
A value that is wrong, out of range or inconsistent with another is refused with one line naming
the file, the key and what is allowed (exit code 2).

Every key changes a bake. A key marked *Acts only ...* changes it only in scenes of that kind (a
drying span, a clamp, a load); `tests/test_keys.py` bakes each key moved off its value, under that
condition where there is one (docs/decisions.md, "Every key acts, or says when").

## Format version

`[scene] format` is the version of the scene file format: this wooddecay reads formats
[{FORMAT_MIN}, {FORMAT}] and its samples declare `format = {FORMAT}`. A file without the key was written
before the key existed and is read as format {FORMAT_UNDECLARED}. A scene that declares a newer format is
refused before any other key is looked at, in one line:
`scene.toml: scene.format: format {FORMAT + 1} is newer than wooddecay X.Y.Z reads (formats [{FORMAT_MIN}, {FORMAT}]); upgrade wooddecay to read this scene`.
The format says how the file is read, not what is simulated: it is not part of the scene hash,
so a scene gives the same outputs, caches and stage whether it declares `format = {FORMAT}` or not.
A change to what scene files mean bumps the format and is listed in CHANGELOG.md.

The baked USD stage records its own format in its customLayerData
(`{STAGE_FORMAT_KEY} = {STAGE_FORMAT}`): `wooddecay diff` and `wooddecay inspect BAKE_DIR` refuse a
stage of a newer format in one line, and read a stage without the key (an older bake) as
format {STAGE_FORMAT_UNDECLARED}.

## Tables
"""


def scene_docs() -> str:
    """The text of docs/scene.md (module docstring)."""
    _check_skeleton_rows()
    lines = _INTRO.splitlines()
    sections = list(PARAMS)
    toc = [f"[{s}]" for s in sections[:1]] + ["[skeleton]"] + [f"[{s}]" for s in sections[1:]]
    toc += ["[tissue.<tissue>]"] + [f"[[{t}]]" if t in ARRAY_TABLES else t for t in TABLES]
    lines += ["", ", ".join(f"`{t}`" for t in toc) + ".", ""]

    for k, section in enumerate(sections):
        lines += [f"## [{section}]", ""]
        if section in TISSUE_SECTIONS:
            lines += ["Every key of this table may be overridden per tissue in `[tissue.<tissue>]`.", ""]
        if section == "scene":
            lines += [f"`quality = \"draft\"` multiplies `strands.r_s`, `strands.rod_length` and "
                      f"`strands.connect_radius` by {_num(DRAFT_SCALE)} after validation.", ""]
        if section == "bark":
            lines += ["Species presets (`pattern`, `threshold`, `tip_gain`, `noise` where the scene leaves them "
                      "out):", "",
                      "| species | " + " | ".join(next(iter(BARK_SPECIES.values()))) + " |",
                      "|---|" + "---|" * len(next(iter(BARK_SPECIES.values())))]
            lines += ["| " + " | ".join([name] + [f'"{v}"' if isinstance(v, str) else format_value(v)
                                                  for v in preset.values()]) + " |"
                      for name, preset in BARK_SPECIES.items()]
            lines.append("")
        lines += _table(_param_rows(PARAMS[section].values()))
        if k == 0:
            lines += _skeleton_section()

    lines += _tissue_section()
    intros = {
        "inoculation": "Where and when a fungus starts; one table per inoculation.",
        "load": "A force on a region over an interval of days (woodstock Fig. 17); one table per load.",
        "collider": "A solid obstacle for the rods (woodstock §5.1); the ground plane is `[mechanics] ground`.",
        "region": "The `region` of an `[[inoculation]]` or a `[[load]]`: an inline table "
                  "`region = { kind = \"box\", min = [...], max = [...] }`. In `wood` space coordinates "
                  "are wood-local (r, phi, s).",
    }
    for name, table in TABLES.items():
        title = f"[[{name}]]" if name in ARRAY_TABLES else name
        lines += [f"## {title}", "", intros[name], ""]
        lines += _table(_param_rows(table.keys.values(), required=True))
        for kind, keys in table.kinds.items():
            lines += [f"### {title}: kind = \"{kind}\"", ""]
            lines += _table(_param_rows(keys.values(), required=True))
    while lines and lines[-1] == "":
        lines.pop()
    return "\n".join(lines) + "\n"


def _skeleton_section() -> list[str]:
    lines = ["## [skeleton]", "",
             "The skeleton graph of the wood (required): nodes with positions, parents and cross-section "
             "profiles, given inline, in a file, or built from a surface mesh or a point cloud "
             "(wooddecay/strands/skeleton_loader.py).", ""]
    titles = {"skeleton": None, "skeleton.node": "### [[skeleton.node]]",
              "profile": "### profile (of a node): `profile = { kind = \"circle\", radius = 0.1 }`"}
    for table, title in titles.items():
        if title:
            lines += [title, ""]
        lines += _table([(f"`{key}`", default, unit, allowed, meaning)
                         for t, key, default, unit, allowed, meaning in SKELETON_ROWS if t == table])
    return lines


def _tissue_section() -> list[str]:
    from wooddecay.strands.rings import TISSUES

    lines = ["## [tissue.&lt;tissue&gt;]", "",
             f"Per-tissue values, `[tissue.{TISSUES[0]}]` ... for the tissues {', '.join(f'`{t}`' for t in TISSUES)}: "
             "any key of " + ", ".join(f"`[{s}]`" for s in TISSUE_SECTIONS) + " by its bare name "
             "(`alpha_w0 = 0.01`), checked against that key's range. A key a tissue leaves out takes the "
             "section's value, or the tissue default below.", "",
             "Keys: " + ", ".join(f"`{name}`" for name in TISSUE_KEYS) + ".", "",
             "### Tissue defaults", "",
             "| tissue | key | default | why |", "|---|---|---|---|"]
    for tissue, table in TISSUE_DEFAULTS.items():
        for name, d in table.items():
            value = f"{_num(d.value)} x the section's value" if d.relative else _num(d.value)
            lines.append(f"| {tissue} | `{name}` | {value} | {_cell(d.why)} |")
    return lines + [""]


def write(root: Path) -> Path:
    """Write :func:`scene_docs` to ``root``/docs/scene.md; returns the path."""
    path = Path(root) / DOCS_PATH
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(scene_docs().encode("utf-8"))
    return path
