"""The model -> sim hand-off (wooddecay.sim.driver): a Simulation reads only the model, and its
schedule and inoculations come from it."""
from __future__ import annotations

import pickle
from dataclasses import replace

import numpy as np

import wooddecay as wd
from wooddecay.wood import Inoculation

from ..conftest import SAMPLES


def _tiny(**overrides):
    return wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", overrides={
        "time.days": 1.0, "time.frames": 3, "mechanics.N_mech": 5, **overrides}))


def test_a_simulation_needs_only_the_model():
    """A model that went through pickle (no scene object anywhere) simulates bit for bit like the
    original, with frames at model.time's days."""
    model = _tiny()
    copy = pickle.loads(pickle.dumps(model))
    runs = [list(wd.Simulation(m).run()) for m in (model, copy)]
    assert [f.t_days for f in runs[0]] == [0.0, 0.5, 1.0]
    for a, b in zip(*runs):
        for k in a.fields:
            assert np.array_equal(a.fields[k], b.fields[k]), k
        for k in a.mech:
            assert np.array_equal(a.mech[k], b.mech[k]), k
    assert runs[0][-1].mech["x"].shape == (len(model.particles), 3)


def test_inoculations_are_read_from_the_model():
    """Replacing model.inoculations changes what the biology-only run applies, and on which day."""
    model = _tiny(**{"time.days": 2.0, "time.frames": 2})
    ends = model.wood_coords[:, 2] <= 0.05
    late = replace(model, inoculations=(Inoculation(day=1.0, fungus="white", activity=0.4, mask=ends),))
    sim = wd.Simulation(late, mechanics=False)
    assert not sim.state.R_w.any()
    sim.advance(1.0)
    assert np.all(sim.state.R_w[ends] >= 0.4 - 1e-12) and sim.state.t_days == 1.0
    assert sim.state.R_w[~ends].max() < 0.4


def test_rod_diagnostics_match_their_numpy_twin():
    """The numba pass against mech_diagnostics_reference on rods with broken connections and
    elements and moving particles; the history's last entry is what the bake reports."""
    from wooddecay.sim.diagnostics import mech_diagnostics, mech_diagnostics_reference

    sim = wd.Simulation(_tiny())
    sim.macro_step(0.5)
    ms = sim.state.mech
    rng = np.random.default_rng(2)
    ms.edge_ok[rng.random(len(ms.edge_ok)) < 0.3, 0] = False
    ms.element_ok[rng.random(len(ms.element_ok)) < 0.2] = False
    ms.v = rng.normal(size=ms.v.shape)
    a, b = mech_diagnostics(ms), mech_diagnostics_reference(ms)
    assert a == b
    assert 0 < a["broken_connections"] < len(ms.edge_ok) and 0 < a["broken_elements"] < len(ms.element_ok)
    assert a["max_speed"] == float(np.sqrt(np.max(np.sum(ms.v**2, axis=1))))
