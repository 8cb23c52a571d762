"""`wooddecay chart schedule` (issue 20 item 5): the adaptive schedule's largest position
difference to the fixed one against wall time over its tolerances, written as a PNG."""
from __future__ import annotations

import re

from click.testing import CliRunner

from wooddecay.cli import main
from wooddecay.studies.schedule import settings

from ..conftest import SAMPLES

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_chart_schedule_on_a_short_tiny_run(tmp_path):
    out = tmp_path / "schedule.png"
    r = CliRunner().invoke(main, ["chart", "schedule", str(SAMPLES / "tiny.toml"), "--days", "3", "-o", str(out)],
                           catch_exceptions=False)
    assert r.exit_code == 0, r.output
    assert out.read_bytes().startswith(PNG_MAGIC) and out.stat().st_size > 1000
    lines = [ln for ln in r.output.splitlines() if " s wall" in ln]
    assert [ln.split(":")[0].strip() for ln in lines] == ["fixed", "adaptive x0.25", "adaptive x1", "adaptive x4"]
    chunks = [int(re.search(r" in (\d+) chunks", ln).group(1)) for ln in lines]
    assert chunks[0] == 6 and all(c <= chunks[0] * 20 for c in chunks[1:])
    assert float(re.search(r"difference (\S+) m", lines[0]).group(1)) == 0.0
    assert not [p for p in tmp_path.iterdir() if p != out]


def test_chart_schedule_names_a_bad_scene_in_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[time]\nschedule = 'sometimes'\n")
    r = CliRunner().invoke(main, ["chart", "schedule", str(bad), "-o", str(tmp_path / "x.png")])
    assert r.exit_code == 2 and "time.schedule" in r.output and not (tmp_path / "x.png").exists()


def test_a_study_scales_the_tolerances_it_is_given():
    scene = str(SAMPLES / "tiny.toml")
    sets = settings(scene, "adaptive", 4.0, overrides={"time.tolerance": 0.05, "time.days": 3.0})
    assert sets["time.tolerance"] == 0.2 and sets["time.days"] == 3.0 and sets["time.schedule"] == "adaptive"
    plain = settings(scene, "adaptive", 4.0)
    assert plain["time.strain_tolerance"] == sets["time.strain_tolerance"] and plain["time.tolerance"] != 0.2
    assert "time.tolerance" not in settings(scene, "fixed", 4.0)
