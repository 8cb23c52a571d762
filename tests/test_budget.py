"""The size estimate of wooddecay/budget.py: close to the built model, above the measured peak
memory within a stated factor, and a scene too large for the machine refused at once."""
from __future__ import annotations

import json
import subprocess
import sys
import time

import pytest
from click.testing import CliRunner

import wooddecay as wd
from wooddecay import budget
from wooddecay.cli import main, parse_size

from .conftest import SAMPLES


@pytest.mark.parametrize("name", ["tiny", "log", "board"])
def test_estimate_counts_match_the_built_model(name):
    scene = wd.load_scene(SAMPLES / f"{name}.toml")
    est = budget.estimate(scene)
    model = wd.build_model(scene)
    assert est.strands == model.n_strands
    assert abs(est.elements / model.n_elements - 1) < 0.05
    assert abs(est.reg_edges / model.n_edges - 1) < 0.15


def test_estimated_peak_bounds_a_measured_bake_within_a_factor_of_two(tmp_path):
    """The peak resident memory of a tiny bake (ru_maxrss of the bake, the only child of a wrapper
    process) is below the estimate and above half of it."""
    wrapper = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]); "
               "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
    bake = [sys.executable, "-m", "wooddecay.cli", "bake", str(SAMPLES / "tiny.toml"), "-o", str(tmp_path / "out"),
            "--days", "2", "--frames", "3"]
    run = subprocess.run([sys.executable, "-c", wrapper, *bake], capture_output=True, text=True)
    code, kib = run.stdout.strip().splitlines()[-1].split()
    assert code == "0", run.stderr
    peak = int(kib) * 1024
    est = budget.estimate(wd.load_scene(SAMPLES / "tiny.toml", {"time.frames": 3}))
    assert 0.5 * est.peak_bytes < peak < est.peak_bytes, (peak, est)


def test_oversized_scene_is_refused_in_one_line_before_anything_is_written(tmp_path):
    out = tmp_path / "out"
    t0 = time.perf_counter()
    r = CliRunner().invoke(main, ["bake", str(SAMPLES / "log.toml"), "-o", str(out), "--set", "strands.r_s=9e-6"])
    seconds = time.perf_counter() - t0
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "strands.r_s" in lines[0] and "rod elements" in lines[0] and "available" in lines[0]
    assert not out.exists() and seconds < 10


def test_max_memory_limit_refuses_and_inspect_prints_the_estimate(tmp_path):
    out = tmp_path / "out"
    r = CliRunner().invoke(main, ["bake", str(SAMPLES / "tiny.toml"), "-o", str(out), "--max-memory", "100M"])
    assert r.exit_code == 2 and "--max-memory limit (100 MB)" in r.stderr and not out.exists()
    r = CliRunner().invoke(main, ["inspect", str(SAMPLES / "tiny.toml"), "--json"])
    est = json.loads(r.stdout)["estimate"]
    assert est == budget.estimate(wd.load_scene(SAMPLES / "tiny.toml")).as_dict()
    assert set(est) == {"strands", "elements", "reg_edges", "meshlet_faces", "output_bytes", "peak_bytes"}


@pytest.mark.parametrize("text, size", [("8G", 8 * 2**30), ("500m", 500 * 2**20), ("2.5GB", int(2.5 * 2**30)),
                                        ("1048576", 2**20)])
def test_parse_size(text, size):
    assert parse_size(text) == size


@pytest.mark.parametrize("text", ["", "-1G", "lots", "0", "inf", "nanG"])
def test_parse_size_rejects(text):
    with pytest.raises(wd.InputError, match="--max-memory"):
        parse_size(text)
