"""The adaptive schedule against the fixed one (Algorithm 1) over a year of each scene, in one run
on the same thread count (wooddecay.studies.schedule).

    python benchmarks/schedule.py [SCENE ...]      (default samples/log.toml samples/tree.toml)

Prints per scene both runs, from one settled state (wall time of the simulation after settling,
seconds of mechanics after settling,
chunks of N_mech substeps, solves, broken REG connections) and the lines
    adaptive_speedup <v> x                      fixed wall / adaptive wall
    adaptive_max_position_error <v> m           largest particle position difference at the end
    adaptive_broken_ratio <v> -                 adaptive / fixed broken connections (1 when both 0)
Wall times are single runs of minutes each; the machine's noise is about 30% (benchmarks/step.py
reports it), so read a speedup to that precision.
"""
from __future__ import annotations

import sys

from timing import SAMPLES

from wooddecay.studies.schedule import compare, describe

#: every scene over one year (the shipped log bakes five)
YEAR = {"time.years": 1.0}


def main(paths: list[str]) -> None:
    for path in paths or [str(SAMPLES / "log.toml"), str(SAMPLES / "tree.toml")]:
        fixed, (adaptive,) = compare(path, factors=(1.0,), overrides=YEAR)
        print(f"# {path}")
        for r in (fixed, adaptive):
            print(describe(r, fixed))
        ratio = adaptive.broken / fixed.broken if fixed.broken else float(adaptive.broken == 0)
        print(f"adaptive_speedup {fixed.wall / adaptive.wall:.2f} x")
        print(f"adaptive_max_position_error {adaptive.error(fixed):.3e} m")
        print(f"adaptive_broken_ratio {ratio:.3f} -", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
