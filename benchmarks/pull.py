"""Pull test (woodstock Fig. 17) on samples/tree.toml: the smallest horizontal pull that
breaks the branch through node b1_2, healthy and decayed, each found by bisection on a log scale
(:mod:`wooddecay.studies.pull`: load, cases, break criterion, bisection; docs/decisions.md "Mechanics").

First the branch cut out of the tree at the tree's resolution and clamped at its fork (the
specimen: cheap), whose brackets, widened by ``--widen``, start the bisection in the whole tree.
Prints ``name value unit`` lines:
    specimen_elements, specimen_threshold_<case>, specimen_ratio, specimen_seconds
    elements, loaded_elements                         the tree
    probe <case> <F> N broke|held <reason> t <s> dmax <m> failures <k> last_failure <s> wall <s>
    pull_threshold_<case>       geometric mean of the final bracket (N)
    pull_bracket_<case>_lo/hi   the bracket: hi broke, lo held (N)
    pull_ratio                  healthy / decayed threshold
    pull_ratio_min              healthy lo / decayed hi (the smallest ratio the brackets allow)
    pull_margin_<case>_held_displacement   largest displacement of the lo probe / break displacement
    pull_margin_<case>_held_quiet          loaded seconds at the end of the lo probe without a failure
    pull_margin_<case>_break_time          break time of the hi probe / loaded time
    settled_<case>              mechanics seconds the case settled (to pull.SETTLE_TOL)
    settle_seconds, probe_seconds, seconds             wall time
Usage: python benchmarks/pull.py [--specimen-only] [--rel 0.2] [--widen 1.25] [--decay 0.5]
                                 [--region all|branch] [--brackets H_LO H_HI D_LO D_HI]
``--decay`` is H_c = H_l of the decayed case; ``--region branch`` lowers it in the tree only in
the branch and its junction (:func:`wooddecay.studies.pull.branch_elements`) instead of all the wood;
``--brackets`` starts the tree's bisections there and skips the specimen.
The whole tree costs about 0.035 s per mechanics substep on two idle cores, 0.07-0.09 s while
it fails (settling to pull.SETTLE_TOL, about 0.25 s healthy and 0.65 s decayed, and probes of up
to 0.3 s at dt_mech 1e-4 s): 33 minutes on one thread with ``--brackets``.
"""
from __future__ import annotations

import argparse
import time

import wooddecay as wd
from wooddecay.studies import pull


def _log(prefix: str):
    def log(case: str, p: pull.Probe) -> None:
        print(f"{prefix}probe {case} {p.force:.4g} N {'broke' if p.broke else 'held'} {p.reason or '-'} "
              f"t {p.seconds:.3f} s dmax {p.max_displacement:.4f} m failures {p.failures} last_failure "
              f"{'-' if p.t_last_failure is None else f'{p.t_last_failure:.3f}'} s wall {p.wall:.1f} s",
              flush=True)
    return log


def _report(prefix: str, st: pull.PullStudy) -> None:
    for th in (st.healthy, st.decayed):
        print(f"{prefix}threshold_{th.case} {th.force:.4g} N")
        print(f"{prefix}bracket_{th.case}_lo {th.lo:.4g} N")
        print(f"{prefix}bracket_{th.case}_hi {th.hi:.4g} N")
    print(f"{prefix}ratio {st.ratio:.3g} 1")
    print(f"{prefix}ratio_min {st.ratio_min:.3g} 1")
    for th in (st.healthy, st.decayed):
        held = th.at(th.lo)
        quiet = st.seconds - (held.t_last_failure or 0.0)
        print(f"{prefix}margin_{th.case}_held_displacement {held.max_displacement / st.displacement:.3f} 1")
        print(f"{prefix}margin_{th.case}_held_quiet {quiet:.3f} s")
        print(f"{prefix}margin_{th.case}_break_time {th.at(th.hi).t_break / st.seconds:.3f} 1")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--specimen-only", action="store_true", help="only the branch cut out of the tree")
    ap.add_argument("--rel", type=float, default=0.2, help="bracket precision in the tree (hi / lo <= 1 + rel)")
    ap.add_argument("--widen", type=float, default=1.25, help="widen the specimen's brackets by this factor")
    ap.add_argument("--decay", type=float, default=pull.DECAY, help="H_c = H_l of the decayed case")
    ap.add_argument("--region", choices=("all", "branch"), default="all",
                    help="decay all the wood of the tree, or only the branch and its junction")
    ap.add_argument("--brackets", type=float, nargs=4, metavar=("H_LO", "H_HI", "D_LO", "D_HI"),
                    help="start the tree's bisections from these brackets (N) and skip the specimen")
    args = ap.parse_args()
    t0 = time.perf_counter()
    if args.brackets is None:
        spec_scene = pull.specimen_scene(quality=None)  # the tree's own resolution
        spec = pull.study(spec_scene, rel=0.1, decay=args.decay, log=_log("specimen_"))
        print(f"specimen_elements {spec.n_elements} 1")
        _report("specimen_", spec)
        print(f"specimen_seconds {time.perf_counter() - t0:.1f} s", flush=True)
        if args.specimen_only:
            return
        w = args.widen
        brackets = (spec.healthy.lo / w, spec.healthy.hi * w, spec.decayed.lo / w, spec.decayed.hi * w)
    else:
        brackets = args.brackets
    t1 = time.perf_counter()
    scene = pull.pull_scene()
    model = wd.build_model(scene)
    region = pull.branch_elements(model) if args.region == "branch" else None
    st = pull.study(scene, model, healthy=brackets[:2], decayed=brackets[2:], rel=args.rel, decay=args.decay,
                    region=region, log=_log(""))
    print(f"elements {st.n_elements} 1")
    print(f"loaded_elements {st.loaded_elements} 1")
    print(f"decayed_elements {model.n_elements if region is None else int(region.sum())} 1")
    _report("pull_", st)
    print(f"settled_healthy {st.settled[0]:.2f} s")
    print(f"settled_decayed {st.settled[1]:.2f} s")
    print(f"settle_seconds {st.settle_seconds:.1f} s")
    print(f"probe_seconds {sum(p.wall for th in (st.healthy, st.decayed) for p in th.probes):.1f} s")
    print(f"seconds {time.perf_counter() - t1:.1f} s (tree) {time.perf_counter() - t0:.1f} s (all)")


if __name__ == "__main__":
    main()
