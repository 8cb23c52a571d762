"""PyElastica reference run: a clamped rod sagging under gravity against beam theory."""
from __future__ import annotations

import math

import pytest

from wooddecay.studies.elastica import elastica_cantilever

KEYS = {"deflection", "analytic", "error", "seconds", "steps", "n_elements"}


@pytest.mark.slow
def test_default_cantilever_matches_beam_theory():
    res = elastica_cantilever()
    assert KEYS <= set(res)
    assert res["n_elements"] == 20
    assert res["steps"] > 0 and res["seconds"] > 0.0
    assert math.isclose(res["analytic"], 450.0 * 9.81 * 0.5**4 / (2 * 1e9 * 0.006**2))
    assert math.isclose(res["analytic"], 3.83e-3, rel_tol=1e-3)
    assert res["drift"] < 1e-3  # settled
    assert res["error"] < 0.03
