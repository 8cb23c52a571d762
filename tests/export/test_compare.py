"""wooddecay.export.compare: each kind of difference between two USD stages, named with its path
and, for numbers, the largest absolute and relative error."""
from __future__ import annotations

import pytest

import wooddecay as wd

STAGE = """#usda 1.0
(
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Z"
    customLayerData = {{ string scene = "{scene}" }}
)

def Xform "World"
{{
    def Mesh "Wood"
    {{
        point3f[] points.timeSamples = {{ 0: [(0, 0, 0), (1, 0, 0), (0, 1, 0)], {t1}: [(0, 0, {z}), (1, 0, 0), (0, 1, 0)] }}
        float[] primvars:H_c = [1, 0.5, {hc}] (
            interpolation = "{interp}"
        )
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
    }}
{extra}}}
"""


def _write(tmp_path, name, scene="log", t1=1, z=0.0, hc=0.25, interp="vertex", extra=""):
    path = tmp_path / f"{name}.usda"
    path.write_text(STAGE.format(scene=scene, t1=t1, z=z, hc=hc, interp=interp, extra=extra))
    return path


def test_identical_stages_have_no_difference(tmp_path):
    assert wd.compare_usd(_write(tmp_path, "a"), _write(tmp_path, "b"), rtol=0, atol=0) == []


def test_a_value_beyond_tolerance_names_its_attribute_and_errors(tmp_path):
    a, b = _write(tmp_path, "a", hc=0.25), _write(tmp_path, "b", hc=0.2)
    (d,) = wd.compare_usd(a, b, rtol=0, atol=1e-3)
    assert (d.path, d.what) == ("/World/Wood.primvars:H_c", "value")
    assert d.max_abs == pytest.approx(0.05) and d.max_rel == pytest.approx(0.25)
    assert "1 of 3 values differ" in d.detail
    assert wd.compare_usd(a, b, rtol=0.3, atol=0) == []  # within rtol |b|


def test_time_sampled_points_are_compared_at_every_sample(tmp_path):
    a, b = _write(tmp_path, "a", z=0.0), _write(tmp_path, "b", z=0.01)
    (d,) = wd.compare_usd(a, b, rtol=0, atol=1e-6)
    assert d.path == "/World/Wood.points" and "time 1" in d.detail and d.max_abs == pytest.approx(0.01)
    (s,) = wd.compare_usd(a, _write(tmp_path, "c", t1=2), rtol=0, atol=0)
    assert (s.path, s.what) == ("/World/Wood.points", "samples")


def test_structure_metadata_and_interpolation_differences(tmp_path):
    base = _write(tmp_path, "a")
    kinds = {d.what: d for d in wd.compare_usd(base, _write(tmp_path, "b", scene="tree", interp="uniform",
                                                            extra='    def Xform "Extra"\n    {\n    }\n'))}
    assert set(kinds) == {"value", "interpolation", "prim"}
    assert kinds["prim"].path == "/World/Extra" and "only in b" in kinds["prim"].detail
    assert kinds["value"].path == "" and "customLayerData[scene]" in kinds["value"].detail
    assert kinds["interpolation"].path == "/World/Wood.primvars:H_c"


def test_an_unreadable_file_is_an_input_error(tmp_path):
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\n def Xform (\n")
    with pytest.raises(wd.InputError):
        wd.compare_usd(_write(tmp_path, "a"), bad)
    with pytest.raises(wd.InputError):
        wd.compare_usd(_write(tmp_path, "a"), tmp_path / "missing.usda")
