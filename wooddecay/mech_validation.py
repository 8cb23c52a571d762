"""Single-strand accuracy studies of the rod solver (SPEC §7 "Mechanics"; used by tests,
``benchmarks/cantilever.py`` and ``wooddecay chart mechanics``).

The strand comes from the real pipeline: a two-node skeleton whose circular profile holds
exactly one strand (radius 1.3 r_s), anchored at its root, so the first element is clamped.
The free length L runs from the clamped element's far particle to the tip.

* :func:`cantilever`: gravity, horizontal strand; tip deflection against q L^4 / (8 E I).
* :func:`tip_moment`: no gravity, a moment M about the world y axis at the tip element; with
  M = 2 pi E I / L the strand curls into a full circle (closure gap |tip - clamp| / L).
* :func:`buckles`: a vertical strand under a tip load P (plus a lateral imperfection of 1e-3 P);
  fixed-free Euler buckling load pi^2 E I / (2 L)^2.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from .scene import parse_scene

SCENE = """
[scene]
name = "strand"
seed = 3
[[skeleton.node]]
id = "root"
position = [0.0, 0.0, 0.0]
anchored = true
profile = {{ kind = "circle", radius = {R} }}
[[skeleton.node]]
id = "tip"
position = [{x1}, {y1}, {z1}]
parent = "root"
profile = {{ kind = "circle", radius = {R} }}
[strands]
r_s = {r_s}
rod_length = {rod}
[bsp]
cells = 0
[mechanics]
E = {E}
G = {G}
rho_dry = {rho}
ground = false
gravity = [0.0, 0.0, {g}]
damping = {damping}
dt_mech = {dt}
iterations = {iterations}
"""


@dataclass
class Strand:
    """A single clamped strand ready to simulate."""

    model: object
    setup: object
    ms: object
    clamp: np.ndarray  # the clamped end of the free length
    length: float  # free length L
    EI: float
    q: float  # weight per length (N/m) of the free part


def strand(length: float = 0.5, n: int = 20, direction=(1.0, 0.0, 0.0), r_s: float = 0.006,
           E: float = 1e9, G: float = 4e8, rho: float = 450.0, g: float = -9.81, damping: float = 20.0,
           dt: float = 0.01, iterations: int = 2) -> Strand:
    """Build the strand of ``n`` free elements over the free length ``length`` (module doc)."""
    from . import build_model
    from .sim import mechanics

    rod = length / n
    total = length + rod  # plus the clamped element
    end = total * np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    text = SCENE.format(R=1.3 * r_s, x1=end[0], y1=end[1], z1=end[2], r_s=r_s, rod=rod, E=E, G=G, rho=rho,
                        g=g, damping=damping, dt=dt, iterations=iterations)
    scene = parse_scene(text)
    model = build_model(scene)
    if model.n_strands != 1:
        raise RuntimeError(f"expected one strand, got {model.n_strands}")
    setup = mechanics.prepare(model, scene)
    ms = mechanics.initial_state(model, setup)
    M = np.full(model.n_elements, scene.moisture.M_init)
    mechanics.set_masses(setup, ms, M)
    ms.limit_elem[:] = np.inf  # no failure in accuracy studies
    ms.limit_edge[:] = np.inf
    fixed = np.flatnonzero(setup.anchored_p)
    clamp = model.particles[fixed.max()]
    free = ~model.anchored
    q = float(np.sum(setup.dry_mass[free] * (1 + M[free])) * abs(g) / np.sum(model.rest_length[free]))
    r = model.radius[0]
    return Strand(model=model, setup=setup, ms=ms, clamp=clamp,
                  length=float(np.linalg.norm(model.particles[-1] - clamp)), EI=E * np.pi * r**4 / 4, q=q)


def settle(s: Strand, seconds: float, substeps: int = 1, force=None) -> float:
    """Run ``seconds`` of simulated time, each step of ``setup.dt`` split into ``substeps``;
    returns the wall time."""
    from .sim import mechanics

    dt = s.setup.dt / substeps
    f = np.zeros((s.setup.n_particles, 3)) if force is None else force
    steps = int(round(seconds / dt))
    t0 = time.perf_counter()
    for _ in range(steps):
        mechanics.substep(s.setup, s.ms, dt, f)
    return time.perf_counter() - t0


def cantilever(length=0.5, n=20, dt=0.001, substeps=1, iterations=10, seconds=1.5, damping=20.0) -> dict:
    """Tip deflection under gravity against q L^4 / (8 E I); error and wall time."""
    s = strand(length=length, n=n, dt=dt, iterations=iterations, damping=damping)
    wall = settle(s, seconds, substeps)
    deflection = float(s.model.particles[-1, 2] - s.ms.x[-1, 2])
    analytic = s.q * s.length**4 / (8 * s.EI)
    return {"deflection": deflection, "analytic": analytic, "error": abs(deflection / analytic - 1),
            "seconds": wall, "dt": dt, "substeps": substeps, "iterations": iterations, "n_elements": n}


def tip_moment(length=0.5, n=40, dt=0.001, iterations=20, seconds=3.0, damping=20.0) -> dict:
    """Closure gap of the strand under the tip moment 2 pi E I / L (about +y)."""
    s = strand(length=length, n=n, g=0.0, dt=dt, iterations=iterations, damping=damping)
    torque = np.zeros((s.setup.n_elements, 3))
    torque[-1, 1] = -2 * np.pi * s.EI / s.length  # curls the tip upwards (+z) for a strand along +x
    s.setup = replace(s.setup, torque=torque)
    wall = settle(s, seconds)
    gap = float(np.linalg.norm(s.ms.x[-1] - s.clamp))
    return {"gap": gap, "gap_over_L": gap / s.length, "seconds": wall}


def buckles(load_ratio: float, length=0.5, n=20, dt=0.001, iterations=20, seconds=2.0, damping=5.0) -> dict:
    """Vertical clamped strand under a downward tip load ``load_ratio`` * pi^2 E I / (2 L)^2 and
    a lateral imperfection 1e-3 of it; returns the lateral tip deflection over L."""
    s = strand(length=length, n=n, direction=(0.0, 0.0, 1.0), g=0.0, dt=dt, iterations=iterations,
               damping=damping)
    P = load_ratio * np.pi**2 * s.EI / (2 * s.length) ** 2
    f = np.zeros((s.setup.n_particles, 3))
    f[-1] = (1e-3 * P, 0.0, -P)
    settle(s, seconds, force=f)
    return {"lateral_over_L": float(np.hypot(*(s.ms.x[-1, :2] - s.clamp[:2])) / s.length), "P": P}
