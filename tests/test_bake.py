"""``wooddecay bake`` and ``wooddecay diff`` end to end."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from click.testing import CliRunner

from wooddecay.cli import main
from wooddecay.export.wood_read import wood_at, wood_meshes
from wooddecay.sim.threads import LoadMonitor

from .conftest import ROOT, SAMPLES

TINY = str(SAMPLES / "tiny.toml")
SHORT = ["--days", "2", "--frames", "3"]
GOLDEN = ROOT / "tests" / "golden" / "tiny.usda"
#: the bake the golden file holds, kept beside it (regenerate: python scripts/regenerate_golden.py)
GOLDEN_ARGS = GOLDEN.with_suffix(".args").read_text("utf-8").split()


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.fixture(scope="module")
def baked(tmp_path_factory):
    out = tmp_path_factory.mktemp("bake")
    res = run("bake", TINY, "-o", out, *SHORT)
    assert res.exit_code == 0, res.output
    return out


def test_bake_writes_usd_glb_and_summary(baked):
    names = sorted(p.name for p in baked.iterdir() if not p.name.startswith("."))
    assert names == ["summary.json", "tiny.glb", "tiny.usdc", "tiny_bark.1001.png", "tiny_bark.1002.png",
                     "tiny_bark.1003.png"]  # the crack map: a UDIM tile per frame
    s = json.loads((baked / "summary.json").read_text())
    assert s["counts"]["frames"] == 3 and s["counts"]["meshlets"] == s["counts"]["elements"]
    assert set(s["seconds"]) == {"build", "simulation", "meshing", "export"}
    assert [f["frame"] for f in s["frames"]] == [0, 1, 2]
    assert all("broken_connections" in f and "mass_loss" in f for f in s["frames"])
    assert s["outputs"]["tiny.usdc"]["bytes"] == (baked / "tiny.usdc").stat().st_size


def test_bake_replaces_an_earlier_crack_map(tmp_path):
    """A bake into a folder that holds an earlier bake's crack map (more frames' tiles, or the
    single image of older versions) leaves only its own tiles: the add-on reads every tile of the
    set as a frame."""
    for name in ("tiny_bark.1001.png", "tiny_bark.1009.png", "tiny_bark.png", "tiny_bark.notes.png"):
        (tmp_path / name).write_bytes(b"old")
    res = run("bake", TINY, "-o", tmp_path, "--days", "2", "--frames", "2")
    assert res.exit_code == 0, res.output
    names = sorted(p.name for p in tmp_path.glob("tiny_bark*"))
    assert names == ["tiny_bark.1001.png", "tiny_bark.1002.png", "tiny_bark.notes.png"]
    assert (tmp_path / "tiny_bark.1001.png").read_bytes().startswith(b"\x89PNG")
    assert f"wrote {tmp_path / 'tiny_bark.<UDIM>.png'}  (2 tiles, one per frame" in res.output
    assert "tiny_bark.1001" not in res.output


def test_bake_reports_under_converged_mechanics_with_its_remedy(tmp_path):
    """The tiny log's strands at the default 1 iteration per 0.1 ms substep are far softer than
    their E (docs/model.md §7): summary.json and one stderr line say so and name the remedy."""
    res = run("bake", TINY, "-o", tmp_path, *SHORT)
    assert res.exit_code == 0, res.output
    conv = json.loads((tmp_path / "summary.json").read_text())["convergence"]
    frames = json.loads((tmp_path / "summary.json").read_text())["frames"]
    assert conv["strain_excess_max"] == max([conv["strain_excess_settled"]] + [f["strain_excess"] for f in frames])
    assert conv["strain_excess_max"] > conv["tolerance"] and not conv["converged"]
    warnings = [ln for ln in res.stderr.splitlines() if ln.startswith("warning: ")]
    assert warnings == [f"warning: {conv['remedy']}"]
    assert "mechanics.iterations (now 1)" in warnings[0] and "mechanics.dt_mech (now 0.0001 s)" in warnings[0]


def test_implicit_bake_holds_every_frame_in_equilibrium(tmp_path):
    """mechanics.solver = "implicit": the settled rods and every frame within an equilibrium
    residual of 0.03 (docs/model.md §7), no warning; the strain excess (XPBD's) is not read. Each
    frame after the first is solved after its coupling (docs/decisions.md, "Implicit frames"), so
    it holds the step tolerance, not only the frame bound."""
    res = run("bake", TINY, "-o", tmp_path, *SHORT, "--set", "mechanics.solver=implicit")
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "summary.json").read_text())
    conv, frames = summary["convergence"], summary["frames"]
    assert conv["converged"] and conv["unconverged_steps"] == 0 and "strain_excess_max" not in conv
    assert conv["equilibrium_residual_max"] == max([conv["equilibrium_residual_settled"]]
                                                   + [f["equilibrium_residual"] for f in frames])
    assert conv["equilibrium_residual_max"] <= 0.03
    assert summary["schedule"]["due"]["frame"] == len(frames) - 1
    assert max(f["equilibrium_residual"] for f in frames[1:]) <= 0.01  # mechanics.residual_tolerance's default
    assert not [ln for ln in res.stderr.splitlines() if ln.startswith("warning: ")]


def test_baked_stage_follows_the_contract(baked):
    from pxr import Usd, UsdGeom, UsdShade, UsdValidation

    stage = Usd.Stage.Open(str(baked / "tiny.usdc"))
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    errors = [e for e in ctx.Validate(stage) if e.GetType() == UsdValidation.ValidationErrorType.Error]
    assert errors == [], [e.GetMessage() for e in errors]
    assert UsdGeom.GetStageUpAxis(stage) == "Z" and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().GetPath() == "/World"
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 2.0)
    meta = stage.GetRootLayer().customLayerData
    assert meta["scene"] == "tiny" and len(meta["scene_hash"]) == 64
    assert meta["format_version"] == 2 and meta["point_tolerance"] == 2e-4 and meta["field_step"] == 2e-3
    wood = stage.GetPrimAtPath("/World/tiny/Wood")
    pieces = wood_meshes(stage)
    assert wood.GetTypeName() == "Xform" and pieces and all(p.GetParent() == wood for p in pieces)
    for piece in pieces:
        pv = UsdGeom.PrimvarsAPI(piece)
        for name in ("H_c", "H_l", "M", "R_w", "R_b", "C", "bark_crack", "bark_crack_depth", "displayColor"):
            p = pv.GetPrimvar(name)
            assert p.GetInterpolation() == "vertex" and p.IsIndexed() and p.GetAttr().GetTimeSamples() == []
        for name in ("element", "tissue", "faceKind", "piece", "face", "exposedFrame"):
            assert pv.GetPrimvar(name).GetInterpolation() == "uniform"
        assert pv.GetPrimvar("wood").GetAttr().GetTimeSamples() == []
        assert UsdGeom.Mesh(piece).GetOrderedXformOps()[0].GetOpName() == "xformOp:transform"
    H_c0, H_c2 = wood_at(stage, 0.0)["H_c"], wood_at(stage, 2.0)["H_c"]
    assert H_c2.min() < H_c0.max()  # brown rot from the root end lowers H_c
    changing = [p for p in pieces if UsdGeom.PrimvarsAPI(p).GetPrimvar("H_c").GetIndicesAttr().GetTimeSamples()]
    assert changing and all(UsdGeom.PrimvarsAPI(p).GetPrimvar("H_c").GetIndicesAttr().GetTimeSamples()
                            == [0.0, 1.0, 2.0] for p in changing)
    mat, _ = UsdShade.MaterialBindingAPI(pieces[0]).ComputeBoundMaterial()
    assert mat.GetPath() == "/World/tiny/Looks/Wood"


def test_diff_same_seed_equal_perturbed_different_malformed_error(baked, tmp_path):
    other = tmp_path / "again"
    assert run("bake", TINY, "-o", other, *SHORT).exit_code == 0
    res = run("diff", baked / "tiny.usdc", other / "tiny.usdc")
    assert res.exit_code == 0, res.output
    from pxr import Usd, UsdGeom, Vt

    stage = Usd.Stage.Open(str(other / "tiny.usdc"))
    piece = wood_meshes(stage)[0]
    h = UsdGeom.PrimvarsAPI(piece).GetPrimvar("H_l").GetAttr()
    vals = list(h.Get())
    vals[-1] += 0.01
    h.Set(Vt.FloatArray(vals))
    stage.GetRootLayer().Export(str(tmp_path / "perturbed.usda"))
    res = run("diff", baked / "tiny.usdc", tmp_path / "perturbed.usda")
    assert res.exit_code == 1
    assert f"{piece.GetPath()}.primvars:H_l" in res.output and "max abs 0.01" in res.output
    (tmp_path / "bad.usda").write_text("#usda 1.0\n(\n  nonsense = [\n")
    res = run("diff", baked / "tiny.usdc", tmp_path / "bad.usda")
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1 and "bad.usda" in res.output


BAD = ROOT / "tests" / "data" / "bad"


@pytest.mark.parametrize("bad", sorted(p.name for p in BAD.glob("*.toml")))
def test_broken_scenes_exit_2_with_one_line_and_no_output(bad, tmp_path):
    """The corpus of broken scenes, skeletons and TreeQSM tables: one line naming the file at
    fault (the scene, or the skeleton file it refers to, in files/), exit 2, nothing written."""
    out = tmp_path / "out"
    res = run("bake", BAD / bad, "-o", out)
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), res.output
    referenced = [f"files/{p.name}" for p in (BAD / "files").iterdir() if p.name in (BAD / bad).read_text(
        "utf-8", errors="replace")] if (BAD / bad).is_file() else []
    assert bad in lines[0] or any(f in lines[0] for f in referenced), lines[0]
    assert not out.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["xpbd", "implicit"])
def test_killed_bake_keeps_earlier_outputs_and_resume_equals_uninterrupted(tmp_path, solver):
    args = ["--days", "6", "--frames", "7", "--set", f"mechanics.solver={solver}"]
    out, ref = tmp_path / "out", tmp_path / "ref"
    assert run("bake", TINY, "-o", ref, *args).exit_code == 0
    assert run("bake", TINY, "-o", out, "--days", "1", "--frames", "2", *args[4:]).exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    env = dict(os.environ, NUMBA_NUM_THREADS="1")
    proc = subprocess.Popen([sys.executable, "-m", "wooddecay.cli", "bake", TINY, "-o", str(out), *args],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 300
    while not (out / ".bake" / "frame_00002.npz").exists():
        assert proc.poll() is None and time.time() < deadline, "bake ended before it could be killed"
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert after == before  # the earlier bake's outputs are untouched, nothing half-written
    res = run("bake", TINY, "-o", out, *args, "--resume")
    assert res.exit_code == 0, res.output
    diff = run("diff", ref / "tiny.usdc", out / "tiny.usdc", "--rtol", "0", "--atol", "0")
    assert diff.exit_code == 0, diff.output


def test_golden_tiny_bake(tmp_path):
    """The baked tiny scene equals the committed golden stage (``wooddecay diff``)."""
    res = run("bake", TINY, "-o", tmp_path, *GOLDEN_ARGS)
    assert res.exit_code == 0, res.output
    diff = run("diff", GOLDEN, tmp_path / "tiny.usdc", "--rtol", "1e-4", "--atol", "1e-5")
    assert diff.exit_code == 0, diff.output


def test_diff_reads_a_format_1_stage_against_format_2():
    """The golden bake written in format 1 (one Mesh, every value at every frame) and in format 2
    hold the same wood: fields within half of ``export.field_step``, points within
    ``export.point_tolerance``, faces, holes and the static primvars equal; the preview colour
    within the palette's step. ``wooddecay diff`` reads both (exit 0 within those tolerances, 1
    below them), format 2 adding only the rest shape."""
    from pxr import Usd

    old, new = (Usd.Stage.Open(str(p)) for p in (GOLDEN.with_name("tiny_format1.usda"), GOLDEN))
    for t in (0.0, 1.0):
        a, b = wood_at(old, t), wood_at(new, t)
        assert set(b) - set(a) == {"rest"} and set(a) <= set(b)
        for name in a:
            bound = {"points": 2e-4 + 1e-6, "displayColor": 0.014, "bark_crack_depth": 1e-4 + 1e-6}.get(
                name, 1e-3 + 1e-6 if a[name].dtype.kind == "f" else 0)
            assert np.abs(a[name].astype(float) - b[name]).max(initial=0) <= bound, name
    fine = run("diff", GOLDEN.with_name("tiny_format1.usda"), GOLDEN, "--rtol", "0", "--atol", "0.014")
    assert fine.exit_code == 1 and len(fine.output.splitlines()) == 2, fine.output  # and the count
    assert fine.output.splitlines()[0].startswith("attribute     wood.rest: only in b")
    coarse = run("diff", GOLDEN.with_name("tiny_format1.usda"), GOLDEN, "--rtol", "0", "--atol", "1e-4")
    assert coarse.exit_code == 1 and "wood.H_c" in coarse.output


def test_auto_beside_busy_cores_runs_one_thread_and_says_why(tmp_path, monkeypatch):
    """With every core of the process read as busy with other work, ``auto`` runs every step on
    one thread, and the bake's summary and its threads line say the load held them."""
    monkeypatch.setattr(LoadMonitor, "__call__", lambda self: float(len(self.cpus)))
    res = run("bake", TINY, "-o", tmp_path / "busy", *SHORT, "--threads", "auto")
    assert res.exit_code == 0, res.output
    used = json.loads((tmp_path / "busy" / "summary.json").read_text())["threads"]
    assert set(used["steps"]) == {"1"} and used["held_by_load"] > 0
    assert f"({used['held_by_load']} held to fewer threads by other processes' load)" in res.output


@pytest.mark.parametrize("solver", ["xpbd", pytest.param("implicit", marks=pytest.mark.slow)])
def test_any_thread_count_bakes_the_same_stage_and_the_summary_says_which(tmp_path, solver):
    outs = {}
    for threads in ("1", "2", "auto"):
        out = tmp_path / threads
        res = run("bake", TINY, "-o", out, *SHORT, "--threads", threads, "--set", f"mechanics.solver={solver}")
        assert res.exit_code == 0, res.output
        outs[threads] = out
        used = json.loads((out / "summary.json").read_text())["threads"]
        assert used["requested"] == ("auto" if threads == "auto" else int(threads))
        assert sum(used["steps"].values()) > 0
    assert set(json.loads((outs["1"] / "summary.json").read_text())["threads"]["steps"]) == {"1"}
    for threads in ("2", "auto"):
        diff = run("diff", outs["1"] / "tiny.usdc", outs[threads] / "tiny.usdc", "--rtol", "0", "--atol", "0")
        assert diff.exit_code == 0, diff.output
    bad = run("bake", TINY, "-o", tmp_path / "bad", "--threads", "0")
    assert bad.exit_code == 2 and "--threads: must be" in bad.output and not (tmp_path / "bad").exists()


@pytest.mark.parametrize("stop", [RuntimeError, KeyboardInterrupt])
def test_a_bake_that_stops_mid_run_says_how_to_resume_it(tmp_path, monkeypatch, stop):
    """A failure (or Ctrl-C) after the first frame keeps the frames and the checkpoint and says so:
    the exception carries the note (a traceback prints it), the CLI prints it after Ctrl-C, and
    --resume finishes the bake."""
    import wooddecay.bake as bake_mod

    saved = []
    real = bake_mod.save_frame

    def save_frame(path, frame):
        if saved:
            raise stop("stopped")
        saved.append(path)
        real(path, frame)

    monkeypatch.setattr(bake_mod, "save_frame", save_frame)
    out = tmp_path / "out"
    res = run("bake", TINY, "-o", out, *SHORT)
    assert res.exit_code == 1 and not (out / "tiny.usdc").exists()
    note = f"the bake stopped after 1 of 3 frames; its frames and checkpoint are kept in {out / '.bake'}"
    if stop is KeyboardInterrupt:
        assert f"note: {note}" in res.output, res.output
    else:
        assert note in res.exception.__notes__[0]
    monkeypatch.setattr(bake_mod, "save_frame", real)
    res = run("bake", TINY, "-o", out, *SHORT, "--resume")
    assert res.exit_code == 0 and (out / "tiny.usdc").exists(), res.output


def test_resumed_bake_counts_the_simulation_seconds_of_the_runs_it_continues(tmp_path):
    """summary.json ``seconds.simulation`` of a resumed bake adds the seconds checkpointed by the
    run it continues: resuming a finished bake simulates nothing and keeps its total."""
    out = tmp_path / "out"
    assert run("bake", TINY, "-o", out, *SHORT).exit_code == 0
    first = json.loads((out / "summary.json").read_text())["seconds"]["simulation"]
    res = run("bake", TINY, "-o", out, *SHORT, "--resume")
    assert res.exit_code == 0, res.output
    again = json.loads((out / "summary.json").read_text())["seconds"]["simulation"]
    assert first > 0.1 and 0.9 * first <= again < 1.5 * first


def test_a_second_bake_loads_the_settled_rods_and_bakes_the_same_stage(tmp_path, settle_cache):
    """summary.json says how the schedule ran and where the settled rods came from; the bake
    that loads them from the cache writes the stage of the one that settled."""
    summaries = []
    for k in range(2):
        res = run("bake", TINY, "-o", tmp_path / str(k), *SHORT)
        assert res.exit_code == 0, res.output
        summaries.append(json.loads((tmp_path / str(k) / "summary.json").read_text())["schedule"])
    assert [s["settled"] for s in summaries] == ["settled", "cached"]
    assert len(list(settle_cache.glob("*.npz"))) == 1
    s = summaries[0]
    assert s["schedule"] == "adaptive" and s["macro_steps"] == 4 and s["chunks"] >= s["solves"]
    assert s["solves"] == sum(s["due"].values())
    diff = run("diff", tmp_path / "0" / "tiny.usdc", tmp_path / "1" / "tiny.usdc", "--rtol", "0", "--atol", "0")
    assert diff.exit_code == 0, diff.output


@pytest.mark.parametrize("summary, reused", [
    ({"frames": [{"frame": 0}]}, True),
    ({"frames": [{"frame": 0}], "scene_hash": "other"}, False),
    ({}, False), ({"frames": None}, False), ({"frames": []}, False), ({"frames": [1, 2]}, False),
])
def test_a_finished_bake_is_a_summary_of_the_scene_with_its_frame_rows(tmp_path, summary, reused):
    """`--resume` (bake.finished) reuses a summary.json of the same scene hash with a row per
    frame; one of another scene, or without rows, is baked again."""
    from wooddecay.bake import finished
    from wooddecay.scene import load_scene

    scene = load_scene(TINY)
    (tmp_path / "summary.json").write_text(json.dumps({"scene_hash": scene.hash, **summary}))
    assert (finished(scene, tmp_path) is not None) is reused
    (tmp_path / "summary.json").write_text("[1, 2")
    assert finished(scene, tmp_path) is None


@pytest.mark.parametrize("damage", [b"not a checkpoint", b"PK\x03\x04 truncated"])
def test_resume_from_a_damaged_checkpoint_is_one_line(tmp_path, damage):
    """`--resume` over a checkpoint that is not one fails with one line naming the file and the
    way out, exit 2, and leaves the folder as it was."""
    out = tmp_path / "out"
    (out / ".bake").mkdir(parents=True)
    ckpt = out / ".bake" / "checkpoint.npz"
    ckpt.write_bytes(damage)
    res = run("bake", TINY, "-o", out, *SHORT, "--resume")
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and str(ckpt) in lines[0] and "without --resume" in lines[0], res.output
    assert ckpt.read_bytes() == damage and sorted(p.name for p in out.rglob("*")) == [".bake", "checkpoint.npz"]


def test_gallery_resume_continues_its_own_checkpoint_and_starts_over_on_another_scenes(tmp_path):
    """A gallery bake with ``resume``: a finished bake is reused (its recorded seconds), another
    scene's checkpoint in the folder is baked over from day 0, not an error."""
    from wooddecay.gallery.bakes import bake_scene

    short = {"time.days": 1.0, "time.frames": 2, "mechanics.iterations": 1}  # the bakes, not the section's cracks
    first = bake_scene("fig6.toml", short, tmp_path)
    again = bake_scene("fig6.toml", short, tmp_path, resume=True)
    assert not first.reused and again.reused and again.summary == first.summary
    assert again.seconds == pytest.approx(sum(first.summary["seconds"].values()))
    other = bake_scene("fig6.toml", {**short, "mechanics.S_R": 0.5}, tmp_path, resume=True)
    assert not other.reused and other.summary["scene_hash"] != first.summary["scene_hash"]
    assert len(other.frames) == 2


def test_gallery_bake_reuses_a_finished_bake_of_the_same_scene_elsewhere(tmp_path):
    """``reuse``: a finished bake of the same scene in another folder is read, not baked again, and
    nothing is written where it would have baked; another scene bakes. Fig. 20's run at the
    default step is the figure's own variant without overrides."""
    from pathlib import Path

    from wooddecay.gallery.bakes import bake_scene
    from wooddecay.gallery.figures import FIGURES
    from wooddecay.gallery.sensitivity import own_bakes

    short = {"time.days": 1.0, "time.frames": 2, "mechanics.iterations": 1}  # the bakes, not the section's cracks
    first = bake_scene("fig6.toml", short, tmp_path / "a")
    again = bake_scene("fig6.toml", short, tmp_path / "b", reuse=(tmp_path / "missing", tmp_path / "a"))
    assert again.reused and again.summary == first.summary and again.usd == tmp_path / "a" / "fig6.usdc"
    assert not (tmp_path / "b").exists()
    other = bake_scene("fig6.toml", {**short, "mechanics.S_R": 0.5}, tmp_path / "c", reuse=(tmp_path / "a",))
    assert not other.reused and (tmp_path / "c" / "fig6.usdc").is_file()
    out = Path("DIR") / "fig20"
    assert own_bakes("fig12", out, FIGURES) == (Path("DIR/fig12/uniform"),)
    assert own_bakes("fig14", out, FIGURES) == (Path("DIR/fig14/trunk"),)


ONE_STRAND = """[scene]
name = "twig"
[[skeleton.node]]
id = "a"
position = [0.0, 0.0, 0.05]
profile = { kind = "circle", radius = 0.009 }
[[skeleton.node]]
id = "b"
position = [0.4, 0.0, 0.05]
parent = "a"
profile = { kind = "circle", radius = 0.009 }
[time]
days = 4
frames = 2
"""


def test_a_branch_of_one_strand_bakes(tmp_path):
    """A branch as thin as one strand (no REG edges) bakes: its stage holds the one strand's
    closed meshlets, and its glTF one piece."""
    from pxr import Usd

    scene = tmp_path / "twig.toml"
    scene.write_text(ONE_STRAND)
    res = run("bake", scene, "-o", tmp_path / "out")
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["counts"]["strands"] == 1 and summary["counts"]["reg_edges"] == 0
    wood = wood_at(Usd.Stage.Open(str(tmp_path / "out" / "twig.usdc")), 1.0)
    assert len(wood["faces"]) > 0 and np.isfinite(wood["points"]).all()
    assert set(np.unique(wood["element"])) == set(range(summary["counts"]["elements"]))


def test_the_stage_carries_the_as_built_rest_shape(baked):
    """``rest`` is the meshlets as built, before the rods settled (each of its points one of the
    model's rest meshlet points), so a frame's points less it are how far the wood moved from the
    shape it was built in."""
    from pxr import Usd
    from scipy.spatial import cKDTree

    import wooddecay as wd

    mesh = wd.build_meshlets(wd.build_model(wd.load_scene(TINY, overrides={"time.days": 2, "time.frames": 3})))
    wood = wood_at(Usd.Stage.Open(str(baked / "tiny.usdc")), 0.0)
    gap, _ = cKDTree(mesh.points).query(wood["rest"])
    assert gap.max() < 1e-6
    moved = np.linalg.norm(wood["points"] - wood["rest"], axis=1)
    assert 1e-5 < moved.max() < 0.05, moved.max()


ONE_ELEMENT = """[scene]
name = "one"
seed = 1
quality = "draft"
[[skeleton.node]]
id = "n0"
position = [0, 0, 0.008]
profile = { kind = "circle", radius = 0.008 }
[[skeleton.node]]
id = "n1"
position = [0.12, 0, 0.008]
profile = { kind = "polygon", points = [[0.008, 0], [-0.004, 0.0069282], [-0.004, -0.0069282]] }
parent = "n0"
[strands]
r_s = 0.004
rod_length = 0.012
[rings]
bark_thickness = 0
[bsp]
cells = 1
[mechanics]
solver = "xpbd"
ground = false
[climate]
preset = "temperate"
[time]
days = 0.5
frames = 1
[bark]
cracks = false
"""


def test_wood_of_one_element_bakes(tmp_path):
    """The fuzzer's find: a draft twig of one element has no transport edge at all, and the
    fronts' spacing divided numpy's int64 bincount of nothing (a casting error at the build)."""
    scene = tmp_path / "one.toml"
    scene.write_text(ONE_ELEMENT)
    res = run("bake", scene, "-o", tmp_path / "out")
    assert res.exit_code == 0, res.output
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["counts"]["elements"] == 1
