"""The scene: one TOML file -> a validated, frozen :class:`Scene` (docs/model.md §1).

A scene describes one simulation: the skeleton graph G (woodstock §3, Fig. 3a) and every
parameter of the paper's Table 3 (woodstock), each a key named after its symbol with the Table 3
typical value as default. ``wooddecay.scene.describe()`` prints the parameters.

* :mod:`~wooddecay.scene.schema`: every key of every table (default, unit, range, doc).
* :mod:`~wooddecay.scene.validate`: values and tables against the schema; one-line errors.
* :mod:`~wooddecay.scene.load`: reading, ``--set`` overrides, resolution.
* :mod:`~wooddecay.scene.types`: the frozen :class:`Scene` and its read-only containers.
* :mod:`~wooddecay.scene.docs`: docs/scene.md written from the schema
  (``python scripts/write_scene_docs.py``).

Sections
--------
``[scene]``        format (the scene file format, :data:`FORMAT`; default 1, a newer one is
                   refused), name (default: file stem), seed (int >= 0), quality
                   (``draft`` | ``final``), description.
``[skeleton]``     inline ``[[skeleton.node]]`` or ``file = ...`` (see
                   :func:`wooddecay.strands.skeleton_loader.load_skeleton`).
``[strands] [rings] [bsp] [weakpoints] [transport] [fungi] [moisture] [wood] [mechanics]
[time] [export]``  scalar parameters (:data:`PARAMS`).
``[tissue.<bark|sapwood|heartwood|pith>]``
                   per-tissue overrides of any key of [fungi], [moisture], [mechanics],
                   [transport], [wood] (bare names, e.g. ``alpha_w0 = 0.01``), validated against
                   that key's range.
``[[inoculation]]`` ``fungus`` (``white`` | ``brown``, required), ``activity`` in (0, 1]
                   (default 0.1), ``day`` >= 0 (default 0), ``region`` (required).
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
"""
from wooddecay.scene.load import Overrides, load_scene, parse_scene, parse_set_option
from wooddecay.scene.schema import (
    DRAFT_SCALE,
    FORMAT,
    PARAMS,
    SECTIONS,
    TABLES,
    TISSUE_KEYS,
    TISSUE_SECTIONS,
    Param,
    Table,
    describe,
    format_range,
    get_param,
)
from wooddecay.scene.types import FrozenMap, Scene, Section
from wooddecay.scene.validate import validate_value
from wooddecay.strands.rings import TISSUES

__all__ = [
    "Scene",
    "Section",
    "FrozenMap",
    "Overrides",
    "load_scene",
    "parse_scene",
    "parse_set_option",
    "Param",
    "Table",
    "PARAMS",
    "SECTIONS",
    "TABLES",
    "TISSUES",
    "TISSUE_SECTIONS",
    "TISSUE_KEYS",
    "DRAFT_SCALE",
    "FORMAT",
    "get_param",
    "describe",
    "format_range",
    "validate_value",
]
