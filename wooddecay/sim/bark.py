"""The bark solver of the simulation loop: cracks from growth and drying, bonds, shedding (docs/model.md §10).

``initial(model, state)`` gives every face of the sheet its initial bond to the wood
(:attr:`~wooddecay.bark.sheet.BarkSheet.bond`) and loads the sheet (:mod:`wooddecay.bark.sheet`) with the growth strain
its rings record, in ``GROWTH_STAGES`` equal increments (the bark cracked over the tree's life,
so earlier cracks shadow later ones, :mod:`wooddecay.bark.cracks`), then with the drying strain
of the moisture at day 0. ``step(model, state, dt)`` after each biology step and coupling:
the loading strain of each face from its element's moisture, cracks grown under it, the bonds
weakened (:mod:`wooddecay.bark.shedding`), the plates whose bond is gone shed, and the cuts of
every shed plate applied to the rods (integrity and limits 0 on the cut pairs and links; the
coupling recomputes them every step, so the cuts are applied after it every time).
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from ..wood import DAYS_PER_YEAR, WoodModel
from ..bark import cracks, shedding
from .events import Events

#: increments in which the growth strain is applied at day 0
GROWTH_STAGES = 20


@dataclass(eq=False)
class BarkState:
    """The sheet's cracks (:class:`~wooddecay.bark.cracks.CrackState`), every face's bond, whether
    it has shed and the moisture it last saw, and the rods' cuts of the shed plates."""

    crack: cracks.CrackState
    bond: np.ndarray  # (F,)
    shed: np.ndarray  # (F,) bool
    M_last: np.ndarray  # (F,)
    eps_seen: np.ndarray  # (F,) the largest loading strain each face has cracked under
    edge_cut: np.ndarray  # (m,) bool
    link_cut: np.ndarray  # (n,) bool

    def arrays(self) -> dict[str, np.ndarray]:
        return {"cracked": self.crack.cracked, "shadow": self.crack.shadow, "bond": self.bond, "shed": self.shed,
                "M_last": self.M_last, "eps_seen": self.eps_seen, "edge_cut": self.edge_cut,
                "link_cut": self.link_cut}

    def copy(self) -> "BarkState":
        return BarkState.from_arrays({k: v.copy() for k, v in self.arrays().items()})

    @classmethod
    def from_arrays(cls, a: dict) -> "BarkState":
        return cls(crack=cracks.CrackState(cracked=a["cracked"], shadow=a["shadow"]), bond=a["bond"], shed=a["shed"],
                   M_last=a["M_last"], eps_seen=a["eps_seen"], edge_cut=a["edge_cut"], link_cut=a["link_cut"])


def drying_strain(sheet, M_face: np.ndarray) -> np.ndarray:
    """S S_T (M_0 - M)^+ of each face's element (woodstock Eq. 16 on the bark)."""
    return sheet.shrinkage * np.maximum(sheet.M_0 - M_face, 0.0)


def _strain(model: WoodModel, M_face: np.ndarray) -> np.ndarray:
    assert model.bark is not None and model.bark_setup is not None
    return model.bark.growth + float(model.bark_setup.drying) * drying_strain(model.bark, M_face)


def _grow(model: WoodModel, st: BarkState, eps: np.ndarray, rose: bool | None = None) -> None:
    """Cracks under the loading ``eps``; none can start where no face's loading rose above what
    it already cracked under (each face's stress is linear in its loading, the shadows only grow),
    so then the search is skipped. ``rose``: whether any face's did, if the caller knows."""
    if rose is None:
        rose = not (eps <= st.eps_seen).all()
    if not rose:
        return
    st.eps_seen = np.maximum(st.eps_seen, eps)
    b = model.bark_setup
    assert b is not None
    cracks.grow(model.bark, st.crack, eps, float(b.tip_gain), float(b.shadow))


def uncracked(model: WoodModel, state) -> BarkState | None:
    """The bark of ``state`` before any crack: whole, bonded, nothing shed; None without a sheet."""
    sheet = model.bark
    if sheet is None:
        return None
    M_face = state.M[sheet.face_element]
    return BarkState(crack=cracks.CrackState.empty(sheet), bond=sheet.bond.copy(),
                     shed=np.zeros(sheet.n_faces, dtype=bool), M_last=M_face.copy(), eps_seen=np.zeros(sheet.n_faces),
                     edge_cut=np.zeros(model.n_edges, dtype=bool), link_cut=np.zeros(model.n_elements, dtype=bool))


def initial(model: WoodModel, state) -> BarkState | None:
    """The bark at day 0 (module docstring); None without a sheet."""
    st = uncracked(model, state)
    if st is None:
        return None
    assert model.bark is not None  # uncracked gave a state: there is a sheet
    for k in range(1, GROWTH_STAGES + 1):
        _grow(model, st, model.bark.growth * (k / GROWTH_STAGES))
    _grow(model, st, _strain(model, st.M_last))
    return st


def advance(model: WoodModel, state, dt: float) -> Events:
    """The driver's bark solver (:mod:`~wooddecay.sim.events`): :func:`step` over ``dt`` days."""
    return Events(searched=step(model, state, dt))


def step(model: WoodModel, state, dt_days: float) -> bool:
    """One bark step after the biology and the coupling (module docstring); returns whether it
    searched for new cracks."""
    st: BarkState | None = state.bark
    if st is None:
        return False
    sheet, b = model.bark, model.bark_setup
    assert sheet is not None and b is not None  # a BarkState exists only with a sheet
    eps = np.empty(sheet.n_faces)
    rose, loose = _faces(sheet.face_element, state.M, state.H_c, state.H_l, sheet.growth, float(b.drying),
                         sheet.shrinkage, sheet.M_0, float(b.shedding), float(dt_days), st.eps_seen, st.bond,
                         st.M_last, st.shed, eps)
    _grow(model, st, eps, rose > 0)
    if loose:  # else no plate comes off: its mean bond exceeds its least face's
        _shed(model, st)
    if state.mech is not None:
        apply_cuts(state.mech, st)
    return bool(rose > 0)


@nb.njit(parallel=True, cache=True)
def _faces(fe, M, H_c, H_l, growth, drying, shrinkage, M_0, rate, dt_days, eps_seen, bond, M_last, shed, eps):
    """One pass over the faces of a step: each face's loading strain into ``eps`` (:func:`_strain`
    of its element's moisture), its bond weakened in place (:func:`shedding.weaken`) and its
    ``M_last`` set to that moisture, in the numpy twins' operation order (the same bits). Returns
    the number of faces whose loading rose above ``eps_seen`` and of faces still on whose bond is
    gone. Why: the twins' gathers and temporaries over the tree's 830,660 faces (its sheet at 1 r_s) cost 25 ms a step,
    this 6 ms (``benchmarks/bark.py``; docs/decisions.md, "The bark's step in one pass")."""
    rose = 0
    loose = 0
    for f in nb.prange(len(fe)):
        m = M[fe[f]]
        d = M_0[f] - m
        e = growth[f] + drying * (shrinkage[f] * (d if d >= 0.0 else 0.0))
        eps[f] = e
        if not e <= eps_seen[f]:
            rose += 1
        decay = (1.0 - 0.5 * (H_c[fe[f]] + H_l[fe[f]])) * dt_days / DAYS_PER_YEAR
        cycles = abs(m - M_last[f]) / (2.0 * max(M_0[f], 1e-6))
        bond[f] = bond[f] - rate * (decay + cycles)
        M_last[f] = m
        if not shed[f] and bond[f] <= 0.0:
            loose += 1
    return rose, loose


def faces_reference(fe, M, H_c, H_l, growth, drying, shrinkage, M_0, rate, dt_days, eps_seen, bond, M_last, shed,
                    eps):
    """Plain-numpy :func:`_faces`: the loading of :func:`_strain`, the bonds of :func:`shedding.weaken`."""
    M_face = M[fe]
    eps[:] = growth + drying * (shrinkage * np.maximum(M_0 - M_face, 0.0))
    bond[:] = shedding.weaken(bond, rate, dt_days, H_c[fe], H_l[fe], M_face - M_last, M_0)
    M_last[:] = M_face
    return int(np.count_nonzero(~(eps <= eps_seen))), int(np.count_nonzero(bond[~shed] <= 0.0))


def _shed(model: WoodModel, st: BarkState) -> None:
    """The plates that come off now, the cracks where they broke from the rest of their plate
    and the pairs and links that let them fall (:mod:`wooddecay.bark.shedding`)."""
    sheet, b = model.bark, model.bark_setup
    assert sheet is not None and b is not None
    label = shedding.plates(sheet, st.crack.cracked, st.shed)
    label, off, breaks = shedding.falling(sheet, label, st.bond, float(b.plate_area))
    breaks = breaks[~st.crack.cracked[breaks]]
    st.crack.cracked[breaks] = True
    cracks.cast_shadows(sheet, st.crack, breaks, float(b.shadow))
    if off.any():
        st.shed |= off
        edge_cut, link_cut, _ = shedding.cuts(model, sheet, label, off)
        st.edge_cut |= edge_cut
        st.link_cut |= link_cut


def apply_cuts(ms, st: BarkState) -> None:
    """Integrity and strain limits 0 on the pairs and links the shed plates cut."""
    ms.integrity[st.edge_cut] = 0.0
    ms.limit_edge[st.edge_cut] = 0.0
    ms.link_integrity[st.link_cut] = 0.0
    ms.limit_elem[st.link_cut] = 0.0


def statistics(model: WoodModel, st: BarkState | None) -> dict:
    """The bark's part of the signature: crack count, length (m), along-grain share and the shed
    share of the bark's area."""
    if st is None:
        return {"bark_crack_count": 0, "bark_crack_length_m": 0.0, "bark_crack_along_grain": 0.0,
                "bark_shed_fraction": 0.0}
    assert model.bark is not None  # a BarkState exists only with a sheet
    out = cracks.statistics(model.bark, st.crack.cracked)
    area = model.bark.face_area
    out["bark_shed_fraction"] = round(float(area[st.shed].sum() / area.sum()), 6)
    return out
