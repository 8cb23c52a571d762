"""Studies beside the pipeline, never imported by it: the validation cases the paper checks
against and their charts (``wooddecay chart``, ``benchmarks/``, ``tests/studies/``).

* :mod:`.transport`: heat kernels and Fisher-KPP fronts on the rod graph (docs/model.md §7).
* :mod:`.cantilever`: a single clamped strand: gravity sag, tip moment, buckling (docs/model.md §7
  "Mechanics"); :mod:`.elastica`: PyElastica's reference run; :mod:`.mechanics_chart`: cost
  against accuracy of the rod solver.
* :mod:`.barrier`: the barrier effect (woodstock §9.4, Fig. 18).
* :mod:`.pull`: the pull test (woodstock Fig. 17); :mod:`.debris`: debris settling (§5.4).

Scene templates live in ``scenes/*.toml`` (:func:`scene_template`).
"""
from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ..scene import Scene, load_scene, parse_scene

#: the folder of the scene templates
SCENES = Path(__file__).resolve().parent / "scenes"


def scene_template(name: str, overrides: Mapping[str, Any], nodes: list[dict] | None = None) -> Scene:
    """The scene ``scenes/<name>.toml`` with ``overrides`` (dotted keys, as
    :func:`wooddecay.scene.load_scene` takes them). ``nodes``, when given, are its
    ``[[skeleton.node]]`` tables: a skeleton that varies with the study's parameters, which
    dotted keys do not reach."""
    path = SCENES / f"{name}.toml"
    if nodes is None:
        return load_scene(path, overrides=overrides)
    data = tomllib.loads(path.read_text("utf-8"))
    data["skeleton"] = {"node": nodes}
    return parse_scene(data, source=str(path), base_dir=path.parent, overrides=overrides)
