"""Crack faces per frame (meshlets/visibility.py, export/usd.py): a frame shows the faces of its
own rod state, however long the bake runs on after it."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.meshlets.visibility import NEVER, exposure, visible_faces

from ..conftest import SAMPLES, cracking_frames


@pytest.fixture(scope="module")
def cracking():
    """The tiny log over 3 frames with a quarter more of its connections broken at each frame."""
    model = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", {"time.days": 2, "time.frames": 3}))
    frames = cracking_frames(model, list(wd.Simulation(model).run()))
    return model, wd.build_meshlets(model), frames


def test_a_face_shows_from_the_first_frame_whose_state_shows_it(cracking):
    model, mesh, frames = cracking
    first = exposure(model, mesh, [f.mech for f in frames])
    for k, f in enumerate(frames):
        np.testing.assert_array_equal((first != NEVER) & (first <= k), visible_faces(model, mesh, f.mech))
    counts = np.bincount(first[first != NEVER])
    assert len(counts) == 3 and counts.min() > 100, counts  # faces open at every frame
    without = exposure(model, mesh, [None, None])  # no mechanics: bark and open faces from the start
    assert set(without) == {0, NEVER} and np.array_equal(without == 0, visible_faces(model, mesh, None))


def triangles(path, t: float) -> np.ndarray:
    """The shown triangles of the stage's Wood mesh at time code ``t`` (its faces but the holes),
    each as its 9 point coordinates, in sorted order."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    wood = UsdGeom.Mesh(stage.GetPrimAtPath("/World/tiny/Wood"))
    faces = np.asarray(wood.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
    shown = np.setdiff1d(np.arange(len(faces)), np.asarray(wood.GetHoleIndicesAttr().Get(t) or [], dtype=int))
    tri = np.asarray(wood.GetPointsAttr().Get(t))[faces[shown]].reshape(-1, 9)
    return tri[np.lexsort(tri.T[::-1])]


def test_a_longer_bake_shows_at_a_frame_the_faces_of_a_bake_that_ends_there(cracking, tmp_path):
    """The stage of 3 frames at time code 1 shows the same triangles as the stage of the first 2
    frames (whose last state shows every face it writes), and its ``exposedFrame`` says when each
    shows; without holes the longer stage would show 1,000s more at frame 1."""
    from pxr import Usd, UsdGeom

    model, mesh, frames = cracking
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    long = wd.export_usd(tmp_path / "a" / "tiny.usdc", model, mesh, frames)
    short = wd.export_usd(tmp_path / "b" / "tiny.usdc", model, mesh, frames[:2])
    np.testing.assert_array_equal(triangles(long, 1.0), triangles(short, 1.0))
    np.testing.assert_array_equal(triangles(long, 0.0), triangles(short, 0.0))
    stage = Usd.Stage.Open(str(long))
    wood = UsdGeom.Mesh(stage.GetPrimAtPath("/World/tiny/Wood"))
    shown = np.asarray(UsdGeom.PrimvarsAPI(wood).GetPrimvar("exposedFrame").Get())
    for t in (0.0, 1.0, 2.0):
        np.testing.assert_array_equal(np.flatnonzero(shown > t), np.asarray(wood.GetHoleIndicesAttr().Get(t)))
    assert np.count_nonzero(shown > 1) > 1000 and np.count_nonzero(shown > 2) == 0
