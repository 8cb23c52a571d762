"""The scene file format version (``[scene] format``; docs/scene.md "Format version"): optional,
format 1 when left out, a newer one refused in one line before anything else, and never part of
the scene hash, so the shipped scenes that now declare it give the same outputs as before."""
from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner

from wooddecay import scene as P
from wooddecay.cli import main
from wooddecay.errors import InputError
from wooddecay.scene import load_scene, parse_scene, parse_set_option
from wooddecay.scene.schema import FORMAT, FORMAT_MIN, FORMAT_UNDECLARED

from .conftest import SKELETON, error, parse

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "wooddecay"
#: every scene file shipped with the package (not skeleton files, not batch files)
SHIPPED = sorted(p for folder in (PACKAGE / "samples", PACKAGE / "studies" / "scenes") for p in folder.rglob("*.toml")
                 if "skeleton" not in p.stem and not p.stem.startswith("batch"))
RANGE = f"[{FORMAT_MIN}, {FORMAT}]"


def test_format_is_a_scene_key_of_version_1():
    p = P.get_param("scene.format")
    assert FORMAT == 1 and FORMAT_UNDECLARED == 1 and p.default == 1 and p.kind == "int"
    assert P.format_range(p) == RANGE


def test_a_scene_without_format_is_format_1():
    s = parse()
    assert s.format == 1 and s.param("scene.format") == 1


def test_a_scene_declaring_format_1_reads_the_same_and_hashes_the_same():
    bare = parse('[scene]\nname = "x"\n')
    declared = parse('[scene]\nformat = 1\nname = "x"\n')
    overridden = parse('[scene]\nname = "x"\n', overrides={"scene.format": 1})
    assert declared.format == overridden.format == 1
    assert bare.to_dict() == declared.to_dict() == overridden.to_dict()
    for attr in ("hash", "settle_hash", "model_hash"):
        assert getattr(bare, attr) == getattr(declared, attr) == getattr(overridden, attr), attr


@pytest.mark.parametrize("extra", [
    "[scene]\nformat = 2\n",
    "[scene]\nformat = 99\n",
    "[scene]\nformat = 2.0\n",
    "[scene]\nformat = 123456789012345678901234567890\n",
    # a newer scene may hold keys and tables this wooddecay does not know: the format is named
    "[scene]\nformat = 2\nsomething_new = 1\n[newer_section]\nx = 1\n",
])
def test_a_newer_format_is_refused_in_one_line(extra):
    err = error(extra)
    text = str(err)
    assert err.file == "samples/log.toml" and err.key == "scene.format"
    assert "newer than wooddecay" in text and f"formats {RANGE}" in text and "upgrade wooddecay" in text
    assert text.startswith("samples/log.toml: scene.format: format ")


def test_a_newer_format_from_an_override_names_the_override():
    with pytest.raises(InputError) as info:
        parse_scene(SKELETON, source="log.toml", overrides=parse_set_option(["scene.format=2"]))
    assert info.value.file == "<--set>" and info.value.key == "scene.format" and RANGE in str(info.value)


@pytest.mark.parametrize("extra, needle", [
    ("[scene]\nformat = 0\n", f"0 is outside {RANGE}"),
    ("[scene]\nformat = -3\n", f"-3 is outside {RANGE}"),
    ('[scene]\nformat = "1"\n', f"expected an integer in {RANGE}, got string '1'"),
    ("[scene]\nformat = 1.5\n", f"expected an integer in {RANGE}, got 1.5"),
    ("[scene]\nformat = true\n", f"expected an integer in {RANGE}, got boolean true"),
    ("[scene]\nformat = [1]\n", f"expected an integer in {RANGE}"),
])
def test_a_malformed_format_is_refused_with_its_range(extra, needle):
    err = error(extra)
    assert err.key == "scene.format" and needle in str(err)


def test_the_cli_refuses_a_newer_scene_in_one_line_exit_2(tmp_path):
    f = tmp_path / "future.toml"
    f.write_text("[scene]\nformat = 2\n[future]\nx = 1\n" + SKELETON)
    r = CliRunner().invoke(main, ["inspect", str(f)])
    assert r.exit_code == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and str(f) in lines[0]
    assert "scene.format" in lines[0] and RANGE in lines[0] and "Traceback" not in r.output


@pytest.mark.parametrize("path", SHIPPED, ids=[str(p.relative_to(PACKAGE)) for p in SHIPPED])
def test_every_shipped_scene_declares_the_current_format(path):
    data = tomllib.loads(path.read_text("utf-8"))
    assert data.get("scene", {}).get("format") == FORMAT, f"{path}: add format = {FORMAT} to its [scene] table"


def test_the_shipped_scenes_are_found():
    names = {p.relative_to(PACKAGE).as_posix() for p in SHIPPED}
    assert {"samples/tiny.toml", "samples/log.toml", "samples/tree.toml", "samples/gallery/fig12.toml",
            "samples/meshes/bent_log.toml", "studies/scenes/barrier.toml"} <= names
    assert not any("skeleton" in n or "batch" in n for n in names)


@pytest.mark.parametrize("name", ["tiny", "board"])
def test_a_shipped_scene_hashes_the_same_without_its_format_key(tmp_path, name):
    """The key changes no result: the scene written without it has the same hashes (the USD
    stage's scene_hash, the bake's resume check, the settled-rod and model caches)."""
    path = PACKAGE / "samples" / f"{name}.toml"
    text = path.read_text("utf-8")
    assert f"\nformat = {FORMAT}\n" in text
    bare = tmp_path / path.name
    bare.write_text(text.replace(f"\nformat = {FORMAT}\n", "\n", 1))
    a, b = load_scene(path), load_scene(bare)
    assert (a.hash, a.settle_hash, a.model_hash) == (b.hash, b.settle_hash, b.model_hash)
