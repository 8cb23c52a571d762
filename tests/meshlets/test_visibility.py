"""Crack faces per frame (meshlets/visibility.py, export/usd.py): a frame shows the faces of its
own rod state and consumed wood, however long the bake runs on after it."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.export.gltf import gltf_document
from wooddecay.export.usd import POINT_TOLERANCE
from wooddecay.export.wood_read import wood_at
from wooddecay.meshlets.sweep import FACE_BARK, FACE_CAP
from wooddecay.meshlets.visibility import NEVER, exposure, visible_faces
from wooddecay.sim.coupling import crumble_scale

from ..conftest import SAMPLES, cracking_frames


@pytest.fixture(scope="module")
def cracking():
    """The tiny log over 3 frames with a quarter more of its connections broken and an eighth more
    of its elements failed at each frame."""
    model = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", {"time.days": 2, "time.frames": 3}))
    frames = cracking_frames(model, list(wd.Simulation(model).run()))
    return model, wd.build_meshlets(model), frames


def first_break(ok: list[np.ndarray]) -> np.ndarray:
    """Per row, the index of the first of the boolean arrays ``ok`` where it is False, else NEVER."""
    down = ~np.stack(ok)
    return np.where(down.any(0), down.argmax(0), NEVER)


def test_each_face_shows_from_the_frame_that_cuts_it(cracking):
    """Independently of the lookup: a side face across a REG edge shows from the frame that breaks
    the edge, a cap between consecutive elements from the frame that fails the lower one (the
    strand link is cut), bark and open faces from the first; every frame shows what its state
    alone shows."""
    model, mesh, frames = cracking
    first = exposure(model, mesh, frames)
    o, n, kind = mesh.face_element, mesh.face_neighbour, mesh.face_kind
    edge_first = first_break([f.mech["edge_ok"][:, 0] for f in frames])
    element_first = first_break([f.mech["element_ok"] for f in frames])
    pair = {(min(a, b), max(a, b)): j for j, (a, b) in enumerate(model.reg_edges)}
    side = np.flatnonzero((kind != FACE_BARK) & (kind != FACE_CAP) & (n >= 0))
    across = [(f, pair[(min(o[f], n[f]), max(o[f], n[f]))]) for f in side if (min(o[f], n[f]), max(o[f], n[f])) in pair]
    assert len(across) > 1000
    for f, j in across:
        assert first[f] == edge_first[j], (f, j)
    caps = np.flatnonzero((kind == FACE_CAP) & (n >= 0))
    np.testing.assert_array_equal(first[caps], element_first[np.minimum(o[caps], n[caps])])
    assert (first[(kind == FACE_BARK) | (n < 0)] == 0).all()
    for k, f in enumerate(frames):
        np.testing.assert_array_equal((first != NEVER) & (first <= k), visible_faces(model, mesh, f))
    counts = np.bincount(first[first != NEVER])
    assert len(counts) == 3 and counts[1:].min() > 1000, counts  # faces open at every frame
    assert np.array_equal(visible_faces(model, mesh, None), (kind == FACE_BARK) | (n < 0))  # intact wood


def test_faces_round_dwindling_wood_show(cracking):
    """An element whose remaining mass falls below 2 m_crumble dwindles towards its centre: every
    face between it and a neighbour shows, its own and the neighbour's, connected or not."""
    model, mesh, frames = cracking
    f = frames[0]
    e = int(np.flatnonzero(f.mech["element_ok"])[len(f.mech["element_ok"]) // 2])
    fields = {k: v.copy() for k, v in f.fields.items()}
    fields["H_c"][e] = fields["H_l"][e] = 0.0
    consumed = replace(f, fields=fields)
    assert crumble_scale(model.coupling, fields["H_c"], fields["H_l"])[e] < 1.0
    shown = visible_faces(model, mesh, consumed)
    round_e = (mesh.face_neighbour >= 0) & ((mesh.face_element == e) | (mesh.face_neighbour == e))
    assert round_e.sum() >= 6 and shown[round_e].all()
    assert np.array_equal(shown & ~round_e, visible_faces(model, mesh, f) & ~round_e)


def triangles(stage, t: float) -> np.ndarray:
    """The shown triangles of the stage's wood at time code ``t`` (its faces but the holes), each as
    its 9 point coordinates, corners in sorted order (the two sides of a crack are one triangle)."""
    wood = wood_at(stage, t)
    tri = wood["points"][wood["faces"][~wood["hole"]]]
    order = np.lexsort(np.round(tri, 4).transpose(2, 0, 1)[::-1])
    return np.take_along_axis(tri, order[:, :, None], 1).reshape(-1, 9)


def same_triangles(a: np.ndarray, b: np.ndarray, tol: float) -> None:
    """As many triangles in ``a`` as in ``b``, and each of either has one in the other within
    ``tol`` at every corner."""
    from scipy.spatial import cKDTree

    assert len(a) == len(b)
    for x, y in ((a, b), (b, a)):
        gap, _ = cKDTree(y).query(x, distance_upper_bound=tol, p=np.inf)
        assert np.isfinite(gap).all()


def test_a_longer_bake_shows_at_a_frame_the_faces_of_a_bake_that_ends_there(cracking, tmp_path):
    """The stage of 3 frames at time code 1 shows the same triangles as the stage of the first 2
    frames (whose last state shows every face it writes; the two write each point within
    ``export.point_tolerance`` of the frame's, so within twice that of each other) and as the glTF
    of frame 1; its ``exposedFrame`` says when each face shows, its holes get a sample where that
    set changes, and the stage passes usd-core's validators."""
    from pxr import Usd, UsdValidation

    model, mesh, frames = cracking
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    stages = {n: Usd.Stage.Open(str(wd.export_usd(tmp_path / n / "tiny.usdc", model, mesh, fr)))
              for n, fr in (("a", frames), ("b", frames[:2]))}
    for t in (0.0, 1.0):
        same_triangles(triangles(stages["a"], t), triangles(stages["b"], t), 2 * POINT_TOLERANCE + 1e-6)
    for t in (0.0, 1.0, 2.0):
        wood = wood_at(stages["a"], t)
        np.testing.assert_array_equal(wood["exposedFrame"] > t, wood["hole"])
    shown = wood_at(stages["a"], 0.0)["exposedFrame"]
    assert np.count_nonzero(shown > 1) > 1000 and np.count_nonzero(shown > 2) == 0
    doc, _ = gltf_document(model, mesh, frames[1])
    gltf_triangles = sum(doc["accessors"][p["indices"]]["count"] // 3 for m in doc["meshes"] for p in m["primitives"])
    assert gltf_triangles == len(triangles(stages["a"], 1.0))
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    errors = [e for e in ctx.Validate(stages["a"]) if e.GetType() == UsdValidation.ValidationErrorType.Error]
    assert errors == [], [e.GetMessage() for e in errors]
