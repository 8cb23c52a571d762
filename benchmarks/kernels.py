"""Foundation kernels against their numpy references, timed in one run (ratios, not absolutes).

Prints ``name value unit`` lines for samples/tree.toml (or the scene given):
    reg_pairs_numba_seconds / reg_pairs_reference_seconds / reg_pairs_speedup
    transport_frames_numba_seconds / transport_frames_reference_seconds / transport_frames_speedup
    components_numba_seconds / components_reference_seconds / components_speedup (medians of 9
    with their spread, a third of the elements and REG connections failed at random)
    schedule_changed_numba_seconds / ..._reference_seconds / ..._speedup (the adaptive schedule's
    change test, medians of 9, 2% of the integrities moved past its tolerance)
    diagnostics_numba_seconds / ..._reference_seconds / ..._speedup / ..._max_relative_difference
    (the per-step diagnostics, medians of 9, H_c at random)
    reg_pairs_numba_seconds_threads_<k>  for k = 1 .. numba.config.NUMBA_NUM_THREADS
Each timing is the best of 3 after a warm-up call.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numba
import numpy as np
from timing import SAMPLES, best, spread, times

import wooddecay as wd
from wooddecay.sim import failure, schedule
from wooddecay.sim.diagnostics import diagnostics, diagnostics_reference
from wooddecay.sim.state import initial_state
from wooddecay.strands.elements import transport_frames_numba, transport_frames_reference
from wooddecay.strands.reg import segment_pairs, segment_pairs_reference


def main() -> None:
    path = Path(sys.argv[1] if len(sys.argv) > 1 else SAMPLES / "tree.toml")
    scene = wd.load_scene(path)
    m = wd.build_model(scene)
    pa, pb = m.particles[m.first_particle], m.particles[m.first_particle + 1]
    radius = scene.strands.connect_radius
    print(f"elements {m.n_elements} -")
    t_nb = best(lambda: segment_pairs(pa, pb, m.strand, radius))
    t_ref = best(lambda: segment_pairs_reference(pa, pb, m.strand, radius), repeat=1)
    print(f"reg_pairs_numba_seconds {t_nb:.4f} s")
    print(f"reg_pairs_reference_seconds {t_ref:.4f} s")
    print(f"reg_pairs_speedup {t_ref / t_nb:.2f} x")
    for k in range(1, numba.config.NUMBA_NUM_THREADS + 1):
        numba.set_num_threads(k)
        print(f"reg_pairs_numba_seconds_threads_{k} {best(lambda: segment_pairs(pa, pb, m.strand, radius)):.4f} s")
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    tangent = m.frames[:, 2]
    d1 = m.frames[m.element_offsets[:-1], 0]
    t_nb = best(lambda: transport_frames_numba(m.element_offsets, tangent, d1))
    t_ref = best(lambda: transport_frames_reference(m.element_offsets, tangent, d1), repeat=1)
    print(f"transport_frames_numba_seconds {t_nb:.5f} s")
    print(f"transport_frames_reference_seconds {t_ref:.4f} s")
    print(f"transport_frames_speedup {t_ref / t_nb:.1f} x")
    ok = np.array_equal(segment_pairs(pa, pb, m.strand, radius), segment_pairs_reference(pa, pb, m.strand, radius))
    print(f"reg_pairs_equal_reference {int(ok)} -")
    ms = initial_state(m, rods=True).mech
    rng = np.random.default_rng(0)
    ms.element_ok[rng.random(len(ms.element_ok)) < 1 / 3] = False
    ms.edge_ok[rng.random(len(ms.edge_ok)) < 1 / 3, 0] = False
    _against("components", lambda: failure.components(m.mech, ms), lambda: failure.components_reference(m.mech, ms))
    tol = m.time.tolerances
    ms.integrity = ms.integrity.copy()
    ms.integrity[rng.random(len(ms.integrity)) < 0.02] -= 2.0 * tol.relative
    _against("schedule_changed", lambda: schedule.changed(m, ms, tol), lambda: schedule.changed_reference(m, ms, tol))
    state = initial_state(m, rods=False)
    state.H_c[:] = rng.uniform(0.0, 1.0, len(state.H_c))
    _against("diagnostics", lambda: diagnostics(m, state), lambda: diagnostics_reference(m, state), _relative)


def _relative(a: dict, b: dict) -> float:
    """Largest relative difference of two diagnostics dicts' numbers."""
    pairs = [(a[k], b[k]) for k in ("mass_loss", "moisture_content_ratio")]
    pairs += [(v, b["tissue_means"][t][f]) for t, means in a["tissue_means"].items() for f, v in means.items()]
    return max(abs(x - y) / max(abs(y), 1e-300) for x, y in pairs)


def _against(name: str, fast, reference, difference=None) -> None:
    """Medians of 9 of ``fast`` and its numpy ``reference``, their per-pair ratio and whether
    they return the same (``difference``: how far apart they are, for results summed in another
    order)."""
    t_nb, t_ref = times(fast, 9), times(reference, 9)
    print(f"{name}_numba_seconds {np.median(t_nb):.5f} s {spread(t_nb)}")
    print(f"{name}_reference_seconds {np.median(t_ref):.5f} s {spread(t_ref)}")
    ratio = [r / n for r, n in zip(t_ref, t_nb)]
    print(f"{name}_speedup {np.median(ratio):.1f} x {spread(ratio)}")
    a, b = fast(), reference()
    if difference is not None:
        print(f"{name}_max_relative_difference {difference(a, b):.1e} -")
        return
    same = all(np.array_equal(x, y) for x, y in zip(a, b)) if isinstance(a, tuple) else np.array_equal(a, b)
    print(f"{name}_equal_reference {int(same)} -")


if __name__ == "__main__":
    main()
