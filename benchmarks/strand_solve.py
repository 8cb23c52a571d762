"""Stage 1 along the strands: the direct solver (wooddecay.sim.strand_solve) against one
Gauss-Seidel sweep of the rod kernels and against its numpy reference, on one scene, in one run.

Prints ``name value unit`` lines (medians of 15 calls with their spread; samples/log.toml unless a
scene is given):
    strand_direct_ms            one direct solve of every strand
    strand_gauss_seidel_ms      one red-black sweep of stretch-shear and bend-twist
    strand_direct_over_gauss_seidel   the cost ratio
    strand_reference_ms         the numpy reference (one call)
    substep_ms_<solver>         a whole mechanics substep with each strand solver (``auto``
                                solves directly only the strands no REG edge binds: none here)
    stage1_plan_ms              the auto plan with half the REG flags and 5% of the elements
                                failed (redone whenever a failure flag changes), and its runs
Usage: python benchmarks/strand_solve.py [SCENE]
"""
from __future__ import annotations

import statistics
import sys
from dataclasses import replace

import numpy as np
from timing import SAMPLES, spread, times

import wooddecay as wd
from wooddecay.sim import mechanics, strand_solve
from wooddecay.sim.state import initial_state


def main(path: str = str(SAMPLES / "log.toml")) -> None:
    model = wd.build_model(wd.load_scene(path))
    state = initial_state(model, rods=True)
    setup, ms = model.mech, state.mech
    mechanics.set_masses(setup, ms, np.full(model.n_elements, 0.5))
    kb, kt = mechanics.joint_stiffness(setup, ms)
    lam = mechanics.multipliers(setup)

    def direct(kernel=strand_solve.solve_strands):
        kernel(setup.strand_offsets[:-1], setup.strand_offsets[1:], setup.joint_of, setup.fp, ms.x, ms.q, ms.w_p,
               ms.w_q, ms.rest_length, setup.k_stretch, setup.k_shear, ms.element_ok, setup.joint_rest,
               setup.joint_length, kb, kt, lam.s, lam.sh, lam.j, setup.dt)

    gs = replace(setup, strand_solver="gauss-seidel")
    plan = mechanics.stage1_plan(gs, ms)

    def gauss_seidel():
        mechanics.strand_stage(gs, ms, (kb, kt), plan, lam, setup.dt)

    print(f"elements {model.n_elements} -")
    t_d, t_g = times(direct, 15), times(gauss_seidel, 15)
    print(f"strand_direct_ms {1e3 * statistics.median(t_d):.3f} ms {spread([1e3 * t for t in t_d])}")
    print(f"strand_gauss_seidel_ms {1e3 * statistics.median(t_g):.3f} ms {spread([1e3 * t for t in t_g])}")
    print(f"strand_direct_over_gauss_seidel {statistics.median(t_d) / statistics.median(t_g):.1f} x")
    t_r = times(lambda: direct(strand_solve.solve_strands_reference), 1)[0]
    print(f"strand_reference_ms {1e3 * t_r:.1f} ms")
    for solver in ("gauss-seidel", "auto", "direct"):
        s = replace(setup, strand_solver=solver)
        t = times(lambda: mechanics._substep(s, ms, s.dt), 15)
        print(f"substep_ms_{solver} {1e3 * statistics.median(t):.3f} ms {spread([1e3 * x for x in t])}")
    rng = np.random.default_rng(0)
    ms.edge_ok[rng.random(ms.edge_ok.shape[0]) < 0.5] = False
    ms.element_ok[rng.random(len(ms.element_ok)) < 0.05] = False
    auto = replace(setup, strand_solver="auto")
    t = times(lambda: mechanics.stage1_plan(auto, ms), 15)
    print(f"stage1_plan_ms {1e3 * statistics.median(t):.3f} ms {spread([1e3 * x for x in t])} "
          f"({len(mechanics.stage1_plan(auto, ms).lo)} direct runs)")


if __name__ == "__main__":
    main(*sys.argv[1:])
