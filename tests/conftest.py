"""Shared fixtures: sample scenes and their models, built once per session."""
from __future__ import annotations

import os
import subprocess
import sys
from functools import cache
from pathlib import Path

import numba
import pytest
from hypothesis import settings

import wooddecay as wd
from wooddecay.sim import threads

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"

# property tests draw the same examples on every run: a CI result does not depend on luck
settings.register_profile("deterministic", derandomize=True)
settings.load_profile("deterministic")


#: test files whose module fixtures bake for minutes, longest first: they go to the two workers
#: before everything else (``--no-loadscope-reorder`` keeps pytest-xdist to this order), so that
#: the short files fill in behind them and both workers finish together
LONGEST_FIRST = ("test_gallery_fig12.py", "test_gallery.py", "test_gallery_trees.py")


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONGEST_FIRST)))  # stable: the rest keep their order


@pytest.fixture(scope="session", autouse=True)
def user_cache(tmp_path_factory):
    """The session's own ``$XDG_CACHE_HOME`` (the Blender add-on renders install, wooddecay.addon),
    never the user's."""
    with pytest.MonkeyPatch.context() as m:
        m.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("xdg-cache")))
        yield


@pytest.fixture(autouse=True)
def settle_cache(tmp_path, monkeypatch) -> Path:
    """Each test bakes with its own empty settled-state cache (wooddecay.sim.settled), never the
    user's."""
    folder = tmp_path / "settled-cache"
    monkeypatch.setenv("WOODDECAY_CACHE", str(folder))
    return folder


def pytest_configure(config):
    """Under pytest-xdist (``-n 2`` in pyproject.toml: two workers on CI's two cores) a worker
    runs on one numba thread and every bake given no thread count on one (``$WOODDECAY_THREADS``;
    ``auto`` sizes itself from the threads numba has, not from a test's count): two workers of two
    threads each on two cores make every parallel region wait for a descheduled thread, and
    ``auto`` would time two threads against one in probe rounds (docs/decisions.md,
    "Threads"). Tests of thread-count independence set their counts themselves."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        os.environ[threads.ENV] = "1"
        numba.set_num_threads(1)


@pytest.fixture(autouse=True)
def one_thread_per_worker():
    """Each test starts on the worker's one thread, whatever the test before it set."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        numba.set_num_threads(1)


@cache
def sample(name: str):
    """(scene, model) of ``samples/<name>.toml``, built once per session."""
    scene = wd.load_scene(SAMPLES / f"{name}.toml")
    return scene, wd.build_model(scene)


@pytest.fixture(scope="session")
def samples_dir() -> Path:
    return SAMPLES


@pytest.fixture(scope="session")
def tiny_scene():
    return sample("tiny")[0]


@pytest.fixture(scope="session")
def tiny_model():
    return sample("tiny")[1]


@pytest.fixture(scope="session")
def log_scene():
    return sample("log")[0]


@pytest.fixture(scope="session")
def log_model():
    return sample("log")[1]


@pytest.fixture(scope="session")
def board_model():
    return sample("board")[1]


def refused_in_one_line(args: list[str], target: Path, process: bool = False) -> str:
    """``wooddecay ARGS`` exits 2 with one ``error:`` line and writes no ``target``: run through
    the command in this process, or with ``process`` as a process of its own (what a user runs:
    no traceback reaches the terminal). Returns the line."""
    if process:
        proc = subprocess.run([sys.executable, "-m", "wooddecay.cli", *args], capture_output=True, text=True)
        code, line = proc.returncode, proc.stderr
    else:
        from click.testing import CliRunner

        from wooddecay.cli import main

        res = CliRunner().invoke(main, args)
        code, line = res.exit_code, res.output
    assert code == 2, (args, line)
    assert line.strip().count("\n") == 0 and line.startswith("error:"), (args, line)
    assert not target.exists(), args
    return line


def cracking_frames(model, frames, seed: int = 0) -> list:
    """Copies of ``frames`` whose rod states break a growing random quarter of the REG connections
    and fail a growing random eighth of the elements per frame after the first (components
    recomputed): cracks that open one frame after another, at CI size."""
    from dataclasses import replace
    from types import SimpleNamespace

    import numpy as np

    from wooddecay.sim.failure import components

    rng = np.random.default_rng(seed)
    edges, elements = rng.permutation(model.n_edges), rng.permutation(model.n_elements)
    out = []
    for k, f in enumerate(frames):
        mech = {key: v.copy() for key, v in f.mech.items()}
        mech["edge_ok"][edges[: k * model.n_edges // 4]] = False
        mech["element_ok"][elements[: k * model.n_elements // 8]] = False
        mech["component"] = components(model.mech, SimpleNamespace(element_ok=mech["element_ok"],
                                                                   edge_ok=mech["edge_ok"]))
        out.append(replace(f, mech=mech))
    return out
