"""PyElastica reference run: a wooden cantilever sagging under its own weight.

A straight Cosserat rod of ``n_elements`` elements, clamped at x = 0 and lying along +x (normal
+z), is loaded by gravity along -z and settles, under viscous damping, to static equilibrium. Its
tip deflection is compared with the Euler-Bernoulli cantilever under a uniform load
q = rho pi r^2 g: w = q L^4 / (8 E I), I = pi r^4 / 4, i.e. rho g L^4 / (2 E r^2) (3.83 mm for the
defaults: a 0.5 m, 12 mm thick wooden rod). Timoshenko shear adds rho g L^2 / (2 alpha G) to
that, 0.04% here, and is ignored.

PyElastica (``pip install pyelastica``, the ``elastica`` module) is optional and imported lazily.

Modelling notes
---------------
* ``CosseratRod.straight_rod`` takes ``youngs_modulus`` and, as a keyword, ``shear_modulus``;
  without it PyElastica assumes Poisson's ratio 0.5 (G = E/3). We pass ``G`` explicitly. It
  scales the shear stiffness by alpha = 27/28 (Timoshenko correction) and the twist by G.
* The mass is ``density * pi r^2 * element length`` lumped half on each node, so gravity acts on
  nodes; the clamped node's share goes into the support.
* The clamp. ``OneEndFixedBC`` fixes node 0 and the director of element 0. Curvature lives on
  the Voronoi nodes between elements, so the first bending hinge sits at the end of element 0
  and the curvature of the half element next to the wall is lost: a rod laid from x = 0 behaves
  as if clamped at x = dx/2, and its tip deflection comes out short by about 2/n (measured,
  settled: 19.0% at n = 10, 9.7% at n = 20, 4.9% at n = 40). We therefore let the clamped
  element straddle the wall: the rod starts at x = -dx/2, has length L + dx/2 and element
  length dx = L / (n - 1/2), so the free span beyond the clamp is exactly L and the first
  hinge's Voronoi cell is [0, dx]. The error then converges at second order (settled: 0.52% at
  n = 10, 0.10% at n = 20, 0.002% at n = 40).
* The comparison is linear beam theory: it holds while the sag is small against L (a soft rod
  with a sag of L/2 comes out 17% short, as it should).

Time step, damping and run length (the least wall time that still settles)
-------------------------------------------------------------------------
* ``dt``: PositionVerlet is stable for dt < 2 / omega_max. For this stiff, thin rod the
  stiffest mode is not the axial wave (limit dx / sqrt(E / rho), 17 us at n = 20) but the
  rotation of one element against its shear and bending springs: rotary inertia rho I dx,
  shear couple alpha G A dx, bending springs E I / dx on either side, so
  omega_max^2 = 4 alpha G / (rho r^2) + 4 E / (rho dx^2) (:func:`stable_dt`). That predicts
  the measured limit to within 5% at n = 10, 20, 40 (6.4, 6.1, 5.1 us for the defaults, runs
  at 0.95 of it stay stable, also for three other rods tried). The default is 0.9 of it,
  5.4 us at n = 20; the rule of thumb dt = 1e-5..1e-4 * L / n (0.25..2.5 us here) would cost
  2-20 times the steps. The shear term dominates, so the step count grows only slowly with n.
* ``damping``: ``AnalyticalLinearDamper`` with a uniform constant gamma (1/s), which scales
  velocities and angular velocities by exp(-gamma dt) each step (unconditionally stable).
  Near-critical damping of the first bending mode settles fastest: with
  omega_1 = 1.8751^2 sqrt(E I / (rho A L^4)) (63 rad/s, 10 Hz, for the defaults) the higher,
  under-damped modes all decay at gamma / 2 and the fundamental barely overshoots. Scanning
  gamma / omega_1 in {1.4, 1.7, 2.0, 2.3, 2.6} (n = 10, 20, 40), the time after which the
  tip stays within 0.1% of its final value and meets the 10% window criterion below is
  omega_1 t = 10.3, 9.3, 9.7, 12.8, 15.4: the default is gamma = 1.7 omega_1 (107 /s).
* ``final_time``: 10 / omega_1 (0.16 s, 29130 steps, about 0.6 s of wall time at n = 20), a
  little past the 9.3 found. Settled means that the tip deflection changes by less than 0.1%
  over the last 10% of the steps; the run reports that change as ``drift`` (0.06% with the
  defaults) and warns when it exceeds 0.1%.
"""
from __future__ import annotations

import contextlib
import io
import math
import time
import warnings
from functools import cache

import numpy as np

#: the settling criterion: relative change of the tip deflection over the last 10% of the run
SETTLE_TOL = 1e-3
#: fraction of the Verlet stability limit used as the default step
DT_SAFETY = 0.9
#: default uniform damping constant in units of omega_1 (2 would be critical)
DAMPING_FACTOR = 1.7
#: default run length in units of 1 / omega_1 (see the module docstring)
OMEGA_T = 10.0
#: PyElastica's Timoshenko shear coefficient
ALPHA_C = 27.0 / 28.0
#: (beta_1 L)^2 of the first cantilever bending mode
BETA1_SQ = 1.8751040687**2


def load_elastica():
    """The PyElastica package, or an ImportError that says how to install it."""
    try:
        import elastica
    except ImportError as err:  # pragma: no cover - depends on the environment
        raise ImportError(
            "elastica_cantilever needs PyElastica: pip install pyelastica"
        ) from err
    return elastica


def first_mode(length: float, radius: float, E: float, rho: float) -> float:
    """Angular frequency (rad/s) of the first bending mode of a round cantilever."""
    return BETA1_SQ / length**2 * math.sqrt(E * radius**2 / (4.0 * rho))


def stable_dt(dx: float, radius: float, E: float, G: float, rho: float) -> float:
    """PositionVerlet stability limit (s) of a PyElastica rod with element length ``dx``."""
    omega_sq = 4.0 * ALPHA_C * G / (rho * radius**2) + 4.0 * E / (rho * dx**2)
    return min(2.0 / math.sqrt(omega_sq), dx / math.sqrt(E / rho))


def _simulator(elastica, n, dx, radius, E, G, rho, g, dt, damping, tip_force=0.0):
    class Cantilever(
        elastica.BaseSystemCollection, elastica.Constraints, elastica.Forcing, elastica.Damping
    ):
        pass

    sim = Cantilever()
    rod = elastica.CosseratRod.straight_rod(
        n,
        np.array([-0.5 * dx, 0.0, 0.0]),  # the clamped element straddles the wall at x = 0
        np.array([1.0, 0.0, 0.0]),
        np.array([0.0, 0.0, 1.0]),
        n * dx,
        radius,
        rho,
        youngs_modulus=E,
        shear_modulus=G,
    )
    sim.append(rod)
    sim.constrain(rod).using(
        elastica.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
    )
    sim.add_forcing_to(rod).using(elastica.GravityForces, acc_gravity=np.array([0.0, 0.0, -g]))
    if tip_force:
        sim.add_forcing_to(rod).using(elastica.EndpointForces, np.zeros(3), np.array([0.0, 0.0, -tip_force]),
                                      ramp_up_time=dt)
    sim.dampen(rod).using(
        elastica.AnalyticalLinearDamper, uniform_damping_constant=damping, time_step=dt
    )
    sim.finalize()
    return sim, rod


def _integrate(sim, t0: float, dt: float, steps: int) -> float:
    from elastica.timestepper import integrate
    from elastica.timestepper.symplectic_steppers import PositionVerlet

    with contextlib.redirect_stdout(io.StringIO()):  # integrate() prints the final time
        return integrate(
            PositionVerlet(), sim, steps * dt, n_steps=steps, restart_time=t0, progress_bar=False
        )


@cache
def _warm_up() -> None:
    """Run a throwaway rod for one step so numba compilation stays out of the timing."""
    elastica = load_elastica()
    sim, _ = _simulator(elastica, 4, 0.1, 0.01, 1e6, 4e5, 1000.0, 9.81, 1e-5, 1.0)
    _integrate(sim, 0.0, 1e-5, 1)


def elastica_cantilever(
    length: float = 0.5,
    radius: float = 0.006,
    E: float = 1e9,
    G: float = 4e8,
    rho: float = 450.0,
    g: float = 9.81,
    n_elements: int = 20,
    dt: float | None = None,
    final_time: float | None = None,
    damping: float | None = None,
    tip_force: float = 0.0,
) -> dict:
    """Static tip sag of a clamped round rod under gravity and a tip force ``tip_force`` (N,
    downwards; PyElastica's EndpointForces) in PyElastica, against beam theory.

    Units are SI; ``G`` is passed to PyElastica as ``shear_modulus``. ``dt`` defaults to 0.9 of
    the PositionVerlet limit (:func:`stable_dt`), ``damping`` (uniform, 1/s) to 1.7 omega_1
    (near-critical for the first bending mode, :func:`first_mode`) and ``final_time`` to
    10 / omega_1; the module docstring gives the reasons and the clamp offset that makes the
    free span exactly ``length``.

    Returns ``deflection`` (|tip z| at the end, m), ``analytic`` (q L^4 / (8 E I) + P L^3 / (3 E I), m),
    ``error`` (|deflection / analytic - 1|), ``seconds`` (wall time of the integration only),
    ``steps``, ``n_elements`` and ``drift`` (relative change of the deflection over the last
    10% of the steps; a warning is raised above 0.1%).
    """
    if n_elements < 2:
        raise ValueError("n_elements must be at least 2")
    elastica = load_elastica()
    n = int(n_elements)
    dx = length / (n - 0.5)
    omega_1 = first_mode(length, radius, E, rho)
    if dt is None:
        dt = DT_SAFETY * stable_dt(dx, radius, E, G, rho)
    if damping is None:
        damping = DAMPING_FACTOR * omega_1
    if final_time is None:
        final_time = OMEGA_T / omega_1
    steps = max(10, math.ceil(final_time / dt))
    tail = max(1, steps // 10)

    _warm_up()
    sim, rod = _simulator(elastica, n, dx, radius, E, G, rho, g, dt, damping, tip_force)
    start = time.perf_counter()
    t = _integrate(sim, 0.0, dt, steps - tail)
    before = -float(rod.position_collection[2, -1])
    _integrate(sim, t, dt, tail)
    seconds = time.perf_counter() - start

    deflection = -float(rod.position_collection[2, -1])
    if not np.all(np.isfinite(rod.position_collection)):
        raise FloatingPointError(f"PyElastica run blew up (dt = {dt:.3g} s too large?)")
    drift = abs(deflection - before) / abs(deflection)
    if drift > SETTLE_TOL:
        warnings.warn(
            f"tip not settled: deflection changed {drift:.2%} over the last 10% of the run",
            RuntimeWarning,
            stacklevel=2,
        )
    q = rho * math.pi * radius**2 * g  # weight per length
    inertia = math.pi * radius**4 / 4.0
    analytic = q * length**4 / (8.0 * E * inertia) + tip_force * length**3 / (3.0 * E * inertia)
    return {
        "deflection": abs(deflection),
        "analytic": analytic,
        "error": abs(abs(deflection) / analytic - 1.0),
        "seconds": seconds,
        "steps": steps,
        "n_elements": n,
        "drift": drift,
    }
