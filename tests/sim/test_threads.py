"""The thread count of a run (wooddecay.sim.threads): fixed counts, the auto choice from the run's
own macro-step times, and the parsing of --threads / $WOODDECAY_THREADS."""
from __future__ import annotations

import subprocess
import sys
import time

import pytest

from wooddecay.errors import InputError
from wooddecay.sim import threads as T


def idle():
    """No other process on the machine (:class:`wooddecay.sim.threads.LoadMonitor`'s reading)."""
    return 0.0


def run(choice, seconds_of, steps, work_of=lambda k: None):
    """Drive ``choice`` for ``steps`` macro steps whose time is ``seconds_of(count, step)`` and
    work ``work_of(step)``; returns the counts used, in order."""
    used = []
    for k in range(steps):
        n = choice.next()
        used.append(n)
        choice.record(n, seconds_of(n, k), work_of(k))
    return used


def test_fixed_count_never_probes_and_is_capped():
    c = T.ThreadChoice(1, available=2)
    assert run(c, lambda n, k: 1.0, 120) == [1] * 120
    c = T.ThreadChoice(8, available=2)
    assert set(run(c, lambda n, k: 1.0, 10)) == {2}
    assert c.summary() == {"requested": 8, "available": 2, "steps": {"2": 10}, "held_by_load": 0,
                           "current": 2}


def test_auto_keeps_all_threads_on_an_idle_machine():
    c = T.ThreadChoice(None, available=2, load=idle)
    used = run(c, lambda n, k: 1.0 / n, 200)
    probes = T.PROBES * 2
    assert used[:T.WARM_UP] == [2] * T.WARM_UP
    assert used[T.WARM_UP:T.WARM_UP + probes] == [1, 2] * T.PROBES
    assert c.current == 2
    assert used.count(1) == T.PROBES * 3     # rounds at steps 1, 51 and 151: test_probes_back_off


def test_auto_drops_to_one_thread_when_threads_wait_and_comes_back_when_idle():
    busy_until = 120
    c = T.ThreadChoice(None, available=2, load=idle)
    used = run(c, lambda n, k: (3.0 if n == 2 else 1.0) if k < busy_until else 1.0 / n, 300)
    first = T.WARM_UP + T.PROBES * 2
    assert set(used[first:T.WARM_UP + T.REPROBE_EVERY]) == {1}        # loaded: one thread
    assert used[-1] == 2 and c.current == 2                            # idle again: both
    assert sum(1 for n in used[:busy_until] if n == 2) <= T.WARM_UP + T.PROBES * 3


def test_probes_back_off_while_the_count_holds():
    """On a machine loaded throughout, the rounds after the one that dropped to one thread come
    at doubling intervals up to REPROBE_MOST, each probing all threads PROBES times."""
    c = T.ThreadChoice(None, available=2, load=idle)
    used = run(c, lambda n, k: 3.0 if n == 2 else 1.0, 2000)
    starts = [1, 51, 151, 351, 751, 1151, 1551, 1951]
    assert [k for k, n in enumerate(used) if n == 2 and k >= T.WARM_UP] == [s + d for s in starts for d in (1, 3)]
    assert T.REPROBE_MOST == 400 and c.current == 1


def test_a_lucky_fast_step_on_a_loaded_machine_does_not_take_all_threads():
    """Beside a CPU-bound process a step on all threads is sometimes fast (both threads ran) and
    mostly slow (one waited): the round weighs what the steps cost on average, so one lucky step
    does not win it (the fastest of them would: 0.6 against 1.0)."""
    c = T.ThreadChoice(None, available=2, load=idle)
    slow = {}

    def seconds(n, k):
        if n == 1:
            return 1.0
        slow[k] = len(slow) % 2 == 1  # 0.6, 5.0, 0.6, 5.0, ...
        return 5.0 if slow[k] else 0.6

    used = run(c, seconds, 300)
    assert c.current == 1
    assert used.count(2) <= T.WARM_UP + T.PROBES * 3


def test_a_count_changes_only_past_the_margin():
    # loaded in the first round (two threads 3x slower): one thread; in the next, two threads 5%
    # faster is within the noise and one thread stays, 15% faster takes both
    steps = T.REPROBE_EVERY + T.WARM_UP + T.MAX_PROBE_STEPS
    for later, expected in ((0.95, 1), (0.85, 2)):
        c = T.ThreadChoice(None, available=2, load=idle)
        run(c, lambda n, k: (3.0 if n == 2 else 1.0) if k < T.REPROBE_EVERY else (1.0 if n == 1 else later), steps)
        assert c.current == expected
    # and all threads stay while they are not slower than one
    c = T.ThreadChoice(None, available=2, load=idle)
    run(c, lambda n, k: 1.0 if n == 1 else 0.95, T.WARM_UP + T.MAX_PROBE_STEPS)
    assert c.current == 2
    c = T.ThreadChoice(None, available=2, load=idle)
    run(c, lambda n, k: 1.0 if n == 1 else 1.05, T.WARM_UP + T.MAX_PROBE_STEPS)
    assert c.current == 1


def test_auto_compares_steps_of_the_same_work():
    # every 4th step solves and costs 10x; the second thread makes every step 1.5x faster. The
    # round's two-thread probes meet its solves: the medians of any two steps per count (1.0
    # against 3.7) would keep one thread, those of the quiet steps keep both
    heavy = lambda k: k % 4 == 2  # noqa: E731
    c = T.ThreadChoice(None, available=2, load=idle)
    used = run(c, lambda n, k: (10.0 if heavy(k) else 1.0) / (1.5 if n == 2 else 1.0), T.REPROBE_EVERY, heavy)
    assert c.current == 2
    assert used[T.WARM_UP:T.WARM_UP + 8] == [1, 2] * 4 and set(used[T.WARM_UP + 8:]) == {2}


def test_auto_weighs_each_work_by_its_time():
    # quiet steps gain 5% from the second thread, solves 40%; the round's first four steps are
    # quiet, its next two solve: the solves' time decides (24 against 15.8)
    heavy = lambda k: k % 8 in (5, 6)  # noqa: E731
    c = T.ThreadChoice(None, available=2, load=idle)
    used = run(c, lambda n, k: (10.0 if n == 1 else 6.0) if heavy(k) else (1.0 if n == 1 else 0.95), 7, heavy)
    assert used[T.WARM_UP:] == [1, 2, 1, 2, 1, 2] and c.current == 2
    assert c.next() == 2                  # the round ended with the solves


def test_a_round_without_equal_work_keeps_the_count_and_ends():
    c = T.ThreadChoice(None, available=2, load=idle)
    used = run(c, lambda n, k: 1.0 if n == 2 else 0.1, T.REPROBE_EVERY, lambda k: k)
    assert c.current == 2
    assert used[T.WARM_UP:T.WARM_UP + T.MAX_PROBE_STEPS] == [1, 2] * (T.MAX_PROBE_STEPS // 2)
    assert set(used[T.WARM_UP + T.MAX_PROBE_STEPS:]) == {2}
    # a work done alike by both counts only once decides at the round's end
    c = T.ThreadChoice(None, available=2, load=idle)
    used = run(c, lambda n, k: 1.0 if n == 2 else 0.1, T.REPROBE_EVERY, lambda k: "x" if k in (3, 4) else k)
    assert used[3:5] == [1, 2] and c.current == 1
    assert set(used[T.WARM_UP + T.MAX_PROBE_STEPS:]) == {1}


def test_a_busy_core_holds_auto_to_the_cores_left_and_probes_nothing():
    """Beside a CPU-bound process (one of two cores busy) auto runs one thread from the first step,
    even where two would time faster, and takes both again when the load goes; a fixed count is
    never held."""
    busy = {"cores": 1.0}
    c = T.ThreadChoice(None, available=2, load=lambda: busy["cores"])
    used = run(c, lambda n, k: 1.0 / n, 120)
    # every step but the one-thread probes of the rounds at steps 1 and 51 wanted two
    assert used == [1] * 120 and c.summary()["held_by_load"] == 120 - T.MAX_PROBE_STEPS
    busy["cores"] = 0.3
    assert run(c, lambda n, k: 1.0 / n, 60)[-1] == 2
    c = T.ThreadChoice(8, available=4, load=lambda: 3.0)
    assert set(run(c, lambda n, k: 1.0, 5)) == {4}
    many = T.ThreadChoice(None, available=16, load=lambda: 2.6)
    assert run(many, lambda n, k: 1.0 / n, T.WARM_UP) == [13]


def test_load_monitor_sees_a_busy_process():
    """A CPU-bound child process reads as at least half a core of other load within 5 s."""
    spin = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        monitor = T.LoadMonitor(window=0.3)
        deadline, reading = time.perf_counter() + 5.0, 0.0
        while reading < 0.5 and time.perf_counter() < deadline:
            time.sleep(0.35)
            reading = monitor()
        assert reading >= 0.5
    finally:
        spin.kill()
        spin.wait()


def test_load_monitor_without_cpu_times_caps_nothing(monkeypatch):
    """Where the CPU times cannot be read (a locked-down /proc) the monitor reads no load, at
    once or later, and auto's timing decides alone."""
    def refuse(*args, **kwargs):
        raise PermissionError("/proc/stat")

    monitor = T.LoadMonitor()
    monkeypatch.setattr(T.psutil, "cpu_times", refuse)
    assert monitor() == 0.0 and monitor() == 0.0
    c = T.ThreadChoice(None, available=2)
    assert c.load() == 0.0
    assert run(c, lambda n, k: 1.0 / n, 20)[-1] == 2


def test_one_thread_machine_has_one_candidate():
    c = T.ThreadChoice(None, available=1)
    assert run(c, lambda n, k: 1.0, 60) == [1] * 60


@pytest.mark.parametrize("value, expected", [("auto", None), (None, None), ("AUTO", None), ("3", 3), (2, 2)])
def test_parse_threads(value, expected):
    assert T.parse_threads(value) == expected


@pytest.mark.parametrize("value", ["0", "-1", "two", "1.5", ""])
def test_parse_threads_rejects_with_one_line(value):
    with pytest.raises(InputError, match=r"^--threads: must be 'auto' or a whole number >= 1") as err:
        T.parse_threads(value)
    assert "\n" not in str(err.value)


def test_environment_default(monkeypatch):
    monkeypatch.setenv(T.ENV, "1")
    assert T.requested_threads(None) == 1
    assert T.requested_threads("auto") is None
    monkeypatch.setenv(T.ENV, "none")
    with pytest.raises(InputError, match=r"^\$WOODDECAY_THREADS: must be"):
        T.requested_threads(None)
