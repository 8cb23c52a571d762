"""Structural similarity (SSIM) of two renders (Wang, Bovik, Sheikh and Simoncelli 2004, Eq. 13),
the measure woodstock §9.5 compares its timestep renders with.

SSIM(x, y) = mean over pixels of (2 mu_x mu_y + C1)(2 sigma_xy + C2) /
((mu_x^2 + mu_y^2 + C1)(sigma_x^2 + sigma_y^2 + C2)), with local means, variances and covariance
under a Gaussian window (sigma 1.5 px, truncated at 3.5 sigma: the paper's 11 x 11 window), on the
luminance (Rec. 601 weights) in [0, 1], C1 = (0.01)^2, C2 = (0.03)^2.
"""
from __future__ import annotations

import numpy as np
from scipy.ndimage import gaussian_filter

C1 = 0.01**2
C2 = 0.03**2
SIGMA = 1.5
TRUNCATE = 3.5


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Luminance in [0, 1] of an 8-bit (h, w, 3 or 4) image, or a grey (h, w) one."""
    a = np.asarray(rgb, dtype=np.float64) / 255.0
    return a if a.ndim == 2 else a[..., :3] @ np.array([0.299, 0.587, 0.114])


def ssim(x: np.ndarray, y: np.ndarray) -> float:
    """Mean SSIM of two grey images of the same shape with values in [0, 1] (module docstring)."""
    if x.shape != y.shape:
        raise ValueError(f"images differ in shape: {x.shape} and {y.shape}")

    def blur(a):
        return gaussian_filter(a, SIGMA, truncate=TRUNCATE, mode="reflect")

    mx, my = blur(x), blur(y)
    vx = blur(x * x) - mx * mx
    vy = blur(y * y) - my * my
    cxy = blur(x * y) - mx * my
    s = ((2 * mx * my + C1) * (2 * cxy + C2)) / ((mx * mx + my * my + C1) * (vx + vy + C2))
    return float(s.mean())


def ssim_reference(x: np.ndarray, y: np.ndarray) -> float:
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
    return float(out.mean())


def ssim_png(a, b) -> float:
    """SSIM of two PNG files (their luminance)."""
    from PIL import Image

    with Image.open(a) as ia, Image.open(b) as ib:
        return ssim(luminance(np.asarray(ia.convert("RGB"))), luminance(np.asarray(ib.convert("RGB"))))
