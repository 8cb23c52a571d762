"""Biology step throughput and memory-bandwidth efficiency.

Prints ``name value unit`` lines for samples/tree.toml (or the scene given):
    bio_updates_per_s_threads_<k>   element-field updates per second (6 fields x elements x substeps)
    bio_substep_seconds_threads_<k> seconds per biology substep
    stream_triad_gb_s               a = b + s c over 3 x 160 MB arrays (numba, all threads, median of 5)
    bio_bytes_per_substep           compulsory traffic of one substep (model below)
    bio_bandwidth_fraction          (bytes per substep / substep time) / triad bandwidth
    diffusing_passes                the transported fields updated: C, M, and R_w and R_b where a
                                    fungus is present (a rot field zero everywhere is skipped)
Traffic model per substep: each diffusing pass streams its CSR row (index, weight) and gathers
u_j and kappa_j: 32 bytes per nonzero, and a fungus' pass also its entries' three shares and the
neighbours' three front factors (sim/fronts.py): 80 bytes; the passes also read and write their
per-element arrays (63 doubles per element over the six updates, and 11 more per fungus: growth
written and read, spacing and transport factors read, front factors written). Timings are medians of 9 substeps after a
warm-up, with their quartiles and extremes, all in this one run.
"""
from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

import numba as nb

import wooddecay as wd
from wooddecay.sim import biology as B
from wooddecay.sim.state import initial_state

from timing import SAMPLES, spread, stream_triad


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main() -> None:
    path = Path(sys.argv[1] if len(sys.argv) > 1 else SAMPLES / "tree.toml")
    scene = wd.load_scene(path, overrides={"fungi.alpha_b0": 0.05, "fungi.D_b": 1e-5})
    model = wd.build_model(scene)
    setup = model.bio
    state = initial_state(model)
    n, nnz = model.n_elements, len(setup.op.indices)
    print(f"elements {n} -")
    print(f"transport_nonzeros {nnz} -")
    dt = 0.5 * setup.bound
    B.step(model, state, dt, n_sub=1)  # compile / load
    passes = 2 + int(state.R_w.any()) + int(state.R_b.any())
    print(f"diffusing_passes {passes} -")
    results = {}
    for k in range(1, nb.config.NUMBA_NUM_THREADS + 1):
        nb.set_num_threads(k)
        runs = [_timed(lambda: B.step(model, state, dt, n_sub=1)) for _ in range(9)]
        results[k] = median = statistics.median(runs)
        print(f"bio_substep_seconds_threads_{k} {median:.5f} s {spread(runs)}")
        print(f"bio_updates_per_s_threads_{k} {6 * n / median:.4g} 1/s")
    nb.set_num_threads(nb.config.NUMBA_NUM_THREADS)
    bw = stream_triad()
    fungi = passes - 2
    traffic = (2 * 32 + fungi * 80) * nnz + (63 + 11 * fungi) * 8 * n
    print(f"stream_triad_gb_s {bw / 1e9:.2f} GB/s")
    print(f"bio_bytes_per_substep {traffic} B")
    print(f"bio_bandwidth_fraction {traffic / min(results.values()) / bw:.3f} -")
    print(f"clamp_count {state.clamp_count} -")


if __name__ == "__main__":
    main()
