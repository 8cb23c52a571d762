"""Fill numba's on-disk cache before the pytest-xdist workers start (tests/conftest.py).

In a fresh environment every kernel compiles on its first call, about 90 s for a bake on one
core, and both workers start with a bake: each compiled the same kernels at the same time. Two
processes that compile different halves instead (``python tests/numba_warm.py mechanics`` and
``... meshes``: the tiny sample's coupled simulation, and its draft bake with meshlets and
export) fill the cache in about half the time, and the workers then load every kernel from it.
With a filled cache each part takes a few seconds."""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import wooddecay as wd
from wooddecay.bake import bake
from wooddecay.sim.driver import Simulation
from wooddecay.sim.threads import ThreadChoice

TINY = Path(__file__).resolve().parent.parent / "samples" / "tiny.toml"
PARTS = ("mechanics", "meshes")


def warm(part: str) -> None:
    quick = {"time.days": 4.0, "time.frames": 1}
    if part == "mechanics":  # the bark's kernels compile in the other part
        scene = wd.load_scene(TINY, overrides={**quick, "bark.cracks": False})
        for _ in Simulation(wd.build_model(scene), threads=ThreadChoice(1)).run():
            pass
    else:
        scene = wd.load_scene(TINY, overrides=quick)
        with tempfile.TemporaryDirectory() as out:
            bake(scene, Path(out), quality="draft", threads=1)


if __name__ == "__main__":
    warm(sys.argv[1])
