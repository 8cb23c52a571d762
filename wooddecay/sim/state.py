"""SimState: the fields that change every step, their initial values and inoculation.

Woodstock §6 (opening), Table 3; SPEC §3. Per rod element: fungal activities R_w, R_b, tissue
health H_c, H_l, defence C (all in [0, 1]) and moisture M in [M_2, M_1] (kg/kg), plus the time in
days and the count of clamp activations (the safety net of Appendix A, which should stay 0).

Initial values come per tissue ([wood] H_c_init, H_l_init, C_init; [moisture] M_init; each
overridable in [tissue.*]). Inoculation regions ([[inoculation]]) raise R_w or R_b to the
region's activity at its day: a box or sphere in world or wood-local coordinates, a sphere around
a skeleton node, a log end (elements within ``depth`` of the root, or of a branch's tip, along
the skeleton) or a bark wound (a sphere on the surface, restricted to bark distance < depth).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..strands.rings import TISSUES

FIELDS = ("R_w", "R_b", "H_c", "H_l", "C", "M")


@dataclass(eq=False)
class SimState:
    """Mutable per-element fields (names as in the paper) and the clock."""

    R_w: np.ndarray
    R_b: np.ndarray
    H_c: np.ndarray
    H_l: np.ndarray
    C: np.ndarray
    M: np.ndarray
    t_days: float = 0.0
    clamp_count: int = 0
    applied: set = field(default_factory=set)  # inoculations already applied (by index)
    mech: object = None  # the rods' MechState (wooddecay.sim.mechanics), None for biology only

    @property
    def integrity(self):
        """I_ij per REG edge (Eq. 21); needs mechanics."""
        return self.mech.integrity

    @property
    def component(self):
        """Connected-component label per element; needs mechanics."""
        return self.mech.component

    def fields(self) -> dict[str, np.ndarray]:
        return {name: getattr(self, name) for name in FIELDS}

    def copy(self) -> "SimState":
        return SimState(**{k: v.copy() for k, v in self.fields().items()}, t_days=self.t_days,
                        clamp_count=self.clamp_count, applied=set(self.applied),
                        mech=None if self.mech is None else self.mech.copy())


def tissue_values(scene, tissue: np.ndarray, name: str) -> np.ndarray:
    """Per-element value of a per-tissue parameter (override, else the section's value)."""
    return np.array([scene.tissue_param(t, name) for t in TISSUES], dtype=np.float64)[tissue]


def initial_state(model, scene) -> SimState:
    """Fields at day 0 from the tissues, then the inoculations of day 0."""
    tissue = model.tissue
    n = model.n_elements
    state = SimState(
        R_w=np.zeros(n), R_b=np.zeros(n),
        H_c=tissue_values(scene, tissue, "H_c_init"),
        H_l=tissue_values(scene, tissue, "H_l_init"),
        C=tissue_values(scene, tissue, "C_init"),
        M=tissue_values(scene, tissue, "M_init"),
    )
    inoculate(model, scene, state)
    return state


def _wood_cartesian(wood_coords: np.ndarray) -> np.ndarray:
    r, phi, s = wood_coords.T
    return np.stack([r * np.cos(phi), r * np.sin(phi), s], axis=1)


def region_mask(model, scene, region) -> np.ndarray:
    """Elements whose centre lies in an inoculation / load region (see module docstring)."""
    kind = region["kind"]
    wood = region.get("space", "world") == "wood"
    if kind == "box":
        x = model.wood_coords if wood else model.centers
        lo, hi = np.asarray(region["min"]), np.asarray(region["max"])
        return np.all((x >= lo) & (x <= hi), axis=1)
    if kind == "sphere":
        if wood:
            x = _wood_cartesian(model.wood_coords)
            r, phi, s = region["center"]
            c = np.array([r * np.cos(phi), r * np.sin(phi), s])
        else:
            x, c = model.centers, np.asarray(region["center"])
        return np.linalg.norm(x - c, axis=1) <= region["radius"]
    if kind == "node":
        c = scene.skeleton.positions[scene.skeleton.ids.index(str(region["id"]))]
        return np.linalg.norm(model.centers - c, axis=1) <= region["radius"]
    if kind == "end":
        s = model.wood_coords[:, 2]
        if region.get("which", "root") == "root":
            return s <= region["depth"]
        s_end = np.zeros(model.n_branches)
        np.maximum.at(s_end, model.branch, s)
        return s_end[model.branch] - s <= region["depth"]
    if kind == "wound":
        near = np.linalg.norm(model.centers - np.asarray(region["position"]), axis=1) <= region["radius"]
        return near & (model.bark_distance <= region["depth"])
    raise ValueError(f"unknown region kind {kind!r}")  # the scene validator rules this out


def inoculate(model, scene, state: SimState) -> None:
    """Apply every inoculation whose day has come and that was not applied yet."""
    for k, ino in enumerate(scene.inoculations):
        if k in state.applied or ino["day"] > state.t_days + 1e-9:
            continue
        field_ = state.R_w if ino["fungus"] == "white" else state.R_b
        mask = region_mask(model, scene, ino["region"])
        np.maximum(field_, np.where(mask, ino["activity"], 0.0), out=field_)
        state.applied.add(k)
