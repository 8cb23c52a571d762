"""Shared set-ups of the sim tests: the jostled tiny log's rods, the digest that the
determinism and checkpoint tests compare, and the tiny log broken into its BSP blocks."""
from __future__ import annotations

import hashlib
from dataclasses import replace

import numpy as np

import wooddecay as wd
from wooddecay.quaternion import normalize_np
from wooddecay.sim import mechanics, sleep
from wooddecay.sim.state import initial_state
from wooddecay.studies import debris

from ..conftest import sample


def perturbed_state(name="tiny", seed=0):
    """(model, state) of a sample with the rods at rest, then jostled and partly decayed."""
    model = sample(name)[1]
    state = initial_state(model, rods=True)
    setup, ms = model.mech, state.mech
    rng = np.random.default_rng(seed)
    ms.x += rng.normal(scale=1e-3, size=ms.x.shape) * (ms.w_p > 0)[:, None]
    ms.q = normalize_np(ms.q + rng.normal(scale=0.02, size=ms.q.shape) * (ms.w_q > 0)[:, None])
    ms.integrity = rng.uniform(0.3, 1.0, len(setup.edges))  # above I_fail: no decay separation
    return model, state


def perturbed(name="tiny", seed=0):
    """(model.mech, state.mech) of :func:`_perturbed_state`, for the kernels' own tests."""
    model, state = perturbed_state(name, seed)
    return model.mech, state.mech


def digest(ms) -> str:
    h = hashlib.sha256()
    for a in (ms.x, ms.v, ms.q, ms.omega, ms.component, ms.edge_ok, ms.element_ok):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def failing_tiny():
    model, state = perturbed_state(seed=3)
    state.mech.limit_elem[:] = 2e-3  # some failures happen
    state.mech.limit_edge[:] = 2e-3
    return model, state


def run_tiny(substeps=30):
    model, state = failing_tiny()
    for _ in range(substeps):
        mechanics.substep(model, state, 1e-3)
    return state.mech


def fragments(**overrides):
    scene, model = sample("tiny")
    if overrides:
        model = wd.build_model(wd.load_scene(scene.path, overrides=overrides))
    sim = wd.Simulation(model)
    debris.fragment(sim)
    mechanics.refresh_pairs(sim.model.mech, sim.state.mech)
    return sim


def quiet_window(st, ms, moved=None) -> int:
    """End a full window in which the particles moved by ``moved`` (P, 3) (default: not at all)."""
    ms.sleep_x = ms.x.copy() if moved is None else ms.x - moved
    ms.sleep_t = np.array([ms.t_seconds - st.sleep_time])
    return sleep.update(st, ms)


def sleep_digest(ms) -> str:
    """The mechanics :func:`digest` and the sleep state."""
    h = hashlib.sha256(digest(ms).encode())
    for a in (ms.w_p, ms.w_q, ms.asleep):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


#: REG connections of the equilibrium and Hessian tests: (central share, offset shares along R, T, L)
CONNECTIONS = {"central": (1.0, (0.0, 0.0, 0.0)), "connection_shear": (0.5, (0.5, 0.5, 0.5)),
               "orthotropic": (0.6, (0.2, 0.5, 0.1))}


def with_connection(setup, central: float, offset: tuple):
    """``setup`` with every REG connection's central share ``central`` and offset shares ``offset``."""
    m = len(setup.edges)
    return replace(setup, central_share=np.full(m, central), offset_share=np.tile(np.asarray(offset, float), (m, 1)))
