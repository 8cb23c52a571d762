"""The settled-state cache (wooddecay.sim.settled): keyed by the wood, not the days or outputs;
loading gives the bits settling gives; a broken file, or one other code wrote, is settled again."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.atomic import tree_hash
from wooddecay.sim import settled

from ..conftest import SAMPLES


def model(**overrides):
    return wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", overrides=overrides))


def arrays(sim) -> dict:
    """The rods, their clock and the bark."""
    return {**sim.state.mech.arrays(), "t": np.array(sim.state.mech.t_seconds),
            **{f"bark_{k}": v for k, v in sim.state.bark.arrays().items()}}


def test_a_cached_settle_gives_the_settled_bits(tmp_path):
    """Rods and the bark's day-0 cracks, loaded, are the bits settling and cracking give."""
    first = wd.Simulation(model(), settle_cache=tmp_path)
    assert first.state.bark.crack.cracked.any()
    assert first.settled == "settled" and len(list(tmp_path.glob("*.npz"))) == 1
    again = wd.Simulation(model(**{"time.days": 3.0, "time.frames": 2, "scene.name": "other"}),
                          settle_cache=tmp_path)
    assert again.settled == "cached"
    a, b = arrays(first), arrays(again)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    bare = wd.Simulation(model())
    assert bare.settled == "settled" and all(np.array_equal(arrays(bare)[k], a[k]) for k in a)


def test_another_bark_loads_the_rods_and_cracks_its_own_bark(tmp_path):
    """[bark] is not in the key: of another crack threshold the rods are loaded and the bark is
    cracked again, the bits of a bake without the cache."""
    first = arrays(wd.Simulation(model(), settle_cache=tmp_path))
    other = {"bark.threshold": 0.5 * model().bark_setup.threshold}
    again = wd.Simulation(model(**other), settle_cache=tmp_path)
    assert again.settled == "cached"
    a, b = arrays(again), arrays(wd.Simulation(model(**other)))
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert a["bark_cracked"].sum() > first["bark_cracked"].sum()


def test_another_inoculation_loads_the_rods_it_would_settle(tmp_path):
    """[[inoculation]] is not in the key: the fungal activity it sets is not the rods' business."""
    wd.Simulation(model(), settle_cache=tmp_path)
    other = {"inoculation.0.activity": 0.5, "inoculation.0.fungus": "white"}
    again = wd.Simulation(model(**other), settle_cache=tmp_path)
    assert again.settled == "cached" and not np.array_equal(again.state.R_w, wd.Simulation(model()).state.R_w)
    a, b = arrays(again), arrays(wd.Simulation(model(**other)))
    assert all(np.array_equal(a[k], b[k]) for k in a)


def test_the_key_covers_the_wood_and_not_the_schedule():
    base = model().info.settle_hash
    assert model(**{"time.days": 9.0, "time.schedule": "fixed", "export.gltf": False}).info.settle_hash == base
    assert model(**{"mechanics.E": 2e9}).info.settle_hash != base
    assert model(**{"scene.seed": 2}).info.settle_hash != base


@pytest.mark.parametrize("damage", [b"not an npz", b"PK\x03\x04 truncated"])
def test_a_broken_cache_file_is_settled_again(tmp_path, damage):
    m = model()
    path = tmp_path / f"{m.info.settle_hash}.npz"
    path.write_bytes(damage)
    assert wd.Simulation(m, settle_cache=tmp_path).settled == "settled"
    assert wd.Simulation(m, settle_cache=tmp_path).settled == "cached"


def test_a_state_other_code_settled_is_settled_again(tmp_path, monkeypatch):
    """The file records the hash of the package's sources: a state settled by older (or newer)
    code would start the bake from other bits than settling gives."""
    m = model()
    monkeypatch.setattr(settled, "code_hash", lambda: "older code")
    assert wd.Simulation(m, settle_cache=tmp_path).settled == "settled"
    assert wd.Simulation(m, settle_cache=tmp_path).settled == "cached"
    monkeypatch.undo()
    assert wd.Simulation(m, settle_cache=tmp_path).settled == "settled"
    assert wd.Simulation(m, settle_cache=tmp_path).settled == "cached"


def test_the_code_hash_follows_the_sources(tmp_path):
    (tmp_path / "sim").mkdir()
    (tmp_path / "sim" / "rods.py").write_text("K = 1\n")
    first = tree_hash(tmp_path, "*.py")
    (tmp_path / "notes.txt").write_text("not a source")
    assert tree_hash(tmp_path, "*.py") == first
    (tmp_path / "sim" / "rods.py").write_text("K = 2\n")
    assert tree_hash(tmp_path, "*.py") != first
    assert settled.code_hash() is settled.code_hash()  # hashed once per process


def test_the_cache_folder_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(settled.ENV, "off")
    assert settled.default_folder() is None
    monkeypatch.setenv(settled.ENV, str(tmp_path))
    assert settled.default_folder() == tmp_path
    monkeypatch.delenv(settled.ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    assert settled.default_folder() == tmp_path / "wooddecay" / "settled"
