"""Contact kernels (wooddecay.sim.contact) against their numpy references on a split log.

The log: strands along z on a hexagonal grid of spacing 0.012 m inside a 0.3 m diameter disc,
segments of 0.04 m (~50k), particles jittered by 1 mm, capsule radius 0.006 m, cut into 10 radial
wedges x 5 axial pieces (50 components); a ground plane and a cylinder collider. Prints
``name value unit`` lines:
    segments / components / candidate_pairs / active_contacts
    candidate_pairs_seconds, candidate_pairs_reference_seconds, candidate_pairs_speedup
    candidate_pairs_seconds_threads_<k>  for k = 1 .. numba.config.NUMBA_NUM_THREADS
    project_contacts_seconds, project_contacts_reference_seconds, project_contacts_speedup
    project_contacts_seconds_threads_<k>, project_contacts_max_abs_diff_reference
    project_colliders_seconds, project_colliders_reference_seconds, project_colliders_speedup
    contact_velocities_seconds, contact_velocities_reference_seconds, contact_velocities_speedup
    candidate_pairs_equal_reference (1 = identical)
Each timing is the best of 5 after a warm-up call (the reference: best of 2).
"""
from __future__ import annotations


import numba
import numpy as np
from timing import best

from wooddecay.sim import contact as C

SPACING, SEG, DIAMETER, N_SEGMENTS, RADIUS, MARGIN = 0.012, 0.04, 0.3, 50_000, 0.006, 0.002
WEDGES, PIECES, K_COL, DT = 10, 5, 1e4, 0.01


def split_log(seed: int = 0):
    """(x, first_particle, radius, component) of the log of the module docstring."""
    rng = np.random.default_rng(seed)
    k = int(DIAMETER / SPACING) + 2
    i, j = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1))
    xy = np.stack([SPACING * (i + 0.5 * (j % 2)), SPACING * np.sqrt(0.75) * j], axis=-1).reshape(-1, 2)
    xy = xy[np.linalg.norm(xy, axis=1) < 0.5 * DIAMETER - 0.5 * SPACING]
    per = int(np.ceil(N_SEGMENTS / len(xy)))
    z = SEG * np.arange(per + 1)
    x = np.concatenate([np.column_stack([np.full(per + 1, a), np.full(per + 1, b), z]) for a, b in xy])
    x += rng.normal(0.0, 0.001, x.shape)
    first = (np.arange(len(xy))[:, None] * (per + 1) + np.arange(per)).ravel()
    wedge = ((np.arctan2(xy[:, 1], xy[:, 0]) + np.pi) / (2 * np.pi) * WEDGES).astype(np.int64) % WEDGES
    piece = np.minimum(np.arange(per) * PIECES // per, PIECES - 1)
    component = (wedge[:, None] * PIECES + piece[None, :]).ravel()
    return x, first, np.full(len(first), RADIUS), component


def report(name, fn, ref):
    t, t_ref = best(fn, repeat=5), best(ref, repeat=2)
    print(f"{name}_seconds {t:.5f} s")
    print(f"{name}_reference_seconds {t_ref:.5f} s")
    print(f"{name}_speedup {t_ref / t:.1f} x")


def main() -> None:
    x, fp, radius, comp = split_log()
    P = len(x)
    print(f"segments {len(fp)} -")
    print(f"components {len(np.unique(comp))} -")
    pairs = C.candidate_pairs(x, fp, radius, comp, MARGIN)
    print(f"candidate_pairs {len(pairs)} -")
    report("candidate_pairs", lambda: C.candidate_pairs(x, fp, radius, comp, MARGIN),
           lambda: C.candidate_pairs_reference(x, fp, radius, comp, MARGIN))
    for k in range(1, numba.config.NUMBA_NUM_THREADS + 1):
        numba.set_num_threads(k)
        t = best(lambda: C.candidate_pairs(x, fp, radius, comp, MARGIN), repeat=5)
        print(f"candidate_pairs_seconds_threads_{k} {t:.5f} s")
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)

    w = np.ones(P)
    w[::50] = 0.0
    force = np.zeros(P)
    n_active, _ = C.project_contacts(x.copy(), w, fp, radius, pairs, K_COL, DT, force)
    print(f"active_contacts {n_active} -")
    report("project_contacts", lambda: C.project_contacts(x.copy(), w, fp, radius, pairs, K_COL, DT, force),
           lambda: C.project_contacts_reference(x.copy(), w, fp, radius, pairs, K_COL, DT, force))
    for k in range(1, numba.config.NUMBA_NUM_THREADS + 1):
        numba.set_num_threads(k)
        t = best(lambda: C.project_contacts(x.copy(), w, fp, radius, pairs, K_COL, DT, force), repeat=5)
        print(f"project_contacts_seconds_threads_{k} {t:.5f} s")
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    x1, x2 = x.copy(), x.copy()
    C.project_contacts(x1, w, fp, radius, pairs, K_COL, DT, np.zeros(P))
    C.project_contacts_reference(x2, w, fp, radius, pairs, K_COL, DT, np.zeros(P))
    print(f"project_contacts_max_abs_diff_reference {np.abs(x1 - x2).max():.2e} m")

    colliders = np.stack([C.collider_row(C.PLANE, 0, 0, 0.01, 0, 0, 1),
                          C.collider_row(C.CYLINDER, 0.1, 0, -1, 0.1, 0, 3, 0.02)])
    prad = np.full(P, RADIUS)
    report("project_colliders", lambda: C.project_colliders(x.copy(), w, prad, colliders, K_COL, DT, force),
           lambda: C.project_colliders_reference(x.copy(), w, prad, colliders, K_COL, DT, force))

    v = np.random.default_rng(1).normal(size=(P, 3))
    touched = np.ones(len(pairs), dtype=bool)
    report("contact_velocities", lambda: C.contact_velocities(v.copy(), x, w, fp, radius, pairs, touched),
           lambda: C.contact_velocities_reference(v.copy(), x, w, fp, radius, pairs, touched))

    ok = np.array_equal(pairs, C.candidate_pairs_reference(x, fp, radius, comp, MARGIN))
    print(f"candidate_pairs_equal_reference {int(ok)} -")


if __name__ == "__main__":
    main()
