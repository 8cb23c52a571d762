"""`wooddecay chart solver` (issue 81 item 9): the bakes it charts run in a child process that is cut
at its cap, the resting log's error removes rigid motion, and the default it rings is the cheapest
setting within the target on both bakes."""
from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

import wooddecay as wd
from wooddecay.cli import main
from wooddecay.studies.solver_chart import TARGET, Run, bake, choose, plot_chart

from ..conftest import SAMPLES


def _run(case, label, wall, residual, finished=True):
    return Run(case, label, walls=[wall], residuals=[residual], finished=finished)


def test_the_default_is_the_cheapest_setting_within_the_target_on_both_bakes():
    runs = [_run("log", "xpbd 1", 10.0, 300.0), _run("fig6", "xpbd 1", 1.0, 20.0),
            _run("log", "xpbd 256", 50.0, 0.02, finished=False), _run("fig6", "xpbd 256", 30.0, 0.02),
            _run("log", "implicit 0.03", 40.0, 0.029), _run("fig6", "implicit 0.03", 30.0, 0.025),
            _run("log", "implicit 0.01", 60.0, 0.009), _run("fig6", "implicit 0.01", 5.0, 0.008),
            _run("log", "implicit 0.1", 5.0, 0.09), _run("fig6", "implicit 0.1", 1.0, 0.01)]
    assert choose(runs) == "implicit 0.01"  # 65 s against 70 s; 0.1 misses on the log, xpbd 256 was killed
    assert choose([r for r in runs if r.label != "implicit 0.01"]) == "implicit 0.03"
    assert choose([r for r in runs if r.label.startswith("xpbd")]) is None
    assert TARGET == 0.03


def test_the_resting_log_error_ignores_where_the_log_rolled():
    rng = np.random.default_rng(3)
    rest = rng.normal(size=(200, 3))
    sag = 1e-3 * rng.normal(size=(200, 3))
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    ref = Run("log", "implicit 0.003", settled=rest + sag, rest=rest)
    moved = Run("log", "xpbd 1", settled=(rest + sag) @ turn.T + [0.3, -0.2, 0.05], rest=rest)
    assert moved.shape_error(ref) < 1e-9
    doubled = Run("log", "xpbd 1", settled=(rest + 2.0 * sag) @ turn.T, rest=rest)
    assert doubled.shape_error(ref) == pytest.approx(1.0, rel=0.05)


def test_a_bake_reports_its_frames_and_one_past_its_cap_is_killed():
    path = str(SAMPLES / "tiny.toml")
    overrides = {"time.days": 4.0, "time.frames": 3}
    run = bake("tiny", path, "xpbd 1", overrides, cap=300.0)
    assert run.finished and len(run.residuals) == 3 and run.walls == sorted(run.walls)
    sim = wd.Simulation(wd.build_model(wd.load_scene(path, overrides)))
    frames = list(sim.run())  # the same bake in this process: the same bits
    assert run.residuals == [f.diagnostics["mechanics"]["equilibrium_residual"] for f in frames]
    assert np.array_equal(run.settled, frames[0].mech["x"])
    killed = bake("tiny", path, "xpbd 256", overrides | {"mechanics.iterations": 256}, cap=0.5)
    assert not killed.finished and killed.wall == 0.5 and len(killed.residuals) < 3


def test_chart_solver_refuses_a_missing_folder_in_one_line(tmp_path):
    r = CliRunner().invoke(main, ["chart", "solver", "-o", str(tmp_path / "no" / "solver.png")])
    assert r.exit_code == 2 and len(r.output.splitlines()) == 1 and "does not exist" in r.output


def test_the_chart_draws_every_panel_and_rings_the_default(tmp_path):
    rng = np.random.default_rng(5)
    rest = rng.normal(size=(50, 3))
    runs = [Run(case, label, walls=[1.0, w], residuals=[r, r], finished=True, settled=rest + 1e-3 * r * rest, rest=rest)
            for case in ("log", "fig6") for label, w, r in
            (("xpbd 1", 10.0, 300.0), ("implicit 0.03", 20.0, 0.02), ("implicit 0.003", 30.0, 0.002))]
    runs.append(Run("log", "xpbd 256", cap=600.0))  # cut before its first frame
    cantilever = [{"label": "xpbd 1", "seconds": 1.5, "error": 0.04}, {"label": "implicit 0.03", "seconds": 0.02, "error": 0.0}]
    out = tmp_path / "solver.png"
    assert plot_chart(runs, cantilever, out) == "implicit 0.03"
    assert out.read_bytes().startswith(b"\x89PNG") and out.stat().st_size > 10_000
