"""The frozen Scene: read-only, picklable, identified by its hash (docs/model.md §1; wooddecay.scene.types)."""
from __future__ import annotations

import pickle

import pytest

from wooddecay.scene import load_scene, parse_scene

from .conftest import SKELETON, parse


def test_scene_is_frozen_and_picklable():
    s = parse()
    with pytest.raises(AttributeError):
        s.name = "x"
    with pytest.raises(AttributeError):
        s.strands.r_s = 1.0
    with pytest.raises(TypeError):
        s.strands["r_s"] = 1.0
    with pytest.raises(AttributeError):
        s.strands.no_such_key
    s2 = pickle.loads(pickle.dumps(s))
    assert s2.hash == s.hash and s2.strands.r_s == s.strands.r_s


def test_hash_stable_and_sensitive(tmp_path):
    a = parse()
    b = parse()
    assert a.hash == b.hash and len(a.hash) == 64
    assert parse("[fungi]\nalpha_w0 = 0.006").hash != a.hash
    assert parse("[scene]\nseed = 1").hash != a.hash
    assert parse("[tissue.bark]\nalpha_w0 = 0.006").hash != a.hash
    assert parse("[[inoculation]]\nfungus = 'white'\nregion = {kind = 'end', depth = 0.1}").hash != a.hash
    moved = parse_scene(SKELETON.replace("[0, 0, 1]", "[0, 0, 2]"), source="samples/log.toml")
    assert moved.hash != a.hash
    # explicit defaults and comment/whitespace changes do not change the hash
    assert parse("# comment\n[strands]\nr_s = 0.006\n[fungi]\nalpha_w0 = 5e-3").hash == a.hash
    # the location of the file does not matter (same stem)
    for d in ("x", "y"):
        (tmp_path / d).mkdir()
        (tmp_path / d / "log.toml").write_text(SKELETON)
    assert load_scene(tmp_path / "x" / "log.toml").hash == load_scene(tmp_path / "y" / "log.toml").hash
    assert load_scene(tmp_path / "x" / "log.toml").hash == a.hash
    assert parse(base_dir=tmp_path).hash == a.hash
