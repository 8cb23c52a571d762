"""`wooddecay chart mechanics` (issue 4 item 7; docs/model.md §7): the cantilever's error against wall
time over dt and iterations, with PyElastica's point, written as a PNG."""
from __future__ import annotations

import re

from click.testing import CliRunner

from wooddecay.cli import main

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_chart_mechanics_quick(tmp_path):
    out = tmp_path / "mech.png"
    r = CliRunner().invoke(main, ["chart", "mechanics", "--quick", "-o", str(out)], catch_exceptions=False)
    assert r.exit_code == 0, r.output
    data = out.read_bytes()
    assert len(data) > 1000 and data.startswith(PNG_MAGIC)
    assert not [p for p in tmp_path.iterdir() if p != out]  # the temp file was moved, not left
    lines = [ln for ln in r.output.splitlines() if " error " in ln]
    ref = [ln for ln in lines if ln.startswith("PyElastica")]
    ours = [ln for ln in lines if ln.startswith("wooddecay")]
    assert len(ref) == 1 and len(ours) == 6  # 3 dt x 2 iterations
    errors = [float(re.search(r" error (\S+)", ln).group(1)) for ln in ours]
    assert min(errors) < 0.03  # at least one setting meets the 3% target
    assert float(re.search(r" error (\S+)", ref[0]).group(1)) < 0.03
    assert r.output.rstrip().endswith(f"wrote {out}")
