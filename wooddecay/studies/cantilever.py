"""Single-strand accuracy studies of the rod solver (docs/model.md §7 "Mechanics"; used by tests,
``benchmarks/cantilever.py`` and ``wooddecay chart mechanics``).

The strand comes from the real pipeline: a two-node skeleton whose circular profile holds
exactly one strand (radius 1.3 r_s), anchored at its root with the clamp plane one element deep
(``[mechanics] clamp_depth``). The free length L runs from the particle on that plane to the tip.

* :func:`cantilever`: gravity, horizontal strand; tip deflection against q L^4 / (8 E I).
* :func:`tip_moment`: no gravity, a moment M about the world y axis at the tip element; with
  M = 2 pi E I / L the strand curls into a full circle of radius L / (2 pi) (closure gap
  |tip - clamp| / L, least-squares circle fit).
* :func:`buckles`: a vertical strand under a tip load P (plus a lateral imperfection of 1e-3 P);
  fixed-free Euler buckling load pi^2 E I / (2 L)^2.
* :func:`sweep_case`: the gravity or tip-loaded cantilever of any slenderness L / r_s, modulus
  and element count at the scene's default solver settings, with the solver's own convergence
  figure (:func:`wooddecay.sim.mechanics.strain_excess`); :data:`SWEEP` spans the range the
  strands of a scene can take.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..model import build_model
from ..scene import Scene
from ..scene.schema import get_param
from ..sim import mechanics
from ..sim.state import initial_state
from . import scene_template


@dataclass
class Strand:
    """A single clamped strand ready to simulate."""

    model: object
    state: object  # SimState; the rods are ``state.mech``
    clamp: np.ndarray  # the clamped end of the free length
    length: float  # free length L
    EI: float
    q: float  # weight per length (N/m) of the free part

    @property
    def setup(self):
        return self.model.mech

    def deflection(self) -> float:
        """The tip's drop from its rest height in the strand's current state."""
        return float(self.model.particles[-1, 2] - self.ms.x[-1, 2])

    @property
    def analytic(self) -> float:
        """Beam theory's tip deflection q L^4 / (8 E I)."""
        return self.q * self.length**4 / (8 * self.EI)

    def deflection_error(self) -> float:
        """|tip deflection / (q L^4 / (8 E I)) - 1| of the strand's current state."""
        return abs(self.deflection() / self.analytic - 1)

    @property
    def ms(self):
        return self.state.mech


def strand_scene(length: float = 0.5, n: int = 20, direction=(1.0, 0.0, 0.0), r_s: float = 0.006,
                 E: float = 1e9, G: float = 4e8, rho: float = 450.0, g: float = -9.81, damping: float = 20.0,
                 dt: float = 0.01, iterations: int = 2, solver: str = "gauss-seidel") -> Scene:
    """``scenes/cantilever.toml`` as the strand of ``n`` free elements over the free length
    ``length`` along ``direction`` (module doc), with its material and solver settings."""
    rod = length / n
    total = length + rod  # plus the clamped element
    end = total * np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    profile = {"kind": "circle", "radius": 1.3 * r_s}
    nodes = [{"id": "root", "position": [0.0, 0.0, 0.0], "anchored": True, "profile": profile},
             {"id": "tip", "position": [float(c) for c in end], "parent": "root", "profile": profile}]
    return scene_template("cantilever", {
        "strands.r_s": r_s, "strands.rod_length": rod, "mechanics.E": E, "mechanics.G": G, "mechanics.rho_dry": rho,
        "mechanics.gravity": [0.0, 0.0, g], "mechanics.clamp_depth": rod, "mechanics.damping": damping,
        "mechanics.dt_mech": dt, "mechanics.iterations": iterations, "mechanics.strand_solver": solver}, nodes)


def strand(length: float = 0.5, n: int = 20, direction=(1.0, 0.0, 0.0), r_s: float = 0.006,
           E: float = 1e9, G: float = 4e8, rho: float = 450.0, g: float = -9.81, damping: float = 20.0,
           dt: float = 0.01, iterations: int = 2, solver: str = "gauss-seidel") -> Strand:
    """Build the strand of ``n`` free elements over the free length ``length`` (module doc)."""
    scene = strand_scene(length, n, direction, r_s, E, G, rho, g, damping, dt, iterations, solver)
    model = build_model(scene)
    if model.n_strands != 1:
        raise RuntimeError(f"expected one strand, got {model.n_strands}")
    state = initial_state(model, rods=True)
    setup, ms = model.mech, state.mech
    M = np.full(model.n_elements, scene.moisture.M_init)
    mechanics.set_masses(setup, ms, M)
    ms.limit_elem[:] = np.inf  # no failure in accuracy studies
    ms.limit_edge[:] = np.inf
    fixed = np.flatnonzero(setup.anchored_p)
    clamp = model.particles[fixed.max()]
    free = ~model.anchored
    q = float(np.sum(setup.dry_mass[free] * (1 + M[free])) * abs(g) / np.sum(model.rest_length[free]))
    r = model.radius[0]
    return Strand(model=model, state=state, clamp=clamp,
                  length=float(np.linalg.norm(model.particles[-1] - clamp)), EI=E * np.pi * r**4 / 4, q=q)


def settle(s: Strand, seconds: float, substeps: int = 1, force=None) -> float:
    """Run ``seconds`` of simulated time under the particle forces ``force`` (default none), each
    step of ``setup.dt`` split into ``substeps``; returns the wall time."""
    dt = s.setup.dt / substeps
    s.ms.force = np.zeros((s.setup.n_particles, 3)) if force is None else force
    steps = int(round(seconds / dt))
    t0 = time.perf_counter()
    for _ in range(steps):
        mechanics.substep(s.model, s.state, dt)
    return time.perf_counter() - t0


def cantilever(length=0.5, n=20, dt=0.001, substeps=1, iterations=10, seconds=1.5, damping=20.0) -> dict:
    """Tip deflection under gravity against q L^4 / (8 E I); error and wall time."""
    s = strand(length=length, n=n, dt=dt, iterations=iterations, damping=damping)
    wall = settle(s, seconds, substeps)
    return {"deflection": s.deflection(), "analytic": s.analytic, "error": s.deflection_error(),
            "seconds": wall, "dt": dt, "substeps": substeps, "iterations": iterations, "n_elements": n}


def tip_moment(length=0.5, n=40, dt=1e-4, iterations=4, ramp=0.5, seconds=1.5, damping=1000.0) -> dict:
    """The strand under the tip moment M = 2 pi E I / L, a constant ("dead") world moment about
    -y that curls a strand along +x up into +z. Statically the moment is M all along the strand,
    so the curvature is M / (E I) and the strand closes into a circle of radius L / (2 pi) (the
    roll-up test of geometrically exact rods, Simo and Vu-Quoc 1986).

    A dead moment is not conservative under finite 3D rotations (Ziegler 1977; Argyris et al.
    1978): a tip that cones out of the plane gains work ~ M times the solid angle it sweeps. At M
    the planar circle is dynamically unstable, in this solver and in PyElastica alike: small
    out-of-plane perturbations grow until the strand whirls (docs/decisions.md, "Mechanics").
    The planar motion is an invariant set of the symmetric problem, so the circle is reached
    quasi-statically inside it, with no constraint: M is ramped linearly over ``ramp`` seconds,
    then held until ``seconds``, under damping ``damping`` (1/s) far above the first bending
    frequency (63 rad/s). Damping does not move the equilibrium; it slows the out-of-plane growth
    from round-off to about 12/s, which ``out_of_plane_over_L`` reports.

    Returns ``gap_over_L`` (|tip - clamp| / L); of the least-squares circle through the particles
    from the clamp to the tip (:func:`fit_circle`), ``radius_error`` (R 2 pi / L - 1),
    ``fit_rms_over_L`` (rms distance of the particles from it over L) and ``centre_error_over_L``
    (distance of its centre from clamp + L / (2 pi) e_z over L); ``out_of_plane_over_L`` (largest
    |y - y_0| / L) and the wall time ``seconds``.
    """
    s = strand(length=length, n=n, g=0.0, dt=dt, iterations=iterations, damping=damping)
    setup, torque = s.setup, s.ms.torque
    M = 2 * np.pi * s.EI / s.length
    y0 = s.ms.x[:, 1].copy()
    t0 = time.perf_counter()
    for k in range(int(round(seconds / dt))):
        torque[-1, 1] = -M * min(1.0, (k + 1) * dt / ramp)
        mechanics.substep(s.model, s.state, dt)
    wall = time.perf_counter() - t0
    free = s.ms.x[np.flatnonzero(setup.anchored_p).max():]  # clamp ... tip
    centre, radius, rms = fit_circle(free)
    R = s.length / (2 * np.pi)
    return {"gap_over_L": float(np.linalg.norm(free[-1] - s.clamp) / s.length),
            "radius_error": float(radius / R - 1), "fit_rms_over_L": rms / s.length,
            "centre_error_over_L": float(np.linalg.norm(centre - (s.clamp + (0.0, 0.0, R))) / s.length),
            "out_of_plane_over_L": float(np.abs(s.ms.x[:, 1] - y0).max() / s.length), "seconds": wall}


def fit_circle(points: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Least-squares circle through 3D points: the plane of least squares (SVD of the centred
    points), then the algebraic circle fit of Kasa (1976) in it, x^2 + y^2 + D x + E y + F = 0.
    Returns the centre, the radius and the rms distance of the points from the circle."""
    c0 = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c0)
    u, v, h = ((points - c0) @ vt.T).T
    D, E, F = np.linalg.lstsq(np.column_stack([u, v, np.ones_like(u)]), -(u**2 + v**2), rcond=None)[0]
    cu, cv = -D / 2, -E / 2
    radius = float(np.sqrt(cu**2 + cv**2 - F))
    dist = np.hypot(np.hypot(u - cu, v - cv) - radius, h)
    return c0 + cu * vt[0] + cv * vt[1], radius, float(np.sqrt(np.mean(dist**2)))


def buckles(load_ratio: float, length=0.5, n=20, dt=0.001, iterations=20, seconds=2.0, damping=5.0,
            solver="gauss-seidel") -> dict:
    """Vertical clamped strand under a downward tip load ``load_ratio`` * pi^2 E I / (2 L)^2 and
    a lateral imperfection 1e-3 of it; returns the lateral tip deflection over L."""
    s = strand(length=length, n=n, direction=(0.0, 0.0, 1.0), g=0.0, dt=dt, iterations=iterations,
               damping=damping, solver=solver)
    P = load_ratio * np.pi**2 * s.EI / (2 * s.length) ** 2
    f = np.zeros((s.setup.n_particles, 3))
    f[-1] = (1e-3 * P, 0.0, -P)
    settle(s, seconds, force=f)
    return {"lateral_over_L": float(np.hypot(*(s.ms.x[-1, :2] - s.clamp[:2])) / s.length), "P": P}


#: the scene's default mechanics step and iterations
DEFAULT_DT = float(get_param("mechanics.dt_mech").default)
DEFAULT_ITERATIONS = int(get_param("mechanics.iterations").default)
DEFAULT_SOLVER = str(get_param("mechanics.strand_solver").default)
#: (L / r_s, E in Pa, free elements) of ``benchmarks/cantilever.py --sweep``: the corners of
#: L / r_s in [20, 200], E in [1, 20] GPa and [10, 200] elements, and a middle case
SWEEP = tuple((lr, E, n) for lr in (20, 200) for E in (1e9, 2e10) for n in (10, 200)) + ((60, 5e9, 50),)
#: the sweep scales the load so that the linear tip deflection is this fraction of L: beam
#: theory, the reference, is linear (the strands' own sag ranges from 1e-5 L to 0.1 L over SWEEP)
SAG = 0.005


def sweep_case(slenderness: float, E: float, n: int, load: str = "gravity", r_s: float = 0.006,
               dt: float | None = None, iterations: int | None = None, solver: str | None = None,
               split: bool = True) -> dict:
    """The clamped horizontal strand of free length ``slenderness`` r_s, modulus ``E`` (G = 0.4 E)
    and ``n`` free elements under gravity (deflection q L^4 / (8 E I)) or a tip force
    (``load = "tip"``, P L^3 / (3 E I)), scaled to a linear deflection of SAG L, at the scene's
    default ``mechanics.dt_mech``, ``iterations`` and ``strand_solver`` unless given. Damping
    1.7 omega_1 (at most the scene's limit of 1000 / s) settles it: 12 time constants of its
    slowest mode, then chunks of 1 / omega_1 until the tip moves less than 1e-4 of its
    deflection in one (at most 200 / omega_1 in all). Under the tip force the substeps split as
    a bake's do under a [[load]] (:func:`~wooddecay.sim.mechanics.load_split`) unless ``split``
    is false.

    Returns ``error`` (deflection / analytic - 1, signed), ``strain_excess`` (the solver's
    convergence figure at the end), ``seconds`` (wall time), ``split`` and the settings."""
    dt = DEFAULT_DT if dt is None else dt
    iterations = DEFAULT_ITERATIONS if iterations is None else iterations
    solver = DEFAULT_SOLVER if solver is None else solver
    L = slenderness * r_s
    probe = strand(length=L, n=n, r_s=r_s, E=E, G=0.4 * E, g=-9.81, dt=dt, iterations=iterations)
    mu = probe.q / 9.81  # mass per length
    omega_1 = 1.8751**2 * np.sqrt(probe.EI / (mu * probe.length**4))
    gravity = load == "gravity"
    unit = mu * probe.length**4 / (8 * probe.EI) if gravity else probe.length**3 / (3 * probe.EI)
    scale = SAG * probe.length / unit  # g in m/s^2, or P in N
    damping = min(1.7 * omega_1, 1000.0)
    decay = damping / 2 if damping < 2 * omega_1 else omega_1**2 / damping  # slowest mode's rate
    s = strand(length=L, n=n, r_s=r_s, E=E, G=0.4 * E, g=-scale if gravity else 0.0, dt=dt,
               iterations=iterations, damping=damping, solver=solver)
    force = None
    if not gravity:
        force = np.zeros((s.setup.n_particles, 3))
        force[-1, 2] = -scale
    analytic = SAG * s.length
    # the bake splits the substeps under a point load as :func:`mechanics.macro_step` does
    split = mechanics.load_split(s.setup, s.ms.w_p, force) if split and not gravity else 1
    wall = settle(s, 12.0 / decay, split, force=force)
    previous, settled = float(s.model.particles[-1, 2] - s.ms.x[-1, 2]), False
    while not settled and s.ms.t_seconds < 200.0 / omega_1:
        wall += settle(s, 1.0 / omega_1, split, force=force)
        deflection = float(s.model.particles[-1, 2] - s.ms.x[-1, 2])
        settled = abs(deflection - previous) <= 1e-4 * analytic
        previous = deflection
    return {"error": deflection / analytic - 1.0, "strain_excess": mechanics.strain_excess(s.setup, s.ms),
            "seconds": wall, "simulated": s.ms.t_seconds, "settled": settled, "slenderness": slenderness, "E": E, "n": n,
            "load": load, "dt": dt, "split": split, "iterations": iterations, "solver": solver}
