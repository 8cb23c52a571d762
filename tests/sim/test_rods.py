"""Rod kernels (wooddecay.sim.rods) against their numpy references; the REG colouring and
Stage 2's colour-ordered data."""
from __future__ import annotations

import numpy as np

from wooddecay.sim import mechanics, rods

from ..conftest import sample
from .helpers import perturbed

def test_rod_kernels_equal_numpy_reference():
    """Stage 2 sweeps some of the tiny log's REG colour classes on one thread and the others in
    parallel (rods.PARALLEL_MIN)."""
    setup, ms = perturbed()
    dt = 1e-3
    sw = setup.sweep
    ms.edge_ok[::3] = False  # failed edges: Stage 2 skips them
    ms.edge_ok[1::7, 1:] = False  # connection only
    kreg = sw.arrays(ms)
    assert len(kreg.active) < len(sw.order)
    sizes = np.diff(kreg.ptr)
    assert (sizes < rods.PARALLEL_MIN).any() and (sizes >= rods.PARALLEL_MIN).any()
    results = []
    for kernels in ((rods.stretch_shear, rods.bend_twist, rods.reg_pass),
                    (rods.stretch_shear_reference, rods.bend_twist_reference, rods.reg_pass_reference)):
        x, q = ms.x.copy(), ms.q.copy()
        lam = mechanics.multipliers(setup)
        ss, bt, rp = kernels
        for elems in setup.elems:
            ss(elems, setup.fp, x, q, ms.w_p, ms.w_q, ms.rest_length, setup.k_stretch, setup.k_shear,
               ms.element_ok, lam.s, lam.sh, dt)
        for idx in setup.joint_sets:
            bt(setup.joints, idx, q, ms.w_q, setup.joint_rest, setup.joint_length, setup.joint_kb,
               setup.joint_kt, lam.j, dt)
        rp(sw.edges, kreg.ptr, kreg.active, setup.fp, x, q, ms.w_p, ms.w_q, kreg.offset, kreg.k_conn, sw.rest,
           sw.length, kreg.k_bend, kreg.k_twist, lam.c, lam.p, dt)
        results.append((x, q, lam))
    (x1, q1, l1), (x2, q2, l2) = results
    assert np.abs(x1 - ms.x).max() > 1e-6  # the projections did something
    np.testing.assert_allclose(x1, x2, rtol=0, atol=1e-12)
    np.testing.assert_allclose(q1, q2, rtol=0, atol=1e-12)
    for k in ("s", "sh", "j", "c", "p"):
        np.testing.assert_allclose(getattr(l1, k), getattr(l2, k), rtol=1e-9, atol=1e-15)


def test_a_fresh_sweep_writes_every_multiplier_it_reads():
    """reg_pass with ``fresh`` on uninitialised multipliers (NaN here) moves the rods and leaves
    the multipliers of every swept edge bit for bit as a sweep from zeros does, and a second sweep
    from them agrees too: the substep need not zero them."""
    setup, ms = perturbed()
    dt = 1e-3
    sw = setup.sweep
    ms.edge_ok[::3] = False
    ms.edge_ok[1::7, 1:] = False
    ms.w_q[::11] = 0.0  # quaternions that do not turn: their pairs' bend-twist is skipped
    kreg = sw.arrays(ms)
    out = []
    for fresh in (False, True):
        x, q = ms.x.copy(), ms.q.copy()
        m = len(setup.edges)
        lam_c, lam_bt = (np.full(m, np.nan), np.full((m, 3), np.nan)) if fresh else (np.zeros(m), np.zeros((m, 3)))
        for first in (fresh, False):
            rods.reg_pass(sw.edges, kreg.ptr, kreg.active, setup.fp, x, q, ms.w_p, ms.w_q, kreg.offset, kreg.k_conn,
                          sw.rest, sw.length, kreg.k_bend, kreg.k_twist, lam_c, lam_bt, dt, first)
        out.append((x, q, lam_c[kreg.active], lam_bt[kreg.active]))
    for a, b in zip(*out):
        np.testing.assert_array_equal(a, b)
    assert np.abs(out[0][2]).max() > 0.0 and not np.isnan(out[1][3]).any()


def test_reg_colouring_has_no_shared_particle():
    setup = sample("log")[1].mech
    sw = setup.sweep
    ptr, order = sw.ptr, sw.order
    assert sorted(order.tolist()) == list(range(len(setup.edges)))
    np.testing.assert_array_equal(sw.edges, setup.edges[order])  # the sweep's data is the edges'
    np.testing.assert_array_equal(sw.rest, setup.edge_rest[order])
    for c in range(len(ptr) - 1):
        assert np.all(np.diff(order[ptr[c]:ptr[c + 1]]) > 0)  # each class in increasing id
        e = sw.edges[ptr[c]:ptr[c + 1]]
        parts = np.concatenate([setup.fp[e[:, 0]], setup.fp[e[:, 0]] + 1, setup.fp[e[:, 1]], setup.fp[e[:, 1]] + 1])
        assert len(np.unique(parts)) == len(parts)
    assert len(ptr) - 1 < 80


def test_sweep_arrays_equal_numpy_gather():
    """RegSweep.arrays: the state's dp and stiffness (base x I_ij, 0 where failed) in colour order."""
    setup, ms = perturbed()
    rng = np.random.default_rng(1)
    ms.edge_ok[:] = rng.random(ms.edge_ok.shape) > 0.3
    ms.rest_offset = ms.rest_offset * rng.uniform(0.9, 1.0, len(ms.rest_offset))
    sw = setup.sweep
    o = sw.order
    want = (ms.rest_offset[o],) + tuple(np.where(ms.edge_ok[o, c], ms.integrity[o] * k0, 0.0)
                                        for c, k0 in enumerate((sw.k_conn0, sw.k_pb0, sw.k_pt0)))
    got = sw.arrays(ms)
    for g, w in zip(got, want):
        np.testing.assert_array_equal(g, w)
    assert (want[1] == 0).any() and (want[1] > 0).any()
    # the active edges: those with any stiffness, each class within its own block
    np.testing.assert_array_equal(got.active, np.flatnonzero((want[1] > 0) | (want[2] > 0) | (want[3] > 0)))
    for c in range(len(sw.ptr) - 1):
        block = got.active[got.ptr[c]:got.ptr[c + 1]]
        assert np.all((block >= sw.ptr[c]) & (block < sw.ptr[c + 1]))
    assert got.ptr[-1] == len(got.active) < len(sw.order)
