"""Brown rot's blocks come apart, fall and come to rest within one adaptive solve (woodstock
Figs. 7, 12; issue: visible decay), on the tiny log with its carbohydrates gone by hand. The
year-long bakes of the samples are measured in the closing notes and docs/decisions.md; this is
their mechanism at CI size."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.sim import coupling, schedule
from wooddecay.sim.signature import signature

from ..conftest import SAMPLES


@pytest.mark.slow
def test_decayed_blocks_separate_fall_and_rest():
    model = wd.build_model(wd.load_scene(SAMPLES / "tiny.toml", {"bsp.elongation": 3.0}))
    sim = wd.Simulation(model)
    st, ms = sim.state, sim.state.mech
    before = signature(model, st)
    st.H_c[:] = 0.1  # brown rot consumed the carbohydrates
    coupling.step(model, st)
    tol = replace(model.time.tolerances, max_seconds=3.0)
    assert schedule.due(model, st, tol) is not None
    z0 = 0.5 * (ms.x[model.mech.fp, 2] + ms.x[model.mech.fp + 1, 2])
    chunks = schedule.solve(model, st, tol)
    after = signature(model, st)
    z = 0.5 * (ms.x[model.mech.fp, 2] + ms.x[model.mech.fp + 1, 2])
    print(f"{chunks} chunks ({ms.t_seconds:.2f} s of mechanics): {after}")
    assert bool(ms.quiet[0]) and chunks * model.time.N_mech * model.mech.dt < 3.0  # came to rest
    assert after["pieces"] >= 20 and after["block_purity"] >= 0.8 and after["largest_piece_fraction"] < 0.2
    assert 0.9 < sum(after["crack_orientation"]) < 1.1
    # blocks, not fibres: few elements in bits of fewer than 5, few connections inside cells broken
    size = np.bincount(ms.component)[ms.component]
    same = model.bsp_leaf[model.reg_edges[:, 0]] == model.bsp_leaf[model.reg_edges[:, 1]]
    assert np.mean(size < 5) < 0.1 and np.mean(~ms.edge_ok[same, 0]) < 0.1
    # blocks slid off the sides: the wood is lower and spread wider than the intact log
    assert after["debris_height_m"] < before["debris_height_m"] - 0.002
    assert after["debris_footprint_m2"] > before["debris_footprint_m2"]
    assert (z - z0).min() < -0.02


@pytest.mark.slow
def test_drying_board_checks_along_the_fibre(tmp_path):
    """Fig. 15: the shipped board's first summer, on a 30 cm piece of it (its white-rot knot lies
    outside), opens separate checks, not a crack network: nothing fails while all the wood is
    above M_0 (Eq. 19's knee), then at least 3 crack clusters, the board in one piece, no strand
    cut across the fibre, and the broken connections lean across the grain."""
    text = (SAMPLES / "board.toml").read_text().replace("position = [1.0, 0.0, 0.025]", "position = [0.3, 0.0, 0.025]")
    path = tmp_path / "board.toml"
    path.write_text(text)
    model = wd.build_model(wd.load_scene(path, {"bsp.cells": 60}))
    sim = wd.Simulation(model)
    st, ms = sim.state, sim.state.mech
    dry_before_failure = None
    while st.t_days < 160.0 - 1e-9:
        sim.macro_step(model.time.dt_bio)
        if dry_before_failure is None and ms.failures:
            dry_before_failure = st.M.min() < model.coupling.M_0.min()
    sig = signature(model, st)
    w = model.reg_dir_weights
    broken = ~ms.edge_ok[:, 0]
    across = w[:, 2] < 0.5
    print(f"{np.count_nonzero(broken)} broken, {sig['crack_clusters']} crack clusters, across-grain share "
          f"{across[broken].mean():.2f} (all {across.mean():.2f}), M {st.M.min():.3f}-{st.M.max():.3f}")
    assert dry_before_failure
    assert sig["crack_clusters"] >= 3 and sig["pieces"] == 1 and ms.element_ok.all()
    assert across[broken].mean() > 1.3 * across.mean()
