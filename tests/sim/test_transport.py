"""The transport operator (wooddecay.sim.transport; docs/model.md §3 "Transport"): symmetric,
non-negative weights, and pure diffusion conserves the volume-weighted sum to round-off."""
from __future__ import annotations

import numpy as np

import wooddecay as wd
from wooddecay.sim import biology as B
from wooddecay.sim.state import initial_state

from ..conftest import SAMPLES


def test_operator_symmetric_nonnegative(log_model):
    op = log_model.bio.op
    np.testing.assert_array_equal(op.weight, op.weight[op.reverse])
    assert op.weight.min() >= 0.0


def test_pure_diffusion_conserves_volume_weighted_sum():
    scene = wd.load_scene(SAMPLES / "log.toml", overrides={
        "fungi.alpha_w0": 0.0, "fungi.beta_w": 0.0, "fungi.D_w": 1e-4, "moisture.k_in0": 0.0, "moisture.k_out0": 0.0,
        "moisture.D_M0": 1e-4, "moisture.k_DM": 2.0, "climate.k_ground": 0.0})
    model = wd.build_model(scene)
    s = initial_state(model)
    rng = np.random.default_rng(2)
    s.R_w = rng.uniform(0, 1, model.n_elements)
    s.M = rng.uniform(0.2, 0.9, model.n_elements)
    V = model.bio.op.volume
    before = [np.sum(V * s.R_w), np.sum(V * s.M)]
    for _ in range(20):
        B.step(model, s, 0.5)
    after = [np.sum(V * s.R_w), np.sum(V * s.M)]
    np.testing.assert_allclose(after, before, rtol=1e-12, atol=0)
    assert np.std(s.R_w) < 0.9 * np.std(rng.uniform(0, 1, 1000))  # it did diffuse
