"""Shared helpers of the benchmark scripts (run as ``python benchmarks/<name>.py`` from any folder):
the sample scenes and a timer."""
from __future__ import annotations

import time
from pathlib import Path

#: the repository's sample scenes, found from this file so the scripts run from any folder
SAMPLES = Path(__file__).resolve().parent.parent / "samples"


def best(fn, repeat=3) -> float:
    """Best wall time of ``repeat`` calls of ``fn`` after one warm-up call."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)
