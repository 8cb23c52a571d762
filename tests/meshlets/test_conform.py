"""Bark on the source surface (wooddecay.meshlets.conform): two tetrahedral cells above the ground
plane's surface, their bark pulled into the band around it, every copy of a shared vertex alike,
and a move that would turn a cell inside out held short."""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from wooddecay.meshlets import checks
from wooddecay.meshlets.conform import BAND, conform_bark
from wooddecay.meshlets.sweep import FACE_BARK, FACE_CAP, FACE_SIDE, Meshlets

R_S = 0.005


def _oriented(P, tri):
    """The tetrahedron ``P`` (4, 3)'s faces ``tri`` turned to face outwards."""
    c = P.mean(axis=0)
    out = []
    for t in tri:
        n = np.cross(P[t[1]] - P[t[0]], P[t[2]] - P[t[0]])
        out.append(t if np.dot(P[t[0]] - c, n) > 0 else t[::-1])
    return np.array(out)


def _two_cells(apex_z: float):
    """Two tetrahedra sharing the side face (a, b, apex), their tops bark 10 mm above z = 0."""
    top = np.array([[0.0, 0.0, 0.01], [0.01, 0.0, 0.01], [0.0, 0.01, 0.01], [0.01, 0.01, 0.01]])
    apex = np.array([0.005, 0.005, apex_z])
    shared = [[1, 2, 0, 4], [1, 2, 3, 4]]  # rest-partition vertices of each cell: b, c, a|d, apex
    G = np.vstack([top, apex])
    points, faces, kinds, nbr, elem, vs = [], [], [], [], [], []
    for e, ids in enumerate(shared):
        P = G[ids]
        tri = _oriented(P, np.array([[0, 1, 2], [0, 1, 3], [1, 2, 3], [2, 0, 3]]))
        faces.append(tri + 4 * e)
        kinds += [FACE_BARK, FACE_SIDE, FACE_CAP, FACE_CAP]  # the top is bark, (b, c, apex) the shared wall
        nbr += [-1, 1 - e, -1, -1]
        elem += [e] * 4
        points.append(P)
        vs += ids
    faces = np.vstack(faces)
    mesh = Meshlets(
        points=np.vstack(points), faces=faces, face_element=np.array(elem), face_kind=np.array(kinds),
        face_neighbour=np.array(nbr), vertex_element=np.repeat([0, 1], 4), vertex_shared=np.array(vs),
        vertex_offsets=np.array([0, 4, 8]), face_offsets=np.array([0, 4, 8]), wood=np.zeros((8, 3)),
        ring=np.zeros(8), skin_indptr=np.arange(9), skin_element=np.repeat([0, 1], 4),
        skin_weight=np.ones(8), skin_local=np.zeros((8, 3)), stats={},
    )
    ground = trimesh.creation.box(extents=[1.0, 1.0, 1.0]).apply_translation([0.0, 0.0, -0.5])
    model = SimpleNamespace(r_s=R_S, skeleton=SimpleNamespace(surface=ground),
                            centers=np.array([[0.004, 0.004, 0.005], [0.006, 0.006, 0.005]]),
                            rest_quat=np.tile([1.0, 0.0, 0.0, 0.0], (2, 1)), ring_age=np.array([3.0, 5.0]))
    return model, mesh


def _conform(model, mesh):
    return conform_bark(model, mesh, FACE_BARK)


def test_bark_comes_into_the_band_and_copies_move_alike():
    model, mesh = _two_cells(apex_z=-0.02)
    out = _conform(model, mesh)
    bark = np.unique(out.faces[out.face_kind == FACE_BARK])
    assert np.allclose(out.points[bark, 2], BAND * R_S)  # 10 mm above the surface -> the band's edge
    for g in np.unique(out.vertex_shared):
        copies = out.points[out.vertex_shared == g]
        assert np.array_equal(copies, np.repeat(copies[:1], len(copies), axis=0))
    assert np.allclose(out.points[out.vertex_shared == 4], [0.005, 0.005, -0.02])  # not bark: stays
    assert checks.closed_oriented(out).all() and (checks.volumes(out) > 0).all()
    assert out.stats["conformed"] == 4 and out.stats["conform_held"] == 0
    assert out.stats["conform_max"] == pytest.approx(0.01 - BAND * R_S)
    # the skinning follows the moved points: each copy in its element's (identity) frame
    assert np.allclose(out.skin_local, out.points - model.centers[out.skin_element])


def test_a_move_that_would_turn_a_cell_over_is_held_short():
    # the cells' shared corner sits 8 mm up, under their shared edge (b, c): taken to the band's
    # edge (2.5 mm), b and c would pass below it and turn both cells over; a and d may go
    model, mesh = _two_cells(apex_z=0.008)
    out = _conform(model, mesh)
    z = {g: out.points[out.vertex_shared == g, 2] for g in range(4)}
    assert (z[1] > 0.008).all() and (z[1] < 0.01).all() and np.array_equal(z[1], z[2])
    assert np.allclose(z[0], BAND * R_S) and np.allclose(z[3], BAND * R_S)
    assert checks.closed_oriented(out).all() and (checks.volumes(out) > 0).all()
    assert out.stats["conform_held"] == 2 and out.stats["conformed"] == 2


def test_meshlets_without_bark_are_left_as_they_are():
    # no bark face (all walls and caps): nothing to pull
    model, mesh = _two_cells(apex_z=-0.02)
    sawn = replace(mesh, face_kind=np.where(mesh.face_kind == FACE_BARK, FACE_SIDE, mesh.face_kind))
    out = _conform(model, sawn)
    assert np.array_equal(out.points, mesh.points) and out.stats["conformed"] == 0
