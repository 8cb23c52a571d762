"""Fig. 6's radial-crack measure (wooddecay.gallery.measures.radial_cracks) on rods held at rest
while their moisture drops: every broken connection opens by exactly its shrinkage."""
from __future__ import annotations

import numpy as np

from wooddecay.gallery import measures
from wooddecay.sim.driver import Frame

from ..conftest import sample


def _frame(model, M, broken):
    edge_ok = np.ones((len(model.reg_edges), 3), dtype=bool)
    edge_ok[broken] = False
    mech = {"x": model.particles.astype(np.float64), "edge_ok": edge_ok,
            "element_ok": np.ones(model.n_elements, dtype=bool)}
    return Frame(index=0, t_days=0.0, fields={"M": np.full(model.n_elements, M)}, mech=mech, diagnostics={})


def test_radial_cracks_sum_the_shrinkage_of_broken_tangential_connections_per_sector():
    model = sample("log")[1]
    cs, e = model.coupling, model.reg_edges
    M_0 = float(cs.M_0_pair.max())
    dry = M_0 - 0.1
    phi = model.wood_coords[:, 1]
    pair_phi = np.angle(np.exp(1j * phi[e[:, 0]]) + np.exp(1j * phi[e[:, 1]]))
    tangential = model.reg_dir_weights[:, 1] > 0.5
    middle = -np.pi + (np.array([20, 7, 28]) + 0.5) * 2.0 * np.pi / measures.SECTORS  # of three sectors
    sector_a = tangential & (np.abs(pair_phi - middle[0]) < 0.08)
    sector_b = tangential & (np.abs(pair_phi - middle[1]) < 0.08)
    radial = (model.reg_dir_weights[:, 0] > 0.5) & (np.abs(pair_phi - middle[2]) < 0.08)
    assert sector_a.sum() >= 3 and sector_b.sum() >= 3 and radial.sum() >= 3
    first = _frame(model, M_0, np.zeros(len(e), dtype=bool))
    shrink = model.mech.offset0 * 0.1 * cs.g_pair  # rest offset lost at M_0 - 0.1, positions unchanged

    one = measures.radial_cracks(model, first, _frame(model, dry, sector_a | radial))
    np.testing.assert_allclose(one["radial_crack_opening_m"], shrink[sector_a].sum(), rtol=1e-9)
    assert one["radial_crack_sectors"] == 1 and one["effective_radial_cracks"] == 1.0

    two = measures.radial_cracks(model, first, _frame(model, dry, sector_a | sector_b))
    a, b = shrink[sector_a].sum(), shrink[sector_b].sum()
    np.testing.assert_allclose(two["effective_radial_cracks"], (a + b) ** 2 / (a * a + b * b), rtol=1e-9)
    assert two["radial_crack_sectors"] == 2

    none = measures.radial_cracks(model, first, _frame(model, M_0, np.zeros(len(e), dtype=bool)))
    assert none == {"radial_crack_opening_m": 0.0, "radial_crack_sectors": 0, "effective_radial_cracks": 0.0}


def test_fragment_share_is_the_weight_average_piece_of_the_remaining_wood():
    model = sample("log")[1]
    n, V = model.n_elements, model.bio.op.volume
    whole = np.ones(n)

    def share(component, H):
        frame = Frame(index=0, t_days=0.0, fields={"H_c": H, "H_l": H}, mech={"component": component}, diagnostics={})
        return measures.fragment_share(model, frame)

    assert share(np.zeros(n, dtype=np.int64), whole) == 1.0
    halves = (np.arange(n) >= n // 2).astype(np.int64)
    a, b = V[: n // 2].sum(), V[n // 2:].sum()
    np.testing.assert_allclose(share(halves, whole), (a * a + b * b) / (a + b) ** 2, rtol=1e-12)
    np.testing.assert_allclose(share(np.arange(n), whole), np.sum(V * V) / V.sum() ** 2, rtol=1e-12)
    consumed = whole.copy()
    consumed[n // 2:] = 0.0  # the second half crumbled: the first is all the wood left
    assert share(halves, consumed) == 1.0
    half_rotted = whole.copy()
    half_rotted[n // 2:] = 0.5  # H_l = H_c = 0.5: half its mass left
    np.testing.assert_allclose(share(halves, half_rotted), (a * a + b * b / 4) / (a + b / 2) ** 2, rtol=1e-12)
