"""SSIM of two 480 x 270 renders (wooddecay.gallery.ssim) against its per-pixel reference
(ssim_reference) on a 48 x 27 crop: seconds (median and spread of 7 runs) and the difference.

    python benchmarks/ssim.py
"""
from __future__ import annotations

import time

import numpy as np

from wooddecay.gallery.ssim import ssim, ssim_reference


def main() -> None:
    rng = np.random.default_rng(1)
    x = rng.random((270, 480))
    y = np.clip(x + 0.05 * rng.standard_normal(x.shape), 0, 1)
    times = []
    for _ in range(7):
        t0 = time.perf_counter()
        ssim(x, y)
        times.append(time.perf_counter() - t0)
    t = np.array(times) * 1e3
    print(f"ssim_480x270_ms {np.median(t):.2f} (min {t.min():.2f}, max {t.max():.2f}, 7 runs)")
    c = (slice(0, 27), slice(0, 48))
    t0 = time.perf_counter()
    ref = ssim_reference(x[c], y[c])
    t_ref = time.perf_counter() - t0
    print(f"reference_48x27_s {t_ref:.2f}; ssim_vs_reference_difference {abs(ssim(x[c], y[c]) - ref):.2e}")


if __name__ == "__main__":
    main()
