"""SSIM of renders (wooddecay.gallery.ssim; woodstock §9.5): against a per-pixel reference and the
closed form for constant images."""
from __future__ import annotations

import numpy as np
import pytest

from wooddecay.gallery.ssim import C1, luminance, ssim, ssim_reference


def test_matches_the_per_pixel_reference():
    rng = np.random.default_rng(3)
    x = rng.random((14, 17))
    y = np.clip(x + 0.1 * rng.standard_normal(x.shape), 0, 1)
    assert ssim(x, y) == pytest.approx(ssim_reference(x, y), abs=1e-12)


def test_constant_images_give_the_luminance_term():
    x, y = np.full((20, 20), 0.3), np.full((20, 20), 0.6)
    assert ssim(x, y) == pytest.approx((2 * 0.3 * 0.6 + C1) / (0.3**2 + 0.6**2 + C1), rel=1e-12)


def test_identity_symmetry_and_noise():
    rng = np.random.default_rng(0)
    x = luminance(rng.integers(0, 256, (40, 60, 3)))
    assert ssim(x, x) == pytest.approx(1.0, abs=1e-12)
    noisy = [np.clip(x + s * rng.standard_normal(x.shape), 0, 1) for s in (0.01, 0.05, 0.2)]
    values = [ssim(x, n) for n in noisy]
    assert values == sorted(values, reverse=True) and values[-1] < 0.9
    assert ssim(x, noisy[1]) == pytest.approx(ssim(noisy[1], x), abs=1e-15)
    with pytest.raises(ValueError):
        ssim(x, x[:-1])
