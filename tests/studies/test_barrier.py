"""The barrier effect (woodstock §9.4, Fig. 18; wooddecay.studies.barrier) and its chart."""
from __future__ import annotations

from click.testing import CliRunner

from wooddecay.cli import main
from wooddecay.studies.barrier import RATIOS, run_barrier


def test_barrier_plateau_lengthens_with_inhibition():
    runs = [run_barrier(r) for r in RATIOS]
    lengths = [r.plateau for r in runs]
    assert lengths[0] == 0.0
    assert all(b > a + 50 for a, b in zip(lengths, lengths[1:])), lengths
    assert all(r.mass_loss[-1] < runs[0].mass_loss[-1] for r in runs[1:])


def test_chart_barrier_writes_png(tmp_path):
    out = tmp_path / "barrier.png"
    r = CliRunner().invoke(main, ["chart", "barrier", "-o", str(out), "--days", "400"])
    assert r.exit_code == 0, r.output
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and "plateau" in r.stdout
