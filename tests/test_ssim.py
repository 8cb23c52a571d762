"""SSIM of renders (wooddecay.gallery.ssim; woodstock §9.5): against a per-pixel reference and the
closed form for constant images."""
from __future__ import annotations

import numpy as np
import pytest

from wooddecay.gallery.ssim import C1, C2, SIGMA, TRUNCATE, luminance, ssim


def _reference(x, y):
    """Per-pixel SSIM with an explicit normalised Gaussian window over a reflected border (the
    same window as scipy's gaussian_filter: radius int(TRUNCATE * SIGMA + 0.5))."""
    r = int(TRUNCATE * SIGMA + 0.5)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / SIGMA) ** 2)
    w = np.outer(k, k) / np.outer(k, k).sum()
    px, py = (np.pad(a, r, mode="symmetric") for a in (x, y))
    out = np.empty(x.shape)
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            a, b = px[i:i + 2 * r + 1, j:j + 2 * r + 1], py[i:i + 2 * r + 1, j:j + 2 * r + 1]
            mx, my = (w * a).sum(), (w * b).sum()
            vx, vy = (w * a * a).sum() - mx * mx, (w * b * b).sum() - my * my
            cxy = (w * a * b).sum() - mx * my
            out[i, j] = (2 * mx * my + C1) * (2 * cxy + C2) / ((mx * mx + my * my + C1) * (vx + vy + C2))
    return out.mean()


def test_matches_the_per_pixel_reference():
    rng = np.random.default_rng(3)
    x = rng.random((14, 17))
    y = np.clip(x + 0.1 * rng.standard_normal(x.shape), 0, 1)
    assert ssim(x, y) == pytest.approx(_reference(x, y), abs=1e-12)


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
