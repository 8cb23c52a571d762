"""How many threads the numba kernels use in a run: a fixed count, or ``auto``: all threads only
while the other processes leave them their cores, and then the faster of one thread and all
threads measured on the run's own macro steps.

The cores other processes use (:class:`LoadMonitor`: the busy time of the CPUs this process may
run on, less this process's own CPU time, over windows of ``WINDOW`` seconds) cap the count at the
cores they leave free, rounded: on 2 cores beside a CPU-bound process ``auto`` runs one thread
and never probes two. Why: there a step on two threads waits in every parallel region for the
descheduled thread, and the probes' few steps did not tell it reliably: a year of the log beside a
busy loop ran 1.4-6.7x as long as on one thread with the timing alone (bakes of each,
alternating, 2026-12-04; docs/decisions.md, "Threads").

Results are bit-identical for any count (docs/model.md §4), so the count may change between macro steps
without changing a bake. ``auto`` probes in rounds: from the macro step after the warm-up ones,
and again ``REPROBE_EVERY`` steps later because the machine's load changes, the interval doubling
(up to ``REPROBE_MOST``) after each later round that keeps the count and back to ``REPROBE_EVERY``
when a round changes it, since a probe of all threads on a loaded machine costs several steps of one
(a year of the tree under a second CPU-bound process: 42 such probes took its 151 s of simulation
on one thread to 199 s, docs/decisions.md "Threads"). A round runs the steps
with each candidate, alternating (1, n, 1, n, ...), and estimates what the round's steps cost with
each count: per work done with both counts (the caller's ``work`` key: what the step ran), the
round's steps of that work times their mean time with the count. The mean, not the fastest: on a
loaded machine a step on all threads is now and then fast (both threads ran) and mostly slow, and
the fastest of a round's few took all threads for a short bake it made twice as slow as one
thread (docs/decisions.md, "Threads").
The round ends once ``PROBES`` pairs of steps of equal work put all ``n`` threads below ``CLEAR``
or above ``LOADED`` times one thread, else after ``MAX_PROBE_STEPS`` steps. Then all ``n``
threads are taken below ``MARGIN`` times one thread, one thread at or above one thread's cost,
and in between (or without a work done by both) the count stays. Settling runs through it too,
in chunks of ``N_mech`` substeps.

Why: on a 2-core machine shared with another CPU-bound process every parallel region waits for
a descheduled thread, and two threads ran up to 5x slower than one. Why by work: under the
adaptive schedule a step that solves costs ten times a quiet one and gains more from the second
thread (a year of the tree: 0.67-0.72 of one thread's time in a solve, 0.89 in a quiet step), so
the times of any two steps compare the schedule, not the threads (docs/decisions.md, "Threads").
"""
from __future__ import annotations

import math
import os
import statistics
import time
from collections import Counter

import numba
import psutil

from ..errors import InputError

#: pairs of steps of equal work that may end a probe round early
PROBES = 2
#: most macro steps a probe round takes
MAX_PROBE_STEPS = 8
#: a round ends early when all threads cost less than CLEAR or more than LOADED times one thread
CLEAR = 0.75
LOADED = 1.25
#: macro steps between the starts of two probe rounds after a round that changed the count
REPROBE_EVERY = 50
#: the most macro steps between the starts of two probe rounds
REPROBE_MOST = 8 * REPROBE_EVERY
#: all threads are taken only when they cost less than this times one thread
MARGIN = 0.9
#: macro steps that compile or load the kernels before any is timed
WARM_UP = 1
#: seconds of wall time over which the other processes' load is measured
WINDOW = 0.25
#: the shortest window of the first reading (CPU times tick every 10 ms)
FIRST_WINDOW = 0.1
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


class LoadMonitor:
    """The cores other processes keep busy on the CPUs this process may run on: their busy time
    (all but idle and iowait; Linux's guest time is already in its user time) less this process's
    own CPU time, per second of wall time, over the last complete window of at least ``window``
    seconds (psutil). The first reading waits until ``first`` seconds have passed since the
    monitor started, if they have not. Where the CPU times cannot be read it reads 0.0 (no cap:
    the timing decides alone)."""

    def __init__(self, window: float = WINDOW, first: float = FIRST_WINDOW):
        self.window, self.first = window, first
        self.other: float | None = None
        self.cpus: list[int] = []
        try:
            self._process = psutil.Process()
            try:
                self.cpus = sorted(self._process.cpu_affinity())
            except (AttributeError, psutil.Error):  # no affinity API (macOS): every CPU
                self.cpus = list(range(psutil.cpu_count() or 1))
        except (OSError, RuntimeError, psutil.Error):
            pass
        self._last = self._sample() if self.cpus else None
        if self._last is None:
            self.other = 0.0

    def _sample(self) -> tuple[float, float, float] | None:
        """(wall clock, the CPUs' busy seconds, this process's CPU seconds), or None where they
        cannot be read."""
        try:
            per_cpu = psutil.cpu_times(percpu=True)
            own = self._process.cpu_times()
        except (OSError, RuntimeError, psutil.Error):
            return None
        busy = 0.0
        for c in self.cpus:
            if c < len(per_cpu):
                t = per_cpu[c]
                busy += (sum(t) - t.idle - getattr(t, "iowait", 0.0) - getattr(t, "guest", 0.0)
                         - getattr(t, "guest_nice", 0.0))
        return time.perf_counter(), busy, own.user + own.system

    def __call__(self) -> float:
        """The other processes' cores, updated when a window has passed."""
        if self._last is None:
            assert self.other is not None  # 0.0 whenever there is no sample
            return self.other
        if self.other is None:
            time.sleep(max(0.0, self._last[0] + self.first - time.perf_counter()))
        now = self._sample()
        if now is None:
            self.other, self._last = 0.0, None
            return self.other
        wall = now[0] - self._last[0]
        if wall >= self.window or self.other is None:
            self.other = max(0.0, ((now[1] - self._last[1]) - (now[2] - self._last[2])) / wall)
            self._last = now
        return self.other


class ThreadChoice:
    """The thread count of each macro step: :meth:`next` before it, :meth:`record` after it.

    ``requested``: a fixed count (capped at the threads numba has) or None for ``auto``; ``load``:
    the other processes' cores (a :class:`LoadMonitor` for ``auto`` unless given)."""

    def __init__(self, requested: int | None = None, available: int | None = None, load=None):
        self.available = int(numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]  # set at runtime, not in numba's stubs
                             if available is None else available)
        self.load = None if requested is not None else load if load is not None else LoadMonitor()
        self.requested = requested
        self.candidates: tuple[int, ...]
        if requested is not None:
            self.candidates = (min(int(requested), self.available),)
        else:
            self.candidates = (1, self.available) if self.available > 1 else (1,)
        self.current = self.candidates[-1]
        self.steps = 0
        self.used: Counter = Counter()
        self._samples: dict[tuple, list[float]] = {}  # (work, count) -> seconds in this round
        self._start = WARM_UP  # the first macro step of the current or next probe round
        self._every = REPROBE_EVERY  # macro steps from its start to the next round's
        self.held_by_load = 0  # macro steps the other processes' load held to fewer threads
        self._held = False  # whether the count :meth:`next` gave last was held down by the load

    def _probe(self, k: int) -> int | None:
        """The candidate macro step ``k`` probes, or None outside a probe round."""
        j = k - self._start
        if len(self.candidates) == 1 or not 0 <= j < MAX_PROBE_STEPS:
            return None
        return self.candidates[j % len(self.candidates)]

    def cap(self) -> int:
        """The most threads the cores the other processes leave free run (module docstring)."""
        if self.load is None:
            return self.available
        cores = len(getattr(self.load, "cpus", ())) or self.available
        return max(1, min(self.available, math.floor(cores - self.load() + 0.5)))

    def next(self) -> int:
        """The count for the next macro step (set it with :func:`numba.set_num_threads`)."""
        probe = self._probe(self.steps)
        want = self.current if probe is None else probe
        count = min(want, self.cap()) if want > 1 else want
        self._held = count < want
        return count

    def record(self, count: int, seconds: float, work=None) -> None:
        """The macro step just run used ``count`` threads, took ``seconds`` and did ``work`` (a
        key: only steps of equal work are compared; module docstring)."""
        k = self.steps
        self.steps += 1
        self.used[count] += 1
        self.held_by_load += self._held
        self._held = False
        if self._probe(k) is None:
            return
        self._samples.setdefault((work, count), []).append(seconds)
        j = k - self._start
        n = self.available
        both = [w for w, c in self._samples if c == 1 and (w, n) in self._samples]
        pairs = sum(min(len(self._samples[(w, 1)]), len(self._samples[(w, n)])) for w in both)
        cost = {c: sum((len(self._samples[(w, 1)]) + len(self._samples[(w, n)]))
                       * statistics.fmean(self._samples[(w, c)]) for w in both) for c in (1, n)}
        ratio = cost[n] / cost[1] if both and cost[1] > 0.0 else None
        if (ratio is not None and pairs >= PROBES and not CLEAR <= ratio < LOADED) or j == MAX_PROBE_STEPS - 1:
            before = self.current
            if ratio is not None and (ratio < MARGIN or ratio >= 1.0):
                self.current = n if ratio < MARGIN else 1
            held = self.current == before and self._start > WARM_UP
            self._every = min(2 * self._every, REPROBE_MOST) if held else REPROBE_EVERY
            self._samples, self._start = {}, self._start + self._every

    def run(self, fn, keyed: bool = False):
        """``fn()`` with the count :meth:`next` gives, recording its wall time; with ``keyed``
        ``fn`` returns the step's work (module docstring), recorded with it (else every step does
        the same work). numba's count is restored afterwards; returns what ``fn`` returns."""
        count, before = self.next(), numba.get_num_threads()
        numba.set_num_threads(count)
        t0 = time.perf_counter()
        done = None
        try:
            done = fn()
            return done
        finally:
            numba.set_num_threads(before)
            self.record(count, time.perf_counter() - t0, done if keyed else None)

    def summary(self) -> dict:
        """What ``summary.json`` records: the request, the threads numba has, the macro steps run
        with each count (macro steps and settling chunks), those the other processes' load held to
        fewer threads than the choice, and the count in use at the end."""
        return {"requested": "auto" if self.requested is None else self.requested,
                "available": self.available, "steps": {str(k): v for k, v in sorted(self.used.items())},
                "held_by_load": self.held_by_load, "current": self.current}
