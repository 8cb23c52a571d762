"""The thread count of a run (wooddecay.sim.threads): fixed counts, the auto choice from the run's
own macro-step times, and the parsing of --threads / $WOODDECAY_THREADS."""
from __future__ import annotations

import pytest

from wooddecay.errors import InputError
from wooddecay.sim import threads as T


def run(choice, seconds_of, steps):
    """Drive ``choice`` for ``steps`` macro steps whose time is ``seconds_of(count, step)``;
    returns the counts used, in order."""
    used = []
    for k in range(steps):
        n = choice.next()
        used.append(n)
        choice.record(n, seconds_of(n, k))
    return used


def test_fixed_count_never_probes_and_is_capped():
    c = T.ThreadChoice(1, available=2)
    assert run(c, lambda n, k: 1.0, 120) == [1] * 120
    c = T.ThreadChoice(8, available=2)
    assert set(run(c, lambda n, k: 1.0, 10)) == {2}
    assert c.summary() == {"requested": 8, "available": 2, "steps": {"2": 10}, "current": 2}


def test_auto_keeps_all_threads_on_an_idle_machine():
    c = T.ThreadChoice(None, available=2)
    used = run(c, lambda n, k: 1.0 / n, 200)
    probes = T.PROBES * 2
    assert used[:T.WARM_UP] == [2] * T.WARM_UP
    assert used[T.WARM_UP:T.WARM_UP + probes] == [1, 2] * T.PROBES
    assert c.current == 2
    assert used.count(1) == T.PROBES * 4     # one probe round every REPROBE_EVERY steps


def test_auto_drops_to_one_thread_when_threads_wait_and_comes_back_when_idle():
    busy_until = 120
    c = T.ThreadChoice(None, available=2)
    used = run(c, lambda n, k: (3.0 if n == 2 else 1.0) if k < busy_until else 1.0 / n, 300)
    first = T.WARM_UP + T.PROBES * 2
    assert set(used[first:T.WARM_UP + T.REPROBE_EVERY]) == {1}        # loaded: one thread
    assert used[-1] == 2 and c.current == 2                            # idle again: both
    assert sum(1 for n in used[:busy_until] if n == 2) <= T.WARM_UP + T.PROBES * 3


def test_all_threads_must_win_by_the_margin():
    c = T.ThreadChoice(None, available=2)
    run(c, lambda n, k: 1.0 if n == 1 else 0.95, T.WARM_UP + T.PROBES * 2)
    assert c.current == 1                 # 5% faster is within the noise: one thread
    c = T.ThreadChoice(None, available=2)
    run(c, lambda n, k: 1.0 if n == 1 else 0.85, T.WARM_UP + T.PROBES * 2)
    assert c.current == 2


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
