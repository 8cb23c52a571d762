"""`wooddecay inspect`, `wooddecay init` and `python -m wooddecay`: reports, templates and one-line errors."""
from __future__ import annotations

import json
import shlex
import subprocess
import sys

import pytest
from click.testing import CliRunner

import wooddecay as wd
from wooddecay.cli import main

from .conftest import ROOT, SAMPLES


def _run(*args):
    return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)


def test_inspect_json_keys():
    r = _run("inspect", SAMPLES / "tiny.toml", "--json")
    assert r.exit_code == 0, r.output
    rep = json.loads(r.stdout)
    for key in ("elements", "reg_edges", "build_seconds", "strands", "bsp_cells", "tissues",
                "estimate", "build_stages", "reg_degree"):
        assert key in rep
    m = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml"))
    assert rep["elements"] == m.n_elements and rep["reg_edges"] == m.n_edges
    assert rep["bsp_cells"] == 40
    assert set(rep["build_stages"]) >= {"strands", "elements", "rings", "reg", "bsp", "weakpoints"}
    assert rep["build_seconds"] > 0


def test_inspect_text_and_set_override():
    r = _run("inspect", SAMPLES / "tiny.toml", "--set", "bsp.cells=10")
    assert r.exit_code == 0
    assert "BSP cells        10" in r.stdout and "REG edges" in r.stdout


@pytest.mark.parametrize("args, needle", [
    (["--set", "strands.r_s=-1"], "strands.r_s"),
    (["--set", "strands.r_ss=1"], "did you mean"),
    (["--set", "bsp.cells"], "<--set>"),
])
def test_inspect_bad_input_one_line_exit_2(args, needle):
    r = CliRunner().invoke(main, ["inspect", str(SAMPLES / "tiny.toml"), *args])
    assert r.exit_code == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.output


BAD_CLI = [line.split("\t") for line in (ROOT / "tests" / "data" / "bad" / "cli.txt").read_text("utf-8").splitlines()
           if line and not line.startswith("#")]


@pytest.mark.parametrize("needle, args", BAD_CLI, ids=[a for _, a in BAD_CLI])
def test_broken_command_lines_are_one_line_exit_2(tmp_path, needle, args):
    """Every command line of the corpus (click's own errors included: argument types, missing
    arguments, unknown options and commands) is one line on stderr with exit 2 and writes nothing."""
    (tmp_path / "dir").mkdir()
    (tmp_path / "file.txt").write_text("not [ a scene\n")
    out = tmp_path / "out"
    argv = [a.format(tiny=SAMPLES / "tiny.toml", dir=tmp_path / "dir", file=tmp_path / "file.txt")
            for a in shlex.split(args)]
    if argv[0] == "bake" and len(argv) > 1 and "-o" not in argv:
        argv += ["-o", str(out)]
    r = CliRunner().invoke(main, argv)
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], r.stderr
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == ["dir", "file.txt"]


def test_inspect_broken_scene_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[strands]\nr_s = 'thick'\n")
    r = CliRunner().invoke(main, ["inspect", str(bad)])
    assert r.exit_code == 2
    assert r.stderr.count("\n") == 1 and "bad.toml" in r.stderr and "strands.r_s" in r.stderr


def test_inspect_missing_file(tmp_path):
    r = CliRunner().invoke(main, ["inspect", str(tmp_path / "nope.toml")])
    assert r.exit_code == 2 and r.stderr.count("\n") == 1


def test_inspect_treeqsm_skeleton(tmp_path):
    (tmp_path / "qsm.csv").write_text(
        "start_x,start_y,start_z,axis_x,axis_y,axis_z,length,radius,parent\n"
        "0,0,0,0,0,1,0.4,0.05,0\n"
        "0,0,0.4,0,0,1,0.4,0.045,1\n"
        "0,0,0.8,0.6,0,0.8,0.3,0.03,2\n")
    (tmp_path / "s.toml").write_text('[skeleton]\nfile = "qsm.csv"\n[strands]\nr_s = 0.005\n')
    r = _run("inspect", tmp_path / "s.toml", "--json")
    rep = json.loads(r.stdout)
    assert rep["elements"] > 100 and rep["branches"] == 1


@pytest.mark.parametrize("template", ["board", "log", "tree"])
def test_init_writes_a_loadable_scene(tmp_path, template, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = _run("init", "mine", "--template", template)
    assert r.exit_code == 0, r.output
    scene = wd.load_scene(tmp_path / "mine.toml")
    assert scene.name == "mine"
    assert len(scene.skeleton.ids) >= 2
    again = CliRunner().invoke(main, ["init", "mine", "--template", template])
    assert again.exit_code == 2 and "already exists" in again.stderr


@pytest.fixture
def no_build(monkeypatch):
    """Fail the test if the model gets built."""
    def fail(*_args, **_kwargs):
        raise AssertionError("the model was built before the --strands-usd path was checked")

    monkeypatch.setattr("wooddecay.model.build_model", fail)


@pytest.mark.parametrize("name, needle", [
    ("x.txt", "must end in .usda, .usdc, .usd"),
    ("missing/x.usda", "does not exist"),
])
def test_inspect_bad_strands_usd_path_fails_before_building(tmp_path, no_build, name, needle):
    r = CliRunner().invoke(main, ["inspect", str(SAMPLES / "tiny.toml"), "--strands-usd", str(tmp_path / name)])
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in r.output
    assert list(tmp_path.iterdir()) == []


def test_python_dash_m_runs_the_command():
    """``python -m wooddecay`` is the command (its name in the usage line), with its exit codes."""
    ok = subprocess.run([sys.executable, "-m", "wooddecay", "inspect", str(SAMPLES / "tiny.toml"), "--json"],
                        capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert json.loads(ok.stdout)["bsp_cells"] == 40
    bad = subprocess.run([sys.executable, "-m", "wooddecay", "frobnicate"], capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.startswith("error:") and bad.stderr.strip().count("\n") == 0
    usage = subprocess.run([sys.executable, "-m", "wooddecay", "--help"], capture_output=True, text=True)
    assert usage.stdout.startswith("Usage: wooddecay "), usage.stdout[:80]
