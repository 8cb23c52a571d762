"""docs/scene.md is written from the scene schema (wooddecay.scene.docs): the committed page is
what the generator writes now, so a schema change without regenerating the page fails here."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from wooddecay.scene import PARAMS, TABLES
from wooddecay.scene_docs import COMMAND, DOCS_PATH, scene_docs
from wooddecay.strands.skeleton import NODE_KEYS
from wooddecay.strands.skeleton_loader import TABLE_KEYS

ROOT = Path(__file__).resolve().parents[2]


def test_committed_scene_docs_are_current():
    committed = (ROOT / DOCS_PATH).read_text("utf-8")
    assert committed == scene_docs(), (
        f"{DOCS_PATH} differs from what the scene schema (wooddecay/scene/schema.py) generates; "
        f"regenerate it with: {COMMAND}")


def test_scene_docs_list_every_table_and_key():
    text = scene_docs()
    for section, table in PARAMS.items():
        assert f"\n## [{section}]\n" in text
        for name in table:
            assert f"| `{name}` |" in text, f"{section}.{name}"
    for name, table in TABLES.items():
        for key in list(table.keys) + [k for kind in table.kinds.values() for k in kind]:
            assert f"| `{key}` |" in text, f"{name}.{key}"
    for key in TABLE_KEYS + NODE_KEYS:
        assert f"| `{key}` |" in text, f"skeleton {key}"
    assert "\n## [skeleton]\n" in text and "\n## [tissue.&lt;tissue&gt;]\n" in text
    assert "\n## Format version\n" in text


def test_scene_docs_rows_give_default_unit_range_and_meaning():
    text = scene_docs()
    assert "| `r_s` | 0.006 | m | (0, 1] | Strand radius r_s" in text
    assert "| `format` | 1 |  | [1, 1] | Version of the scene file format" in text
    assert "| `connect_radius` | 2.5 * r_s | m |" in text
    assert '| `quality` | "final" |  | one of \'draft\', \'final\' |' in text
    assert "| `threshold` | from `species` |" in text
    assert "| `fungus` | required |  | one of 'white', 'brown' |" in text
    assert "&lt;name&gt;.usdc" in text  # no raw <name> for Markdown to take for a tag
    assert all(line.count("|") - line.count("\\|") == 6 for line in text.splitlines() if line.startswith("| `"))


def test_the_script_checks_the_committed_page():
    r = subprocess.run([sys.executable, str(ROOT / "scripts" / "write_scene_docs.py"), "--check"],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0 and "up to date" in r.stdout, r.stderr
