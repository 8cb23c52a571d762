"""Regenerate tests/golden/tiny.usda, the stage the golden test compares a fresh bake against.

Run after a deliberate change of the simulation, meshing or export (and say why in the commit)::

    python scripts/regenerate_golden.py

It bakes samples/tiny.toml with the arguments in tests/golden/tiny.args (which
tests/test_bake.py reads too) and writes the stage as text (.usda) so reviews can read the change.
"""
from __future__ import annotations

import tempfile
from pathlib import Path

from click.testing import CliRunner

from wooddecay.cli import main

ROOT = Path(__file__).resolve().parent.parent
TINY = str(ROOT / "samples" / "tiny.toml")
GOLDEN = ROOT / "tests" / "golden" / "tiny.usda"
GOLDEN_ARGS = GOLDEN.with_suffix(".args").read_text("utf-8").split()


def regenerate() -> Path:
    from pxr import Sdf

    with tempfile.TemporaryDirectory() as tmp:
        res = CliRunner().invoke(main, ["bake", TINY, "-o", tmp, *GOLDEN_ARGS])
        if res.exit_code != 0:
            raise SystemExit(res.output)
        GOLDEN.parent.mkdir(parents=True, exist_ok=True)
        Sdf.Layer.FindOrOpen(str(Path(tmp) / "tiny.usdc")).Export(str(GOLDEN))
    return GOLDEN


if __name__ == "__main__":
    print(f"wrote {regenerate()}")
