"""Write docs/scene.md from the scene schema (wooddecay/scene/schema.py): every table and key of a
scene file with its default, unit, allowed range and meaning.

Run after changing the schema (tests/scene/test_scene_docs.py fails until you do)::

    python scripts/write_scene_docs.py           # write docs/scene.md
    python scripts/write_scene_docs.py --check   # exit 1 when docs/scene.md is out of date
"""
from __future__ import annotations

import sys
from pathlib import Path

from wooddecay.scene_docs import COMMAND, DOCS_PATH, scene_docs, write

ROOT = Path(__file__).resolve().parent.parent


def main(argv: list[str]) -> int:
    if argv not in ([], ["--check"]):
        print(__doc__.strip(), file=sys.stderr)
        return 2
    if argv == ["--check"]:
        path = ROOT / DOCS_PATH
        current = path.read_text("utf-8") if path.is_file() else None
        if current != scene_docs():
            print(f"{DOCS_PATH} is out of date; run: {COMMAND}", file=sys.stderr)
            return 1
        print(f"{DOCS_PATH} is up to date")
        return 0
    print(f"wrote {write(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
