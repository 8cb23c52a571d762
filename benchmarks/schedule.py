"""The adaptive schedule against the fixed one (Algorithm 1) over a year of each scene, in one run
on the same thread count (wooddecay.studies.schedule).

    python benchmarks/schedule.py [--pairs N] [SCENE ...]   (default 3 pairs; samples/log.toml samples/tree.toml)

Runs each scene N times with the fixed and N times with the adaptive schedule, alternating, from
one settled state, and prints every run (wall time of the simulation after settling, seconds of
mechanics after settling, chunks of N_mech substeps, solves, broken REG connections) and the lines
    adaptive_speedup <v> x                      fixed wall / adaptive wall, median over the pairs
    adaptive_max_position_error <v> m           largest particle position difference at the end
    adaptive_max_shape_error <v> m              the same once each piece is moved rigidly onto the
                                                fixed run's (how differently the wood deformed)
    adaptive_broken_ratio <v> -                 adaptive / fixed broken connections (1 when both 0)
The runs of one schedule give the same bits, so only the wall times vary: the ratio is taken per
pair (both runs under the same load of this shared machine) and given with its spread. A pair
takes about 12 s on the log and 15 min on the tree.
"""
from __future__ import annotations

import argparse
import statistics

from timing import SAMPLES, spread

from wooddecay.studies.schedule import describe, pairs

#: every scene over one year (the shipped log bakes five)
YEAR = {"time.years": 1.0}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument("scenes", nargs="*", default=[str(SAMPLES / "log.toml"), str(SAMPLES / "tree.toml")])
    args = ap.parse_args(argv)
    for path in args.scenes:
        fixed, adaptive = pairs(path, args.pairs, overrides=YEAR)
        print(f"# {path}")
        for f, a in zip(fixed, adaptive):
            print(describe(f, fixed[0]))
            print(describe(a, fixed[0]))
        f, a = fixed[0], adaptive[0]
        ratio = a.broken / f.broken if f.broken else float(a.broken == 0)
        speedups = [f.wall / a.wall for f, a in zip(fixed, adaptive)]
        print(f"adaptive_speedup {statistics.median(speedups):.2f} x {spread(speedups)}")
        print(f"adaptive_max_position_error {a.error(f):.3e} m")
        print(f"adaptive_max_shape_error {a.shape_error(f):.3e} m")
        print(f"adaptive_broken_ratio {ratio:.3f} -", flush=True)


if __name__ == "__main__":
    main()
