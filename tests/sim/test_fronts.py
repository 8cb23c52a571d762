"""The fronts' diffusivity factor (wooddecay.sim.fronts): the analytic lattice speed it inverts, the
spacing it reads off the transport operator, and its numba kernel against the numpy reference.
Front speeds on the rod graph with it: tests/studies/test_transport.py."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.sim import fronts

from ..conftest import SAMPLES


@pytest.fixture(scope="module")
def table():
    return fronts.rho_table()


@pytest.mark.parametrize("q", [0.3, 1.0, 3.29, 6.57, 12.0])
def test_rho_brings_the_lattice_front_to_the_continuum_speed(table, q):
    """A 1D lattice at q with its diffusivity scaled by rho(q) runs at 2 sqrt(g D):
    R(q / sqrt rho) sqrt rho = 1 (van Saarloos 2003), R from a direct minimisation."""
    rho = fronts.rho_at(q, table)
    assert fronts.lattice_speed_ratio(q / np.sqrt(rho)) * np.sqrt(rho) == pytest.approx(1.0, abs=1e-4)


def test_rho_falls_from_one(table):
    """rho(0) = 1 (a resolved front needs no correction), rho <= 1 everywhere (the explicit step's
    bound holds) and it falls with q; beyond the table and at q = inf it is the table's last value."""
    assert table[0] == 1.0
    assert np.all(np.diff(table) <= 0.0) and table[-1] > 0.0
    assert fronts.rho_at(1e3, table) == table[-1] == fronts.rho_at(np.inf, table)


def test_spacing_is_the_lattice_spacing():
    """h^2 = sum w d^4 / sum w d^2: h on a lattice of spacing h, and between the two spacings of a
    row with neighbours at two distances."""
    d = np.array([[0.0, 0.0, 0.06], [0.0, 0.0, -0.06], [0.018, 0.0, 0.0], [-0.018, 0.0, 0.0],
                  [0.036, 0.0, 0.0], [-0.036, 0.0, 0.0]])
    w = np.array([1.0, 1.0, 2.0, 2.0, 1.0, 1.0])
    h = fronts.spacing(np.zeros(6, dtype=np.int64), d, w, 1)[0]
    assert h[2] == pytest.approx(0.06, rel=1e-12)
    assert h[1] == 0.0
    expect = np.sqrt((4 * 0.018**4 + 2 * 0.036**4) / (4 * 0.018**2 + 2 * 0.036**2))
    assert h[0] == pytest.approx(expect, rel=1e-12) and 0.018 < h[0] < 0.036


def test_operator_shares_are_symmetric_and_sum_to_one():
    """Each CSR entry's shares along (e_r, e_t, e_l) sum to 1 and equal its reverse entry's, so the
    scaled weights stay symmetric and diffusion conserves the fungus; the shipped log's chain links
    lie along the grain and its spacing along the grain is about a rod (6 cm)."""
    model = wd.build_model(wd.load_scene(SAMPLES / "log.toml"))
    op = model.bio.op
    assert np.allclose(op.share.sum(axis=1), 1.0)
    assert np.array_equal(op.share, op.share[op.reverse])
    assert np.median(op.spacing[:, 2]) == pytest.approx(0.06, rel=0.15)


def test_element_rho_matches_the_reference(table):
    """The numba factor per element and direction against fronts.rho_reference, with growth at
    and below zero, a zero diffusivity and a zero spacing among the cases."""
    import numba as nb

    @nb.njit
    def fill(g, kappa, h, aniso, table, rho):
        for i in range(len(g)):
            fronts.element_rho(i, g[i], kappa[i], h, aniso, table, rho)
        return rho

    rng = np.random.default_rng(3)
    n = 200
    g = rng.uniform(-0.01, 0.05, n)
    g[:3] = 0.0
    kappa = rng.uniform(0.0, 2e-6, n)
    kappa[3:6] = 0.0
    h = rng.uniform(0.0, 0.08, (n, 3))
    h[6:9, 1] = 0.0
    aniso = np.tile([0.25, 1.0, 4.0], (n, 1))
    got = fill(g, kappa, h, aniso, table, np.empty((n, 3)))
    ref = fronts.rho_reference(g, kappa, h, aniso, table)
    assert np.allclose(got, ref, rtol=1e-12, atol=1e-15)
    assert np.all(got[g <= 0.0] == 1.0) and np.all(got[kappa == 0.0] == 1.0)
    assert got.min() < 0.5
