"""Shared helpers of the benchmark scripts (run as ``python benchmarks/<name>.py`` from any folder):
the sample scenes, timers and the STREAM-triad bandwidth of this machine.

These machines are shared: report medians with their spread (:func:`spread`), measured in the
same run as what they are compared with, rather than the best run."""
from __future__ import annotations

import statistics
import time
from pathlib import Path

import numba as nb
import numpy as np

#: the repository's sample scenes, found from this file so the scripts run from any folder
SAMPLES = Path(__file__).resolve().parent.parent / "samples"


def times(fn, repeat: int) -> list[float]:
    """Wall times of ``repeat`` calls of ``fn`` after one warm-up call."""
    fn()
    out = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def best(fn, repeat=3) -> float:
    """Best wall time of ``repeat`` calls of ``fn`` after one warm-up call."""
    return min(times(fn, repeat))


def spread(xs) -> str:
    """``median unit`` context for a ``name value unit`` line: quartiles, extremes and count."""
    xs = sorted(xs)
    q1, _, q3 = statistics.quantiles(xs, n=4, method="inclusive") if len(xs) > 1 else (xs[0],) * 3
    return f"(median of {len(xs)}; quartiles {q1:.4g}-{q3:.4g}, min {xs[0]:.4g}, max {xs[-1]:.4g})"


@nb.njit(parallel=True, cache=True)
def _triad(a, b, c, s):
    for i in nb.prange(len(a)):
        a[i] = b[i] + s * c[i]


def stream_triad(n: int = 20_000_000, repeat: int = 5) -> float:
    """Bytes per second of ``a = b + s c`` over three arrays of ``n`` doubles (all threads; the
    median of ``repeat`` runs)."""
    a, b, c = np.zeros(n), np.ones(n), np.full(n, 2.0)
    return 3 * 8 * n / statistics.median(times(lambda: _triad(a, b, c, 3.0), repeat))
