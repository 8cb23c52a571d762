"""Coupling (wooddecay.sim.coupling): Eqs. 16, 17, 19 and 21 on the tiny log."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from wooddecay.sim import coupling
from wooddecay.sim.state import initial_state

from ..conftest import sample

def test_coupling_equations():
    scene, model = sample("tiny")
    setup = model.mech
    state = initial_state(model, rods=True)
    ms = state.mech
    M_0 = scene.mechanics.M_0
    state.M[:] = M_0 - 0.05
    state.H_c[:] = 0.5
    state.H_l[:] = 1.0
    assert scene.moisture.M_1 == 1.0 and scene.moisture.M_2 == 0.1 and not scene.moisture.schedule
    coupling.step(model, state)
    np.testing.assert_allclose(ms.rest_length, setup.rest_length0 * (1 - 0.05 * scene.mechanics.s))  # Eq. 17
    mech = scene.mechanics
    dw = model.reg_dir_weights
    g_edge = mech.S * (mech.S_R * dw[:, 0] + mech.S_T * dw[:, 1]) + mech.s * dw[:, 2]
    np.testing.assert_allclose(ms.rest_offset, setup.offset0 * (1 - 0.05 * g_edge))  # Eq. 16
    expect_I = np.where(model.reg_theta == 1, 1 - mech.k_c * 0.5, 1.0)  # Eq. 21, H_l = 1
    np.testing.assert_allclose(ms.integrity, expect_I)
    f = ((M_0 - 0.05 - 0.1) / (M_0 - 0.1)) ** mech.p_l_stretch  # Eq. 19, its knee at M_0
    # Eq. 21 on the strand link e, e + 1: theta = 1 where the two lie in different BSP leaves
    leaf, n = model.bsp_leaf, model.n_elements
    nxt = np.minimum(np.arange(n) + 1, n - 1)
    crosses = (leaf != leaf[nxt]) & ~np.isin(np.arange(n), model.element_offsets[1:] - 1)
    assert crosses.sum() > 100
    np.testing.assert_allclose(ms.limit_elem[:, 0], mech.L_0_stretch * f * np.where(crosses, 1 - mech.k_c * 0.5, 1.0))
    assert coupling.limit_factor(np.array(0.05), 0.2, 0.1, 4.0) == 0.0
    assert np.isclose(coupling.limit_factor(np.array(0.15), 0.2, 0.1, 4.0), 0.5 ** 4, rtol=1e-12, atol=0)
    # wet wood keeps its strength: the factor is 1 from M_0 up, not only at M_1
    assert coupling.limit_factor(np.array(0.2), 0.2, 0.1, 4.0) == 1.0
    assert coupling.limit_factor(np.array(0.5), 0.2, 0.1, 4.0) == 1.0
    assert coupling.limit_factor(np.array(0.15), 0.1, 0.1, 4.0) == 1.0
    assert coupling.limit_factor(np.array(0.05), 0.1, 0.1, 4.0) == 0.0
    # L_knee = 1: Eq. 19 as printed, the knee at M_1
    cs = replace(model.coupling, L_knee=np.ones(model.n_elements))
    M_k = coupling.knee(cs, np.full(model.n_elements, 1.0))
    assert np.allclose(M_k, 1.0)
    np.testing.assert_allclose(coupling.limit_factor(np.array(0.5), M_k[:1], 0.1, 4.0), (0.4 / 0.9) ** 4)
    # brown-rot shrinkage: half the carbohydrates gone shrinks rest lengths, offsets and radii by S_c / 2
    shrunk = replace(model, coupling=replace(model.coupling, S_c=np.full(model.n_elements, 0.3)))
    coupling.step(shrunk, state)
    np.testing.assert_allclose(ms.rest_length, setup.rest_length0 * (1 - 0.05 * scene.mechanics.s) * 0.85)
    np.testing.assert_allclose(ms.rest_offset, setup.offset0 * (1 - 0.05 * g_edge) * 0.85)
    np.testing.assert_allclose(ms.radius, setup.radius * 0.85)
    for end in (setup.fp, setup.fp + 1):  # a particle's collider clearance is its largest element's
        assert np.all(ms.radius_p[end] >= ms.radius)
    assert ms.radius_p.max() == ms.radius.max() and len(ms.radius_p) == setup.n_particles


def test_even_drying_shrinks_the_tiny_log_as_one_strain_field():
    """Eq. 16's gain of every REG offset is the first-order length change of that offset under one
    homogeneous shrinkage F = 1 - d G, G = S (S_R e_R e_R^T + S_T e_T e_T^T) + s e_L e_L^T with
    e_L the log's axis: at S_R = S_T the offsets of evenly drying wood stay those of one shrunk
    log, however the strands wander between the tapered log's end profiles (up to a few degrees
    off the axis), so no connection is strained. Gains from the strands' own frames missed it by
    up to 0.021 here."""
    scene, model = sample("tiny")
    mech = scene.mechanics
    assert mech.S_R == mech.S_T
    e = model.reg_edges
    d = model.centers[e[:, 1]] - model.centers[e[:, 0]]
    n = d / np.linalg.norm(d, axis=1)[:, None]
    axis = np.array([1.0, 0.0, 0.0])  # the skeleton's a -> b
    n_l = n @ axis
    G_nn = mech.S * mech.S_R * (1.0 - n_l**2) + mech.s * n_l**2
    np.testing.assert_allclose(model.coupling.g_pair, G_nn, rtol=0, atol=1e-12)
    strand_l = np.abs(model.frames[:, 2] @ axis)
    assert strand_l.min() < np.cos(np.radians(1.0))  # the strands do wander


def test_coupling_kernel_matches_its_numpy_twin():
    """coupling.step (one numba pass over elements and one over pairs) against step_reference on
    random moisture and health, below, inside and above [M_2, M_1] and M_0."""
    _, model = sample("tiny")
    state = initial_state(model, rods=True)
    rng = np.random.default_rng(4)
    n = model.n_elements
    state.M[:] = rng.uniform(0.0, 1.2, n)
    state.H_c[:] = rng.uniform(0.0, 1.0, n)
    state.H_l[:] = rng.uniform(0.0, 1.0, n)
    # the default knee (M_0) and a knee anywhere between M_0 and M_1 per element
    # and brown-rot shrinkage S_c anywhere in its range per element
    for m in (model, replace(model, coupling=replace(model.coupling, L_knee=rng.uniform(0.0, 1.0, n))),
              replace(model, coupling=replace(model.coupling, S_c=rng.uniform(0.0, 0.9, n)))):
        coupling.step(m, state)
        for name, expect in coupling.step_reference(m, state).items():
            np.testing.assert_allclose(getattr(state.mech, name), expect, rtol=1e-15, atol=0.0, err_msg=name)
