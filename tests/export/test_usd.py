"""frames -> export: the exporters read the model, the meshlets and the simulated frames alone."""
from __future__ import annotations

import pickle

from click.testing import CliRunner

import wooddecay as wd
from wooddecay import __version__
from wooddecay.bake import load_frame
from wooddecay.cli import main

from ..conftest import SAMPLES

TINY = SAMPLES / "tiny.toml"
SHORT = {"time.days": 2, "time.frames": 3}


def test_stage_and_glb_from_model_meshlets_and_saved_frames_equal_the_bake(tmp_path):
    """Re-exporting a finished bake from a pickled model, meshlets built from it and the frames the
    bake saved gives the bake's own stage (``compare_usd`` with zero tolerance) and glb (bytes)."""
    out = tmp_path / "bake"
    res = CliRunner().invoke(main, ["bake", str(TINY), "-o", str(out), "--days", "2", "--frames", "3"])
    assert res.exit_code == 0, res.output
    model = pickle.loads(pickle.dumps(wd.build_model(wd.load_scene(TINY, overrides=SHORT))))
    frames = [load_frame(p) for p in sorted((out / ".bake").glob("frame_*.npz"))]
    assert len(frames) == 3
    mesh = wd.build_meshlets(model)
    (tmp_path / "again").mkdir()
    usd = wd.export_usd(tmp_path / "again" / "tiny.usdc", model, mesh, frames, version=__version__)
    glb = wd.export_gltf(tmp_path / "again.glb", model, mesh, frames[-1], version=__version__)
    assert wd.compare_usd(out / "tiny.usdc", usd, rtol=0, atol=0) == []
    assert glb.read_bytes() == (out / "tiny.glb").read_bytes()
