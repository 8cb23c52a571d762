"""Per-step diagnostics of the biology (woodstock §9.4; SPEC §3).

* mass loss = 1 - (H_l + k H_c) / (1 + k), k = k_H (2.5), volume-weighted over the wood;
* moisture content ratio = (M - M_2)(1 + k) l / ((M_1 - M_2)(H_l + k H_c)), l = 1, volume-
  weighted (elements whose remaining mass is below 1e-9 are left out of the ratio);
* mean of every field per tissue.
"""
from __future__ import annotations

import numpy as np

from ..strands.rings import TISSUES
from .biology import K_H, moisture_bounds
from .state import FIELDS, SimState


def mass_remaining(H_c: np.ndarray, H_l: np.ndarray, k: np.ndarray) -> np.ndarray:
    """(H_l + k H_c) / (1 + k) per element."""
    return (H_l + k * H_c) / (1.0 + k)


def mass_loss(model, state: SimState) -> float:
    """1 - the remaining mass, volume-weighted over the wood."""
    V, k = model.bio.op.volume, model.bio.P[model.bio.tissue, K_H]
    return float(np.sum(V * (1.0 - mass_remaining(state.H_c, state.H_l, k))) / np.sum(V))


def diagnostics(model, state: SimState) -> dict:
    """Mass loss, moisture content ratio and per-tissue field means at the state's time."""
    setup = model.bio
    V = setup.op.volume
    k = setup.P[setup.tissue, K_H]
    remaining = mass_remaining(state.H_c, state.H_l, k)
    M12 = moisture_bounds(setup, state.t_days)[setup.tissue]
    alive = remaining > 1e-9
    ratio = (state.M - M12[:, 1]) * (1.0 + k) / ((M12[:, 0] - M12[:, 1]) * np.where(alive, remaining * (1.0 + k), 1.0))
    out = {
        "t_days": float(state.t_days),
        "mass_loss": mass_loss(model, state),
        "moisture_content_ratio": float(np.sum((V * ratio)[alive]) / max(np.sum(V[alive]), 1e-300)),
        "clamp_count": int(state.clamp_count),
        "tissue_means": {},
    }
    n = len(TISSUES)
    volume = np.bincount(setup.tissue, weights=V, minlength=n)
    sums = {f: np.bincount(setup.tissue, weights=V * getattr(state, f), minlength=n) for f in FIELDS}
    for code in np.flatnonzero(np.bincount(setup.tissue, minlength=n)):
        out["tissue_means"][TISSUES[code]] = {f: float(sums[f][code] / volume[code]) for f in FIELDS}
    return out
