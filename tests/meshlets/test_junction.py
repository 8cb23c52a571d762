"""Walls where branches meet (wooddecay.meshlets.junction): the winding number against a cube,
and on the forked sample the bark faces behind which the other branch's wood lies turned into
walls to it, hidden while the two stay connected."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from wooddecay.meshlets import checks
from wooddecay.meshlets.junction import _winding
from wooddecay.meshlets.sweep import BARK, SIDE, build_meshlets
from wooddecay.meshlets.visibility import visible_faces
from wooddecay.model import build_model
from wooddecay.scene import load_scene

SAMPLES = Path(__file__).resolve().parents[2] / "wooddecay" / "samples" / "meshes"


class _Shell:
    """One closed shell in the layout ``_winding`` reads."""

    def __init__(self, mesh):
        self.points, self.faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        self.face_offsets = np.array([0, len(self.faces)])


def test_winding_number_of_a_cube():
    shell = _Shell(trimesh.creation.box(extents=[1.0, 2.0, 3.0]))
    points = np.array([[0.0, 0.0, 0.0], [0.49, 0.9, -1.4], [0.51, 0.0, 0.0], [3.0, 3.0, 3.0]])
    w = _winding(shell, np.zeros(len(points), dtype=np.int64), points)
    assert np.allclose(w, [1.0, 1.0, 0.0, 0.0], atol=1e-9)


def test_forked_branch_walls_face_the_other_branch():
    model = build_model(load_scene(SAMPLES / "forked_branch.toml"))
    mesh = build_meshlets(model)
    walls = mesh.stats["junction_walls"]
    print(f"{walls} walls of {int((mesh.face_kind == BARK).sum()) + walls} bark faces")
    assert walls > 0
    wall = (mesh.face_kind == SIDE) & (mesh.face_neighbour >= 0)
    wall &= model.branch[mesh.face_element] != model.branch[np.maximum(mesh.face_neighbour, 0)]
    assert wall.sum() == walls
    assert checks.closed_oriented(mesh).all()
    # intact wood (no mechanics): a wall is never exported
    assert not visible_faces(model, mesh, None)[wall].any()
