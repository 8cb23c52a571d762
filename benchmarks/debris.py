"""Debris: fragments of the tiny log fall onto the ground and (should) settle (woodstock §5.4,
Fig. 12; issue: mechanics, "Debris").

The log settles on the ground (``wd.Simulation``), then falls apart into its BSP blocks the way
advanced brown rot leaves it (Fig. 12): every theta = 1 REG connection and every element whose
strand successor lies in another BSP leaf lose all strength and fail through
:func:`wooddecay.sim.failure.update` (so the failure rules apply: an element next to a cut or at
a strand end does not fail). The pieces are lifted by ``DROP`` and fall under gravity with the
scene's contact, friction and damping. Prints ``name value unit`` lines every 0.1 s of
mechanics and at the end:
    pieces, max_speed (largest particle speed), p99_speed,
    max_penetration_over_r_s (largest capsule overlap between intact elements of different
    pieces beyond their overlap in the intact wood, over r_s), max_raw_overlap_over_r_s (the
    same without subtracting it), z_min (lowest particle), broken_connections, seconds (wall).
The issue's target: afterwards max_speed < 1e-3 m/s and max_penetration_over_r_s < 0.1.
"""
from __future__ import annotations

import sys
import time

import numpy as np

import wooddecay as wd
from wooddecay.sim import contact, failure
from wooddecay.sim import mechanics as mech

SCENE = "samples/tiny.toml"
DROP = 0.05  # m
SECONDS = 3.0  # of mechanics after the drop


def fragment(sim) -> None:
    """Fail the BSP-boundary connections and strand links of ``sim`` (module docstring)."""
    model, st, ms = sim.model, sim.mech_setup, sim.state.mech
    leaf = model.bsp_leaf
    boundary = np.zeros(model.n_elements, dtype=bool)
    boundary[:-1] = leaf[:-1] != leaf[1:]
    ms.limit_edge[model.reg_theta.astype(bool)] = -np.inf
    ms.limit_elem[boundary] = -np.inf
    failure.update(st, ms)


def penetration(st, ms) -> tuple[float, float]:
    """Largest overlap of two intact capsules of different pieces beyond the overlap they had in
    the intact wood (:mod:`wooddecay.sim.contact`, "Rest overlap"), and the largest raw one."""
    pairs = contact.candidate_pairs(ms.x, st.fp, st.radius, ms.component, 0.0)
    pairs = pairs[ms.element_ok[pairs[:, 0]] & ms.element_ok[pairs[:, 1]]]
    phi = contact.capsule_contact_reference(*_ends(ms.x, st, pairs))[3]
    rest = contact.capsule_contact_reference(*_ends(st.x_rest, st, pairs))[3]
    return float(np.max(phi - rest, initial=0.0)), float(phi.max(initial=0.0))


def _ends(x, st, pairs):
    a, b = st.fp[pairs[:, 0]], st.fp[pairs[:, 1]]
    return x[a], x[a + 1], st.radius[pairs[:, 0]], x[b], x[b + 1], st.radius[pairs[:, 1]]


def main(path: str = SCENE, seconds: float = SECONDS) -> None:
    scene = wd.load_scene(path)
    sim = wd.Simulation(wd.build_model(scene), scene)
    st, ms = sim.mech_setup, sim.state.mech
    fragment(sim)
    r_s = scene.strands.r_s
    print(f"pieces {ms.component.max() + 1} -")
    ms.x[:, 2] += DROP
    t0, t_end = time.perf_counter(), ms.t_seconds + seconds
    per = int(round(0.1 / st.dt))
    while ms.t_seconds < t_end - 1e-9:
        mech.macro_step(st, ms, 0.0, per)
        speed = np.sqrt(np.sum(ms.v**2, axis=1))
        pen, raw = penetration(st, ms)
        print(f"t {ms.t_seconds:.2f} s: max_speed {speed.max():.3e} m/s, p99_speed {np.percentile(speed, 99):.2e} m/s, "
              f"max_penetration_over_r_s {pen / r_s:.3f} (raw {raw / r_s:.3f}), z_min {ms.x[:, 2].min():.4f} m, "
              f"pieces {ms.component.max() + 1}", flush=True)
    speed = np.sqrt(np.sum(ms.v**2, axis=1))
    print(f"max_speed {speed.max():.3e} m/s")
    print(f"p99_speed {np.percentile(speed, 99):.3e} m/s")
    pen, raw = penetration(st, ms)
    print(f"max_penetration_over_r_s {pen / r_s:.3f} -")
    print(f"max_raw_overlap_over_r_s {raw / r_s:.3f} -")
    print(f"z_min {ms.x[:, 2].min():.4f} m")
    print(f"broken_connections {np.count_nonzero(~ms.edge_ok[:, 0])} -")
    print(f"seconds {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main(*sys.argv[1:2], *map(float, sys.argv[2:3]))
