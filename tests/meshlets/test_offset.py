"""The bark contour grown by r_s (meshlets/offset.py): every offset vertex at r_s from the
contour, edges no closer, and Steiner's formula for the area of a grown convex polygon."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from wooddecay.meshlets.offset import offset_contour


def signed_area(xy):
    """Shoelace area of a closed polygon (positive when counter-clockwise)."""
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def seg_dist(q, P):
    """Distance from points q (k, 2) to the closed polygon P (m, 2) (its edges)."""
    a, b = P, np.roll(P, -1, 0)
    ab = b - a
    t = np.clip(((q[:, None] - a[None]) * ab[None]).sum(-1) / (ab * ab).sum(-1)[None], 0, 1)
    foot = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(q[:, None] - foot, axis=-1).min(1)


@pytest.mark.parametrize("join", ["round", "miter"])
def test_offset_contour_distance(join):
    rng = np.random.default_rng(8)
    # a convex contour and a non-convex star (r_s below the local feature size)
    X = rng.normal(size=(40, 2))
    hull = X[ConvexHull(X).vertices]
    k = np.arange(10)
    rad = np.where(k % 2 == 0, 2.0, 1.0)
    star = np.stack([rad * np.cos(k * np.pi / 5), rad * np.sin(k * np.pi / 5)], 1)
    r = 0.1
    for poly in (hull, star):
        Q, owner = offset_contour(poly, r, join=join, max_angle=np.pi / 16)
        assert signed_area(Q) > signed_area(poly) > 0
        assert np.all(np.diff(owner) >= 0) and owner[-1] == len(poly) - 1
        dv = seg_dist(Q, poly)
        if join == "round":
            assert np.allclose(dv, r, rtol=1e-9)               # every offset vertex at r_s
        else:
            assert np.all(dv >= r * (1 - 1e-9))
        # sample points along the offset edges
        s = rng.uniform(0, 1, (len(Q), 5))
        samples = (Q[:, None] + s[..., None] * (np.roll(Q, -1, 0) - Q)[:, None]).reshape(-1, 2)
        ds = seg_dist(samples, poly)
        lo = r * np.cos(np.pi / 32) * (1 - 1e-9) if join == "round" else r * (1 - 1e-9)
        assert np.all(ds >= lo)
        if join == "round":
            assert np.all(ds <= r * (1 + 1e-9))
    # Steiner: a convex polygon grown by r has area A + perimeter r + pi r^2 (chords: slightly less)
    Q, _ = offset_contour(hull, r, max_angle=np.pi / 64)
    per = np.linalg.norm(np.roll(hull, -1, 0) - hull, axis=1).sum()
    steiner = signed_area(hull) + per * r + np.pi * r * r
    assert signed_area(Q) == pytest.approx(steiner, rel=1e-4)
    assert signed_area(Q) <= steiner
