"""The gravity cantilever in wooddecay's XPBD rods and in PyElastica (docs/model.md §7).

Default run (L = 0.5 m, r_s = 6 mm, E = 1 GPa, 20 elements); prints ``name value unit`` lines:
    cantilever_error, cantilever_seconds     ours at dt = 2e-4 s, 2 iterations, 1 s simulated
    pyelastica_error, pyelastica_seconds     PyElastica (wooddecay.studies.elastica), settled
    cantilever_error_dt_<dt>_it_<k>          ours over a few other settings (same 1 s)
Errors are |deflection / (q L^4 / 8 E I) - 1|; seconds are wall time of the time stepping.

``--sweep``: every case of :data:`wooddecay.studies.cantilever.SWEEP` (L / r_s 20-200, E 1-20
GPa, 10-200 elements) at the scene's default solver settings (``strand_solver = "auto"``: a lone
strand is solved directly) and with ``mechanics.strand_solver = "gauss-seidel"``, gravity and tip
load, beside PyElastica under the same (scaled) loads; one line per case with the signed errors,
the strain excess (the solver's own convergence figure) and wall times, then
    cantilever_max_error <v> -          largest |error| at the defaults (target <= 0.03)
    cantilever_gauss_seidel_max_error <v> -   the same with Gauss-Seidel along the strands
    pyelastica_max_error <v> -          PyElastica's over the same cases
    strain_excess_min_flagged <v> -     the smallest strain excess of a case off by more than 3%
                                        (above the bake's tolerance: each such case is reported)
Usage: python benchmarks/cantilever.py [--sweep]
"""
from __future__ import annotations

import sys

import numpy as np

from wooddecay.sim.mechanics import STRAIN_EXCESS_TOLERANCE
from wooddecay.studies import cantilever as mv
from wooddecay.studies.elastica import elastica_cantilever


def default() -> None:
    mv.cantilever(dt=2e-3, iterations=1, seconds=0.01)  # compile
    ours = mv.cantilever(dt=2e-4, iterations=2, seconds=1.0)
    print(f"cantilever_error {ours['error']:.4f} 1")
    print(f"cantilever_seconds {ours['seconds']:.3f} s")
    ref = elastica_cantilever()
    print(f"pyelastica_error {ref['error']:.4f} 1")
    print(f"pyelastica_seconds {ref['seconds']:.3f} s")
    for dt, it in ((1e-3, 2), (1e-3, 10), (5e-4, 2), (1e-2, 2)):
        r = mv.cantilever(dt=dt, iterations=it, seconds=1.0)
        print(f"cantilever_error_dt_{dt:g}_it_{it} {r['error']:.4f} 1")
        print(f"cantilever_seconds_dt_{dt:g}_it_{it} {r['seconds']:.3f} s")


def sweep() -> None:
    mv.cantilever(dt=2e-3, iterations=1, seconds=0.01)  # compile
    worst = {mv.DEFAULT_SOLVER: 0.0, "gauss-seidel": 0.0}
    worst_ref, flagged = 0.0, []
    for slenderness, E, n in mv.SWEEP:
        for load in ("gravity", "tip"):
            line = f"case L/r {slenderness:g} E {E / 1e9:g} GPa n {n} {load}:"
            for solver in worst:
                r = mv.sweep_case(slenderness, E, n, load=load, solver=solver)
                line += (f" {solver} {r['error']:+.4f} excess {r['strain_excess']:.3g}"
                         f"{'' if r['settled'] else ' (not settled)'} {r['seconds']:.2f} s;")
                worst[solver] = max(worst[solver], abs(r["error"]))
                if abs(r["error"]) > 0.03:
                    flagged.append(r["strain_excess"])
            s = mv.strand(length=slenderness * 0.006, n=n, E=E, G=0.4 * E)
            mu, w = s.q / 9.81, mv.SAG * s.length
            if load == "gravity":
                g, P = w / (mu * s.length**4 / (8 * s.EI)), 0.0
            else:
                g, P = 0.0, w / (s.length**3 / (3 * s.EI))
            ref = elastica_cantilever(length=s.length, radius=0.006, E=E, G=0.4 * E,
                                      rho=mu / (np.pi * 0.006**2), g=g, n_elements=n, tip_force=P)
            worst_ref = max(worst_ref, ref["error"])
            line += f" pyelastica {ref['error']:+.4f} {ref['seconds']:.2f} s"
            print(line, flush=True)
    for solver in worst:  # fixed-free Euler buckling at 0.95 and 1.05 of pi^2 E I / (2 L)^2
        below, above = (mv.buckles(ratio, dt=mv.DEFAULT_DT, iterations=mv.DEFAULT_ITERATIONS, solver=solver)
                        for ratio in (0.95, 1.05))
        print(f"buckling_lateral_over_L_{solver} {below['lateral_over_L']:.4f} {above['lateral_over_L']:.4f} - "
              "(at 0.95 and 1.05 of the Euler load; straight below, buckled above)")
    print(f"cantilever_max_error {worst[mv.DEFAULT_SOLVER]:.4f} - (strand_solver {mv.DEFAULT_SOLVER})")
    print(f"cantilever_gauss_seidel_max_error {worst['gauss-seidel']:.4f} -")
    print(f"pyelastica_max_error {worst_ref:.4f} -")
    print(f"strain_excess_min_flagged {min(flagged, default=float('nan')):.3g} - (tolerance {STRAIN_EXCESS_TOLERANCE:g})")


if __name__ == "__main__":
    sweep() if "--sweep" in sys.argv[1:] else default()
