"""Helpers shared by the scene tests: a two-node skeleton and parsing with a file name."""
from __future__ import annotations

import pytest

from wooddecay.errors import InputError
from wooddecay.scene import Scene, parse_scene

SKELETON = """
[skeleton]
node = [
  {id = "root", position = [0, 0, 0], profile = {kind = "circle", radius = 0.1}},
  {id = "tip", position = [0, 0, 1], parent = "root", profile = {kind = "circle", radius = 0.08}},
]
"""


def scene_text(extra: str = "") -> str:
    # extra first: a trailing table would otherwise swallow nothing, but keep sections apart
    return extra + "\n" + SKELETON


def parse(extra: str = "", **kw) -> Scene:
    kw.setdefault("source", "samples/log.toml")
    return parse_scene(scene_text(extra), **kw)


def error(extra: str = "", **kw) -> InputError:
    with pytest.raises(InputError) as info:
        parse(extra, **kw)
    err = info.value
    assert "\n" not in str(err)
    return err
