"""Single-strand accuracy of the rod solver (SPEC §7 "Mechanics"; wooddecay.studies.cantilever):
the gravity cantilever, the tip moment and fixed-free buckling."""
from __future__ import annotations

import pytest

from wooddecay.studies import cantilever as mv


def test_cantilever_deflection_within_3_percent():
    r = mv.cantilever(dt=2e-4, iterations=2, seconds=1.0)
    assert r["error"] < 0.03, r


@pytest.mark.slow
def test_tip_moment_curls_into_a_circle():
    """SPEC §7: the tip moment 2 pi E I / L closes a clamped strand into a circle of radius
    L / (2 pi) (cantilever.tip_moment: ramped, held, strongly damped; no constraint)."""
    r = mv.tip_moment()
    assert r["gap_over_L"] <= 0.05, r
    assert abs(r["radius_error"]) < 0.02, r  # least-squares circle through the particles
    assert r["fit_rms_over_L"] < 1e-3, r
    assert r["centre_error_over_L"] < 0.01, r  # curled up (+z), not down
    # the dead moment's circle is unstable out of its plane (docs/decisions.md): the run must
    # stay on the planar path of the symmetric problem
    assert r["out_of_plane_over_L"] < 1e-6, r


@pytest.mark.slow
def test_fixed_free_buckling_load_within_5_percent():
    below = mv.buckles(0.95, dt=2e-4, iterations=2, seconds=1.0)["lateral_over_L"]
    above = mv.buckles(1.05, dt=2e-4, iterations=2, seconds=1.0)["lateral_over_L"]
    assert below < 0.05 and above > 0.2, (below, above)
