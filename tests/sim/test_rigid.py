"""Rigid pieces of the implicit step: the small loose blocks of the broken tiny log move as rigid
bodies (their shape exact to round-off, where the same blocks as rods deform), fall as backward
Euler says, are judged by their net force and torque, and break by decay only."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from wooddecay.sim import equilibrium, failure, implicit, rigid

from .helpers import fragments

IMPLICIT = {"mechanics.solver": "implicit"}


def _shape_change(x0: np.ndarray, x1: np.ndarray, rb: rigid.Bodies) -> float:
    """Largest change of a distance between two particles of one rigid piece."""
    return max((float(np.abs(pdist(x1[rb.particle == k]) - pdist(x0[rb.particle == k])).max())
                for k in range(rb.n_pieces)), default=0.0)


def test_only_small_loose_pieces_are_rigid_and_only_under_the_implicit_solver():
    sim = fragments(**IMPLICIT)
    setup, ms = sim.model.mech, sim.state.mech
    element = rigid.pieces(setup, ms)
    size = np.bincount(ms.component, weights=ms.element_ok.astype(float))
    small = size[ms.component] < rigid.RIGID_FRACTION * setup.n_elements
    assert np.array_equal(element >= 0, small)
    assert 0 < element.max() + 1 < len(size)
    held = replace(setup, anchored_e=np.isin(ms.component, ms.component[element >= 0]))
    assert (rigid.pieces(held, ms) == -1).all()
    xpbd = fragments()
    assert (rigid.pieces(xpbd.model.mech, xpbd.state.mech) == -1).all()


def test_rigid_pieces_keep_their_shape_where_the_same_pieces_as_rods_deform():
    """Three steps of 0.01 s of the broken tiny log on the ground from rest: the rigid blocks'
    particle distances change by round-off only; with no rigid piece the same blocks bend under
    their weight and contacts."""
    changes = {}
    for fraction in (rigid.RIGID_FRACTION, 0.0):
        sim = fragments(**IMPLICIT)
        setup, ms = sim.model.mech, sim.state.mech
        rb = rigid.bodies(setup, ms)
        x0 = ms.x.copy()
        saved, rigid.RIGID_FRACTION = rigid.RIGID_FRACTION, fraction
        try:
            for _ in range(3):
                implicit.step(setup, ms, 0.01, tol=1e-3)
        finally:
            rigid.RIGID_FRACTION = saved
        assert np.linalg.norm(ms.x - x0, axis=1)[rb.particle >= 0].max() > 1e-6  # they moved
        changes[fraction] = _shape_change(x0, ms.x, rb)
    assert changes[rigid.RIGID_FRACTION] < 1e-12
    assert changes[0.0] > 1e-8


def test_a_rigid_piece_falls_as_backward_euler_says():
    """No ground: from rest, one step of h moves every particle by h^2 g (M (x - x~) / h^2 = m g;
    the pieces touch only at their rest overlaps, which a common translation keeps)."""
    sim = fragments(**IMPLICIT, **{"mechanics.ground": False})
    setup, ms = sim.model.mech, sim.state.mech
    x0, h = ms.x.copy(), 0.05
    report = implicit.step(setup, ms, h, tol=1e-6, max_newton=10)
    rb = rigid.bodies(setup, ms)
    drop = ms.x - x0
    assert report.converged
    assert np.abs(drop[rb.particle >= 0] - h * h * setup.gravity).max() < 1e-6 * h * h * 9.81
    assert np.abs(ms.v[rb.particle >= 0] - h * setup.gravity).max() < 1e-6 * h * 9.81


def _lone_strand():
    """The tiny log with every REG connection of its first strand failed: that strand is a piece
    of its own, rigid, lifted 1 m clear of the rest and of the ground."""
    sim = fragments(**IMPLICIT)
    setup, ms = sim.model.mech, sim.state.mech
    strand = np.arange(setup.strand_offsets[0], setup.strand_offsets[1])
    ms.element_ok[:] = True
    ms.edge_ok[:] = True
    ms.edge_ok[np.isin(setup.edges, strand).any(axis=1)] = False
    ms.component = failure.components(setup, ms)
    ends = np.union1d(setup.fp[strand], setup.fp[strand] + 1)
    ms.x[ends] += [0.0, 0.0, 1.0]
    return setup, ms, strand


def test_a_rigid_piece_is_judged_by_its_net_force_and_torque():
    """A rigid piece's own elastic forces cancel in its net force and torque: lifted clear of all
    else it reads its weight exactly (gravity has no torque about its centre of mass), and
    squeezing its rest lengths, which makes its strands pull hard, changes nothing."""
    setup, ms, strand = _lone_strand()
    rb = rigid.bodies(setup, ms)
    k = rb.element[strand[0]]
    assert k >= 0 and (rb.element[strand] == k).all() and (rb.element >= 0).sum() == len(strand)
    weight = ms.mass_p[rb.particle == k].sum() * np.linalg.norm(setup.gravity)
    F = equilibrium.forces(setup, ms)[0]
    assert equilibrium._rigid_remainder(setup, ms, F, rb)[k] == pytest.approx(weight, rel=1e-9)
    ms.rest_length[strand] *= 0.9
    F2 = equilibrium.forces(setup, ms)[0]
    assert np.abs(F2.f[rb.particle == k]).max() > 1e3 * weight
    assert equilibrium._rigid_remainder(setup, ms, F2, rb)[k] == pytest.approx(weight, rel=1e-6)


def test_static_friction_takes_up_to_its_share():
    """The lone strand laid on the ground: its weight is carried, so it reads near zero; pushed
    sideways by less than mu_f times its weight it stays balanced, by more it reads the excess."""
    setup, ms, strand = _lone_strand()
    on = np.isin(np.arange(setup.n_particles), np.union1d(setup.fp[strand], setup.fp[strand] + 1))
    ms.x[on, 2] = ms.radius_p[on] - 1e-4  # pressed 0.1 mm into the ground
    rb = rigid.bodies(setup, ms)
    k = rb.element[strand[0]]
    assert np.array_equal(on, rb.particle == k)
    F = equilibrium.forces(setup, ms)[0]
    weight = ms.mass_p[on].sum() * np.linalg.norm(setup.gravity)
    support = F.contact[on].sum(axis=0)[2]
    lift = weight - support  # what the contacts leave unbalanced
    base = equilibrium._rigid_remainder(setup, ms, F, rb)[k]
    twist = base - abs(lift)  # its weight and even support do not quite share a line
    assert 0.0 <= twist < 0.25 * abs(lift)
    for share, excess in ((0.5, 0.0), (2.0, 1.0)):
        pushed = F._replace(f=F.f + on[:, None] * [share * setup.mu_f * support / on.sum(), 0.0, 0.0])
        read = equilibrium._rigid_remainder(setup, ms, pushed, rb)[k]
        assert read == pytest.approx(np.hypot(lift, excess * setup.mu_f * support) + twist, rel=0.02)


def test_rigid_pieces_break_by_decay_not_by_their_frozen_strain():
    sim = fragments(**IMPLICIT)
    setup, ms = sim.model.mech, sim.state.mech
    rb = rigid.bodies(setup, ms)
    inner = np.flatnonzero((rb.element >= 0) & setup.inner & ms.element_ok)
    ms.rest_length[inner] *= 0.7  # a shrink far past every limit, which the rigid shape does not answer
    rigid.freeze_strains(setup, ms, rb)
    assert failure.update(setup, ms) == 0
    ms.link_integrity[inner] = 0.0
    assert failure.update(setup, ms) >= 1
    assert not ms.element_ok[inner].all()
