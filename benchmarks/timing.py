"""Shared timing helper of the benchmark scripts (run as ``python benchmarks/<name>.py``)."""
from __future__ import annotations

import time


def best(fn, repeat=3) -> float:
    """Best wall time of ``repeat`` calls of ``fn`` after one warm-up call."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)
