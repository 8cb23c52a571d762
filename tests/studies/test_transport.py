"""Transport accuracy on the irregular rod graph (docs/model.md §7; wooddecay.studies.transport): heat
kernels and Fisher-KPP fronts along e_l, e_r and e_t."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.sim.fronts import lattice_speed_ratio
from wooddecay.studies.transport import fisher_speed_ratio, front_resolution, heat_kernel_ratio

from ..conftest import SAMPLES


@pytest.mark.slow
@pytest.mark.parametrize("direction", ["l", "r", "t"])
def test_heat_kernel_variance_grows_as_2Dt(direction):
    """A point release on the irregular rod graph: d var / dt = 2 D a_dir within 3%."""
    ratio, clamps = heat_kernel_ratio(direction)
    assert ratio == pytest.approx(1.0, abs=0.03)
    assert clamps == 0


@pytest.mark.slow
@pytest.mark.parametrize("direction", ["l", "r", "t"])
def test_fisher_kpp_front_speed(direction):
    """Planar Fisher-KPP fronts move at 2 sqrt(alpha D_dir) within 5% (long-time fit with
    Bramson's correction; wooddecay.studies.transport)."""
    ratio, clamps = fisher_speed_ratio(direction)
    assert ratio == pytest.approx(1.0, abs=0.05)
    assert clamps == 0


def test_lattice_speed_ratio_matches_a_simulated_lattice():
    """lattice_speed_ratio against an explicit 1D lattice Fisher-KPP run (plain numpy): front
    position from the mass of u, speed fitted over t in [30, 60] / alpha with Bramson's
    correction, within 1%; 1 as q -> 0."""
    alpha, h = 1.0, 1.0
    assert lattice_speed_ratio(1e-3) == pytest.approx(1.0, abs=1e-5)
    for q, alpha_dt in ((1.0, 0.1), (3.0, 0.02), (3.0, 0.2)):
        D, dt = alpha * (h / q) ** 2, alpha_dt / alpha
        u = np.zeros(600)
        u[:20] = 1.0
        ts, X = [], []
        for k in range(1, int(round(60.0 / dt)) + 1):
            lap = np.zeros_like(u)
            lap[1:-1] = u[2:] - 2 * u[1:-1] + u[:-2]
            lap[0] = u[1] - u[0]
            u = u + dt * (D * lap / h**2 + alpha * u * (1 - u))
            ts.append(k * dt)
            X.append(u.sum() * h)
        ts, X = np.array(ts), np.array(X)
        late = ts >= 30.0
        v = np.polyfit(ts[late], X[late] + 1.5 * np.sqrt(D / alpha) * np.log(alpha * ts[late]), 1)[0]
        assert v / (2 * np.sqrt(alpha * D)) == pytest.approx(lattice_speed_ratio(q, alpha_dt), rel=0.01)


@pytest.mark.parametrize(("direction", "q", "tol"), [("r", 3.29, 0.05), ("t", 1.64, 0.05), ("l", 2.74, 0.05),
                                                 ("r", 6.57, 0.12)])
def test_under_resolved_fronts_keep_the_continuum_speed(direction, q, tol):
    """At the shipped samples' resolution of white rot (q 3.29 / 1.64 / 2.74 across the grain,
    along the rings and along the grain) and at twice the spacing across it (6.57), with the
    samples' biology step (alpha dt about 0.01), a front on the rod graph keeps 2 sqrt(alpha D_dir)
    within ``tol``; without the fronts' correction it ran 1.18 / 1.11 / 1.16 times as fast at
    the shipped q and a 1D lattice at 6.57 runs 1.53 times (sim/fronts.py; docs/decisions.md,
    "Decay fronts on a coarse graph")."""
    ratio, clamps = fisher_speed_ratio(direction, q=q, alpha_dt=0.02)
    assert ratio == pytest.approx(1.0, abs=tol)
    assert clamps == 0


def test_front_resolution_scales_with_the_spacing():
    """q = h sqrt(g / (D a_dir)): the shipped log's white rot across the grain at r_s 9 mm (2 r_s
    = 18 mm, g = alpha_w0 (lambda_l + lambda_c) / (K_c + 1) = 0.01 / 1.2 per day, D a_r = 1e-6 x
    0.25 m^2 per day) is 3.29; strands twice as wide double q across the grain and leave it along."""
    fine = front_resolution(wd.build_model(wd.load_scene(SAMPLES / "log.toml")))
    coarse = front_resolution(wd.build_model(wd.load_scene(SAMPLES / "log.toml", {"strands.r_s": 0.018})))
    assert fine["white"]["r"] == pytest.approx(0.018 * np.sqrt(0.01 / 1.2 / 2.5e-7), rel=1e-9)
    for fungus in ("white", "brown"):
        assert coarse[fungus]["r"] == pytest.approx(2.0 * fine[fungus]["r"], rel=1e-9)
        assert coarse[fungus]["t"] == pytest.approx(2.0 * fine[fungus]["t"], rel=1e-9)
        assert coarse[fungus]["l"] == pytest.approx(fine[fungus]["l"], rel=0.05)
