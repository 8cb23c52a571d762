"""The gallery (``wooddecay gallery``; wooddecay.gallery): figures' quick scenes baked and decided
in CI, the direction of each claim asserted through its ``holds``, one figure rendered through the
add-on, and the command's errors.

CI bakes the seven figures whose quick scenes bake within about 2 min each (CI_FIGURES, about
5 min in all on one thread beside the other worker, 2026-11-27) and decides them; of Fig. 6 it
also asserts the first cracks' orientation per shrinkage ratio and that every section's radial
cracks open (docs/gallery.md). Fig. 12 is decided in tests/gallery/test_gallery_fig12.py and Figs. 16 and
19 in tests/gallery/test_gallery_trees.py. Fig. 20's study is decided by the full gallery (at quick size it
bakes for about 11 min beside Figs. 12 and 14, the quick log at half the step alone 358 s,
2026-11-27); its scenes are loaded here, and the part of it that holds at quick size is asserted
in tests/gallery/test_gallery_fig20.py."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

from wooddecay.gallery import FIGURES, run_gallery
from wooddecay.gallery.bakes import SCENES
from wooddecay.gallery.figures import fig6_orientations
from wooddecay.scene import load_scene

from ..conftest import refused_in_one_line

CI_FIGURES = ("fig6", "fig11", "fig13", "fig14", "fig15", "fig17", "fig18")


def test_every_figure_has_its_scenes_and_claim():
    assert list(FIGURES) == ["fig6", "fig11", "fig12", "fig13", "fig14", "fig15", "fig16", "fig17", "fig18", "fig19",
                             "fig20"]
    for fig in FIGURES.values():
        assert fig.claim and fig.test and fig.caption
        assert (fig.study is None) == bool(fig.variants)
        for v in fig.variants:
            load_scene(SCENES / (v.scene or fig.scene), overrides={**v.overrides, **fig.quick})


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("gallery")
    return out, run_gallery(CI_FIGURES, out, quick=True, renders=False, log=print)


@pytest.mark.slow
@pytest.mark.parametrize("key", CI_FIGURES)
def test_quick_figure_holds(quick, key):
    """Each figure's claim, decided on its quick scenes (figures.py: the test per figure)."""
    out, result = quick
    entry = result[key]
    print(key, json.dumps({k: {s: v.get(s) for s in ("signature",) if s in v} for k, v in entry["variants"].items()}))
    assert entry["holds"] is True, f"{key}: {entry['test']}"


@pytest.mark.slow
def test_quick_fig6_first_cracks_follow_the_shrinkage(quick):
    """Fig. 6 on its quick sections: tangential shrinkage alone and balanced shrinkage first break
    tangential connections (radial splits), radial shrinkage alone radial ones (delamination), and
    the radial cracks of every section open."""
    variants = quick[1]["fig6"]["variants"]
    assert fig6_orientations(variants)
    for v in variants.values():
        assert v["radial_crack_opening_m"] > 0.0 and v["effective_radial_cracks"] >= 1.0


@pytest.mark.slow
def test_bakes_made_ahead_on_two_processes_are_measured_alike(quick, tmp_path):
    """Fig. 6's quick sections baked ahead on two one-thread processes (wooddecay.gallery.pool)
    give the signatures and frame rows of the bakes made in this process, as fresh bakes."""
    lines = []
    entry = run_gallery(("fig6",), tmp_path, quick=True, renders=False, log=lines.append, workers=2)["fig6"]
    assert lines[0] == f"baking {len(FIGURES['fig6'].variants)} scenes ahead on 2 processes"
    same = quick[1]["fig6"]["variants"]
    for name, v in entry["variants"].items():
        assert v["signature"] == same[name]["signature"] and v["frames"] == same[name]["frames"]
        assert not v["reused"] and v["seconds"] > 0.0
        assert (tmp_path / "fig6" / name / "summary.json").is_file()
    assert entry["holds"] == quick[1]["fig6"]["holds"]


@pytest.mark.slow
def test_signatures_json_and_page(quick):
    out, result = quick
    on_disk = json.loads((out / "signatures.json").read_text())
    assert on_disk == json.loads(json.dumps(result))
    page = (out / "gallery.md").read_text()
    for key in CI_FIGURES:
        assert f"## {key}" in page


@pytest.mark.slow
@pytest.mark.blender
def test_gallery_command_resumes_and_renders_panels(quick, tmp_path):
    """`wooddecay gallery 6 --quick --resume` over the quick bakes of Fig. 6: it bakes nothing
    (each variant's bake reused, its summary untouched) and renders a panel per variant through
    the add-on, listed in signatures.json, each of its variant's last frame."""
    shutil.copytree(quick[0] / "fig6", tmp_path / "fig6")
    summaries = sorted((tmp_path / "fig6").glob("*/summary.json"))
    before = [p.stat().st_mtime_ns for p in summaries]
    proc = subprocess.run([sys.executable, "-m", "wooddecay.cli", "gallery", "6", "--quick", "--resume", "-o",
                           str(tmp_path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    entry = json.loads((tmp_path / "signatures.json").read_text())["fig6"]
    n = len(FIGURES["fig6"].variants)
    assert len(summaries) == n == 5 and [p.stat().st_mtime_ns for p in summaries] == before
    assert all(v["reused"] for v in entry["variants"].values()) and proc.stderr.count("(bake reused)") == n
    assert len(entry["panels"]) == n
    for name, v in entry["variants"].items():
        assert f"fig6/{name}_f{len(v['frames']) - 1}.png" in entry["panels"]
    for p in entry["panels"]:
        assert (tmp_path / p).stat().st_size > 10_000
    assert "fig6   holds" in proc.stdout


def test_unknown_figure_is_one_line(tmp_path):
    line = refused_in_one_line(["gallery", "fig7", "-o", str(tmp_path / "g")], tmp_path / "g", process=True)
    assert "fig7" in line and "fig6" in line


def test_a_bad_threads_variable_is_one_line_before_anything_is_written(tmp_path, monkeypatch):
    monkeypatch.setenv("WOODDECAY_THREADS", "two")
    out = tmp_path / "g"
    line = refused_in_one_line(["gallery", "18", "--quick", "--no-render", "--jobs", "1", "-o", str(out)], out)
    assert "$WOODDECAY_THREADS: must be" in line


@pytest.mark.parametrize("earlier", ["[1,", '{"fig6": {"title": "Shrinkage"}}', "[]"])
def test_a_damaged_signatures_json_is_one_line_before_any_bake(tmp_path, earlier):
    """An -o folder whose signatures.json is not the gallery's: one line naming it, exit 2, the
    file untouched and nothing baked (gallery.md is rewritten from every figure in it)."""
    from click.testing import CliRunner

    from wooddecay.cli import main

    (tmp_path / "signatures.json").write_text(earlier)
    res = CliRunner().invoke(main, ["gallery", "6", "--quick", "--no-render", "-o", str(tmp_path)])
    assert res.exit_code == 2
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and "signatures.json" in lines[0] and "another -o" in lines[0], res.output
    assert (tmp_path / "signatures.json").read_text() == earlier and sorted(tmp_path.iterdir()) == [
        tmp_path / "signatures.json"]


def test_an_output_folder_that_cannot_be_made_is_one_line(tmp_path):
    (tmp_path / "file").write_text("")
    proc = subprocess.run([sys.executable, "-m", "wooddecay.cli", "gallery", "18", "--no-render", "-o",
                           str(tmp_path / "file" / "g")], capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.strip().count("\n") == 0, proc.stderr
    assert "cannot create the output folder" in proc.stderr


def test_panel_frames_and_shared_camera_box():
    """Panels picked by the claim's frame (Fig. 15: the most checks before decay); the
    sensitivity study's one camera box holds both bakes' elements."""
    from types import SimpleNamespace

    import numpy as np

    from wooddecay.gallery.figures import FIGURES
    from wooddecay.gallery.sensitivity import fit_box

    rows = [{"signature": {"crack_clusters": c, "mass_loss": ml}} for c, ml in ((0, 0), (3, 0.01), (7, 0.015), (9, 0.03))]
    pick = FIGURES["fig15"].panels[0]
    assert pick(rows) == 2
    a = SimpleNamespace(mech={"x": np.array([[0.0, 0.0, 0.0], [1.0, 0.2, 0.3]])})
    b = SimpleNamespace(mech={"x": np.array([[-0.5, 0.1, 0.0], [0.5, 0.1, 0.4]])})
    assert [float(v) for v in fit_box([a, b], 0.01)] == [-0.51, -0.01, -0.01, 1.01, 0.21, 0.41]


def test_sparser_rods_compare_block_purity_only_where_the_default_came_apart():
    """A whole trunk (one piece) has block purity 0 by definition; a sparser bake with one loose
    block reads 0.5 and is not a change of its pattern, nor is a trunk in 3 pieces against 2 (the
    median of so few is one piece's). A log in 100 pieces is compared on it."""
    from wooddecay.gallery.sensitivity import within_tolerance

    sig = {"mass_loss": 0.68, "hollow_fraction": 0.52, "largest_piece_fraction": 0.6, "block_purity": 0.0, "pieces": 1}
    loose = {**sig, "block_purity": 0.51, "pieces": 2}
    assert within_tolerance(loose, sig)
    assert not within_tolerance({**loose, "hollow_fraction": 0.64}, sig)
    assert within_tolerance(loose, {**sig, "block_purity": 1.0, "pieces": 3})
    log = {**sig, "hollow_fraction": 0.0, "block_purity": 1.0, "pieces": 107}
    assert not within_tolerance({**log, "block_purity": 0.6, "pieces": 13}, log)
    assert within_tolerance({**log, "block_purity": 0.9, "pieces": 68}, log)


def test_the_timestep_renders_are_compared_with_the_default_through_one_camera(tmp_path, monkeypatch):
    """Fig. 20's SSIM: every run against ``dt``, all rendered through one camera box; the floor's
    run differs from the default only by k_col x (1 + PERTURBATION)."""
    from types import SimpleNamespace

    import numpy as np
    from PIL import Image

    from wooddecay.gallery import sensitivity

    runs = sensitivity.variants("fig12", quick=True, figures=FIGURES)
    changed = {k for k in runs["perturbed"] if runs["perturbed"][k] != runs["dt"].get(k)}
    assert changed == {"mechanics.k_col"} and runs["perturbed"]["mechanics.k_col"] == 1e7 * (1 + sensitivity.PERTURBATION)
    boxes = []

    def render(usd, png, frame, options):
        boxes.append(options[options.index("--fit-box") + 1:])
        grey = np.full((40, 60), 128, np.uint8)
        grey[10:20, 10:30] = 0 if usd == "dt_half.usdc" else 255
        Image.fromarray(grey).save(png)

    monkeypatch.setattr(sensitivity, "render_panel", render)
    frame = SimpleNamespace(index=3, mech={"x": np.zeros((2, 3))})
    frames = {v: [frame] for v in ("dt", "dt_half", "perturbed")}
    ssim = sensitivity.ssim_at(frames, {v: f"{v}.usdc" for v in frames}, 0, tmp_path, "degraded", 0.01)
    assert set(ssim) == {"dt_half", "perturbed"} and ssim["perturbed"] == 1.0 and ssim["dt_half"] < 0.9
    assert len(boxes) == 3 and all(b == boxes[0] for b in boxes)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dt_degraded.png", "dt_half_degraded.png", "perturbed_degraded.png"]
