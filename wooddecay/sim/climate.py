"""The environment that wets and dries the wood: seasons, exposed surfaces and ground contact.

Eq. 15 (woodstock §6) exchanges moisture with the surroundings through k_in (uptake towards M_1)
and k_out (loss towards M_2), both functions of the distance bd to the bark. A climate modulates
them over the year and adds the soil (docs/model.md §8):

    k_in  = w_in(t) k_in0 max(0, 1 - k_r_in bd) H_c + w_ground(t) k_ground g,
    k_out = w_out(t) k_out0 max(0, 1 - k_r_out H_c) max(0, bd_0 - bd),

* ``w_in``, ``w_out``, ``w_ground``: seasonal factors, keyframes by day of the year interpolated
  linearly and repeated every year (:data:`PRESETS`, or ``[climate] seasons``);
* ``bd``: the distance to the nearest exposed surface, the bark or a cut end of the wood (a log's
  end grain dries and wets too: :func:`exposure_distance`);
* ``g``: 1 where the element touches the ground (its lowest point within ``ground_depth`` of the
  ground plane, at the rods' current positions: a fallen block starts to soak), else 0;
  ground water needs no carbohydrates to enter, so this term is not scaled by H_c.

``constant`` is Table 3's Eq. 15 unchanged (factors 1, no ground), for the paper's figures.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..wood import WoodModel
from ..wood import DAYS_PER_YEAR as YEAR_DAYS

#: seasonal keyframes [day of year, w_in, w_out, w_ground]; day 0 is 1 January (northern
#: hemisphere). The factors scale the Table 3 exchange rates; a surface in equilibrium sits at
#: M = (w_in k_in M_1 + w_out k_out M_2) / (w_in k_in + w_out k_out) (docs/decisions.md,
#: "Climates").
PRESETS: dict[str, tuple[tuple[float, float, float, float], ...]] = {
    # Table 3's Eq. 15: the surface settles at M = 0.7 and the wood never dries
    "constant": ((0.0, 1.0, 1.0, 0.0),),
    # cool temperate: wet winters (surface ~0.85), dry summers from June to mid-September
    # (surface ~0.16, below M_0 = 0.2)
    "temperate": ((15.0, 1.5, 0.5, 1.0), (105.0, 0.8, 2.0, 1.0), (152.0, 0.2, 6.0, 0.5), (258.0, 0.2, 6.0, 0.5),
                  (305.0, 1.5, 0.8, 1.0)),
    # dry (a Mediterranean yard, a shed): the surface dries to ~0.15 in winter, ~0.11 in summer
    "dry": ((15.0, 0.3, 4.0, 0.0), (196.0, 0.05, 8.0, 0.0)),
    # a forest floor: wet soil under the wood all year, short summer drying of the exposed top
    "wet-ground": ((15.0, 2.0, 0.3, 3.0), (105.0, 1.5, 1.0, 3.0), (196.0, 0.5, 4.0, 2.0), (288.0, 2.0, 0.5, 3.0)),
}


@dataclass(frozen=True, eq=False)
class Climate:
    """A resolved ``[climate]``: periodic keyframes and the ground's wetting."""

    days: np.ndarray  # (k,) day of the year of each keyframe, increasing in [0, YEAR_DAYS)
    start_day: float  # day of the year of the bake's day 0
    w: np.ndarray  # (k, 3) w_in, w_out, w_ground
    k_ground: float  # 1/day uptake where the wood touches the ground
    ground_z: float | None  # the ground plane's height, None without a ground
    ground_depth: float  # m: an element within this of the ground touches it

    @property
    def w_max(self) -> np.ndarray:
        """(3,) the largest w_in, w_out, w_ground of the year (the stability bound's)."""
        return self.w.max(axis=0)

    def factors(self, t_days: float) -> np.ndarray:
        """(3,) w_in, w_out, w_ground on day ``t_days`` of the bake: linear between keyframes,
        wrapping from the year's last keyframe to the next year's first."""
        d = np.concatenate([self.days[-1:] - YEAR_DAYS, self.days, self.days[:1] + YEAR_DAYS])
        w = np.concatenate([self.w[-1:], self.w, self.w[:1]])
        t = (float(t_days) + self.start_day) % YEAR_DAYS
        return np.array([np.interp(t, d, w[:, j]) for j in range(3)])


def exposure_distance(model: WoodModel) -> np.ndarray:
    """(n,) distance of each element to the nearest exposed surface: its bark distance, or
    along its strand to a cut end when the strand reaches one (the first node of a skeleton
    root that is not anchored in the ground, or a tip: a node without children)."""
    skel, topo = model.skeleton, model.topology
    first = model.cp_offsets[:-1]
    last = model.cp_offsets[1:] - 1
    node0, node1 = model.cp_node[first], model.cp_node[last]
    leaf = np.array([len(c) == 0 for c in topo.children], dtype=bool)
    open0 = (skel.parent[node0] < 0) & ~skel.anchored[node0]
    # a strand that stops part-way along an edge ends inside the wood
    open1 = leaf[node1] & np.isclose(model.cp_s[last], topo.s[node1])
    s = model.wood_coords[:, 2]
    k = model.strand
    to0 = np.where(open0[k], s - model.cp_s[first][k], np.inf)
    to1 = np.where(open1[k], model.cp_s[last][k] - s, np.inf)
    return np.minimum(model.bark_distance, np.maximum(0.0, np.minimum(to0, to1)))


def ground_contact(model: WoodModel, climate: Climate, x: np.ndarray) -> np.ndarray:
    """(n,) 1.0 where an element's lowest point (its particles at ``x`` less its radius) lies
    within ``ground_depth`` of the ground, else 0.0 (all 0 without a ground)."""
    if climate.ground_z is None or climate.k_ground == 0.0:
        return np.zeros(model.n_elements)
    fp = model.first_particle
    low = np.minimum(x[fp, 2], x[fp + 1, 2]) - model.radius
    return (low <= climate.ground_z + climate.ground_depth).astype(np.float64)
