"""The gravity cantilever (L = 0.5 m, r_s = 6 mm, E = 1 GPa, 20 elements) in wooddecay's XPBD
rods and in PyElastica (SPEC §7). Prints ``name value unit`` lines:
    cantilever_error, cantilever_seconds     ours at dt = 2e-4 s, 2 iterations, 1 s simulated
    pyelastica_error, pyelastica_seconds     PyElastica (wooddecay.studies.elastica), settled
    cantilever_error_dt_<dt>_it_<k>          ours over a few other settings (same 1 s)
Errors are |deflection / (q L^4 / 8 E I) - 1|; seconds are wall time of the time stepping.
"""
from __future__ import annotations

from wooddecay.studies import cantilever as mv
from wooddecay.studies.elastica import elastica_cantilever


def main() -> None:
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


if __name__ == "__main__":
    main()
