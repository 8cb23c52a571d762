"""Strand-group debug export as USD BasisCurves (woodstock Fig. 3b)."""
from __future__ import annotations

import json

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom  # noqa: E402

from wooddecay.errors import InputError  # noqa: E402
from wooddecay.export.strands_usd import TISSUE_COLORS, write_strands_usd  # noqa: E402


def _expected_per_vertex(model, values):
    """Reference for the vertex rule, written as a plain loop over strands."""
    out = []
    for k in range(model.n_strands):
        e0, e1 = model.element_offsets[k], model.element_offsets[k + 1]
        v = list(values[e0:e1])
        out.extend(v + [v[-1]])
    return np.asarray(out)


@pytest.fixture(scope="module")
def tiny_usd(tmp_path_factory, tiny_model):
    path = tmp_path_factory.mktemp("usd") / "tiny_strands.usda"
    write_strands_usd(path, tiny_model)
    return path


def _curves(path, model):
    stage = Usd.Stage.Open(str(path))
    prim = stage.GetPrimAtPath(f"/World/{model.info.name}/Strands")
    assert prim.IsValid()
    return stage, UsdGeom.BasisCurves(prim)


def test_stage_and_geometry(tiny_usd, tiny_model):
    stage, curves = _curves(tiny_usd, tiny_model)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().GetPath() == "/World"
    assert curves.GetTypeAttr().Get() == UsdGeom.Tokens.linear
    assert curves.GetWrapAttr().Get() == UsdGeom.Tokens.nonperiodic
    counts = np.asarray(curves.GetCurveVertexCountsAttr().Get())
    assert len(counts) == tiny_model.n_strands
    assert counts.sum() == len(tiny_model.particles)
    np.testing.assert_array_equal(counts, np.diff(tiny_model.particle_offsets))
    points = np.asarray(curves.GetPointsAttr().Get())
    np.testing.assert_allclose(points, tiny_model.particles, rtol=1e-6, atol=1e-6)
    widths = np.asarray(curves.GetWidthsAttr().Get())
    assert curves.GetWidthsInterpolation() == UsdGeom.Tokens.vertex
    np.testing.assert_allclose(widths, 2 * _expected_per_vertex(tiny_model, tiny_model.radius), rtol=1e-6)


def test_primvars(tiny_usd, tiny_model):
    _, curves = _curves(tiny_usd, tiny_model)
    pv = UsdGeom.PrimvarsAPI(curves)
    tissue_pv = pv.GetPrimvar("tissue")
    assert tissue_pv.GetInterpolation() == UsdGeom.Tokens.vertex
    tissue = np.asarray(tissue_pv.Get())
    expected = _expected_per_vertex(tiny_model, tiny_model.tissue)
    np.testing.assert_array_equal(tissue, expected)
    # first particle of each strand takes its first element, last the last element
    e_off, p_off = tiny_model.element_offsets, tiny_model.particle_offsets
    np.testing.assert_array_equal(tissue[p_off[:-1]], tiny_model.tissue[e_off[:-1]])
    np.testing.assert_array_equal(tissue[p_off[1:] - 1], tiny_model.tissue[e_off[1:] - 1])
    ring = np.asarray(pv.GetPrimvar("ring").Get())
    np.testing.assert_allclose(ring, _expected_per_vertex(tiny_model, tiny_model.ring_age), rtol=1e-6)
    color_pv = curves.GetDisplayColorPrimvar()
    assert color_pv.GetInterpolation() == UsdGeom.Tokens.vertex
    np.testing.assert_allclose(np.asarray(color_pv.Get()), TISSUE_COLORS[expected], rtol=1e-6)


@pytest.mark.parametrize("suffix", [".usdc", ".usd"])
def test_binary_formats_and_no_temp_left(tmp_path, tiny_model, suffix):
    path = tmp_path / f"strands{suffix}"
    write_strands_usd(path, tiny_model)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]
    _, curves = _curves(path, tiny_model)
    assert len(curves.GetCurveVertexCountsAttr().Get()) == tiny_model.n_strands


def test_rejects_other_suffix(tmp_path, tiny_model):
    with pytest.raises(InputError, match=r"strands.txt: a strands USD file must end in .usda, .usdc, .usd"):
        write_strands_usd(tmp_path / "strands.txt", tiny_model)


def test_missing_folder_is_not_created(tmp_path, tiny_model):
    with pytest.raises(InputError, match="does not exist"):
        write_strands_usd(tmp_path / "no" / "such" / "strands.usda", tiny_model)
    assert list(tmp_path.iterdir()) == []


def test_failed_write_is_input_error_and_leaves_no_temp(tmp_path, tiny_model):
    (tmp_path / "strands.usda").mkdir()  # a folder where the file should go: the rename fails
    with pytest.raises(InputError, match="cannot write the strands USD file") as info:
        write_strands_usd(tmp_path / "strands.usda", tiny_model)
    assert "\n" not in str(info.value)
    assert [p.name for p in tmp_path.iterdir()] == ["strands.usda"]


def test_cli_inspect_writes_usd(tmp_path, samples_dir):
    from click.testing import CliRunner

    from wooddecay.cli import main

    out = tmp_path / "X.usda"
    result = CliRunner().invoke(
        main, ["inspect", str(samples_dir / "tiny.toml"), "--strands-usd", str(out), "--json"])
    assert result.exit_code == 0, result.output
    assert out.is_file()
    rep = json.loads(result.stdout)
    for key in ("elements", "reg_edges", "build_seconds"):
        assert key in rep
    stage = Usd.Stage.Open(str(out))
    assert stage.GetPrimAtPath("/World/tiny/Strands").IsValid()
