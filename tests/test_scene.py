"""Scene loading and validation (SPEC §1; wooddecay.scene, wooddecay.params)."""
from __future__ import annotations

import json
import math
import pickle
import string

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wooddecay import params as P
from wooddecay.errors import InputError
from wooddecay.scene import Scene, load_scene, parse_scene, parse_set_option

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


# ------------------------------------------------------------------------------------ schema

def test_schema_keys_unique_across_tissue_sections():
    seen = set()
    for sec in P.TISSUE_SECTIONS:
        for name in P.PARAMS[sec]:
            assert name not in seen
            seen.add(name)
    assert set(P.TISSUE_KEYS) == seen


def test_schema_defaults_validate_and_have_docs():
    for sec, table in P.PARAMS.items():
        for name, p in table.items():
            assert p.section == sec and p.name == name
            assert p.doc and "\n" not in p.doc
            if p.default is not None:
                assert P.validate_value(p, p.default, "x") == p.default
    assert "alpha_w0" in P.describe()


def test_table3_symbols_present():
    for key in ["fungi.alpha_w0", "fungi.D_b", "moisture.k_DM", "mechanics.M_0", "mechanics.S", "mechanics.s",
                "mechanics.p_l_bend", "mechanics.k_c", "mechanics.k_l", "mechanics.k_col", "mechanics.mu_f"]:
        P.get_param(key)
    assert P.get_param("fungi.alpha_w0").unit == "1/day"
    # SI units need a stiffer contact than Table 3's 30 N/m^2 (docs/decisions.md); the doc says so
    assert P.get_param("mechanics.k_col").default == 1e7 and "30" in P.get_param("mechanics.k_col").doc


# ------------------------------------------------------------------------------- valid scene

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


# -------------------------------------------------------------------------------- errors

@pytest.mark.parametrize("extra, key, needle", [
    ("[strands]\nr_s = -1", "strands.r_s", "-1 is outside (0, 1] m"),
    ("[strands]\nr_s = 0", "strands.r_s", "(0, 1] m"),
    ("[strands]\nr_s = 'big'", "strands.r_s", "got string 'big'"),
    ("[strands]\nr_s = true", "strands.r_s", "got boolean true"),
    ("[strands]\nr_s = [1]", "strands.r_s", "got array"),
    ("[strands]\nr_s = nan", "strands.r_s", "not a finite number"),
    ("[strands]\nr_s = inf", "strands.r_s", "not a finite number"),
    ("[weakpoints]\nk_W = 1.0", "weakpoints.k_W", "1.0 is outside [0, 1)"),
    ("[fungi]\nD_w = 1", "fungi.D_w", "outside [0, 0.01] m^2/day"),
    ("[fungi]\nalpha_w0 = -0.1", "fungi.alpha_w0", "[0, 10] 1/day"),
    ("[time]\nframes = 0", "time.frames", "0 is outside [1, 100000]"),
    ("[time]\nframes = 2.5", "time.frames", "expected an integer in [1, 100000]"),
    ("[time]\nframes = true", "time.frames", "got boolean"),
    ("[scene]\nseed = -1", "scene.seed", "-1 is outside [0, inf)"),
    ("[scene]\nquality = 'best'", "scene.quality", "one of 'draft', 'final'"),
    ("[scene]\nname = 3", "scene.name", "expected a string"),
    ("[export]\nusd = 1", "export.usd", "expected true or false"),
    ("[export]\ngltf_frame = 1.5", "export.gltf_frame", "expected an integer"),
    ("[mechanics]\ngravity = [0, 0]", "mechanics.gravity", "3 finite numbers"),
    ("[mechanics]\ngravity = [0, 0, nan]", "mechanics.gravity", "not finite"),
    ("[mechanics]\ngravity = [0, 0, true]", "mechanics.gravity", "boolean"),
    ("[mechanics]\nE = 0", "mechanics.E", "0 is outside (0, 1e13] Pa"),
    ("[moisture]\nschedule = [[0, 1.0, 0.1], [0, 1.0, 0.1]]", "moisture.schedule[1]", "strictly increasing"),
    ("[moisture]\nschedule = [[-1, 1.0, 0.1]]", "moisture.schedule[0]", "[0, inf) day"),
    ("[moisture]\nschedule = [[5, 0.1, 0.5]]", "moisture.schedule[0]", "M_2 0.5 must be < M_1 0.1"),
    ("[moisture]\nschedule = [[5, 0.1]]", "moisture.schedule[0]", "[day, M_1, M_2]"),
    ("[moisture]\nschedule = 3", "moisture.schedule", "got integer 3"),
    ("strands = 3", "strands", "expected a table [strands]"),
])
def test_value_errors(extra, key, needle):
    err = error(extra)
    assert err.file == "samples/log.toml"
    assert err.key == key
    assert needle in err.message, str(err)
    assert str(err).startswith(f"samples/log.toml: {key}: ")


def test_error_message_exact():
    assert str(error("[strands]\nr_s = -1")) == "samples/log.toml: strands.r_s: -1 is outside (0, 1] m"


def test_did_you_mean():
    err = error("[fungi]\nalpah_w0 = 1e-3")
    assert err.key == "fungi.alpah_w0"
    assert err.message == "unknown key 'alpah_w0' in [fungi]; did you mean 'alpha_w0'?"
    err = error("[fungii]\nalpha_w0 = 1e-3")
    assert err.key == "fungii" and "did you mean 'fungi'?" in err.message
    err = error("[fungi]\nM_1 = 1.0")
    assert "belongs in [moisture]" in err.message
    err = error("r_s = 1.0")
    assert err.key == "r_s" and "belongs in [strands]" in err.message
    err = error("[tissue.heartwod]\nalpha_w0 = 0.01")
    assert err.key == "tissue.heartwod" and "did you mean 'heartwood'?" in err.message
    err = error("[tissue.heartwood]\nalpha_w = 0.01")
    assert err.key == "tissue.heartwood.alpha_w" and "did you mean 'alpha_w0'?" in err.message
    err = error("[tissue.heartwood]\nr_s = 0.01")
    assert err.key == "tissue.heartwood.r_s"
    err = error("[scene]\nquality = 'drafts'")
    assert "did you mean 'draft'?" in err.message


def test_tissue_override_validated_against_range():
    err = error("[tissue.pith]\nk_W = 0.5")  # not a tissue section key
    assert err.key == "tissue.pith.k_W"
    err = error("[tissue.sapwood]\nalpha_w0 = 11")
    assert err.key == "tissue.sapwood.alpha_w0" and "outside [0, 10] 1/day" in err.message
    err = error("[tissue.sapwood]\nmu_f = 'x'")
    assert err.key == "tissue.sapwood.mu_f" and "[0, 2]" in err.message
    err = error("tissue = 1")
    assert err.key == "tissue"
    err = error("[tissue]\nbark = 1")
    assert err.key == "tissue.bark"


def test_consistency_errors():
    err = error("[moisture]\nM_2 = 1.0")
    assert err.key == "moisture.M_2" and "moisture.M_1" in err.message and "< M_1" in err.message
    err = error("[moisture]\nM_1 = 0.5\nM_2 = 0.6")
    assert err.key == "moisture.M_2"
    err = error("[moisture]\nM_init = 2.0")
    assert err.key == "moisture.M_init" and "[M_2, M_1]" in err.message
    err = error("[fungi]\nM_min = 0.9\nM_max = 0.2")
    assert err.key == "fungi.M_min" and "fungi.M_max" in err.message
    err = error("[strands]\nconnect_radius = 0.011")
    assert err.key == "strands.connect_radius" and "strands.r_s" in err.message
    err = error("[strands]\nr_s = 0.01\nconnect_radius = 0.015")
    assert err.key == "strands.connect_radius"
    assert parse("[strands]\nconnect_radius = 0.012").strands.connect_radius == 0.012
    err = error("[tissue.heartwood]\nM_2 = 1.5")
    assert err.key == "tissue.heartwood.M_2" and "tissue.heartwood.M_1" in err.message
    err = error("[tissue.bark]\nM_max = 0.1")
    assert err.key == "tissue.bark.M_max"


def test_connect_radius_default():
    s = parse("[strands]\nr_s = 0.01")
    assert s.strands.connect_radius == pytest.approx(0.025)
    assert parse().strands.connect_radius == pytest.approx(2.5 * 0.006)


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


@pytest.mark.parametrize("region, key, needle", [
    ("{kind = 'cube'}", "inoculation[0].region.kind", "one of 'box', 'sphere', 'node', 'end', 'wound'"),
    ("{min = [0, 0, 0]}", "inoculation[0].region.kind", "missing required key 'kind'"),
    ("{kind = 'box', min = [0, 0, 0], max = [1, 0, 1]}", "inoculation[0].region.max", "every component"),
    ("{kind = 'box', min = [0, 0, 0]}", "inoculation[0].region.max", "missing required key"),
    ("{kind = 'sphere', center = [0, 0, 0], radius = 0}", "inoculation[0].region.radius", "(0, inf) m"),
    ("{kind = 'sphere', centre = [0, 0, 0], radius = 1}", "inoculation[0].region.centre", "did you mean 'center'?"),
    ("{kind = 'node', id = 'tpi', radius = 0.1}", "inoculation[0].region.id", "did you mean 'tip'?"),
    ("{kind = 'node', id = true, radius = 0.1}", "inoculation[0].region.id", "node id"),
    ("{kind = 'end', which = 'top', depth = 0.1}", "inoculation[0].region.which", "'root', 'tip'"),
    ("{kind = 'end', depth = -0.1}", "inoculation[0].region.depth", "(0, inf) m"),
    ("{kind = 'wound', position = [0, 0], radius = 1, depth = 1}", "inoculation[0].region.position", "3 finite"),
    ("{kind = 'sphere', center = [0, 0, 0], radius = 1, space = 'local'}", "inoculation[0].region.space",
     "'world', 'wood'"),
    ("3", "inoculation[0].region", "expected a region table"),
])
def test_region_errors(region, key, needle):
    err = error(f"[[inoculation]]\nfungus = 'white'\nregion = {region}")
    assert err.key == key and needle in err.message, str(err)


@pytest.mark.parametrize("body, key, needle", [
    ("region = {kind = 'end', depth = 0.1}", "inoculation[0].fungus", "missing required key 'fungus'"),
    ("fungus = 'white'", "inoculation[0].region", "missing required key 'region'"),
    ("fungus = 'grey'\nregion = {kind = 'end', depth = 0.1}", "inoculation[0].fungus", "one of 'white', 'brown'"),
    ("fungus = 'white'\nactivity = 0\nregion = {kind = 'end', depth = 0.1}", "inoculation[0].activity", "(0, 1]"),
    ("fungus = 'white'\nday = -1\nregion = {kind = 'end', depth = 0.1}", "inoculation[0].day", "[0, inf) day"),
    ("fungus = 'white'\nstrength = 1\nregion = {kind = 'end', depth = 0.1}", "inoculation[0].strength",
     "unknown key"),
])
def test_inoculation_errors(body, key, needle):
    err = error(f"[[inoculation]]\n{body}")
    assert err.key == key and needle in err.message, str(err)


def test_inoculation_not_array():
    assert error("inoculation = 3").key == "inoculation"
    assert error("[inoculation]\nfungus = 'white'").key == "inoculation"


@pytest.mark.parametrize("body, key, needle", [
    ("force = [0, 0, 1]\ndays = [0, 1]", "load[0].region", "missing required key"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 1]\ndays = [0, 1]", "load[0].force", "3 finite"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 0, 1]\ndays = [2, 1]", "load[0].days", "start"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 0, 1]\ndays = [-1, 1]", "load[0].days", "[0, inf) day"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 0, 1]\ndays = 3", "load[0].days", "[start, end]"),
    ("region = {kind = 'end', depth = 0.1}\nforce = [0, 0, 1]", "load[0].days", "missing required key"),
])
def test_load_errors(body, key, needle):
    err = error(f"[[load]]\n{body}")
    assert err.key == key and needle in err.message, str(err)


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


# ------------------------------------------------------------------------- overrides / --set

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


# ------------------------------------------------------------------------------------ hash

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


# ------------------------------------------------------------------------------------ fuzzing

ALL_KEYS = sorted({name for table in P.PARAMS.values() for name in table}
                  | {"fungus", "activity", "day", "region", "kind", "space", "min", "max", "center", "radius",
                     "id", "which", "depth", "position", "force", "days", "node", "file", "scale", "format",
                     "profile", "parent", "anchored", "a", "b", "angle", "points"})
TOP_KEYS = sorted(set(P.PARAMS) | {"skeleton", "tissue", "inoculation", "load"} | set(P.TISSUES))
NAMES = st.sampled_from(ALL_KEYS + TOP_KEYS) | st.text(string.ascii_letters + string.digits + "_-", min_size=1,
                                                       max_size=8)

finite = st.floats(allow_nan=False, allow_infinity=False)
SCALARS = (st.integers(-10, 10) | st.integers() | st.floats() | finite.map(lambda x: x / 1e6)
           | st.booleans() | st.text(max_size=8) | st.sampled_from(["white", "brown", "draft", "final", "box",
                                                                     "sphere", "node", "end", "wound", "root",
                                                                     "tip", "wood", "world"]))


def near_valid(p: P.Param):
    """Values around a parameter's range (to get past validation and into later checks)."""
    if p.kind in ("float", "int"):
        lo = p.lo if p.lo is not None else -10.0
        hi = p.hi if p.hi is not None else 10.0
        pts = [lo, hi, (lo + hi) / 2]
        if p.default is not None:
            pts.append(p.default)
        base = st.sampled_from(pts) | st.floats(min_value=lo, max_value=hi)
        return base.map(lambda x: int(x) if p.kind == "int" else x)
    if p.kind == "enum":
        return st.sampled_from(p.choices)
    if p.kind == "vec3":
        return st.lists(finite, min_size=3, max_size=3)
    if p.kind == "list":
        return st.lists(st.tuples(st.floats(0, 400), st.floats(0.5, 2), st.floats(0, 0.4)).map(list), max_size=3)
    if p.kind == "bool":
        return st.booleans()
    return st.text(max_size=8)


def values(depth=2):
    if depth == 0:
        return SCALARS
    return st.one_of(SCALARS, st.lists(values(depth - 1), max_size=4),
                     st.dictionaries(NAMES, values(depth - 1), max_size=4))


@st.composite
def section_table(draw, sec):
    out = {}
    params = draw(st.lists(st.sampled_from(list(P.PARAMS[sec].values())), max_size=4, unique_by=lambda p: p.name))
    for p in params:
        out[p.name] = draw(near_valid(p) | values(1))
    if draw(st.booleans()):
        out.update(draw(st.dictionaries(NAMES, values(1), max_size=2)))
    return out


def region_strategy():
    v3 = st.lists(st.floats(-1, 1) | st.integers(-2, 2), min_size=3, max_size=3)
    pos = st.floats(0.001, 1)
    return st.one_of(
        st.fixed_dictionaries({"kind": st.just("box"), "min": v3, "max": v3}),
        st.fixed_dictionaries({"kind": st.just("sphere"), "center": v3, "radius": pos},
                              optional={"space": st.sampled_from(["world", "wood", "x"])}),
        st.fixed_dictionaries({"kind": st.just("node"), "id": st.sampled_from(["root", "tip", "x", 1]),
                               "radius": pos}),
        st.fixed_dictionaries({"kind": st.just("end"), "depth": pos},
                              optional={"which": st.sampled_from(["root", "tip", "mid"])}),
        st.fixed_dictionaries({"kind": st.just("wound"), "position": v3, "radius": pos, "depth": pos}),
        st.dictionaries(NAMES, values(1), max_size=4),
    )


@st.composite
def scene_documents(draw):
    doc: dict = {}
    if draw(st.integers(0, 9)) > 0:
        doc["skeleton"] = {"node": [
            {"id": "root", "position": [0, 0, 0], "profile": {"kind": "circle", "radius": 0.1}},
            {"id": "tip", "position": [0, 0, 1], "parent": "root", "profile": {"kind": "circle", "radius": 0.08}},
        ]}
        if draw(st.integers(0, 5)) == 0:
            doc["skeleton"].update(draw(st.dictionaries(NAMES, values(2), max_size=2)))
    for sec in draw(st.lists(st.sampled_from(list(P.PARAMS)), max_size=5, unique=True)):
        doc[sec] = draw(section_table(sec))
    if draw(st.booleans()):
        doc["tissue"] = draw(st.dictionaries(
            st.sampled_from(list(P.TISSUES)) | NAMES,
            st.dictionaries(st.sampled_from(sorted(P.TISSUE_KEYS)) | NAMES,
                            st.sampled_from(list(P.TISSUE_KEYS.values())).flatmap(near_valid) | values(1),
                            max_size=3) | values(1),
            max_size=3))
    if draw(st.booleans()):
        doc["inoculation"] = draw(st.lists(st.fixed_dictionaries(
            {"fungus": st.sampled_from(["white", "brown", "grey"]), "region": region_strategy()},
            optional={"activity": st.floats(0, 1.2) | values(0), "day": st.floats(-1, 100) | values(0),
                      "extra": values(1)}) | values(1), max_size=3))
    if draw(st.booleans()):
        doc["load"] = draw(st.lists(st.fixed_dictionaries(
            {"region": region_strategy(), "force": st.lists(st.floats(-10, 10), min_size=3, max_size=3) | values(1),
             "days": st.lists(st.floats(-1, 10), min_size=2, max_size=2) | values(1)}) | values(1), max_size=2))
    if draw(st.booleans()):
        doc.update(draw(st.dictionaries(NAMES, values(2), max_size=3)))
    return doc


def toml_string(text: str) -> str:
    """A TOML basic string (escapes for quotes, backslashes, control and non-ASCII characters)."""
    out = []
    for ch in text:
        c = ord(ch)
        if ch in '"\\':
            out.append("\\" + ch)
        elif 32 <= c < 127:
            out.append(ch)
        elif c <= 0xFFFF:
            out.append(f"\\u{c:04x}")
        else:
            out.append(f"\\U{c:08x}")
    return '"' + "".join(out) + '"'


def toml_key(k: str) -> str:
    return toml_string(k)


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return toml_string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(doc: dict) -> str:
    return "\n".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in doc.items()) + "\n"


def only_input_errors(fn, *args, **kw):
    try:
        fn(*args, **kw)
    except InputError as err:
        assert "\n" not in str(err) and err.file


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=300) | st.binary(max_size=300))
def test_fuzz_random_text_and_bytes(data):
    only_input_errors(parse_scene, data, source="fuzz.toml")


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.sampled_from(list("[]{}=\"'.,#\n \t-+_0123456789aeinftrus") + ALL_KEYS + TOP_KEYS),
                max_size=60).map(lambda parts: "".join(parts) + "\n" + SKELETON))
def test_fuzz_toml_like_text(text):
    only_input_errors(parse_scene, text, source="fuzz.toml")


@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(scene_documents())
def test_fuzz_random_documents(doc):
    text = to_toml(doc)
    try:
        s = parse_scene(text, source="fuzz.toml")
    except InputError as err:
        assert "\n" not in str(err) and err.file == "fuzz.toml"
        return
    json.dumps(s.to_dict(), allow_nan=False)
    assert len(s.hash) == 64


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(
    st.sampled_from([p.key for t in P.PARAMS.values() for p in t.values()]
                    + [f"tissue.{t}.{k}" for t in P.TISSUES for k in ("alpha_w0", "M_2", "mu_f")])
    | st.text(max_size=20),
    values(1), max_size=4))
def test_fuzz_overrides(over):
    only_input_errors(parse_scene, SKELETON, source="fuzz.toml", overrides=over)
    items = [f"{k}={toml_value(v)}" for k, v in over.items()]
    try:
        parsed = parse_set_option(items)
    except InputError as err:
        assert err.file == "<--set>"
        return
    only_input_errors(parse_scene, SKELETON, source="fuzz.toml", overrides=parsed)


def test_parse_scene_takes_the_parsed_toml_mapping(tmp_path):
    """A scene built in code (a dict as tomllib returns it) validates like its text and is
    not changed by the parse."""
    import copy
    import tomllib
    from pathlib import Path
    path = Path(__file__).resolve().parent.parent / "wooddecay" / "samples" / "tiny.toml"
    data = tomllib.loads(path.read_text())
    before = copy.deepcopy(data)
    assert parse_scene(data, source=str(path), base_dir=path.parent).hash == load_scene(path).hash
    assert data == before
    data["strands"]["r_s"] = -1.0
    with pytest.raises(InputError, match="strands.r_s"):
        parse_scene(data, source="built")
