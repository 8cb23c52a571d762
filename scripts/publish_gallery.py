"""Copy a gallery run into the docs: ``DIR/signatures.json``, the panels and charts into
``docs/gallery/`` and ``docs/gallery.md`` (the run's page, its images under ``gallery/``). What
follows the line NOTES in the old docs/gallery.md (what the renders show, written by a person
who looked at them) is kept.

    wooddecay gallery -o /tmp/gallery && python scripts/publish_gallery.py /tmp/gallery
"""
from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

from wooddecay.gallery.run import markdown

DOCS = Path(__file__).resolve().parent.parent / "docs"
NOTES = "<!-- notes: kept by scripts/publish_gallery.py -->"


def main(run: str) -> None:
    run = Path(run)
    result = json.loads((run / "signatures.json").read_text())
    target = DOCS / "gallery"
    shutil.rmtree(target, ignore_errors=True)
    for entry in result.values():
        for panel in entry["panels"]:
            (target / panel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(run / panel, target / panel)
    shutil.copy2(run / "signatures.json", target / "signatures.json")
    page = DOCS / "gallery.md"
    old = page.read_text() if page.is_file() else ""
    notes = old[old.index(NOTES):] if NOTES in old else NOTES + "\n"
    page.write_text(markdown(result, prefix="gallery/") + "\n" + notes)
    print(f"wrote {DOCS / 'gallery.md'} and {target}")


if __name__ == "__main__":
    main(sys.argv[1])
