"""Node frames, arc length and branches of a skeleton (strands/topology.py)."""
from __future__ import annotations

import numpy as np

import wooddecay as wd
from wooddecay.strands.topology import build_topology

from ..conftest import SAMPLES


def test_frames_orthonormal_right_handed_and_along_skeleton():
    skel = wd.load_scene(SAMPLES / "tree.toml").skeleton
    topo = build_topology(skel)
    F = topo.frames
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", F, F), np.broadcast_to(np.eye(3), F.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(F), 1.0, atol=1e-12)
    for i in range(len(skel.ids)):
        p = skel.parent[i]
        if p >= 0:
            d = skel.positions[i] - skel.positions[p]
            assert np.dot(F[i, 2], d) > 0.5 * np.linalg.norm(d)  # T roughly along the edge
            # parallel transport: U changes little between neighbouring nodes
            assert np.dot(F[i, 0], F[p, 0]) > 0.5
            assert np.isclose(topo.s[i], topo.s[p] + np.linalg.norm(d))


def test_horizontal_log_frame_has_v_up():
    skel = wd.load_scene(SAMPLES / "tiny.toml").skeleton
    topo = build_topology(skel)
    np.testing.assert_allclose(topo.frames[:, 1], np.tile([0, 0, 1.0], (len(skel.ids), 1)), atol=1e-12)
    np.testing.assert_allclose(topo.up2d, np.tile([0, 1.0], (len(skel.ids), 1)), atol=1e-12)


def test_branches_and_orders():
    skel = wd.load_scene(SAMPLES / "tree.toml").skeleton
    topo = build_topology(skel)
    trunk = [skel.ids.index(f"t{k}") for k in range(10)]
    assert len(set(topo.branch[trunk].tolist())) == 1  # the trunk is one branch (largest child)
    assert topo.branch_order.max() == 2  # trunk, branches, twigs
    assert topo.n_branches == 1 + 5 + 10
