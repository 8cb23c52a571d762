"""The gallery's bakes made ahead on processes (wooddecay.gallery.pool): how many processes, and a
bad bake's one-line error across the process boundary."""
from __future__ import annotations

import pickle

import pytest

from wooddecay.errors import InputError
from wooddecay.gallery import bakes, pool
from wooddecay.gallery.run import plan, select

JOBS = [pool.Job("fig6.toml", {}, f"/tmp/never/{k}") for k in range(3)]


def test_an_input_error_keeps_its_parts_through_pickling():
    err = pickle.loads(pickle.dumps(InputError("scene.toml", "strands.r_s", "-1 is outside (0, 1] m")))
    assert type(err) is InputError and (err.file, err.key, err.message) == ("scene.toml", "strands.r_s",
                                                                               "-1 is outside (0, 1] m")
    assert str(err) == "scene.toml: strands.r_s: -1 is outside (0, 1] m"


def test_workers_are_one_per_core_capped_by_the_jobs_and_the_memory(monkeypatch):
    monkeypatch.setattr(pool.os, "cpu_count", lambda: 8)
    monkeypatch.setattr(pool, "available_bytes", lambda: 2**40)
    assert pool.workers_for(JOBS, None) == 3 and pool.workers_for(JOBS, 2) == 2 and pool.workers_for([], None) == 0
    monkeypatch.setattr(pool, "available_bytes", lambda: 1)
    assert pool.workers_for(JOBS, None) == 1


def test_the_plan_is_every_variant_then_the_studies_bakes_in_figure_order(tmp_path):
    jobs = plan(select(("fig12", "fig20")), tmp_path, quick=True, resume=False)
    assert [j.folder.relative_to(tmp_path).as_posix() for j in jobs] == [
        "fig12/uniform", "fig12/one_side", *(f"fig20/{f}/{v}" for f in ("fig12", "fig14")
                                             for v in ("dt_half", "perturbed", "sparse2", "sparse4"))]
    assert jobs[1].overrides["inoculation.1.activity"] == 0.8 and jobs[0].overrides["strands.r_s"] == 0.012


def test_a_resumed_plan_leaves_out_the_finished_bakes_of_variants_and_studies(tmp_path, monkeypatch):
    monkeypatch.setattr(bakes, "finished_bake", lambda scene, folder: folder.name in ("uniform", "sparse4") or None)
    folders = [j.folder.relative_to(tmp_path).as_posix() for j in plan(select(("fig12", "fig20")), tmp_path, True, True)]
    assert folders == ["fig12/one_side", *(f"fig20/{f}/{v}" for f in ("fig12", "fig14")
                                           for v in ("dt_half", "perturbed", "sparse2"))]
    assert len(plan(select(("fig12", "fig20")), tmp_path, True, False)) == 10


@pytest.mark.slow
def test_a_bad_bake_ahead_raises_its_one_line_error_where_it_is_read(tmp_path):
    bad = pool.Job("fig6.toml", {"strands.r_s": -1.0}, tmp_path / "bad")
    with pytest.raises(InputError) as err:
        with pool.baking_ahead([bad], 2, bakes.timed_bake):
            pool.take(bad.folder)
    assert err.value.key == "strands.r_s" and "\n" not in str(err.value)
    assert pool.take(bad.folder) is None and not (tmp_path / "bad").exists()


@pytest.mark.parametrize("jobs", ["0", "two", "-1"])
def test_a_bad_jobs_count_is_one_line_before_anything_is_written(tmp_path, jobs):
    from click.testing import CliRunner

    from wooddecay.cli import main

    res = CliRunner().invoke(main, ["gallery", "6", "--quick", "--no-render", "--jobs", jobs, "-o", str(tmp_path / "g")])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "--jobs" in lines[0] and repr(jobs) in lines[0], res.output
    assert not (tmp_path / "g").exists()
