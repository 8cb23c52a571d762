"""The gallery's bakes ahead, on a pool of processes: every variant of the figures run (and the
sensitivity study's runs) is baked by one of ``workers`` processes of cores // workers numba
threads each, in the figures' order, while the gallery measures, renders and decides each figure
in turn as its bakes finish (:func:`wooddecay.gallery.bakes.bake_scene` takes them from here).

Why: a bake's kernels gain 1.5x from a second thread on two cores (Stage 2's gathers; the
biology, bark and coupling between mechanics run on one), so two one-thread bakes side by side do
more in the same time (docs/decisions.md, "The gallery's bakes on processes"). A bake is the same
bits on any thread count (docs/model.md §4), so the gallery measures what it would measure in one process.

Workers are spawned, not forked: the gallery's process may have started numba's thread pool, and
a fork copies only the thread that calls it. A failed bake raises in the figure that reads it; the
pool is then terminated and the bakes still running are lost, as in a bake that is killed: each
writes atomically, and ``--resume`` continues from what finished.
"""
from __future__ import annotations

import multiprocessing
import os
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, NamedTuple

from ..budget import available_bytes, estimate
from ..scene import load_scene

#: the gallery's scenes (samples/gallery)
SCENES = Path(__file__).resolve().parent.parent / "samples" / "gallery"
#: bakes running or queued in the pool, by their resolved output folder
_AHEAD: dict = {}


class Job(NamedTuple):
    """A bake of ``samples/gallery/<scene_file>`` with ``overrides`` into ``folder`` (``resume``:
    see :func:`wooddecay.gallery.bakes.bake_scene`)."""

    scene_file: str
    overrides: dict
    folder: Path
    resume: bool = False


def workers_for(jobs: list[Job], requested: int | None) -> int:
    """Processes for ``jobs``: ``requested``, or for None (``auto``) one per core; never more than
    the jobs, nor more than can hold the largest bakes' estimated peak memory
    (:func:`wooddecay.budget.estimate`) at once."""
    n = min(len(jobs), requested or os.cpu_count() or 1)
    if n <= 1:
        return max(n, 0)
    peaks = sorted((estimate(load_scene(SCENES / j.scene_file, overrides=j.overrides)).peak_bytes for j in jobs),
                   reverse=True)
    while n > 1 and sum(peaks[:n]) > available_bytes():
        n -= 1
    return n


def _init(threads: int) -> None:
    """A worker: ``threads`` numba threads; Ctrl-C is the gallery's to handle (it terminates the
    pool), not every worker's to print."""
    import signal

    import numba

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))


@contextmanager
def baking_ahead(jobs: list[Job], workers: int, bake: Callable[[Job, int], float]):
    """Bake ``jobs`` with ``bake(job, threads)`` (:func:`wooddecay.gallery.bakes.timed_bake`) on
    ``workers`` processes while the body runs (nothing with fewer than two);
    :func:`take` hands each result to the figure that reads it. The body's own numba kernels (a
    study's, a model's build) run on one thread meanwhile: the cores are the workers', and a
    parallel region on a busy core waits for its descheduled threads (Fig. 17's pull study took
    285 s beside the pool on two threads, against 34 s alone)."""
    if workers < 2 or not jobs:
        yield
        return
    import numba

    threads = max(1, (os.cpu_count() or 1) // workers)
    pool = multiprocessing.get_context("spawn").Pool(workers, _init, (threads,))
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        for job in jobs:
            _AHEAD[Path(job.folder).resolve()] = pool.apply_async(bake, (job, threads))
        yield
    except BaseException:
        pool.terminate()
        raise
    else:
        pool.close()
    finally:
        numba.set_num_threads(before)
        _AHEAD.clear()
        pool.join()


def take(folder: Path) -> float | None:
    """The wall seconds of the bake into ``folder`` made ahead (waiting for it to finish; its
    error, if it failed), or None if none is."""
    result = _AHEAD.pop(Path(folder).resolve(), None)
    return None if result is None else float(result.get())
