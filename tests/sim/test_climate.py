"""The climate of Eq. 15 (sim/climate.py): seasons, exposed ends, ground contact."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.errors import InputError
from wooddecay.scene.schema import PARAMS
from wooddecay.scene.validate import validate_value
from wooddecay.sim import biology as B
from wooddecay.sim import climate as C
from wooddecay.sim.state import initial_state

from ..conftest import SAMPLES


def _tiny(**over):
    return wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", overrides=over))


def test_seasons_interpolate_and_repeat_every_year():
    c = C.Climate(days=np.array([10.0, 200.0]), start_day=0.0, w=np.array([[1.0, 2.0, 0.0], [3.0, 0.0, 1.0]]),
                  k_ground=0.1, ground_z=0.0, ground_depth=0.01)
    np.testing.assert_allclose(c.factors(10.0), [1.0, 2.0, 0.0])
    np.testing.assert_allclose(c.factors(105.0), [2.0, 1.0, 0.5])
    np.testing.assert_allclose(c.factors(200.0 + 5 * C.YEAR_DAYS), [3.0, 0.0, 1.0])
    # from the last keyframe (day 200) to the next year's first (day 375.25): halfway at 287.625
    np.testing.assert_allclose(c.factors(287.625), [2.0, 1.0, 0.5])
    np.testing.assert_allclose(c.factors(287.625 - C.YEAR_DAYS), c.factors(287.625))
    np.testing.assert_allclose(c.w_max, [3.0, 2.0, 1.0])
    later = C.Climate(days=c.days, start_day=100.0, w=c.w, k_ground=0.1, ground_z=0.0, ground_depth=0.01)
    np.testing.assert_allclose(later.factors(5.0), c.factors(105.0))


@pytest.mark.parametrize("name", sorted(C.PRESETS))
def test_presets_are_valid_seasons(name):
    rows = [list(r) for r in C.PRESETS[name]]
    assert validate_value(PARAMS["climate"]["seasons"], rows, "x.toml") == tuple(map(tuple, rows))


@pytest.mark.parametrize("rows, key, words", [
    ([[0, 1, 1]], "climate.seasons[0]", "[day_of_year, w_in, w_out, w_ground]"),
    ([[0, 1, 1, 0], [0, 1, 1, 0]], "climate.seasons[1]", "strictly increasing"),
    ([[400, 1, 1, 0]], "climate.seasons[0]", "365.25"),
    ([[0, -1, 1, 0]], "climate.seasons[0]", "w_in -1.0 is outside [0, 100]"),
])
def test_bad_seasons_name_the_row(tmp_path, rows, key, words):
    with pytest.raises(InputError) as e:
        wd.load_scene(SAMPLES / "tiny.toml", overrides={"climate.seasons": rows})
    assert e.value.key == key and words in str(e.value)


def test_unknown_preset_lists_the_presets():
    with pytest.raises(InputError, match="one of 'temperate', 'dry', 'wet-ground', 'constant'"):
        wd.load_scene(SAMPLES / "tiny.toml", overrides={"climate.preset": "tropical"})


def test_cut_ends_count_as_exposed_surface():
    """A log's two cut ends are surfaces: near them the exposure distance is the distance
    along the grain to the end; elsewhere it is the bark distance."""
    model = _tiny()
    s, bd = model.wood_coords[:, 2], model.bark_distance
    bx = model.bio.bd
    length = model.cp_s.max()
    expect = np.minimum(bd, np.minimum(s - 0.0, length - s))
    np.testing.assert_allclose(bx, expect, atol=1e-12)
    assert (bx < bd).sum() > 0.05 * len(bx)


def test_an_anchored_root_is_not_a_cut_end():
    scene = wd.load_scene(SAMPLES / "tiny.toml", overrides={"mechanics.ground": True})
    data = scene.skeleton
    model = wd.build_model(scene)
    assert not data.anchored.any()
    anchored = np.zeros_like(data.anchored)
    anchored[data.parent < 0] = True
    from dataclasses import replace
    model_a = replace(model, skeleton=replace(data, anchored=anchored))
    bx = C.exposure_distance(model_a)
    s = model.wood_coords[:, 2]
    near_root = s < 0.02
    np.testing.assert_allclose(bx[near_root], np.minimum(model.bark_distance, model.cp_s.max() - s)[near_root])


def test_ground_contact_follows_the_rods():
    model = _tiny()
    cl = model.bio.climate
    g = C.ground_contact(model, cl, model.particles)
    fp = model.first_particle
    low = np.minimum(model.particles[fp, 2], model.particles[fp + 1, 2]) - model.radius
    np.testing.assert_array_equal(g == 1.0, low <= cl.ground_depth)
    assert 0 < g.sum() < 0.2 * len(g)
    lifted = model.particles + np.array([0.0, 0.0, 1.0])
    assert C.ground_contact(model, cl, lifted).sum() == 0
    no_ground = _tiny(**{"mechanics.ground": False})
    assert C.ground_contact(no_ground, no_ground.bio.climate, model.particles).sum() == 0


def _exchange_only(**seasons):
    """Tiny log with no diffusion, no fungi: Eq. 15 pointwise."""
    return _tiny(**{"moisture.D_M0": 0.0, "fungi.D_b": 0.0, "inoculation.0.day": 5000.0, **seasons})


def test_surface_relaxes_to_the_climate_equilibrium():
    """With the seasons constant (w_in, w_out) and no diffusion, Eq. 15 at each element is the
    linear ODE M' = (M_1 - M) a - (M - M_2) b, whose forward-Euler solution is exact:
    M_n = M_eq + (M_0 - M_eq) (1 - h (a + b))^n, M_eq = (a M_1 + b M_2) / (a + b)."""
    w_in, w_out = 0.2, 6.0
    model = _exchange_only(**{"climate.seasons": [[0, w_in, w_out, 0.0]]})
    s = initial_state(model)
    M0 = s.M.copy()
    P = model.materials
    bd = model.bio.bd
    a = w_in * P.per_element("k_in0") * np.maximum(0, 1 - P.per_element("k_r_in") * bd) * s.H_c
    b = w_out * P.per_element("k_out0") * np.maximum(0, 1 - P.per_element("k_r_out") * s.H_c) * np.maximum(0, P.per_element("bd_0") - bd)
    M1, M2 = P.per_element("M_1"), P.per_element("M_2")
    h, n = 1.0, 150
    for _ in range(n):
        B.step(model, s, h)
    k = a + b
    eq = np.where(k > 0, (a * M1 + b * M2) / np.where(k > 0, k, 1.0), M0)
    np.testing.assert_allclose(s.M, eq + (M0 - eq) * (1 - h * k) ** n, rtol=1e-12, atol=1e-14)
    surface = bd < 0.005
    assert s.M[surface].max() < PARAMS["mechanics"]["M_0"].default  # dried below M_0
    assert s.clamp_count == 0


def test_ground_contact_wets_the_touching_wood():
    """Only the ground term: M' = (M_1 - M) w_ground k_ground g."""
    model = _exchange_only(**{"climate.seasons": [[0, 0.0, 0.0, 2.0]], "climate.k_ground": 0.05})
    s = initial_state(model)
    M0 = s.M.copy()
    g = C.ground_contact(model, model.bio.climate, model.particles)
    for _ in range(30):
        B.step(model, s, 1.0)
    M1 = model.materials.per_element("M_1")
    np.testing.assert_allclose(s.M, M1 - (M1 - M0) * (1 - 0.1 * g) ** 30, rtol=1e-12)
    assert (s.M[g == 1] > M0[g == 1] + 0.1).all() and (s.M[g == 0] == M0[g == 0]).all()


def test_numba_step_matches_the_reference_with_climate():
    model = _tiny(**{"climate.preset": "wet-ground", "time.dt_bio": 3.0})
    a, b = initial_state(model), initial_state(model)
    a.t_days = b.t_days = 150.0
    for _ in range(10):
        B.step(model, a, 3.0)
        B.step_reference(model, b, 3.0)
    for name in ("R_b", "H_c", "M"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=1e-15)


def test_temperate_year_dries_the_surface_in_summer_and_wets_it_in_winter():
    """The default climate on the tiny log: in late summer a fifth of the outer wood is below
    M_0 (the rest near it), and in winter the outer wood is back above 0.6."""
    model = _tiny(**{"inoculation.0.day": 5000.0})
    assert model.bio.climate.w.tolist() == [list(r[1:]) for r in C.PRESETS["temperate"]]
    s = initial_state(model)
    surface = model.bio.bd < 0.006
    M_0 = PARAMS["mechanics"]["M_0"].default
    mean, below = {}, {}
    for day in range(1, 366):
        B.step(model, s, 1.0)
        mean[day], below[day] = s.M[surface].mean(), (s.M[surface] < M_0).mean()
    assert max(below[d] for d in range(200, 280)) > 0.2 and min(mean[d] for d in range(200, 280)) < M_0 + 0.1
    assert max(below[d] for d in range(1, 150)) == 0.0 and mean[365] > 0.6
    assert s.clamp_count == 0
