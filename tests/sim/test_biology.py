"""Biophysics (woodstock §6, Eqs. 8-15, 20; docs/model.md §3 and §7): kernel vs reference, conservation,
the invariant box, stability and the rot signatures."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import wooddecay as wd
from wooddecay.cli import main
from wooddecay.scene import PARAMS
from wooddecay.sim import biology as B
from wooddecay.sim.diagnostics import diagnostics, diagnostics_reference
from wooddecay.sim.state import FIELDS, SimState, initial_state
from wooddecay.strands.rings import HEARTWOOD, SAPWOOD

from ..conftest import ROOT, SAMPLES

ACTIVE = {
    "fungi.alpha_w0": 0.08, "fungi.alpha_b0": 0.1, "fungi.D_w": 2e-5, "fungi.D_b": 3e-5,
    "fungi.beta_w": 0.02, "fungi.beta_b": 0.01, "fungi.gamma_cw": 0.02, "fungi.gamma_cb": 0.03,
    "fungi.gamma_lw": 0.02, "fungi.rho_c": 0.001, "fungi.rho_l": 0.002, "fungi.kappa": 0.05,
    "fungi.delta": 0.001, "fungi.D_C": 1e-5, "moisture.D_M0": 1e-4, "moisture.k_in0": 0.05,
    "moisture.k_out0": 1.0,
}


def _random_state(model, scene, rng) -> SimState:
    s = initial_state(model)
    for f in ("R_w", "R_b", "H_c", "H_l", "C"):
        setattr(s, f, rng.uniform(0, 1, model.n_elements))
    s.M = rng.uniform(scene.moisture.M_2, scene.moisture.M_1, model.n_elements)
    return s


#: the sample tree with strands 2.5x wider and twice as long (the gallery's quick trees): its
#: forks' transport edges at a tenth of the elements of the reference's minutes
COARSE = {"tree": {"strands.r_s": 0.02, "strands.rod_length": 0.1}}


@pytest.mark.parametrize("name", ["tiny", "log", "board", "tree"])
def test_numba_step_equals_numpy_reference(name):
    scene = wd.load_scene(SAMPLES / f"{name}.toml", overrides={**ACTIVE, **COARSE.get(name, {})})
    model = wd.build_model(scene)
    a = _random_state(model, scene, np.random.default_rng(0))
    b = a.copy()
    for _ in range(5):
        B.step(model, a, 0.5)
        B.step_reference(model, b, 0.5)
    for f in FIELDS:
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=0, atol=1e-12, err_msg=f)
    assert a.clamp_count == b.clamp_count == 0


def test_a_field_without_fungus_stays_zero_as_in_the_reference():
    """The kernel skips Eq. 8 or 9 where its fungus is absent everywhere: the same values as the
    reference, which computes it."""
    scene = wd.load_scene(SAMPLES / "log.toml", overrides=ACTIVE)
    model = wd.build_model(scene)
    for absent in ("R_w", "R_b"):
        a = _random_state(model, scene, np.random.default_rng(1))
        setattr(a, absent, np.zeros(model.n_elements))
        b = a.copy()
        for _ in range(3):
            B.step(model, a, 0.5)
            B.step_reference(model, b, 0.5)
        assert not getattr(a, absent).any()
        for f in FIELDS:
            np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=0, atol=1e-12, err_msg=f)


_THREADS = """
import hashlib, sys, numpy as np, wooddecay as wd
from wooddecay.sim import biology as B
scene = wd.load_scene(sys.argv[1], overrides={"fungi.alpha_b0": 0.1, "fungi.D_b": 3e-5})
sim = wd.Simulation(wd.build_model(scene), mechanics=False)
sim.advance(20.0)
h = hashlib.sha256()
for f in ("R_w", "R_b", "H_c", "H_l", "C", "M"):
    h.update(getattr(sim.state, f).tobytes())
print(h.hexdigest())
"""


@pytest.mark.slow
def test_biology_identical_for_1_and_2_threads():
    out = []
    for threads in ("1", "2"):
        r = subprocess.run([sys.executable, "-c", _THREADS, str(SAMPLES / "log.toml")],
                           env=dict(os.environ, NUMBA_NUM_THREADS=threads), capture_output=True,
                           text=True, cwd=ROOT, check=True)
        out.append(r.stdout.strip())
    assert out[0] == out[1]


# ------------------------------------------------------------------ invariant box (Appendix A)


@pytest.fixture(scope="module")
def box_setup():
    scene = wd.load_scene(SAMPLES / "tiny.toml")
    model = wd.build_model(scene)
    return model, scene, model.bio


def _range(name):
    p = next(PARAMS[s][name] for s in ("fungi", "moisture") if name in PARAMS[s])
    lo = p.lo + (1e-6 if p.lo_open else 0.0)
    hi = p.hi
    return st.one_of(st.just(lo), st.just(hi), st.floats(lo, hi, allow_nan=False))


_BIO = [k for k in B.BIO_PARAMS if k not in ("M_min", "M_max")]


@st.composite
def bio_case(draw):
    params = {k: draw(_range(k)) for k in _BIO}
    M_2 = draw(st.one_of(st.just(0.0), st.floats(0.0, 2.0)))
    M_1 = M_2 + draw(st.one_of(st.just(1e-3), st.floats(1e-3, 3.0)))
    M_min = draw(st.floats(0.0, 4.0))
    M_max = M_min + draw(st.floats(1e-3, 4.0))
    k_W = draw(st.one_of(st.just(0.0), st.just(0.999), st.floats(0.0, 0.999)))
    dt = draw(st.one_of(st.just(0.5), st.floats(1e-3, 0.5)))
    seed = draw(st.integers(0, 2**32 - 1))
    # per-tissue bounds inside [M_2, M_1] (tissues may override M_1, M_2)
    shrink = draw(st.lists(st.tuples(st.floats(0, 0.45), st.floats(0, 0.45)), min_size=4, max_size=4))
    return params, (M_1, M_2, M_min, M_max), k_W, dt, seed, shrink


@pytest.mark.slow
@settings(max_examples=500, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=bio_case())
def test_invariant_box_under_random_parameters(box_setup, case):
    model, scene, setup = box_setup
    params, (M_1, M_2, M_min, M_max), k_W, dt, seed, shrink = case
    P = setup.P.copy()
    for k, v in params.items():
        P[:, B.BIO_PARAMS.index(k)] = v
    P[:, B.M_MIN], P[:, B.M_MAX] = M_min, M_max
    wfac = 1.0 + k_W * (2.0 * model.W - 1.0)
    t = setup.tissue
    kappa = np.stack([P[t, B.D_W], P[t, B.D_B], P[t, B.D_C]], 1) * wfac[:, None]
    span = M_1 - M_2
    per_tissue = tuple((np.zeros(1), np.array([M_1 - b * span]), np.array([M_2 + a * span]))
                       for a, b in shrink)
    envelope = [min(m2[0] for _, _, m2 in per_tissue), max(m1[0] for _, m1, _ in per_tissue)]
    s2 = replace(setup, P=P, wfac=wfac, kappa=kappa, schedules=per_tissue,
                 box_M=np.tile(envelope, (len(P), 1)))
    s2 = replace(s2, bound=B.stability_bound(s2))
    # extreme rates (k_out0 bd_0 up to 1e6 / day) need ~1e6 substeps per day: keep each example
    # to at most 20 substeps per step, still crossing from one substep to many
    dt = min(dt, 20.0 * s2.bound)
    rng = np.random.default_rng(seed)
    n = model.n_elements
    # clipped uniforms put a share of the values exactly on the box faces (extremes)
    state = SimState(*(np.clip(rng.uniform(-0.2, 1.2, n), 0, 1) for _ in range(5)),
                     M=np.clip(rng.uniform(M_2 - 0.2, M_1 + 0.2, n), *envelope))
    with_s2 = replace(model, bio=s2)
    for _ in range(2):
        B.step(with_s2, state, dt)
    assert all(np.all(np.isfinite(getattr(state, f))) for f in FIELDS)
    # the box holds by itself: the clamp (which would hide a violation) never had to act
    assert state.clamp_count == 0


def test_step_past_stability_bound_leaves_the_box():
    rng = np.random.default_rng(4)
    fast = wd.load_scene(SAMPLES / "tiny.toml", overrides={"fungi.D_b": 5e-3, "fungi.alpha_b0": 1.0})
    model = wd.build_model(fast)
    setup = model.bio
    start = initial_state(model)
    start.R_b = rng.uniform(0, 1, model.n_elements)
    unstable = start.copy()
    dt = 4.0 * setup.bound
    B.step(model, unstable, dt, n_sub=1)
    assert unstable.clamp_count > 0  # explicit Euler overshot the box; the clamp caught it
    stable = start.copy()
    n = B.step(model, stable, dt)
    assert n == B.substeps(dt, setup.bound) >= 4 and stable.clamp_count == 0
    # without the clamp, explicit diffusion past the bound diverges: the largest excursion of an
    # alternating perturbation grows every step, while substeps within the bound damp it
    kappa = setup.kappa[:, 1]
    u = rng.uniform(-1, 1, model.n_elements) * 1e-3
    v = u.copy()
    dt_diff = 4.0 / setup.op.row_sums(kappa).max()
    sizes = []
    for _ in range(6):
        u = u + dt_diff * setup.op.apply(u, kappa)
        sizes.append(np.abs(u).max())
        for _ in range(8):
            v = v + dt_diff / 8 * setup.op.apply(v, kappa)
    assert all(b > 1.5 * a for a, b in zip(sizes, sizes[1:])) and sizes[-1] > 1.0
    assert np.abs(v).max() <= 1e-3


def test_inspect_reports_bound_and_substeps():
    r = CliRunner().invoke(main, ["inspect", str(SAMPLES / "tiny.toml"), "--json", "--set", "time.dt_bio=50"])
    rep = json.loads(r.stdout)["biology"]
    assert rep["stability_bound_days"] > 0
    assert rep["substeps"] == int(np.ceil(50 / rep["stability_bound_days"]))


# ------------------------------------------------------------------ studies


def _log_with(inoculations: str, extra: str = "", days: float = 400.0) -> wd.Scene:
    text = (SAMPLES / "log.toml").read_text()
    ends = [i for i in (text.find("\n[tissue."), text.find("[[inoculation]]")) if i >= 0]
    text = text[:min(ends)]  # the log's tissue tables and inoculations give way to the test's
    return wd.parse_scene(text + extra + inoculations, source="log.toml", base_dir=SAMPLES,
                          overrides={"time.days": days, "time.frames": 2})


_FAST = """
[fungi]
alpha_w0 = 0.08
alpha_b0 = 0.08
D_w = 2e-5
D_b = 2e-5
gamma_cw = 0.03
gamma_cb = 0.03
gamma_lw = 0.03
"""


def _run(scene):
    sim = wd.Simulation(wd.build_model(scene), mechanics=False)
    for _ in sim.run():
        pass
    return sim


def _rot_from_root_end(fungus: str):
    """State after the fast log run with ``fungus`` at the root end, and its rotted mask."""
    sim = _run(_log_with(f'[[inoculation]]\nfungus = "{fungus}"\nactivity = 0.3\n'
                         'region = { kind = "end", which = "root", depth = 0.1 }\n', _FAST))
    rotted = sim.state.H_c < 0.3
    assert rotted.sum() > 100
    return sim.state, rotted


@pytest.mark.slow
def test_brown_rot_keeps_lignin():
    s, rotted = _rot_from_root_end("brown")
    assert np.all(s.H_l[rotted] >= 0.9)


@pytest.mark.slow
def test_white_rot_takes_both():
    s, rotted = _rot_from_root_end("white")
    assert np.median(s.H_l[rotted]) < 0.5


@pytest.mark.slow
def test_white_rot_hollows_heartwood_first_when_its_defences_are_low():
    defences = _FAST + """
[tissue.sapwood]
kappa = 1.0
beta_w = 1.0
C_init = 1.0
[tissue.heartwood]
kappa = 0.0
C_init = 0.0
"""
    sim = _run(_log_with('[[inoculation]]\nfungus = "white"\nactivity = 0.3\n'
                         'region = { kind = "end", which = "root", depth = 0.3 }\n', defences, days=180))
    s, tissue = sim.state, sim.model.tissue
    hollow = s.H_l < 0.5
    heart = hollow[tissue == HEARTWOOD].mean()
    sap = hollow[tissue == SAPWOOD].mean()
    assert heart > 0.5 and sap < 0.05, (heart, sap)


def test_simulation_frames_and_diagnostics(tiny_model, tiny_scene):
    sim = wd.Simulation(tiny_model, mechanics=False)
    frames = list(sim.run())
    assert [f.index for f in frames] == list(range(tiny_scene.time.frames))
    np.testing.assert_allclose([f.t_days for f in frames], np.linspace(0, tiny_scene.time.days, tiny_scene.time.frames))
    d = frames[-1].diagnostics
    assert set(d) >= {"mass_loss", "moisture_content_ratio", "clamp_count", "tissue_means"}
    assert 0.0 <= d["mass_loss"] <= 1.0 and d["clamp_count"] == 0
    ml = [h["mass_loss"] for h in sim.history]
    assert np.all(np.diff(ml) >= -1e-15)  # no recovery (rho = 1e-4 is slower than depletion)
    assert len(sim.history) == 1 + int(np.ceil(tiny_scene.time.days / tiny_scene.time.dt_bio))  # day 0 + steps


def test_diagnostics_match_their_numpy_twin(tiny_model):
    """The numba pass against diagnostics_reference on a decayed state with consumed elements
    (left out of the moisture ratio) and moisture off its bounds."""
    sim = wd.Simulation(tiny_model, mechanics=False)
    for _ in range(3):
        sim.macro_step(tiny_model.time.dt_bio)
    s = sim.state
    rng = np.random.default_rng(1)
    gone = rng.random(len(s.H_c)) < 0.2
    s.H_c[gone] = s.H_l[gone] = 0.0
    s.M[:] = rng.uniform(0.1, 1.2, len(s.M))
    a, b = diagnostics(tiny_model, s), diagnostics_reference(tiny_model, s)
    assert a.keys() == b.keys() and a["tissue_means"].keys() == b["tissue_means"].keys()
    for key in ("mass_loss", "moisture_content_ratio"):
        assert a[key] == pytest.approx(b[key], rel=1e-12), key
    for tissue, means in a["tissue_means"].items():
        for f, v in means.items():
            assert v == pytest.approx(b["tissue_means"][tissue][f], rel=1e-12), (tissue, f)
    assert 0.1 < a["mass_loss"] < 1.0
