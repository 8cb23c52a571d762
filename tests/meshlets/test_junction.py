"""Walls where branches meet (wooddecay.meshlets.sweep and .junction): the winding number against
a cube, and on the forked sample the faces against the other branch's strands past the fork and
the bark faces behind which the other branch's wood lies, walls to it, hidden while the two stay
connected; past a fork, the branch's own section of the source surface and the cells of sites
outside it."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from wooddecay.meshlets import checks
from wooddecay.meshlets.branch import OUTSIDE_GAP, _mirrors
from wooddecay.meshlets.junction import _winding, _winding_reference
from wooddecay.meshlets.sweep import FACE_BARK, FACE_SIDE, build_meshlets
from wooddecay.meshlets.visibility import visible_faces
from wooddecay.model import build_model
from wooddecay.scene import load_scene
from wooddecay.strands import profiles
from wooddecay.strands.mesh_input import surface_distance
from wooddecay.strands.mesh_skeleton import contour_around

SAMPLES = Path(__file__).resolve().parents[2] / "wooddecay" / "samples" / "meshes"


class _Shell:
    """One closed shell in the layout ``_winding`` reads."""

    def __init__(self, mesh):
        self.points, self.faces = np.asarray(mesh.vertices), np.asarray(mesh.faces)
        self.face_offsets = np.array([0, len(self.faces)])


def test_winding_number_of_a_cube():
    shell = _Shell(trimesh.creation.box(extents=[1.0, 2.0, 3.0]))
    points = np.array([[0.0, 0.0, 0.0], [0.49, 0.9, -1.4], [0.51, 0.0, 0.0], [3.0, 3.0, 3.0]])
    for winding in (_winding, _winding_reference):
        w = winding(shell, np.zeros(len(points), dtype=np.int64), points)
        assert np.allclose(w, [1.0, 1.0, 0.0, 0.0], atol=1e-9)


def test_winding_kernel_matches_its_numpy_twin(tiny_model):
    mesh = build_meshlets(tiny_model)
    rng = np.random.default_rng(1)
    elements = rng.integers(0, mesh.count, 400)
    points = tiny_model.centers[elements] + rng.normal(scale=tiny_model.r_s, size=(400, 3))
    w = _winding(mesh, elements, points)
    assert np.allclose(w, _winding_reference(mesh, elements, points), rtol=0, atol=1e-12)
    assert 50 < np.count_nonzero(w > 0.5) < 350  # points inside and outside their meshlets


def test_forked_branch_walls_face_the_other_branch():
    model = build_model(load_scene(SAMPLES / "forked_branch.toml"))
    mesh = build_meshlets(model)
    walls = mesh.stats["junction_walls"]
    wall = (mesh.face_kind == FACE_SIDE) & (mesh.face_neighbour >= 0)
    wall &= model.branch[mesh.face_element] != model.branch[np.maximum(mesh.face_neighbour, 0)]
    print(f"{wall.sum()} walls between branches ({walls} from the junction pass) of "
          f"{int((mesh.face_kind == FACE_BARK).sum()) + wall.sum()} bark faces")
    # the sweep's faces against the strands that leave at the fork, and the junction pass's
    assert wall.sum() > walls > 0
    # each lies against its neighbour's wood: within 2 r_s of that meshlet's surface
    fo = mesh.face_offsets
    for f in np.flatnonzero(wall):
        n = mesh.face_neighbour[f]
        shell = trimesh.Trimesh(mesh.points, mesh.faces[fo[n]:fo[n + 1]], process=False)
        centroid = mesh.points[mesh.faces[f]].mean(axis=0)
        assert surface_distance(shell, centroid[None], model.r_s)[0] < 2.0 * model.r_s
    assert checks.closed_oriented(mesh).all()
    # intact wood (no mechanics): a wall is never exported
    assert not visible_faces(model, mesh, None)[wall].any()


def test_the_branch_s_own_section_of_a_slice():
    # two rods side by side: the contour around the sites is the rod they lie in, else none
    rods = trimesh.util.concatenate([trimesh.creation.cylinder(0.04, 0.5, sections=64).apply_translation(t)
                                     for t in ([-0.05, 0.0, 0.0], [0.06, 0.0, 0.0])])
    U, V = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    sites = np.array([[0.05, 0.01], [0.07, -0.02], [-0.05, 0.0]])
    poly = contour_around(rods, np.zeros(3), U, V, sites, 0.005)
    assert abs(profiles.polygon_area(poly) - np.pi * 0.04 ** 2) < 0.03 * np.pi * 0.04 ** 2
    assert np.allclose(profiles.polygon_centroid(poly), [0.06, 0.0], atol=1e-3)
    assert contour_around(rods, np.zeros(3), U, V, np.array([[0.0, 0.3]]), 0.005) is None


def test_a_site_outside_the_surface_s_section_ends_just_beyond_it():
    r_s = 0.005
    poly = profiles.circle(0.05).polygon
    pts = np.array([[0.0, 0.04], [0.056, 0.0]])  # inside, 1 cm from the bark; outside by 6 mm
    off, dist, ok = _mirrors(poly, pts, r_s, surface=True)
    assert ok[:, 0].all()
    assert np.allclose(pts[0] + off[0, 0], [0.0, 0.06], atol=2e-3)  # the mirror across the bark
    assert np.allclose(off[1, 0], [2.0 * OUTSIDE_GAP * r_s, 0.0], atol=1e-4)  # its cell ends 0.25 r_s out
    plain = _mirrors(poly, pts, r_s)
    assert not plain[2][1, 0]  # across the section itself that mirror would land inside the wood
