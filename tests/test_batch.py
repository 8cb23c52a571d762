"""``wooddecay batch`` on dask.distributed: variants, failures that do not stop the others, resume,
a worker killed mid-bake, identity with single bakes, and broken batch files."""
from __future__ import annotations

import json
import os
import signal
import threading
import time

import pytest
from click.testing import CliRunner

from wooddecay import batch as batch_mod
from wooddecay.cli import main

from .conftest import ROOT, SAMPLES

BAD = ROOT / "tests" / "data" / "bad_batch"


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def write_batch(folder, grid: str, days: int = 2, frames: int = 2):
    """A batch of the tiny log over ``grid`` (TOML lines), ``days`` and ``frames`` each."""
    path = folder / "b.toml"
    path.write_text(f'[batch]\nscenes = ["{SAMPLES / "tiny.toml"}"]\n[batch.set]\n"time.days" = {days}\n'
                    f'"time.frames" = {frames}\n[batch.grid]\n{grid}\n')
    return path


@pytest.mark.parametrize("bad", sorted(p.name for p in BAD.glob("*.toml")))
def test_broken_batch_files_exit_2_with_one_line_and_no_output(bad, tmp_path):
    out = tmp_path / "out"
    res = run("batch", BAD / bad, "-o", out)
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and bad in lines[0], res.output
    assert not out.exists()


def test_variants_are_the_grid_over_every_scene_with_the_common_overrides(tmp_path):
    path = write_batch(tmp_path, '"scene.seed" = [1, 2, 3]\n"moisture.M_2" = [0.2, 0.4]')
    variants = batch_mod.load_batch(path)
    assert len(variants) == 6 and len({v.name for v in variants}) == 6
    assert variants[0].name == "tiny__scene.seed=1__moisture.M_2=0.2"
    assert all(v.overrides["time.days"] == 2 and v.overrides["time.frames"] == 2 for v in variants)
    assert sorted((v.overrides["scene.seed"], v.overrides["moisture.M_2"]) for v in variants) == [
        (s, m) for s in (1, 2, 3) for m in (0.2, 0.4)]


@pytest.mark.slow
def test_batch_on_a_local_cluster_equals_single_bakes_and_resumes(tmp_path):
    """Two good variants and one with a bad override: the bad one fails on one line, the others
    bake and equal a single `wooddecay bake` of the same scene (`wooddecay diff` exit 0); a second
    run with --resume bakes nothing again (the bad variant fails again)."""
    path = write_batch(tmp_path, '"scene.seed" = [1, 2]\n"strands.r_s" = [0.006, -1]')
    out = tmp_path / "out"
    res = run("batch", path, "-o", out, "--workers", "2")
    assert res.exit_code == 1, res.output  # a variant failed
    rows = json.loads((out / "batch.json").read_text())
    assert [r["status"] for r in rows] == ["done", "failed", "done", "failed"]
    assert all("strands.r_s: -1 is outside (0, 1] m" in r["error"] for r in rows if r["status"] == "failed")
    assert all(r["signature"]["pieces"] >= 1 and r["seconds"] > 0 for r in rows if r["status"] == "done")
    assert len((out / "batch.csv").read_text().splitlines()) == 5
    single = tmp_path / "single"
    assert run("bake", SAMPLES / "tiny.toml", "-o", single, "--days", "2", "--frames", "2",
               "--set", "scene.seed=2").exit_code == 0
    variant = out / "tiny__scene.seed=2__strands.r_s=0.006"
    assert run("diff", variant / "tiny.usdc", single / "tiny.usdc").exit_code == 0

    again = run("batch", path, "-o", out, "--workers", "2", "--resume")
    assert "0 done, 2 skipped, 2 failed" in again.output, again.output
    assert [r["status"] for r in json.loads((out / "batch.json").read_text())] == ["skipped", "failed"] * 2


@pytest.mark.slow
def test_a_worker_killed_mid_bake_has_its_variant_retried_with_the_same_result(tmp_path):
    """Kill the worker process running a variant; Dask runs the variant again elsewhere and its
    stage equals a single bake's."""
    path = write_batch(tmp_path, '"scene.seed" = [3]', days=20, frames=4)
    variants = batch_mod.load_batch(path)
    client = batch_mod.client_for(None, 2)
    killed = []

    pids = client.run(os.getpid)

    def kill_the_busy_worker():
        deadline = time.time() + 60
        while time.time() < deadline and not killed:
            busy = [w for w, tasks in client.processing().items() if tasks]
            if busy:
                time.sleep(0.5)  # inside the bake
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(busy[0])
            time.sleep(0.05)

    try:
        killer = threading.Thread(target=kill_the_busy_worker)
        killer.start()
        rows = batch_mod.run_batch(variants, tmp_path / "out", client)
        killer.join()
    finally:
        client.cluster.close()
        client.close()
    assert killed and rows[0]["status"] == "done", rows
    single = tmp_path / "single"
    assert run("bake", SAMPLES / "tiny.toml", "-o", single, "--days", "20", "--frames", "4",
               "--set", "scene.seed=3").exit_code == 0
    assert run("diff", tmp_path / "out" / variants[0].name / "tiny.usdc", single / "tiny.usdc").exit_code == 0


def test_variants_of_the_same_wood_share_one_built_model_and_bake_the_same(tmp_path, monkeypatch):
    """Two variants that differ only in [time] build the model once on a worker; the second,
    baked from the retimed model, equals a single bake of its scene."""
    import wooddecay.model

    builds = []
    real = wooddecay.model.build_model
    monkeypatch.setattr(wooddecay.model, "build_model", lambda scene: builds.append(scene.name) or real(scene))
    monkeypatch.setattr(batch_mod, "_models", {})
    path = tmp_path / "b.toml"
    path.write_text(f'[batch]\nscenes = ["{SAMPLES / "tiny.toml"}"]\n[batch.set]\n"time.frames" = 2\n'
                    '[batch.grid]\n"time.days" = [1, 3]\n')
    rows = [batch_mod.bake_variant(v, str(tmp_path / v.name), 1) for v in batch_mod.load_batch(path)]
    assert [r["status"] for r in rows] == ["done", "done"] and len(builds) == 1
    single = tmp_path / "single"
    assert run("bake", SAMPLES / "tiny.toml", "-o", single, "--days", "3", "--frames", "2").exit_code == 0
    assert run("diff", tmp_path / "tiny__time.days=3" / "tiny.usdc", single / "tiny.usdc").exit_code == 0


def test_variants_of_the_same_wood_share_their_meshlets_and_bake_the_same(tmp_path, monkeypatch):
    """Variants under other climates (another model, the same wood) mesh once on a worker; a
    variant of another seed (other strands) meshes again; each equals a single bake."""
    from wooddecay.meshlets import sweep

    meshed = []
    real = sweep.build_meshlets
    monkeypatch.setattr(sweep, "build_meshlets", lambda model: meshed.append(model.info.settle_hash) or real(model))
    monkeypatch.setattr(batch_mod, "_models", {})
    monkeypatch.setattr(batch_mod, "_meshlets", {})
    path = tmp_path / "b.toml"
    path.write_text(f'[batch]\nscenes = ["{SAMPLES / "tiny.toml"}"]\n[batch.set]\n"time.frames" = 2\n"time.days" = 2\n'
                    '[batch.grid]\n"scene.seed" = [1, 2]\n"climate.preset" = ["temperate", "dry"]\n')
    rows = [batch_mod.bake_variant(v, str(tmp_path / v.name), 1) for v in batch_mod.load_batch(path)]
    assert [r["status"] for r in rows] == ["done"] * 4
    assert len(meshed) == 2 and len(set(meshed)) == 2  # one per seed
    name = "tiny__scene.seed=2__climate.preset=dry"
    single = tmp_path / "single"
    assert run("bake", SAMPLES / "tiny.toml", "-o", single, "--days", "2", "--frames", "2",
               "--set", "scene.seed=2", "--set", "climate.preset=dry").exit_code == 0
    assert run("diff", tmp_path / name / "tiny.usdc", single / "tiny.usdc").exit_code == 0
    assert (tmp_path / name / "tiny.glb").read_bytes() == (single / "tiny.glb").read_bytes()


def test_bake_refuses_meshlets_of_another_model(tmp_path, log_model):
    from wooddecay.bake import bake
    from wooddecay.meshlets.sweep import build_meshlets
    from wooddecay.scene import load_scene

    scene = load_scene(SAMPLES / "tiny.toml", overrides={"time.days": 1.0, "time.frames": 2})
    with pytest.raises(ValueError, match="meshlets given to bake"):
        bake(scene, tmp_path / "out", meshlets=build_meshlets(log_model))
    assert not (tmp_path / "out").exists()
