"""Growth rings by reversed growth of a cross-section contour, and the tissue of each element.

branch-fracture §3.3: ring boundaries are the successive erosions of the outer contour (the
iso-lines of the distance to the boundary), with the innermost rings blended towards a
near-circular contour around the pith (their Fig. 7) and eccentric rings from direction-
dependent erosion (their Fig. 8). woodification §4.1-4.3: the annual ring width follows the
Weibull growth rate s(t) = c t^(c-1) exp(-t^c) (Eq. 2), eccentricity scales the growth by
(1 + e n.y) (Eq. 3), and the interior rings are the reversed (eroded) growth of the adult
surface.

Construction per profile (all 2D, node frame):

* eccentric depth  d_e(x) = bd(x) / (1 + e n(x).y), n the outward direction from the
  profile centroid, y the world up projected into the section. For e > 0 the upper side erodes
  faster (wider rings there) and the pith moves down.
* the pith x_p is the maximum of d_e; the outer radial coordinate q_out = 1 - d_e / d_e(x_p)
  (0 at the pith, 1 on the bark) follows the contour, the inner one q_in = |x - x_p| / d_e(x_p)
  is circular; q blends q_in -> q_out over the inner ``pith_blend`` fraction.
* the number of years is Y = max(1, round(R_eq / ring_width)); year j (0 at the pith) has width
  proportional to s(t_j), t_j the tree's age in Weibull time when the ring formed (the tree's
  life, its oldest section's Y years, spans [T_BIRTH, T_LIFE]), times a per-calendar-year noise
  factor shared by the whole tree; the cumulative normalised widths Q_j map q to the ring age
  (fractional years from the pith). Between two profiles an element's q is interpolated and
mapped through both profiles' ring tables, so age stays monotone in q along an edge.
"""
from __future__ import annotations

import numpy as np

from .. import fmath as fm
from .profiles import Profile, contains, signed_distance

#: the tree's life in Weibull time [T_BIRTH, T_LIFE]: juvenile rise, "prime of life" peak,
#: mature decline (c = 2). Starting above 0 keeps the first rings of a sapling finite in width.
T_BIRTH, T_LIFE = 0.3, 2.0
#: grid resolution used to locate the pith (maximum of the eccentric depth)
PITH_GRID = 32

BARK, SAPWOOD, HEARTWOOD, PITH = 0, 1, 2, 3
TISSUES = ("bark", "sapwood", "heartwood", "pith")


def weibull_rate(t: np.ndarray, c: float) -> np.ndarray:
    """s(t) = c t^(c-1) exp(-t^c), woodification Eq. 2."""
    return c * fm.power(t, c - 1.0) * fm.exp(-fm.power(t, c))


def year_noise(max_years: int, width_noise: float, rng: np.random.Generator) -> np.ndarray:
    """Per calendar year width factor (index 0 = the outermost, most recent ring)."""
    return np.clip(rng.normal(1.0, width_noise, max_years), 0.1, None)


def cumulative_widths(years: int, c: float, noise: np.ndarray, tree_years: int) -> np.ndarray:
    """Q (years + 1,): normalised radius at the end of each year from the pith, Q_0 = 0, Q_Y = 1.

    Weibull time is the tree's age (woodification §4.1): a section with ``years`` rings in a tree
    of ``tree_years`` was formed in the last ``years`` years, t in [T_BIRTH, T_LIFE] over the
    tree's life, so a twig's rings are those of the mature (declining) years.
    """
    first = tree_years - years
    t = T_BIRTH + (first + np.arange(years) + 0.5) / tree_years * (T_LIFE - T_BIRTH)
    w = weibull_rate(t, c) * noise[:years][::-1]
    return np.concatenate([[0.0], np.cumsum(w) / w.sum()])


def eccentric_depth(profile: Profile, up2d: np.ndarray, e: float, pts: np.ndarray) -> np.ndarray:
    """d_e = bd / (1 + e n.y): the depth whose iso-lines are the eccentric erosion fronts."""
    rel = pts - profile.centroid
    n = rel / np.maximum(np.linalg.norm(rel, axis=1, keepdims=True), 1e-300)
    return np.maximum(signed_distance(profile.polygon, pts), 0.0) / (1.0 + e * (n @ up2d))


def find_pith(profile: Profile, up2d: np.ndarray, e: float) -> tuple[np.ndarray, float]:
    """Pith position (maximum of the eccentric depth on a grid) and the depth there."""
    lo, hi = profile.polygon.min(axis=0), profile.polygon.max(axis=0)
    g = (np.arange(PITH_GRID) + 0.5) / PITH_GRID
    pts = np.stack(np.meshgrid(lo[0] + g * (hi[0] - lo[0]), lo[1] + g * (hi[1] - lo[1])), -1).reshape(-1, 2)
    pts = np.vstack([pts[contains(profile.polygon, pts)], profile.centroid[None]])
    d = eccentric_depth(profile, up2d, e, pts)
    k = int(np.argmax(d))
    return pts[k], max(float(d[k]), 1e-300)


def radial_coordinate(
    profile: Profile, up2d: np.ndarray, e: float, pith_blend: float, pts: np.ndarray
) -> np.ndarray:
    """q in [0, 1]: 0 at the pith, 1 on the bark (see module docstring)."""
    pith, d_max = find_pith(profile, up2d, e)
    q_out = np.clip(1.0 - eccentric_depth(profile, up2d, e, pts) / d_max, 0.0, 1.0)
    q_in = np.linalg.norm(pts - pith, axis=1) / d_max
    if pith_blend <= 0.0:
        return q_out
    z = np.clip(q_out / pith_blend, 0.0, 1.0)
    w = 1.0 - z * z * (3.0 - 2.0 * z)  # 1 at the pith, 0 from q_out >= pith_blend on
    return np.clip(w * q_in + (1.0 - w) * q_out, 0.0, 1.0)


def profile_years(profile: Profile, ring_width: float) -> int:
    """Rings in a cross-section: its equivalent radius over the mean ring width."""
    return max(1, int(round(profile.equivalent_radius / ring_width)))


def age_of(q: np.ndarray, years: int, weibull_c: float, noise: np.ndarray, tree_years: int) -> np.ndarray:
    """Fractional ring age (years from the pith) at radial coordinate ``q`` of a section with
    ``years`` rings: the inverse of the cumulative ring widths."""
    Q = cumulative_widths(years, weibull_c, noise, tree_years)
    return np.interp(q, Q, np.arange(years + 1, dtype=np.float64))


def classify_tissue(
    bd: np.ndarray,
    age: np.ndarray,
    years: np.ndarray,
    *,
    bark_thickness: float,
    sapwood_rings: int,
    pith_rings: int,
) -> np.ndarray:
    """Tissue code per element: bark (bd < bark thickness), pith (the first ``pith_rings``
    rings), sapwood (the outermost ``sapwood_rings`` rings), heartwood (the rest)."""
    tissue = np.full(len(bd), HEARTWOOD, dtype=np.int8)
    tissue[years - age < sapwood_rings] = SAPWOOD
    tissue[age < pith_rings] = PITH
    tissue[bd < bark_thickness] = BARK
    return tissue
