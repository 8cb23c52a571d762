"""Shared fixtures: sample scenes and their models, built once per session."""
from __future__ import annotations

from pathlib import Path

import pytest

import wooddecay as wd

ROOT = Path(__file__).resolve().parent.parent
SAMPLES = ROOT / "samples"


@pytest.fixture(scope="session")
def samples_dir() -> Path:
    return SAMPLES


@pytest.fixture(scope="session")
def tiny_scene():
    return wd.load_scene(SAMPLES / "tiny.toml")


@pytest.fixture(scope="session")
def tiny_model(tiny_scene):
    return wd.build_model(tiny_scene)


@pytest.fixture(scope="session")
def log_scene():
    return wd.load_scene(SAMPLES / "log.toml")


@pytest.fixture(scope="session")
def log_model(log_scene):
    return wd.build_model(log_scene)


@pytest.fixture(scope="session")
def board_model():
    return wd.build_model(wd.load_scene(SAMPLES / "board.toml"))
