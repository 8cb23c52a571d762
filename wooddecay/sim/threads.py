"""How many threads the numba kernels use in a run: a fixed count, or ``auto``, the faster of one
thread and all threads measured on the run's own macro steps.

Results are bit-identical for any count (SPEC §4), so the count may change between macro steps
without changing a bake. ``auto`` times the first macro step after the warm-up ones with each
candidate, ``PROBES`` times each, alternating (1, n, 1, n, ...), keeps all ``n`` threads only
when their median is below ``MARGIN`` times one thread's, and probes again every
``REPROBE_EVERY`` macro steps because the machine's load changes. Settling runs through it too,
in chunks of ``N_mech`` substeps. Why: on a 2-core machine shared
with another CPU-bound process every parallel region waits for a descheduled thread, and two
threads ran up to 5x slower than one (docs/decisions.md, "Threads").
"""
from __future__ import annotations

import os
import statistics
import time
from collections import Counter

import numba

from ..errors import InputError

#: timed macro steps per candidate in a probe round
PROBES = 2
#: macro steps between the starts of two probe rounds
REPROBE_EVERY = 50
#: all threads are kept only when at least this much faster than one (median ratio)
MARGIN = 0.9
#: macro steps that compile or load the kernels before any is timed
WARM_UP = 1
#: environment variable with the default of ``wooddecay bake --threads``
ENV = "WOODDECAY_THREADS"


def parse_threads(value, source: str = "--threads") -> int | None:
    """``auto`` (None) or a count >= 1 from ``value`` (a string or int); InputError otherwise."""
    if value is None or str(value).strip().lower() == "auto":
        return None
    try:
        n = int(str(value).strip())
    except ValueError:
        n = 0
    if n < 1:
        raise InputError(source, "", f"must be 'auto' or a whole number >= 1, not {value!r}")
    return n


def requested_threads(option: str | None) -> int | None:
    """The ``--threads`` option, else ``$WOODDECAY_THREADS``, else ``auto`` (None)."""
    if option is not None:
        return parse_threads(option)
    return parse_threads(os.environ.get(ENV), f"${ENV}")


class ThreadChoice:
    """The thread count of each macro step: :meth:`next` before it, :meth:`record` after it.

    ``requested``: a fixed count (capped at the threads numba has) or None for ``auto``."""

    def __init__(self, requested: int | None = None, available: int | None = None):
        self.available = int(numba.config.NUMBA_NUM_THREADS if available is None else available)
        self.requested = requested
        if requested is not None:
            self.candidates = (min(int(requested), self.available),)
        else:
            self.candidates = (1, self.available) if self.available > 1 else (1,)
        self.current = self.candidates[-1]
        self.steps = 0
        self.used: Counter = Counter()
        self._samples: dict[int, list[float]] = {}

    def _probe(self, k: int) -> int | None:
        """The candidate macro step ``k`` probes, or None outside a probe round."""
        if len(self.candidates) == 1 or k < WARM_UP:
            return None
        j = (k - WARM_UP) % REPROBE_EVERY
        n = PROBES * len(self.candidates)
        return self.candidates[j % len(self.candidates)] if j < n else None

    def next(self) -> int:
        """The count for the next macro step (set it with :func:`numba.set_num_threads`)."""
        probe = self._probe(self.steps)
        return self.current if probe is None else probe

    def record(self, count: int, seconds: float) -> None:
        """The macro step just run used ``count`` threads and took ``seconds``."""
        k = self.steps
        self.steps += 1
        self.used[count] += 1
        if self._probe(k) is None:
            return
        self._samples.setdefault(count, []).append(seconds)
        if all(len(self._samples.get(c, ())) >= PROBES for c in self.candidates):
            one = statistics.median(self._samples[1])
            many = statistics.median(self._samples[self.available])
            self.current = self.available if many < MARGIN * one else 1
            self._samples = {}

    def run(self, fn):
        """``fn()`` with the count :meth:`next` gives, recording its wall time; numba's count is
        restored afterwards."""
        count, before = self.next(), numba.get_num_threads()
        numba.set_num_threads(count)
        t0 = time.perf_counter()
        try:
            return fn()
        finally:
            numba.set_num_threads(before)
            self.record(count, time.perf_counter() - t0)

    def summary(self) -> dict:
        """What ``summary.json`` records: the request, the threads numba has, the macro steps run
        with each count (macro steps and settling chunks) and the count in use at the end."""
        return {"requested": "auto" if self.requested is None else self.requested,
                "available": self.available, "steps": {str(k): v for k, v in sorted(self.used.items())},
                "current": self.current}
