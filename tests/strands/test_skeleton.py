"""Skeleton graph input: native nodes and the [skeleton] table (docs/model.md §1)."""
import copy
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wooddecay.errors import InputError
from wooddecay.strands.skeleton import parse_nodes
from wooddecay.strands.skeleton_loader import load_skeleton

SRC = "scene.toml"


def tree():
    """A small valid tree: root -> mid -> two tips, listed children first."""
    return [
        {"id": "tip_a", "position": [0.3, 0.0, 1.5], "parent": "mid", "profile": {"kind": "circle", "radius": 0.03}},
        {"id": "mid", "position": [0.0, 0.0, 1.0], "parent": 0,
         "profile": {"kind": "ellipse", "a": 0.06, "b": 0.05, "angle": 0.3}},
        {"id": 0, "position": [0.0, 0.0, 0.0], "anchored": True, "profile": {"kind": "circle", "radius": 0.1}},
        {"id": "tip_b", "position": [-0.3, 0.0, 1.5], "parent": "mid",
         "profile": {"kind": "polygon", "points": [[0.0, 0.0], [0.04, 0.0], [0.04, 0.03], [0.0, 0.03]]}},
    ]


def rejection(nodes, node_id):
    """Parse ``nodes``, expecting an InputError that names ``node_id``; return its text."""
    with pytest.raises(InputError) as info:
        parse_nodes(nodes, SRC)
    text = str(info.value)
    assert f"[{node_id}]" in text, text
    assert "\n" not in text and text.startswith(f"{SRC}: skeleton.node[")
    return text


def test_parse_valid_tree_reorders_parents_first():
    sk = parse_nodes(tree(), SRC)
    assert sk.ids == ("0", "mid", "tip_a", "tip_b")
    assert sk.parent.tolist() == [-1, 0, 1, 1]
    assert sk.children(1) == (2, 3) and sk.children(0) == (1,)
    np.testing.assert_allclose(sk.positions[2], [0.3, 0.0, 1.5])
    assert sk.anchored.tolist() == [True, False, False, False]
    assert [p.kind for p in sk.profiles] == ["circle", "ellipse", "circle", "polygon"]
    assert sk.profiles[1].area == pytest.approx(math.pi * 0.06 * 0.05)
    assert sk.source == SRC and sk.positions.dtype == np.float64 and sk.parent.dtype == np.int64


def test_ellipse_angle_defaults_to_zero_and_empty_parent_is_root():
    nodes = [{"id": "r", "parent": "", "position": [0, 0, 0], "profile": {"kind": "ellipse", "a": 0.2, "b": 0.1}},
             {"id": "t", "parent": "r", "position": [1, 0, 0], "profile": {"kind": "circle", "radius": 0.1}}]
    sk = parse_nodes(nodes, SRC)
    assert sk.parent.tolist() == [-1, 0]
    assert dict(sk.profiles[0].params)["angle"] == 0.0


def test_a_skeleton_without_an_edge_is_refused_in_one_line():
    """Wood grows along edges: a lone node (or roots only) is refused at validation, not at the
    build (where strand sampling found nothing to concatenate)."""
    nodes = [{"id": "r", "position": [0, 0, 0], "profile": {"kind": "circle", "radius": 0.1}}]
    with pytest.raises(InputError) as info:
        parse_nodes(nodes, SRC)
    assert "no edge" in str(info.value) and "\n" not in str(info.value)


def test_reject_cycle():
    nodes = tree()
    nodes[2]["parent"] = "tip_a"  # 0 -> tip_a -> mid -> 0: no root left either
    del nodes[2]["anchored"]  # only roots may be anchored
    text = rejection(nodes, "tip_a")
    assert "cycle tip_a -> mid -> 0 -> tip_a" in text and "no root" in text


def test_reject_cycle_beside_a_valid_tree():
    nodes = tree() + [
        {"id": "x", "parent": "y", "position": [1, 0, 0], "profile": {"kind": "circle", "radius": 0.1}},
        {"id": "y", "parent": "x", "position": [2, 0, 0], "profile": {"kind": "circle", "radius": 0.1}},
    ]
    text = rejection(nodes, "x")
    assert "cycle x -> y -> x" in text


def test_reject_missing_parent():
    nodes = tree()
    nodes[0]["parent"] = "nowhere"
    text = rejection(nodes, "tip_a")
    assert "'nowhere' is not the id of any node" in text


def test_reject_zero_length_edge():
    nodes = tree()
    nodes[3]["position"] = [0.0, 0.0, 1.0]
    text = rejection(nodes, "tip_b")
    assert "from its parent 'mid'" in text and "1e-09" in text


def test_reject_non_finite_number():
    nodes = tree()
    nodes[1]["position"] = [0.0, float("nan"), 1.0]
    text = rejection(nodes, "mid")
    assert "position[1]" in text and "finite" in text


def test_reject_non_positive_radius():
    nodes = tree()
    nodes[0]["profile"]["radius"] = -0.1
    text = rejection(nodes, "tip_a")
    assert "skeleton.node[tip_a].profile.radius: must be > 0 m (got -0.1)" in text


def test_reject_non_positive_semi_axis():
    nodes = tree()
    nodes[1]["profile"]["b"] = 0
    assert "profile.b: must be > 0 m" in rejection(nodes, "mid")


def test_reject_self_intersecting_polygon():
    nodes = tree()
    nodes[3]["profile"]["points"] = [[0.0, 0.0], [0.04, 0.03], [0.04, 0.0], [0.0, 0.03]]
    assert "self-intersecting" in rejection(nodes, "tip_b")


def test_reject_clockwise_polygon():
    nodes = tree()
    nodes[3]["profile"]["points"].reverse()
    assert "clockwise" in rejection(nodes, "tip_b")


def test_reject_polygon_with_two_points():
    nodes = tree()
    nodes[3]["profile"]["points"] = [[0.0, 0.0], [0.04, 0.0]]
    assert ">= 3" in rejection(nodes, "tip_b")


def test_reject_duplicate_id():
    nodes = tree()
    nodes[3]["id"] = "tip_a"
    assert "duplicate id" in rejection(nodes, "tip_a")


def test_reject_unknown_key_with_suggestion():
    nodes = tree()
    nodes[1]["posiiton"] = nodes[1].pop("position")
    text = rejection(nodes, "mid")
    assert "skeleton.node[mid].posiiton: unknown key; did you mean 'position'?" in text


def test_reject_unknown_profile_key_and_wrong_types():
    nodes = tree()
    nodes[0]["profile"]["radus"] = nodes[0]["profile"].pop("radius")
    assert "did you mean 'radius'" in rejection(nodes, "tip_a")
    nodes = tree()
    nodes[0]["profile"]["radius"] = "0.1"
    assert "must be a number (got string '0.1')" in rejection(nodes, "tip_a")
    nodes = tree()
    nodes[2]["anchored"] = "yes"
    assert "true or false" in rejection(nodes, "0")
    nodes = tree()
    nodes[1]["position"] = [0.0, True, 1.0]
    assert "must be a number" in rejection(nodes, "mid")


def test_reject_anchored_node_with_parent():
    nodes = tree()
    nodes[1]["anchored"] = True
    text = rejection(nodes, "mid")
    assert "skeleton.node[mid].anchored: only a root node can be anchored" in text


def test_unknown_key_without_close_match_lists_allowed_keys():
    nodes = tree()
    nodes[1]["zzz"] = 1
    text = rejection(nodes, "mid")
    assert "skeleton.node[mid].zzz: unknown key; allowed keys: id, position, parent, profile, anchored" in text


def test_reject_integer_too_long_for_text():
    nodes = tree()
    nodes[0]["profile"]["radius"] = 10**5000
    assert "must be a finite number (got <integer of about 5001 digits>)" in rejection(nodes, "tip_a")


@pytest.mark.parametrize("bad", [None, [], {}, "nodes", [1, 2]])
def test_reject_bad_node_array(bad):
    with pytest.raises(InputError):
        parse_nodes(bad, SRC)


def test_load_skeleton_inline_scaled():
    sk = load_skeleton({"node": tree(), "scale": 2.0}, base_dir=None, source=SRC)
    np.testing.assert_allclose(sk.positions[1], [0.0, 0.0, 2.0])
    assert dict(sk.profiles[0].params)["radius"] == pytest.approx(0.2)
    assert sk.profiles[3].area == pytest.approx(4 * 0.04 * 0.03)


def test_load_skeleton_native_file(tmp_path):
    (tmp_path / "tree.toml").write_text(
        '[[node]]\nid = "r"\nposition = [0, 0, 0]\nprofile = {kind = "circle", radius = 0.1}\n'
        '[[node]]\nid = "t"\nparent = "r"\nposition = [0, 0, 1]\nprofile = {kind = "circle", radius = 0.05}\n'
    )
    sk = load_skeleton({"file": "tree.toml"}, tmp_path, str(tmp_path / "scene.toml"))
    assert sk.ids == ("r", "t") and sk.source == str(tmp_path / "tree.toml")
    (tmp_path / "bad.toml").write_text('[[node]]\nid = "r"\nposition = [0, 0]\nprofile = {kind = "circle", radius = 0.1}\n')
    with pytest.raises(InputError, match=r"bad.toml: node\[r\].position: must be an array of 3 numbers"):
        load_skeleton({"file": "bad.toml"}, tmp_path, "scene.toml")
    (tmp_path / "broken.toml").write_text("[[node]\n")
    with pytest.raises(InputError, match="not valid TOML"):
        load_skeleton({"file": "broken.toml"}, tmp_path, "scene.toml")


def test_load_skeleton_table_errors(tmp_path):
    with pytest.raises(InputError, match="exactly one"):
        load_skeleton({"node": tree(), "file": "x.toml"}, tmp_path, SRC)
    with pytest.raises(InputError, match="exactly one"):
        load_skeleton({}, tmp_path, SRC)
    with pytest.raises(InputError, match=r"skeleton.scael: unknown key; did you mean 'scale'\?"):
        load_skeleton({"node": tree(), "scael": 2}, tmp_path, SRC)
    with pytest.raises(InputError, match=r"skeleton.scale: must be > 0 m"):
        load_skeleton({"node": tree(), "scale": 0}, tmp_path, SRC)
    with pytest.raises(InputError, match="is not a file"):
        load_skeleton({"file": "missing.toml"}, tmp_path, SRC)
    (tmp_path / "tree.obj").write_text("")
    with pytest.raises(InputError, match="skeleton.format: cannot tell the format"):
        load_skeleton({"file": "tree.obj"}, tmp_path, SRC)
    with pytest.raises(InputError, match="skeleton.format"):
        load_skeleton({"node": tree(), "format": "treeqsm"}, tmp_path, SRC)


# --------------------------------------------------------------------------- fuzzing

scalars = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(min_value=-10**400, max_value=10**400),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8),
    st.sampled_from(["circle", "ellipse", "polygon", "", "r", "a"]),
)
keys = st.one_of(
    st.sampled_from(["id", "position", "parent", "profile", "anchored", "kind", "radius", "a", "b", "angle",
                     "points"]),
    st.text(max_size=6),
)
garbage = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=5), st.dictionaries(keys, inner, max_size=6)),
    max_leaves=30,
)


def mutate(nodes, data):
    """Replace one value somewhere inside ``nodes`` by garbage."""
    target = data.draw(st.integers(0, len(nodes) - 1))
    node = nodes[target]
    path = data.draw(st.sampled_from(["id", "position", "parent", "profile", "anchored", "radius", "points"]))
    where = node["profile"] if path in ("radius", "points") else node
    where[path] = data.draw(garbage)
    return nodes


@settings(max_examples=300, deadline=None)
@given(st.one_of(garbage, st.lists(garbage, max_size=4), st.data()))
def test_fuzz_parse_nodes_only_input_error(value):
    if isinstance(value, st.DataObject):
        value = mutate(copy.deepcopy(tree()), value)
    try:
        sk = parse_nodes(value, SRC)
    except InputError as err:
        assert "\n" not in str(err)
    else:
        assert len(sk.ids) == len(sk.positions) == len(sk.profiles)
