"""Transport accuracy on the irregular rod graph (SPEC §7; wooddecay.studies.transport): heat
kernels and Fisher-KPP fronts along e_l, e_r and e_t."""
from __future__ import annotations

import pytest

from wooddecay.studies.transport import fisher_speed_ratio, heat_kernel_ratio


@pytest.mark.slow
@pytest.mark.parametrize("direction", ["l", "r", "t"])
def test_heat_kernel_variance_grows_as_2Dt(direction):
    """A point release on the irregular rod graph: d var / dt = 2 D a_dir within 3%."""
    ratio, clamps = heat_kernel_ratio(direction)
    assert ratio == pytest.approx(1.0, abs=0.03)
    assert clamps == 0


@pytest.mark.slow
@pytest.mark.parametrize("direction", ["l", "r", "t"])
def test_fisher_kpp_front_speed(direction):
    """Planar Fisher-KPP fronts move at 2 sqrt(alpha D_dir) within 5% (long-time fit with
    Bramson's correction; wooddecay.studies.transport)."""
    ratio, clamps = fisher_speed_ratio(direction)
    assert ratio == pytest.approx(1.0, abs=0.05)
    assert clamps == 0
