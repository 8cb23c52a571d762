"""Initial fields per tissue, inoculation regions and the seasonal moisture schedule."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.sim import biology as B
from wooddecay.sim.state import initial_state
from wooddecay.strands.regions import region_mask
from wooddecay.strands.rings import BARK, HEARTWOOD

from ..conftest import SAMPLES


def test_initial_fields_follow_tissues():
    scene = wd.load_scene(SAMPLES / "log.toml", overrides={
        "tissue.heartwood.C_init": 0.7, "tissue.bark.M_init": 0.3, "wood.H_c_init": 0.9})
    model = wd.build_model(scene)
    s = initial_state(model)
    t = model.tissue
    assert np.all(s.C[t == HEARTWOOD] == 0.7) and np.all(s.C[t != HEARTWOOD] == 0.0)
    assert np.all(s.M[t == BARK] == 0.3) and np.all(s.M[t != BARK] == scene.moisture.M_init)
    assert np.all(s.H_c == 0.9) and np.all(s.H_l == 1.0)


@pytest.mark.parametrize("region, expect", [
    ({"kind": "box", "min": [0.0, -1, -1], "max": [0.2, 1, 1]}, lambda m, s: m.centers[:, 0] <= 0.2),
    ({"kind": "sphere", "center": [0.5, 0.0, 0.15], "radius": 0.1},
     lambda m, s: np.linalg.norm(m.centers - [0.5, 0, 0.15], axis=1) <= 0.1),
    ({"kind": "box", "space": "wood", "min": [0.0, -4, 0.0], "max": [0.05, 4, 2.0]},
     lambda m, s: m.wood_coords[:, 0] <= 0.05),
    ({"kind": "end", "which": "root", "depth": 0.1}, lambda m, s: m.wood_coords[:, 2] <= 0.1),
    ({"kind": "end", "which": "tip", "depth": 0.1},
     lambda m, s: m.wood_coords[:, 2] >= m.wood_coords[:, 2].max() - 0.1),
    ({"kind": "node", "id": "mid", "radius": 0.08},
     lambda m, s: np.linalg.norm(m.centers - s.skeleton.positions[1], axis=1) <= 0.08),
    ({"kind": "wound", "position": [0.5, 0.0, 0.3], "radius": 0.1, "depth": 0.02},
     lambda m, s: (np.linalg.norm(m.centers - [0.5, 0, 0.3], axis=1) <= 0.1) & (m.bark_distance <= 0.02)),
])
def test_region_masks(log_model, log_scene, region, expect):
    mask = region_mask(log_model, region)
    np.testing.assert_array_equal(mask, expect(log_model, log_scene))
    assert 0 < mask.sum() < log_model.n_elements


def test_inoculation_sets_activity_on_its_day(tiny_model):
    text = (SAMPLES / "tiny.toml").read_text().split("[[inoculation]]")[0] + """
[[inoculation]]
fungus = "white"
activity = 0.4
region = { kind = "end", which = "root", depth = 0.05 }
[[inoculation]]
fungus = "brown"
activity = 0.3
day = 2.0
region = { kind = "end", which = "tip", depth = 0.05 }
"""
    scene = wd.parse_scene(text, source="tiny.toml")
    sim = wd.Simulation(wd.build_model(scene), mechanics=False)
    root = tiny_model.wood_coords[:, 2] <= 0.05
    assert np.all(sim.state.R_w[root] == 0.4) and not sim.state.R_b.any()
    sim.advance(1.0)
    assert not sim.state.R_b.any()
    sim.advance(1.5)
    tip = tiny_model.wood_coords[:, 2] >= tiny_model.wood_coords[:, 2].max() - 0.05
    assert np.all(np.abs(sim.state.R_b[tip] - 0.3) < 0.01)  # applied at day 2, then half a day of spread
    assert sim.state.R_b[~tip].max() < 0.3


def test_seasonal_schedule_interpolates():
    scene = wd.load_scene(SAMPLES / "tiny.toml", overrides={
        "moisture.schedule": [[0.0, 1.0, 0.1], [100.0, 0.6, 0.2]], "tissue.bark.schedule": []})
    setup = wd.build_model(scene).bio
    np.testing.assert_allclose(B.moisture_bounds(setup, 50.0)[1], [0.8, 0.15])  # sapwood
    np.testing.assert_allclose(B.moisture_bounds(setup, 500.0)[2], [0.6, 0.2])  # held after
    np.testing.assert_allclose(B.moisture_bounds(setup, 50.0)[0], [1.0, 0.1])  # bark: constant
    np.testing.assert_allclose(setup.box_M[1], [0.1, 1.0])


def test_inoculation_between_steps_is_applied_on_its_day():
    text = (SAMPLES / "tiny.toml").read_text().split("[[inoculation]]")[0] + """
[[inoculation]]
fungus = "brown"
activity = 0.3
day = 2.0
region = { kind = "end", which = "root", depth = 0.05 }
"""
    scene = wd.parse_scene(text, source="tiny.toml", overrides={"time.dt_bio": 50.0})
    sim = wd.Simulation(wd.build_model(scene), mechanics=False)
    sim.advance(2.0)
    assert sim.state.t_days == 2.0 and sim.state.R_b.max() == 0.3
    sim.advance(48.0)
    assert [round(h["t_days"], 9) for h in sim.history] == [0.0, 2.0, 50.0]


def test_M_init_must_lie_in_the_schedule():
    with pytest.raises(wd.InputError, match="schedule"):
        wd.load_scene(SAMPLES / "tiny.toml", overrides={
            "moisture.schedule": [[0.0, 0.6, 0.2], [100.0, 0.6, 0.2]], "moisture.M_init": 0.9})


def test_moisture_box_is_one_envelope_over_tissues():
    """Tissues with different M bounds share one clamp box, so diffusion between them cannot
    push M out of it (each update is a convex combination of values inside)."""
    scene = wd.load_scene(SAMPLES / "tiny.toml", overrides={
        "tissue.bark.M_1": 0.4, "tissue.bark.M_init": 0.35, "fungi.D_w": 0.0,
        "moisture.D_M0": 1e-3, "moisture.k_in0": 0.0, "moisture.k_out0": 0.0, "climate.k_ground": 0.0})
    model = wd.build_model(scene)
    setup = model.bio
    np.testing.assert_allclose(setup.box_M, np.tile([0.1, 1.0], (4, 1)))
    s = initial_state(model)
    V = setup.op.volume
    before = np.sum(V * s.M)
    for _ in range(20):
        B.step(model, s, setup.bound)
    assert s.clamp_count == 0
    np.testing.assert_allclose(np.sum(V * s.M), before, rtol=1e-12)
