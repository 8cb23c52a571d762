"""Rigid motion apart from shape (wooddecay.export.tracks): the batched Kabsch fit against known
motions and a per-piece scipy reference, and the written state's bound."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from wooddecay.export.tracks import PoseTrack, changed, piece_max, rigid_fit


def pieces(seed: int, sizes=(7, 40, 4, 120)):
    rng = np.random.default_rng(seed)
    start = np.concatenate([[0], np.cumsum(sizes)])
    L = rng.normal(size=(start[-1], 3)) * 0.05 + np.repeat(rng.normal(size=(len(sizes), 3)), sizes, axis=0)
    return L, start, rng


def test_a_rigid_motion_is_found_exactly():
    L, start, rng = pieces(1)
    R = Rotation.random(len(start) - 1, random_state=2).as_matrix()
    c = rng.normal(size=(len(start) - 1, 3))
    k = np.repeat(np.arange(len(start) - 1), np.diff(start))
    X = np.einsum("vij,vj->vi", R[k], L) + c[k]
    R_fit, c_fit, gap = rigid_fit(L, X, start)
    np.testing.assert_allclose(R_fit, R, atol=1e-10)
    np.testing.assert_allclose(c_fit, c, atol=1e-10)
    assert gap.max() < 1e-12
    assert np.allclose(np.linalg.det(R_fit), 1.0)


def test_the_fit_equals_a_per_piece_reference_on_noisy_points():
    """With noise the fit is scipy's least-squares alignment of the centred points, piece by piece."""
    L, start, rng = pieces(3)
    X = L @ Rotation.from_euler("xyz", [0.3, -1.2, 2.0]).as_matrix().T + 0.4 + rng.normal(size=L.shape) * 1e-3
    R_fit, c_fit, gap = rigid_fit(L, X, start)
    for k in range(len(start) - 1):
        a, b = L[start[k]:start[k + 1]], X[start[k]:start[k + 1]]
        rot, _ = Rotation.align_vectors(b - b.mean(0), a - a.mean(0))
        np.testing.assert_allclose(R_fit[k], rot.as_matrix(), atol=1e-9)
        np.testing.assert_allclose(c_fit[k], b.mean(0) - rot.as_matrix() @ a.mean(0), atol=1e-9)
        assert np.isclose(gap[k], np.linalg.norm(a @ R_fit[k].T + c_fit[k] - b, axis=1).max())


def test_a_mirror_is_never_fitted():
    L, start, _ = pieces(4, sizes=(30,))
    R, _, gap = rigid_fit(L, L * np.array([1.0, 1.0, -1.0]), start)
    assert np.isclose(np.linalg.det(R[0]), 1.0) and gap[0] > 0.01


def test_the_track_writes_a_pose_for_motion_points_for_a_change_of_shape_and_nothing_for_rest():
    tol = 2e-4
    L, start, rng = pieces(5)
    track = PoseTrack(L, start)
    np.testing.assert_allclose(track.world(), L, atol=1e-12)
    k = np.repeat(np.arange(len(start) - 1), np.diff(start))
    X = L.copy()
    X[k == 0] += 0.5 * tol  # within the tolerance: nothing
    X[k == 1] = X[k == 1] @ Rotation.from_euler("z", 0.7).as_matrix().T + 1.0  # falls: a pose
    X[k == 3] *= 1.01  # shrinks: its points
    pose, shape = track.update(X, tol)
    assert pose.tolist() == [False, True, False, False] and shape.tolist() == [False, False, False, True]
    assert np.linalg.norm(track.world() - X, axis=1).max() <= tol
    for seed in range(5):  # a random walk of noise, motion and strain stays within the tolerance
        noise = np.random.default_rng(seed).normal(size=X.shape) * tol * 0.3
        X = X @ Rotation.from_euler("x", 0.01 * seed).as_matrix().T + noise
        track.update(X, tol)
        assert np.linalg.norm(track.world() - X, axis=1).max() <= tol * (1 + 1e-9)


def test_changed_and_piece_max():
    start = np.array([0, 2, 2, 5])
    assert piece_max(np.arange(5.0), start).tolist() == [1.0, -np.inf, 4.0]
    old = np.zeros((5, 2))
    new = old.copy()
    new[3, 1] = 1
    assert changed(new, old, start, 0).tolist() == [[False, False], [False, False], [False, True]]


def test_the_exporters_defaults_are_the_schemas():
    from wooddecay.export.usd import FIELD_STEP, POINT_TOLERANCE
    from wooddecay.scene.schema import get_param

    assert get_param("export.point_tolerance").default == POINT_TOLERANCE
    assert get_param("export.field_step").default == FIELD_STEP
