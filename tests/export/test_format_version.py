"""The baked stage's format (customLayerData ``format_version``, wooddecay.export.usd): written by
every bake, read as format 1 when an older bake lacks it, and a newer one refused in one line by
``wooddecay diff`` and ``wooddecay inspect BAKE_DIR`` (exit 2)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from click.testing import CliRunner

import wooddecay as wd
from wooddecay.cli import main
from wooddecay.errors import InputError
from wooddecay.export.usd import FORMAT, FORMAT_KEY, FORMAT_MIN, FORMAT_UNDECLARED, check_bake_format, stage_format

ROOT = Path(__file__).resolve().parents[2]
RANGE = f"[{FORMAT_MIN}, {FORMAT}]"

STAGE = """#usda 1.0
(
    customLayerData = {{
        {meta}
        string scene = "log"
    }}
    defaultPrim = "World"
    metersPerUnit = 1
    upAxis = "Z"
)

def Xform "World"
{{
    def Mesh "Wood"
    {{
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
    }}
}}
"""


def _stage(folder: Path, name: str, meta: str) -> Path:
    path = folder / f"{name}.usda"
    path.write_text(STAGE.format(meta=meta))
    return path


def test_the_stage_format_key_follows_customlayerdata_naming():
    assert FORMAT == 2 and FORMAT_UNDECLARED == 1 and FORMAT_KEY == "format_version"


def test_the_golden_stage_declares_the_current_format():
    from pxr import Sdf

    layer = Sdf.Layer.OpenAsAnonymous(str(ROOT / "tests" / "golden" / "tiny.usda"), True)
    data = dict(layer.customLayerData)
    assert data[FORMAT_KEY] == FORMAT and isinstance(data[FORMAT_KEY], int)


@pytest.mark.parametrize("data, expected", [({}, 1), (None, 1), ({"scene": "x"}, 1), ({FORMAT_KEY: 1}, 1)])
def test_stage_format_reads_an_older_stage_as_format_1(data, expected):
    assert stage_format(data, "a.usdc") == expected


@pytest.mark.parametrize("value, needle", [
    (FORMAT + 1, f"stage format {FORMAT + 1} is newer than wooddecay {wd.__version__} reads (formats {RANGE})"),
    (0, f"stage format 0 is older than wooddecay {wd.__version__} reads (formats {RANGE})"),
    ("1", f"expected a whole number in {RANGE}"),
    (1.0, f"expected a whole number in {RANGE}"),
    (True, f"expected a whole number in {RANGE}"),
])
def test_stage_format_refuses_newer_or_malformed_in_one_line(value, needle):
    with pytest.raises(InputError) as info:
        stage_format({FORMAT_KEY: value}, "bake/a.usdc")
    err = info.value
    assert err.file == "bake/a.usdc" and err.key == f"customLayerData.{FORMAT_KEY}"
    assert needle in str(err) and "\n" not in str(err)


def test_diff_compares_stages_of_format_1_with_or_without_the_key(tmp_path):
    old = _stage(tmp_path, "old", "")
    new = _stage(tmp_path, "new", "int format_version = 1")
    (d,) = wd.compare_usd(old, new)
    assert d.what == "metadata" and f"customLayerData[{FORMAT_KEY}] only in b" in d.detail
    assert wd.compare_usd(new, new) == [] and wd.compare_usd(old, old) == []


@pytest.mark.parametrize("which", ["a", "b"])
def test_diff_refuses_a_newer_stage_in_one_line_exit_2(tmp_path, which):
    ok = _stage(tmp_path, "ok", "int format_version = 1")
    future = _stage(tmp_path, "future", f"int format_version = {FORMAT + 1}")
    with pytest.raises(InputError) as info:
        wd.compare_usd(*((future, ok) if which == "a" else (ok, future)))
    assert info.value.file == str(future)
    args = [str(future), str(ok)] if which == "a" else [str(ok), str(future)]
    r = CliRunner().invoke(main, ["diff", *args])
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {future}: customLayerData.{FORMAT_KEY}: stage format {FORMAT + 1}")
    assert RANGE in lines[0] and "Traceback" not in r.output


SIGNATURE = {"mass_loss": 0.1, "pieces": 1, "largest_piece_fraction": 1.0, "block_purity": 0.5,
             "hollow_fraction": 0.0, "crumbled_elements": 0, "debris_height_m": 0.0, "debris_footprint_m2": 0.0,
             "crack_clusters": 0, "crack_orientation": [0.0, 0.0, 0.0]}


def _bake_dir(tmp_path: Path, meta: str | None) -> Path:
    out = tmp_path / "bake"
    out.mkdir()
    (out / "summary.json").write_text(json.dumps({"frames": [{"frame": 0, "t_days": 0.0, "signature": SIGNATURE}]}))
    if meta is not None:
        _stage(out, "log", meta)
    return out


@pytest.mark.parametrize("meta", [None, "", "int format_version = 1"])
def test_inspect_bake_reads_format_1_and_older_bakes(tmp_path, meta):
    out = _bake_dir(tmp_path, meta)
    check_bake_format(out)
    r = CliRunner().invoke(main, ["inspect", str(out), "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)[0]["frame"] == 0


def test_inspect_bake_refuses_a_newer_stage_in_one_line_exit_2(tmp_path):
    out = _bake_dir(tmp_path, f"int format_version = {FORMAT + 1}")
    r = CliRunner().invoke(main, ["inspect", str(out)])
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and str(out / "log.usda") in lines[0] and f"stage format {FORMAT + 1} is newer" in lines[0]
    assert RANGE in lines[0] and "Traceback" not in r.output
