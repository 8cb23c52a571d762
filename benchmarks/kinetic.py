"""Kinetic Delaunay sweep of one branch (woodstock §8.1).

A synthetic branch: ``n`` sites (default 500) uniform in the unit disk, carried over ``S`` sections
(default 50, d_t = 0..1) by a random smooth motion (a few low-frequency sinusoids in d_t per site,
amplitude about two mean site spacings), sampled at the sections (piecewise linear in between, as in
§8.1). Prints ``name value unit`` lines:
    kinetic_sites / kinetic_sections   the problem size
    kinetic_events <n>                 all events (sections, flips, hull changes, inserts, deletes)
    kinetic_flips / kinetic_hull       in-circle flips and convex-hull flips
    kinetic_seconds <v> s              wall time of ``sweep`` (best of 2 after a small warm-up)
    kinetic_us_per_event               seconds per event
Usage: python benchmarks/kinetic.py [n] [S]
"""
from __future__ import annotations

import sys
import time

import numpy as np

from wooddecay.meshlets.kinetic import sweep


def smooth_branch(n: int, S: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    r = np.sqrt(rng.uniform(0, 1, n))
    th = rng.uniform(0, 2 * np.pi, n)
    base = np.stack([r * np.cos(th), r * np.sin(th)], axis=1)
    spacing = np.sqrt(np.pi / n)
    d = np.linspace(0.0, 1.0, S)
    P = np.repeat(base[None], S, axis=0)
    for f in (1.0, 2.0, 3.0):
        amp = rng.normal(0.0, 2.0 * spacing / f, (n, 2))
        ph = rng.uniform(0, 2 * np.pi, (n, 2))
        P += amp[None] * np.sin(2 * np.pi * f * d[:, None, None] + ph[None])
    return d, P


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 500
    S = int(sys.argv[2]) if len(sys.argv) > 2 else 50
    d, P = smooth_branch(n, S)
    sweep(*smooth_branch(30, 4))                     # numba warm-up (cached kernels)
    best, res = np.inf, None
    for _ in range(2):
        t0 = time.perf_counter()
        res = sweep(d, P)
        best = min(best, time.perf_counter() - t0)
    print(f"kinetic_sites {n} -")
    print(f"kinetic_sections {S} -")
    print(f"kinetic_events {res.n_events}")
    for k in ("flips", "hull", "inserts", "deletes"):
        print(f"kinetic_{k} {res.counts[k]} -")
    print(f"kinetic_seconds {best:.3f} s")
    print(f"kinetic_us_per_event {1e6 * best / res.n_events:.1f} us")


if __name__ == "__main__":
    main()
