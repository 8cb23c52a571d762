"""Every valid scene bakes (issue 84): Hypothesis draws small scenes across the schema's shapes
(skeletons of 1-5 inline nodes with forks, every profile kind, branches from one strand to many,
anchors and clamp depths; or a small TreeQSM table or a surface mesh; colliders, loads, climates,
inoculations or none, bark or none, 1-4 frames, both qualities and solvers, short spans, ``--set``
overrides of frame and export keys) and bakes each in seconds. A draw either bakes, with finite
outputs whose fields stay in their ranges, a stage usd-core's validators pass, a glTF the Khronos
validator passes and closed, oriented meshlets, or is refused
with one line (an InputError, before anything is written). The default run draws a few scenes;
the ``slow`` run many more, each baked again on two threads to the same stage.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import wooddecay as wd
from wooddecay.bake import bake
from wooddecay.errors import InputError
from wooddecay.export.wood_read import wood_at
from wooddecay.meshlets.checks import closed_oriented

from .export.test_gltf import gltf_validator, validate  # noqa: F401 (a fixture)
from .export.test_gltf import summary as gltf_summary


def _vec(v) -> str:
    return "[" + ", ".join(f"{float(x):.6g}" for x in v) + "]"


@st.composite
def profiles(draw, radius: float) -> str:
    kind = draw(st.sampled_from(["circle", "ellipse", "polygon"]))
    if kind == "circle":
        return f'{{ kind = "circle", radius = {radius:.6g} }}'
    if kind == "ellipse":
        b = radius * draw(st.floats(0.5, 1.0))
        return f'{{ kind = "ellipse", a = {radius:.6g}, b = {b:.6g}, angle = {draw(st.floats(0, 3.1)):.4g} }}'
    n = draw(st.integers(3, 7))
    pts = [[radius * math.cos(2 * math.pi * k / n), radius * math.sin(2 * math.pi * k / n)] for k in range(n)]
    return f'{{ kind = "polygon", points = [{", ".join(_vec(p) for p in pts)}] }}'


@st.composite
def treeqsm(draw, radius: float, z: float) -> str:
    """A TreeQSM cylinder table of 1-3 cylinders along x, the later ones continuing or forking."""
    rows = ["start_x,start_y,start_z,axis_x,axis_y,axis_z,length,radius,parent"]
    ends = []
    for k in range(draw(st.integers(1, 3))):
        parent = draw(st.integers(0, k)) if k else 0  # 0: none
        start = ends[parent - 1] if parent else [0.0, 0.0, z]
        axis = [1.0, draw(st.floats(-0.3, 0.3)), draw(st.floats(0.0, 0.3))]
        length = draw(st.floats(0.08, 0.2))
        norm = math.sqrt(sum(a * a for a in axis))
        ends.append([s + length * a / norm for s, a in zip(start, axis)])
        rows.append(",".join(f"{v:.6g}" for v in [*start, *axis, length, radius * draw(st.floats(0.7, 1.0)), parent]))
    return "\n".join(rows) + "\n"


def cylinder_obj(radius: float, length: float, z: float) -> str:
    """A closed cylinder along x (16 sides) as OBJ text."""
    import trimesh

    body = trimesh.creation.cylinder(radius=radius, height=length, sections=16)
    body.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))
    body.apply_translation([length / 2, 0.0, z])
    return trimesh.exchange.obj.export_obj(body)


@st.composite
def scenes(draw) -> tuple[str, dict, dict]:
    """(scene TOML, overrides, files beside it) of a small scene (module docstring)."""
    rare = st.integers(0, 9).map(lambda k: k == 0)  # a draw one time in ten
    frames = draw(st.integers(1, 4))
    r_s = draw(st.sampled_from([0.004, 0.006, 0.009]))
    # from one strand to a few across (rarely narrower than 1.12 r_s: it holds none, refused)
    radius = (1.0 if draw(rare) else draw(st.floats(2.0, 6.0))) * r_s
    z = radius + draw(st.sampled_from([0.0, 0.02, 0.2]))
    lines = ['[scene]', 'name = "fuzz"', f'seed = {draw(st.integers(0, 5))}',
             f'quality = "{draw(st.sampled_from(["final", "draft"]))}"']
    source = draw(st.sampled_from(["nodes"] * 4 + ["treeqsm", "mesh"]))
    files = {}
    n = 2
    if source == "treeqsm":
        files["tree.csv"] = draw(treeqsm(radius, z))
        lines += ["[skeleton]", 'file = "tree.csv"']
    elif source == "mesh":
        files["log.obj"] = cylinder_obj(max(radius, 2.5 * r_s), draw(st.floats(0.15, 0.4)), z + r_s)
        lines += ["[skeleton]", 'mesh = "log.obj"']
    else:
        n = 1 if draw(rare) else draw(st.integers(2, 5))  # one node: no edge, refused
    for k in range(n if source == "nodes" else 0):
        parent = draw(st.integers(0, k - 1)) if k else None  # a fork wherever two share a parent
        pos = [0.12 * k, draw(st.floats(-0.05, 0.05)) if k else 0.0, z + (draw(st.floats(0, 0.05)) if k else 0.0)]
        lines += ["[[skeleton.node]]", f'id = "n{k}"', f"position = {_vec(pos)}",
                  f"profile = {draw(profiles(radius * draw(st.floats(0.85, 1.0))))}"]
        if parent is not None:
            lines.append(f'parent = "n{parent}"')
        elif draw(st.booleans()):
            lines.append("anchored = true")
    lines += ["[strands]", f"r_s = {r_s}", f"rod_length = {r_s * draw(st.sampled_from([3.0, 5.0])):.6g}",
              "[rings]", f"bark_thickness = {draw(st.sampled_from([0.0, 0.003])):.6g}",
              "[bsp]", f"cells = {draw(st.integers(1, 40))}",
              "[mechanics]", f'solver = "{draw(st.sampled_from(["xpbd", "implicit"]))}"',
              f"clamp_depth = {draw(st.sampled_from([0.01, 0.05, 0.3])):.6g}",
              f"ground = {str(draw(st.booleans())).lower()}",
              "[climate]", f'preset = "{draw(st.sampled_from(["temperate", "dry", "wet-ground", "constant"]))}"',
              "[time]", f"days = {draw(st.sampled_from([0.5, 2.0, 6.0]))}", f"frames = {frames}",
              "[bark]", f"cracks = {str(draw(st.booleans())).lower()}"]
    if draw(st.booleans()):
        fungus = draw(st.sampled_from(["brown", "white"]))
        lines += ["[[inoculation]]", f'fungus = "{fungus}"',
                  'region = { kind = "end", which = "root", depth = 0.05 }']
    if draw(st.booleans()):
        lines += ["[[collider]]", 'kind = "box"', f"min = {_vec([0.03, -0.2, -0.1])}", f"max = {_vec([0.06, 0.2, 0.0])}"]
    if draw(st.booleans()) and source == "nodes":
        lines += ["[[load]]", f'region = {{ kind = "node", id = "n{n - 1}", radius = 0.05 }}',
                  f"force = {_vec([0.0, 0.0, -draw(st.floats(0.0, 5.0))])}", "days = [0.0, 1.0]"]
    overrides = {}
    if draw(st.booleans()):
        overrides["export.gltf_frame"] = frames if draw(rare) else draw(st.integers(-frames, frames - 1))
    if draw(st.booleans()):
        overrides["export.gltf"] = False
    if draw(rare):
        overrides["time.frames"] = draw(st.integers(1, 3))
    return "\n".join(lines) + "\n", overrides, files


def check_bake(tmp_path, text: str, overrides: dict, files: dict, validator, threads: int = 1) -> dict | None:
    """Bake the drawn scene; None when validation refused it in one line. ``validator``: the
    glTF validator's command (:func:`tests.export.test_gltf.gltf_validator`)."""
    path = tmp_path / "fuzz.toml"
    path.write_text(text)
    for name, content in files.items():
        (tmp_path / name).write_text(content)
    event("skeleton: " + {"tree.csv": "TreeQSM table", "log.obj": "surface mesh"}.get(next(iter(files), ""), "nodes"))
    out = tmp_path / f"out{threads}"
    try:
        scene = wd.load_scene(path, overrides=overrides)
    except InputError as err:
        assert "\n" not in str(err)
        event("refused at validation")
        return None
    try:
        summary = bake(scene, out, threads=threads)
    except InputError as err:  # the memory check or the build: before anything is written
        assert "\n" not in str(err) and not (out / "fuzz.usdc").exists()
        event("refused before writing")
        return None
    event("baked")
    from pxr import Usd, UsdValidation

    stage = Usd.Stage.Open(str(out / "fuzz.usdc"))
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    errors = [e.GetMessage() for e in ctx.Validate(stage) if e.GetType() == UsdValidation.ValidationErrorType.Error]
    assert errors == []
    for t in range(int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode()) + 1):
        wood = wood_at(stage, t)
        for name in ("points", "H_c", "H_l", "M", "rest"):
            assert np.isfinite(wood[name]).all(), name
        step = stage.GetRootLayer().customLayerData["field_step"]
        for name in ("H_c", "H_l"):
            assert (wood[name] >= -step).all() and (wood[name] <= 1 + step).all(), name
    assert (out / "fuzz.glb").exists() == overrides.get("export.gltf", True)
    if (out / "fuzz.glb").exists():
        report = validate(validator, out / "fuzz.glb")
        assert report["issues"]["numErrors"] == 0, gltf_summary(report)
    assert closed_oriented(wd.build_meshlets(wd.build_model(scene))).all()
    return summary


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                                                HealthCheck.function_scoped_fixture])
@given(scenes())
def test_a_drawn_scene_bakes_or_is_refused_in_one_line(tmp_path_factory, gltf_validator, drawn):
    check_bake(tmp_path_factory.mktemp("fuzz"), *drawn, gltf_validator)


@pytest.mark.slow
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                                                 HealthCheck.function_scoped_fixture])
@given(scenes())
def test_many_drawn_scenes_bake_the_same_stage_on_one_and_two_threads(tmp_path_factory, gltf_validator, drawn):
    tmp = tmp_path_factory.mktemp("fuzz")
    if check_bake(tmp, *drawn, gltf_validator, threads=1) is None:
        return
    check_bake(tmp, *drawn, gltf_validator, threads=2)
    assert wd.compare_usd(tmp / "out1" / "fuzz.usdc", tmp / "out2" / "fuzz.usdc", rtol=0, atol=0) == []
