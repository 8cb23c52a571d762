"""Per-step diagnostics of the biology (woodstock §9.4; docs/model.md §3).

* mass loss = 1 - (H_l + k H_c) / (1 + k), k = k_H (2.5), volume-weighted over the wood;
* moisture content ratio = (M - M_2)(1 + k) l / ((M_1 - M_2)(H_l + k H_c)), l = 1, volume-
  weighted (elements whose remaining mass is below 1e-9 are left out of the ratio);
* mean of every field per tissue;
* of the rods (:func:`mech_diagnostics`): pieces, broken connections and elements, failures and
  the largest particle speed.
"""
from __future__ import annotations

import numba as nb
import numpy as np

from ..wood import WoodModel
from ..strands.rings import TISSUES
from .biology import K_H, moisture_bounds
from .state import FIELDS, SimState


def mass_remaining(H_c: np.ndarray, H_l: np.ndarray, k: np.ndarray) -> np.ndarray:
    """(H_l + k H_c) / (1 + k) per element."""
    return (H_l + k * H_c) / (1.0 + k)


def mass_loss(model: WoodModel, state: SimState) -> float:
    """1 - the remaining mass, volume-weighted over the wood."""
    V, k = model.bio.op.volume, model.bio.P[model.bio.tissue, K_H]
    return float(np.sum(V * (1.0 - mass_remaining(state.H_c, state.H_l, k))) / np.sum(V))


def diagnostics(model: WoodModel, state: SimState) -> dict:
    """Mass loss, moisture content ratio and per-tissue field means at the state's time, in one
    serial numba pass over the elements (:func:`diagnostics_reference` is its numpy twin). Why:
    the twin's temporaries took 0.22 ms of every macro step of the log against 0.05 ms, a year's
    quiet steps being mostly overhead (docs/decisions.md, "Adaptive schedule")."""
    setup = model.bio
    M12 = moisture_bounds(setup, state.t_days)
    fields = tuple(getattr(state, f) for f in FIELDS)
    sums = _sums(setup.tissue, setup.op.volume, setup.P[:, K_H], M12, fields, FIELDS.index("H_c"),
                 FIELDS.index("H_l"), FIELDS.index("M"))
    return _report(state, *sums)


@nb.njit(cache=True)
def _sums(tissue, V, k_t, M12, fields, c, l, m):
    """Sums of :func:`diagnostics` in element order: V (1 - remaining), V ratio and V over the
    living elements, V over all, and per tissue V and V f for every field f."""
    n_t = len(k_t)
    lost = ratio = alive = total = 0.0
    volume = np.zeros(n_t)
    sums = np.zeros((len(fields), n_t))
    for i in range(len(tissue)):
        t, v = tissue[i], V[i]
        k = k_t[t]
        remaining = (fields[l][i] + k * fields[c][i]) / (1.0 + k)
        total += v
        lost += v * (1.0 - remaining)
        if remaining > 1e-9:
            ratio += v * (fields[m][i] - M12[t, 1]) / ((M12[t, 0] - M12[t, 1]) * remaining)
            alive += v
        volume[t] += v
        for f in range(len(fields)):
            sums[f, t] += v * fields[f][i]
    return lost / total, ratio / max(alive, 1e-300), volume, sums


def diagnostics_reference(model: WoodModel, state: SimState) -> dict:
    """Plain-numpy :func:`diagnostics`."""
    setup = model.bio
    V = setup.op.volume
    k = setup.P[setup.tissue, K_H]
    remaining = mass_remaining(state.H_c, state.H_l, k)
    M12 = moisture_bounds(setup, state.t_days)[setup.tissue]
    alive = remaining > 1e-9
    ratio = (state.M - M12[:, 1]) * (1.0 + k) / ((M12[:, 0] - M12[:, 1]) * np.where(alive, remaining * (1.0 + k), 1.0))
    n = len(TISSUES)
    volume = np.bincount(setup.tissue, weights=V, minlength=n)
    sums = np.array([np.bincount(setup.tissue, weights=V * getattr(state, f), minlength=n) for f in FIELDS])
    return _report(state, mass_loss(model, state), float(np.sum((V * ratio)[alive]) / max(np.sum(V[alive]), 1e-300)),
                   volume, sums)


def _report(state: SimState, loss: float, ratio: float, volume: np.ndarray, sums: np.ndarray) -> dict:
    """The diagnostics dict from the sums; field means for the tissues that hold wood."""
    means = {TISSUES[t]: {f: float(sums[j, t] / volume[t]) for j, f in enumerate(FIELDS)}
             for t in np.flatnonzero(volume > 0.0)}
    return {"t_days": float(state.t_days), "mass_loss": float(loss), "moisture_content_ratio": float(ratio),
            "clamp_count": int(state.clamp_count), "tissue_means": means}


def mech_diagnostics(ms) -> dict:
    """Crack statistics of the rod state (a :class:`~wooddecay.sim.mechanics.MechState`), in one
    serial numba pass (:func:`mech_diagnostics_reference` is its numpy twin). Why: the twin's
    temporaries took 0.1 ms of every macro step of the log (docs/decisions.md, "Biology on one
    build")."""
    broken_k, broken_e, v2 = _rod_counts(ms.edge_ok, ms.element_ok, ms.v)
    return _rod_report(ms, broken_k, broken_e, v2)


@nb.njit(cache=True)
def _rod_counts(edge_ok, element_ok, v):
    """Broken connections (``edge_ok[:, 0]`` cleared), broken elements and the largest squared
    particle speed."""
    broken_k = broken_e = 0
    for k in range(len(edge_ok)):
        broken_k += not edge_ok[k, 0]
    for e in range(len(element_ok)):
        broken_e += not element_ok[e]
    v2 = 0.0
    for p in range(len(v)):
        v2 = max(v2, v[p, 0] * v[p, 0] + v[p, 1] * v[p, 1] + v[p, 2] * v[p, 2])
    return broken_k, broken_e, v2


def mech_diagnostics_reference(ms) -> dict:
    """Plain-numpy :func:`mech_diagnostics`."""
    return _rod_report(ms, np.count_nonzero(~ms.edge_ok[:, 0]), np.count_nonzero(~ms.element_ok),
                       np.max(np.sum(ms.v**2, axis=1), initial=0.0))


def _rod_report(ms, broken_k, broken_e, v2) -> dict:
    return {"components": int(ms.component.max(initial=-1) + 1), "broken_connections": int(broken_k),
            "broken_elements": int(broken_e), "failures": int(ms.failures), "max_speed": float(np.sqrt(v2))}
