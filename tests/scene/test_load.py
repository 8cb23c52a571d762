"""Reading and resolving scenes, overrides and --set (docs/model.md §1; wooddecay.scene.load)."""
from __future__ import annotations

import json

import pytest

from wooddecay import scene as P
from wooddecay.errors import InputError
from wooddecay.scene import load_scene, parse_scene, parse_set_option

from .conftest import SKELETON, parse


def test_minimal_scene_defaults(tmp_path):
    f = tmp_path / "mylog.toml"
    f.write_text(SKELETON)
    s = load_scene(f)
    assert s.name == "mylog"
    assert s.path == f and s.base_dir == tmp_path
    assert s.seed == 0 and s.quality == "final" and s.description == ""
    for sec, table in P.PARAMS.items():
        if sec == "scene":
            continue
        for name, p in table.items():
            if p.default is not None:
                assert getattr(getattr(s, sec), name) == p.default, (sec, name)
    assert s.strands.r_s == 0.006
    assert s.fungi.alpha_w0 == 5e-3
    assert s.time.days == 365.0 and isinstance(s.time.days, float)
    assert s.time.frames == 24 and isinstance(s.time.frames, int)
    assert s.mechanics.gravity == (0.0, 0.0, -9.81)
    assert s.moisture.schedule == ()
    assert s.export.usd is True and s.export.gltf_frame == -1
    assert s.param("fungi.alpha_w0") == 5e-3
    assert s.param("scene.seed") == 0
    with pytest.raises(KeyError):
        s.param("fungi.nope")
    assert len(s.skeleton.ids) == 2 and set(s.skeleton.ids) == {"root", "tip"}
    assert set(s.tissues) == set(P.TISSUES) and all(len(v) == 0 for v in s.tissues.values())
    assert s.inoculations == () and s.loads == ()
    d = s.strands.as_dict()
    assert d["r_s"] == 0.006 and isinstance(d, dict)
    json.dumps(s.to_dict(), allow_nan=False)


def test_full_scene():
    s = parse("""
[scene]
name = "board"
seed = 7
description = "a board"
[strands]
r_s = 0.004
connect_radius = 0.009
[fungi]
alpha_w0 = 1e-2
[moisture]
schedule = [[0, 1.0, 0.1], [180, 0.8, 0.2]]
[mechanics]
gravity = [0, 0, -1]
[tissue.heartwood]
alpha_w0 = 0.02
M_init = 0.3
[tissue.bark]
a_l = 1
[[inoculation]]
fungus = "brown"
region = {kind = "sphere", center = [0, 0, 0.5], radius = 0.05}
[[inoculation]]
fungus = "white"
activity = 0.5
day = 10
region = {kind = "node", id = "tip", radius = 0.1}
[[inoculation]]
fungus = "white"
region = {kind = "end", depth = 0.02}
[[inoculation]]
fungus = "white"
region = {kind = "wound", position = [0.1, 0, 0.5], radius = 0.02, depth = 0.01, space = "world"}
[[inoculation]]
fungus = "brown"
region = {kind = "box", min = [0, 0, 0], max = [0.05, 6.3, 0.2], space = "wood"}
[[load]]
region = {kind = "end", which = "tip", depth = 0.05}
force = [0, 10, 0]
days = [100, 101]
""")
    assert s.name == "board" and s.seed == 7
    assert s.strands.connect_radius == 0.009
    assert s.moisture.schedule == ((0.0, 1.0, 0.1), (180.0, 0.8, 0.2))
    assert s.tissue_param("heartwood", "alpha_w0") == 0.02
    assert s.tissue_param("heartwood", "fungi.alpha_w0") == 0.02
    assert s.tissue_param("sapwood", "alpha_w0") == 1e-2
    assert s.tissue_param("bark", "a_l") == 1.0
    assert s.tissue_param("heartwood", "M_init") == 0.3
    with pytest.raises(KeyError):
        s.tissue_param("heartwood", "moisture.alpha_w0")
    with pytest.raises(KeyError):
        s.tissue_param("wood", "alpha_w0")
    inoc = s.inoculations
    assert [i["fungus"] for i in inoc] == ["brown", "white", "white", "white", "brown"]
    assert inoc[0]["activity"] == 0.1 and inoc[0]["day"] == 0.0 and inoc[0]["region"]["space"] == "world"
    assert inoc[1]["region"]["id"] == "tip" and inoc[1]["day"] == 10.0
    assert inoc[2]["region"]["which"] == "root"
    assert inoc[4]["region"]["space"] == "wood"
    with pytest.raises(TypeError):
        inoc[0]["fungus"] = "white"
    assert s.loads[0]["days"] == (100.0, 101.0) and s.loads[0]["force"] == (0.0, 10.0, 0.0)
    json.dumps(s.to_dict(), allow_nan=False)


def test_integer_node_id_and_integral_float_for_int():
    text = """
[bsp]
cells = 1e3
[[inoculation]]
fungus = "white"
region = {kind = "node", id = 2, radius = 0.1}
[skeleton]
node = [
  {id = 1, position = [0, 0, 0], profile = {kind = "circle", radius = 0.1}},
  {id = 2, position = [0, 0, 1], parent = 1, profile = {kind = "circle", radius = 0.08}},
]
"""
    s = parse_scene(text)
    assert s.bsp.cells == 1000 and isinstance(s.bsp.cells, int)
    assert s.inoculations[0]["region"]["id"] == "2"


def test_connect_radius_default():
    s = parse("[strands]\nr_s = 0.01")
    assert s.strands.connect_radius == pytest.approx(0.025)
    assert parse().strands.connect_radius == pytest.approx(2.5 * 0.006)


def test_duration_in_days_or_years():
    """time.years sets time.days (365.25 days a year); a file may give both only if they agree;
    an override of one replaces the file's other."""
    from .conftest import error

    assert parse("[time]\nyears = 2").time.days == pytest.approx(730.5)
    assert parse("[time]\ndays = 730.5\nyears = 2").time.days == pytest.approx(730.5)
    assert parse().time.days == 365.0
    e = error("[time]\ndays = 100\nyears = 2")
    assert e.key == "time.days" and "give one of the two" in str(e)
    assert parse("[time]\nyears = 2", overrides={"time.days": 10}).time.days == 10
    assert parse("[time]\ndays = 10", overrides={"time.years": 0.5}).time.days == pytest.approx(182.625)


def test_quality_draft_scales_strands():
    final = parse()
    draft = parse("[scene]\nquality = 'draft'")
    assert draft.quality == "draft"
    assert draft.strands.r_s == pytest.approx(1.5 * final.strands.r_s)
    assert draft.strands.rod_length == pytest.approx(1.5 * final.strands.rod_length)
    assert draft.strands.connect_radius == pytest.approx(2.5 * draft.strands.r_s)
    explicit = parse("[scene]\nquality = 'draft'\n[strands]\nr_s = 0.01\nconnect_radius = 0.03")
    assert explicit.strands.r_s == pytest.approx(0.015)
    assert explicit.strands.connect_radius == pytest.approx(0.045)
    # validation happens before scaling: r_s = 1 is allowed even though 1.5 is outside (0, 1]
    assert parse("[scene]\nquality = 'draft'\n[strands]\nr_s = 1").strands.r_s == pytest.approx(1.5)
    assert draft.hash != final.hash


def test_skeleton_errors_are_input_errors():
    with pytest.raises(InputError) as info:
        parse_scene("[strands]\nr_s = 0.01\n", source="a.toml")
    assert info.value.key == "skeleton" and info.value.file == "a.toml"
    with pytest.raises(InputError):
        parse_scene("skeleton = 3\n")
    with pytest.raises(InputError):
        parse_scene("[skeleton]\nnode = [{id = 'a', position = [0, 0, 0], profile = {kind = 'circle', radius = -1}}]")


def test_syntax_and_file_errors(tmp_path):
    with pytest.raises(InputError) as info:
        parse_scene("[strands]\nr_s = = 1\n", source="bad.toml")
    assert info.value.file == "bad.toml" and "line 2" in str(info.value)
    with pytest.raises(InputError) as info:
        load_scene(tmp_path / "missing.toml")
    assert info.value.file.endswith("missing.toml") and "cannot read" in info.value.message
    with pytest.raises(InputError):
        load_scene(tmp_path)  # a directory
    bad = tmp_path / "latin1.toml"
    bad.write_bytes(b"[scene]\nname = '\xe9'\n")
    with pytest.raises(InputError) as info:
        load_scene(bad)
    assert "UTF-8" in info.value.message
    with pytest.raises(InputError):
        parse_scene(b"\xff\xfe")
    with pytest.raises(InputError):
        load_scene(None)  # type: ignore[arg-type]
    with pytest.raises(InputError):
        parse_scene("a = " + "[" * 5000)


def test_bom_and_bytes_accepted():
    s = parse_scene(("\ufeff" + SKELETON).encode("utf-8"))
    assert len(s.skeleton.ids) == 2


def test_skeleton_file_relative_to_scene(tmp_path):
    (tmp_path / "sk").mkdir()
    (tmp_path / "sk" / "nodes.toml").write_text("""
[[node]]
id = "a"
position = [0, 0, 0]
profile = {kind = "circle", radius = 0.1}
[[node]]
id = "b"
parent = "a"
position = [1, 0, 0]
profile = {kind = "ellipse", a = 0.1, b = 0.05}
""")
    (tmp_path / "scene.toml").write_text("[skeleton]\nfile = 'sk/nodes.toml'\n")
    s = load_scene(tmp_path / "scene.toml")
    assert s.skeleton.ids == ("a", "b")
    json.dumps(s.to_dict(), allow_nan=False)


def test_parse_set_option():
    o = parse_set_option(["strands.r_s=0.01", "scene.name = my log", "export.usd=false",
                          "mechanics.gravity=[0, 0, -1]", "scene.description=a=b", "tissue.heartwood.alpha_w0=2e-2",
                          "scene.name=x\ny = 2"])
    assert o["strands.r_s"] == 0.01
    assert o["export.usd"] is False
    assert o["mechanics.gravity"] == [0, 0, -1]
    assert o["scene.description"] == "a=b"
    assert o["tissue.heartwood.alpha_w0"] == 0.02
    assert o["scene.name"] == "x\ny = 2"  # not silently two TOML keys
    assert parse_set_option([]) == {}
    for bad in ["strands.r_s", "r_s=1", "=1", "strands.=1", ".r_s=1", "a b.c=1"]:
        with pytest.raises(InputError) as info:
            parse_set_option([bad])
        assert info.value.file == "<--set>"
    with pytest.raises(InputError):
        parse_set_option([3])  # type: ignore[list-item]
    with pytest.raises(InputError):
        parse_set_option("strands.r_s=1")  # type: ignore[arg-type]


def test_overrides_applied_and_validated(tmp_path):
    f = tmp_path / "log.toml"
    f.write_text("[time]\ndays = 100\n" + SKELETON)
    s = load_scene(f, overrides={"time.days": 30, "scene.seed": 3, "tissue.heartwood.alpha_w0": 0.02})
    assert s.time.days == 30.0 and s.seed == 3
    assert s.tissue_param("heartwood", "alpha_w0") == 0.02
    assert s.tissue_param("sapwood", "alpha_w0") == 5e-3
    s = load_scene(f, overrides=parse_set_option(["strands.r_s=0.01", "scene.quality=draft"]))
    assert s.strands.r_s == pytest.approx(0.015) and s.quality == "draft"

    cases = [
        ({"strands.r_s": -1}, "<overrides>", "strands.r_s", "outside (0, 1] m"),
        ({"strands.rs": 1}, "<overrides>", "strands.rs", "did you mean 'r_s'?"),
        ({"strand.r_s": 1}, "<overrides>", "strand.r_s", "did you mean 'strands'?"),
        ({"tissue.heartwod.alpha_w0": 1}, "<overrides>", "tissue.heartwod.alpha_w0", "did you mean 'heartwood'?"),
        ({"tissue.heartwood.r_s": 1}, "<overrides>", "tissue.heartwood.r_s", "cannot be set per tissue"),
        ({"tissue.heartwood": 1}, "<overrides>", "tissue.heartwood", "tissue.<tissue>.<key>"),
        ({"strands": 1}, "<overrides>", "strands", "expected strands.<key>"),
        ({"time.days": True}, "<overrides>", "time.days", "boolean"),
        ({"tissue.bark.M_2": 5.0}, "<overrides>", "tissue.bark.M_2", "tissue.bark.M_1"),
        ({"moisture.M_2": 1.0}, "<overrides>", "moisture.M_2", "moisture.M_1"),
    ]
    for over, file, key, needle in cases:
        with pytest.raises(InputError) as info:
            load_scene(f, overrides=over)
        assert (info.value.file, info.value.key) == (file, key), str(info.value)
        assert needle in info.value.message, str(info.value)
    with pytest.raises(InputError) as info:
        load_scene(f, overrides=parse_set_option(["time.days=-5"]))
    assert str(info.value) == "<--set>: time.days: -5 is outside [0, 1000000] day"
    with pytest.raises(InputError) as info:
        load_scene(f, overrides=parse_set_option(["time.dayz=5"]))
    assert info.value.file == "<--set>"


def test_override_error_in_file_still_names_file(tmp_path):
    f = tmp_path / "log.toml"
    f.write_text("[strands]\nphi_pack = 2\n" + SKELETON)
    with pytest.raises(InputError) as info:
        load_scene(f, overrides={"strands.r_s": 0.01})
    assert info.value.file == str(f) and info.value.key == "strands.phi_pack"


def test_parse_scene_takes_the_parsed_toml_mapping(tmp_path):
    """A scene built in code (a dict as tomllib returns it) validates like its text and is
    not changed by the parse."""
    import copy
    import tomllib
    from pathlib import Path
    path = Path(__file__).resolve().parent.parent.parent / "wooddecay" / "samples" / "tiny.toml"
    data = tomllib.loads(path.read_text())
    before = copy.deepcopy(data)
    assert parse_scene(data, source=str(path), base_dir=path.parent).hash == load_scene(path).hash
    assert data == before
    data["strands"]["r_s"] = -1.0
    with pytest.raises(InputError, match="strands.r_s"):
        parse_scene(data, source="built")


def test_overrides_reach_entry_tables():
    """``inoculation.<i>.<key>`` and ``inoculation.<i>.region.<key>`` edit an entry of the file;
    a missing index, a malformed key and a bad value are one-line errors naming the override."""
    extra = '[[inoculation]]\nfungus = "brown"\nregion = { kind = "sphere", center = [0, 0, 0.5], radius = 0.05 }\n'
    s = parse(extra, overrides={"inoculation.0.fungus": "white", "inoculation.0.region.radius": 0.1})
    assert s.inoculations[0]["fungus"] == "white" and s.inoculations[0]["region"]["radius"] == 0.1
    for key, value, words in (("inoculation.1.fungus", "white", "no index 1"),
                              ("inoculation.x.fungus", "white", "inoculation.<index>.<key>"),
                              ("inoculation.0.fungus", "green", "is not one of")):
        with pytest.raises(InputError) as info:
            parse(extra, overrides={key: value})
        assert info.value.file == "<overrides>" and words in str(info.value), str(info.value)
