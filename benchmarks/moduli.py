"""The converged bundle's homogenised moduli against the species tables (docs/model.md §4
"Species moduli"; wooddecay.studies.moduli, wooddecay.species).

Default run: a 0.6 x 0.2 x 0.2 m clear-wood specimen at r_s 9, 6 and 4.5 mm (rods 6, 4, 3 cm; the
calibration saw these three) is stretched along L, squeezed across R and T and sheared in LR,
LT and RT with every species' calibrated rods; a round branch (radius 5 cm, r_s 6 mm, never seen
by the calibration) is stretched and bent along the grain. Prints one line per species,
resolution and modulus:
    <species> r_s_mm <r> elements <n> <modulus> <v> Pa ratio <v/table>
(G_RT is not fitted: docs/limits.md, "Rolling shear"), then
    moduli_max_error <v> -        the largest |ratio - 1| of E_L, E_R, E_T, G_LR, G_LT, the branch's E_L
    measure_seconds_<r> <v> s     one specimen's six solves at r_s <r> mm (median over species)
``--fourth``: also the specimen at r_s 3 mm, rods 2 cm (about 34k elements; minutes a species).
``--species NAME``: one species. ``--calibrate``: fit the rods of the species on the three
specimens (:func:`wooddecay.studies.moduli.calibrate`) and print them as RodModuli per unit E_L,
the numbers wooddecay/species.py holds.
Usage: python benchmarks/moduli.py [--fourth] [--species NAME] [--calibrate]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from wooddecay.species import MODULI, SPECIES
from wooddecay.studies import moduli as mo

#: (r_s, rod length) of the specimens the calibration sees
RESOLUTIONS = ((0.009, 0.06), (0.006, 0.04), (0.0045, 0.03))
FOURTH = (0.003, 0.02)
#: the branch's resolution
BRANCH = (0.006, 0.04)


def calibrate(names: list[str]) -> None:
    specimens = [mo.specimen(*res) for res in RESOLUTIONS]
    for name in names:
        wood = SPECIES[name]
        t0 = time.perf_counter()
        p, got = mo.calibrate(specimens, wood.moduli())
        ratios = " ".join(f"{k} {np.mean([m[k] for m in got]) / getattr(wood, k):.3f}" for k in MODULI)
        print(f"{name} rods=RodModuli({', '.join(f'{v / wood.E_L:#.4g}' for v in p)}) mean ratios {ratios} "
              f"{time.perf_counter() - t0:.0f} s", flush=True)


def check(names: list[str], resolutions) -> None:
    worst, seconds = 0.0, {}
    for r_s, rod in resolutions:
        spec = mo.specimen(r_s, rod)
        K_parts = mo.parts(spec)
        for name in names:
            wood = SPECIES[name]
            t0 = time.perf_counter()
            got = mo.measure(spec, mo.assemble(K_parts, wood.rod_moduli()))
            seconds.setdefault(r_s, []).append(time.perf_counter() - t0)
            for k in MODULI:
                ratio = got[k] / getattr(wood, k)
                if k in mo.FITTED:
                    worst = max(worst, abs(ratio - 1.0))
                print(f"{name} r_s_mm {r_s * 1e3:g} elements {spec.model.n_elements} {k} {got[k]:.4g} Pa "
                      f"ratio {ratio:.3f}{'' if k in mo.FITTED else ' (not fitted)'}", flush=True)
    spec = mo.branch(*BRANCH)
    K_parts = mo.parts(spec)
    for name in names:
        wood = SPECIES[name]
        got = mo.along_grain(spec, mo.assemble(K_parts, wood.rod_moduli()))
        for k, v in got.items():
            worst = max(worst, abs(v / wood.E_L - 1.0))
            print(f"{name} branch r_s_mm {BRANCH[0] * 1e3:g} elements {spec.model.n_elements} {k} {v:.4g} Pa "
                  f"ratio {v / wood.E_L:.3f}", flush=True)
    print(f"moduli_max_error {worst:.3f} -")
    for r_s, s in seconds.items():
        print(f"measure_seconds_{r_s * 1e3:g} {np.median(s):.2f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fourth", action="store_true")
    ap.add_argument("--species", choices=sorted(SPECIES))
    ap.add_argument("--calibrate", action="store_true")
    args = ap.parse_args()
    names = [args.species] if args.species else list(SPECIES)
    if args.calibrate:
        calibrate(names)
    else:
        check(names, RESOLUTIONS + ((FOURTH,) if args.fourth else ()))


if __name__ == "__main__":
    main()
