"""The schedule study's per-piece shape error (wooddecay.studies.schedule.Run.shape_error): the
position difference left once each piece is moved rigidly, against hand-made runs."""
from __future__ import annotations

import numpy as np

from wooddecay.studies.schedule import Run


def _run(x, piece):
    return Run(label="r", wall=0.0, mechanics_seconds=0.0, solves=0, chunks=0, broken=0, x=x, piece=piece)


def _rotation(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def test_pieces_moved_rigidly_leave_no_shape_error_but_a_position_error():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(40, 3))
    piece = np.repeat([0, 1], 20)
    moved = x.copy()
    moved[:20] = x[:20] @ _rotation([1, 2, 0.5], 0.7).T + [0.3, -0.1, 2.0]
    moved[20:] = x[20:] @ _rotation([0, 0, 1], -1.2).T + [-1.0, 0.0, 0.0]
    ref, run = _run(x, piece), _run(moved, piece)
    assert run.error(ref) > 1.0
    assert run.shape_error(ref) < 1e-12


def test_a_deformed_piece_shows_its_deformation_and_not_a_mirror_image():
    x = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])
    piece = np.zeros(len(x), dtype=np.int64)
    bent = x.copy()
    bent[4] += [0.0, 0.0, 0.01]
    assert 0.005 < _run(bent, piece).shape_error(_run(x, piece)) <= 0.01
    mirrored = x * [1.0, 1.0, -1.0]  # no rotation maps it back: a proper fit leaves it
    assert _run(mirrored, piece).shape_error(_run(x, piece)) > 0.1
