"""SimState: the fields that change every step, their initial values and inoculation.

Woodstock §6 (opening), Table 3; docs/model.md §3. Per rod element: fungal activities R_w, R_b, tissue
health H_c, H_l, defence C (all in [0, 1]) and moisture M in [M_2, M_1] (kg/kg), plus the time in
days and the count of clamp activations (the safety net of Appendix A, which should stay 0).

Initial values come per tissue ([wood] H_c_init, H_l_init, C_init; [moisture] M_init; each
overridable in [tissue.*]). Inoculations ([[inoculation]], their regions resolved by
:mod:`wooddecay.strands.regions` when the model is built) raise R_w or R_b to the region's
activity at its day.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..wood import WoodModel
from . import mechanics

if TYPE_CHECKING:
    from .bark import BarkState

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
    mech: mechanics.MechState | None = None  # the rods' MechState (wooddecay.sim.mechanics), None for biology only
    bark: BarkState | None = None  # the bark's BarkState (wooddecay.sim.bark), None without a bark sheet

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
                        mech=None if self.mech is None else self.mech.copy(),
                        bark=None if self.bark is None else self.bark.copy())


def initial_state(model: WoodModel, rods: bool = False) -> SimState:
    """Fields at day 0 from the tissues (``model.materials``), then the inoculations of day 0;
    with ``rods`` also the rods at rest (:func:`wooddecay.sim.mechanics.initial_state`, before
    any coupling)."""
    mat = model.materials
    n = model.n_elements
    state = SimState(
        R_w=np.zeros(n), R_b=np.zeros(n),
        H_c=mat.per_element("H_c_init"), H_l=mat.per_element("H_l_init"),
        C=mat.per_element("C_init"), M=mat.per_element("M_init"),
    )
    inoculate(model, state)
    if rods:
        state.mech = mechanics.initial_state(model)
    return state


def inoculate(model: WoodModel, state: SimState) -> None:
    """Apply every inoculation of ``model.inoculations`` whose day has come and that was not
    applied yet."""
    for k, ino in enumerate(model.inoculations):
        if k in state.applied or ino.day > state.t_days + 1e-9:
            continue
        field_ = state.R_w if ino.fungus == "white" else state.R_b
        np.maximum(field_, np.where(ino.mask, ino.activity, 0.0), out=field_)
        state.applied.add(k)
