"""Coupling of moisture and decay back to the mechanics (woodstock §7, Eqs. 16-19 and 21;
Algorithm 1 lines 12-13; docs/model.md §4).

After each biology step, with (x)^+ = max(x, 0):

* Eq. 16 with the direction-dependent gain of docs/model.md §4 (Table 2, Fig. 6): REG rest offsets
  dp = dp_0 (1 - (M_0 - M)^+ g_edge), g_edge = S (S_R n_r^2 + S_T n_t^2) + s n_l^2, n the
  offset's direction in the cross-section's frame of its two elements (``reg_dir_weights``,
  :func:`wooddecay.strands.elements.radial_frames`), not the strands' own: to first
  order this is the length change of the offset vector dp_0 n under the shrinkage strains
  (S S_R, S S_T, s) (M_0 - M)^+ along (e_r, e_t, e_l), and with one frame per cross-section
  evenly drying wood shrinks as one strain field. The along-grain gain is the strands' own
  s of Eq. 17, in place of docs/model.md's S S_L: an offset's along-grain part is measured along the
  strands, and a different gain there makes uniformly drying wood pull its strands apart
  lengthwise (docs/decisions.md);
* Eq. 17: rest lengths l_r = l_r0 (1 - (M_0 - M)^+ s);
* brown-rot shrinkage: wood that loses its carbohydrates shrinks (woodstock §3), by the linear
  factor phi = 1 - S_c (1 - H_c) (:func:`shrink_factor`) on the rest length of Eqs. 16-17, the
  contact radius and the meshlet; a REG offset takes the pair mean of S_c (1 - H_c). A loose
  brown-rotted cube shrinks as a whole and its pile settles lower (Fig. 12); a half-rotted
  section shrinks at its rotted side and checks there (docs/decisions.md, "Brown rot shrinks").
  S_c = 0 (the default) leaves Eqs. 16-17 as printed;
* Eqs. 18-19: strain limits L(M) = L_0 f(M - M_2), f(x) = clip(x / (M_k - M_2), 0, 1)^p_l, per
  constraint type (stretch, shear on elements; bundle, bend, twist on REG pairs), with M_1, M_2
  the tissue's bounds on the current day (seasonal schedule) and the knee
  M_k = M_0 + L_knee (M_1 - M_0). By default (L_knee = 0) it is M_0, where §7 says "reduced
  failure or strain capacity" starts, not Eq. 19's M_1 (L_knee = 1): with M_1 = 1 the factor at
  M = 0.24 (wood still above M_0) was 7e-4 and a drying board shattered before any of it shrank
  (docs/decisions.md, "Limits reduce below M_0"). Wood at or above M_k keeps L_0;
* Eq. 21: I_ij = (1 - theta_ij k_c (1 - H_c)) (1 - k_l (1 - H_l)), clipped to [0, 1]. It scales
  the pair's stiffness (docs/model.md §4) and, as the paper's "connection strength", its strain limits:
  with stiff wood and dt = 0.01 s a connection is effectively rigid until I_ij is tiny, so the
  stiffness alone would not let decay concentrate failure on the weakened pairs
  (docs/decisions.md). The strand link between consecutive elements e, e + 1 is a pair of the
  same kind: its theta is 1 where the two lie in different BSP leaves, and its I (pair means of
  H_c, H_l) scales the stretch and shear limits of e, the element whose failure cuts that link
  (:mod:`wooddecay.sim.failure`). Without it decay never weakened a strand, and brown rot could
  break the REG across a BSP boundary but not the strands running through it, so no cubical
  pieces came loose (Figs. 7, 12). Both integrities are kept (``integrity``, ``link_integrity``): a pair or
  link below ``I_fail`` fails (:mod:`wooddecay.sim.failure`, separation from decay);
* crumbling: an element whose remaining mass fraction (H_l + k H_c) / (1 + k) (k = k_H, §9.4)
  is below ``m_crumble`` is consumed (``crumbled``): its pairs and both its strand links get
  integrity 0, so they fail (:mod:`wooddecay.sim.failure`), and the element itself fails whatever
  its neighbours; its meshlet dwindles (:func:`crumble_scale`, :mod:`wooddecay.meshlets.skin`);
* the element masses rho_dry (1 + M) pi r^2 l (docs/model.md §2).

Pair quantities (M, H_c, H_l and the per-tissue parameters) are the mean of the two elements.
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from ..wood import WoodModel
from .. import fmath as fm
from .biology import moisture_bounds
from .diagnostics import mass_remaining
from .events import Events
from .mechanics import set_masses, set_radius

#: constraint types of L_0 and p_l, in column order (elements: 0, 1; pairs: 2, 3, 4)
LIMIT_TYPES = ("stretch", "shear", "bundle", "bend", "twist")


@dataclass(frozen=True, eq=False)
class CouplingSetup:
    """The per-element and per-pair gains, limits and decay weights of the coupling, built once
    with the model (``model.coupling``)."""

    M_0: np.ndarray  # (n,)
    L_knee: np.ndarray  # (n,) the knee M_k of Eq. 19 between M_0 (0) and M_1 (1)
    s: np.ndarray  # (n,) rest-length gain
    S_c: np.ndarray  # (n,) brown-rot shrinkage
    g_pair: np.ndarray  # (m,) g_edge of Eq. 16 (pair means of the gains)
    M_0_pair: np.ndarray  # (m,)
    L_0: np.ndarray  # (n, 5) per LIMIT_TYPES
    p_l: np.ndarray  # (n, 5)
    k_c: np.ndarray  # (m,) theta_ij k_c (pair mean)
    k_l: np.ndarray  # (m,)
    link_next: np.ndarray  # (n,) e + 1, or e for the last element of a strand
    k_c_link: np.ndarray  # (n,) theta k_c of the link e, e + 1 (pair mean; 0 at a strand end)
    k_l_link: np.ndarray  # (n,)
    k_H: np.ndarray  # (n,) carbohydrate weight of the remaining mass (§9.4)
    m_crumble: np.ndarray  # (n,)


def prepare(model: WoodModel) -> CouplingSetup:
    """Gains, limits and decay weights from the tissues' parameters (``model.materials``)."""
    per_element = model.materials.per_element
    i, j = model.reg_edges[:, 0], model.reg_edges[:, 1]

    def pair(name):
        v = per_element(name)
        return 0.5 * (v[i] + v[j])

    n = model.n_elements
    nxt = np.arange(n) + 1
    nxt[model.element_offsets[1:] - 1] -= 1  # the last element of a strand links to itself
    leaf = model.bsp_leaf
    k_c_e, k_l_e = per_element("k_c"), per_element("k_l")
    dw = model.reg_dir_weights
    g_edge = pair("S") * (pair("S_R") * dw[:, 0] + pair("S_T") * dw[:, 1]) + pair("s") * dw[:, 2]
    return CouplingSetup(
        M_0=per_element("M_0"), L_knee=per_element("L_knee"), s=per_element("s"), S_c=per_element("S_c"),
        g_pair=g_edge, M_0_pair=pair("M_0"),
        L_0=np.stack([per_element(f"L_0_{k}") for k in LIMIT_TYPES], axis=1),
        p_l=np.stack([per_element(f"p_l_{k}") for k in LIMIT_TYPES], axis=1),
        k_c=model.reg_theta * pair("k_c"), k_l=pair("k_l"), link_next=nxt,
        k_c_link=(leaf != leaf[nxt]) * 0.5 * (k_c_e + k_c_e[nxt]), k_l_link=0.5 * (k_l_e + k_l_e[nxt]),
        k_H=per_element("k_H"), m_crumble=per_element("m_crumble"),
    )


def limit_factor(M: np.ndarray, M_k: np.ndarray, M_2: np.ndarray, p_l: np.ndarray) -> np.ndarray:
    """f(M - M_2) of Eq. 19 with its knee at M_k (module docstring): 1 at or above M_k, 0 at or
    below M_2 (when M_2 >= M_k too), a power p_l between."""
    span = np.where(M_k > M_2, M_k - M_2, 1.0)
    return np.where(M >= M_k, 1.0, fm.power(np.clip((M - M_2) / span, 0.0, 1.0), p_l))


def knee(cs: "CouplingSetup", M_1: np.ndarray) -> np.ndarray:
    """M_k = M_0 + L_knee (M_1 - M_0) per element, ``M_1`` its tissue's bound today."""
    return cs.M_0 + cs.L_knee * (M_1 - cs.M_0)


def crumble_scale(cs: CouplingSetup, H_c: np.ndarray, H_l: np.ndarray) -> np.ndarray:
    """Size of each element's meshlet: 1 down to a remaining mass of 2 m_crumble, then linearly to
    0 at m_crumble (crumbled); 1 everywhere with m_crumble = 0."""
    m = cs.m_crumble
    return np.where(m > 0.0, np.clip((mass_remaining(H_c, H_l, cs.k_H) - m) / np.where(m > 0.0, m, 1.0), 0.0, 1.0), 1.0)


def shrink_factor(cs: CouplingSetup, H_c: np.ndarray) -> np.ndarray:
    """phi = 1 - S_c (1 - H_c) per element: the linear size of brown-rotted wood (module docstring)."""
    return 1.0 - cs.S_c * (1.0 - H_c)


def integrity(k_c: np.ndarray, k_l: np.ndarray, H_c_pair: np.ndarray, H_l_pair: np.ndarray) -> np.ndarray:
    """I_ij of Eq. 21 with k_c already multiplied by theta_ij, clipped to [0, 1]."""
    I = (1.0 - k_c * (1.0 - H_c_pair)) * (1.0 - k_l * (1.0 - H_l_pair))
    return np.clip(I, 0.0, 1.0)


def advance(model: WoodModel, state, dt: float) -> Events:
    """The driver's coupling solver (:mod:`~wooddecay.sim.events`): :func:`step` at the end of a
    step of ``dt`` days (the coupling is instantaneous: it reads the fields as they are)."""
    step(model, state)
    return Events()


def step(model: WoodModel, state) -> None:
    """Update the rods of ``state`` (``state.mech``: rest data, limits, integrity and masses)
    from its fields, with each tissue's M_1, M_2 on the day ``state.t_days``. The coupling is
    instantaneous, so unlike the other solvers it takes no dt. One parallel pass over elements
    and one over REG pairs (:func:`_couple`; :func:`step_reference` is its numpy twin)."""
    cs, setup, ms = model.coupling, model.mech, state.mech
    n, m = len(state.M), len(setup.edges)
    out = (np.empty(n), np.empty(m), np.empty(m), np.empty(n), np.empty(n, dtype=np.bool_), np.empty((n, 2)),
           np.empty((m, 3)), np.empty(n))
    _couple(state.M, state.H_c, state.H_l, model.bio.tissue, moisture_bounds(model.bio, state.t_days),
            setup.edges, cs.link_next, cs.M_0, cs.L_knee, cs.s, cs.S_c, setup.rest_length0, setup.radius, cs.g_pair,
            cs.M_0_pair, setup.offset0, cs.L_0, cs.p_l, cs.k_c, cs.k_l, cs.k_c_link, cs.k_l_link, cs.k_H, cs.m_crumble,
            np.empty((n, 5)), *out)
    ms.rest_length, ms.rest_offset, ms.integrity, ms.link_integrity, ms.crumbled, ms.limit_elem, ms.limit_edge = out[:7]
    set_radius(setup, ms, out[7])
    set_masses(setup, ms, state.M)


@nb.njit(inline="always", cache=True)
def _crumbled(e, H_c, H_l, k_H, m_crumble):
    return (H_l[e] + k_H[e] * H_c[e]) / (1.0 + k_H[e]) < m_crumble[e]


@nb.njit(inline="always", cache=True)
def _integrity(k_c, k_l, H_c_pair, H_l_pair):
    return min(max((1.0 - k_c * (1.0 - H_c_pair)) * (1.0 - k_l * (1.0 - H_l_pair)), 0.0), 1.0)


@nb.njit(parallel=True, cache=True)
def _couple(M, H_c, H_l, tissue, M12, edges, link_next, M_0, L_knee, s, S_c, rest_length0, radius0, g_pair, M_0_pair,
            offset0, L_0, p_l, k_c, k_l, k_c_link, k_l_link, k_H, m_crumble, L, rest_length, rest_offset, integrity_out,
            link_out, crumbled, limit_elem, limit_edge, radius):
    """:func:`step`'s arrays (module docstring): per element the rest length (Eq. 17 and the
    brown-rot shrinkage), the contact radius, the limits L(M) of Eq. 19 (into the scratch ``L``),
    the strand link's I and the stretch and shear limits it scales; per REG pair the rest offset
    (Eq. 16), I_ij (Eq. 21) and the pair limits. Each entry is written by its own element or pair
    only."""
    for e in nb.prange(len(M)):
        M_2 = M12[tissue[e], 1]
        M_k = M_0[e] + L_knee[e] * (M12[tissue[e], 0] - M_0[e])
        f = 1.0 if M[e] >= M_k else (0.0 if M[e] <= M_2 else (M[e] - M_2) / (M_k - M_2))
        for c in range(5):  # 1 ** p_l is 1: wood above the knee skips the pow
            L[e, c] = L_0[e, c] if f == 1.0 else L_0[e, c] * f ** p_l[e, c]
        phi = 1.0 - S_c[e] * (1.0 - H_c[e])
        rest_length[e] = rest_length0[e] * (1.0 - max(M_0[e] - M[e], 0.0) * s[e]) * phi
        radius[e] = radius0[e] * phi
        e1 = link_next[e]
        link = _integrity(k_c_link[e], k_l_link[e], 0.5 * (H_c[e] + H_c[e1]), 0.5 * (H_l[e] + H_l[e1]))
        crumbled[e] = _crumbled(e, H_c, H_l, k_H, m_crumble)
        if crumbled[e] or _crumbled(e1, H_c, H_l, k_H, m_crumble):
            link = 0.0
        link_out[e] = link
        limit_elem[e, 0] = L[e, 0] * link
        limit_elem[e, 1] = L[e, 1] * link
    for k in nb.prange(len(edges)):
        i, j = edges[k, 0], edges[k, 1]
        phi = 1.0 - 0.5 * (S_c[i] * (1.0 - H_c[i]) + S_c[j] * (1.0 - H_c[j]))
        rest_offset[k] = offset0[k] * (1.0 - max(M_0_pair[k] - 0.5 * (M[i] + M[j]), 0.0) * g_pair[k]) * phi
        I = _integrity(k_c[k], k_l[k], 0.5 * (H_c[i] + H_c[j]), 0.5 * (H_l[i] + H_l[j]))
        if crumbled[i] or crumbled[j]:  # written by the element loop, which has ended
            I = 0.0
        integrity_out[k] = I
        for c in range(3):
            limit_edge[k, c] = 0.5 * (L[i, c + 2] + L[j, c + 2]) * I


def step_reference(model: WoodModel, state) -> dict[str, np.ndarray]:
    """Plain-numpy :func:`step`: the rest lengths, rest offsets, radii, integrity and limits it sets."""
    cs, setup = model.coupling, model.mech
    M12, tissue = moisture_bounds(model.bio, state.t_days), model.bio.tissue
    M = state.M
    i, j = setup.edges[:, 0], setup.edges[:, 1]
    M_pair = 0.5 * (M[i] + M[j])
    f = limit_factor(M[:, None], knee(cs, M12[tissue, 0])[:, None], M12[tissue, 1][:, None], cs.p_l)
    L = cs.L_0 * f
    crumbled = mass_remaining(state.H_c, state.H_l, cs.k_H) < cs.m_crumble
    I = integrity(cs.k_c, cs.k_l, 0.5 * (state.H_c[i] + state.H_c[j]), 0.5 * (state.H_l[i] + state.H_l[j]))
    I = np.where(crumbled[i] | crumbled[j], 0.0, I)
    e1 = cs.link_next
    link = integrity(cs.k_c_link, cs.k_l_link, 0.5 * (state.H_c + state.H_c[e1]), 0.5 * (state.H_l + state.H_l[e1]))
    link = np.where(crumbled | crumbled[e1], 0.0, link)
    phi = shrink_factor(cs, state.H_c)
    return {"rest_offset": setup.offset0 * (1.0 - np.maximum(cs.M_0_pair - M_pair, 0.0) * cs.g_pair)
            * 0.5 * (phi[i] + phi[j]),
            "rest_length": setup.rest_length0 * (1.0 - np.maximum(cs.M_0 - M, 0.0) * cs.s) * phi,
            "radius": setup.radius * phi,
            "integrity": I, "link_integrity": link, "crumbled": crumbled, "limit_elem": L[:, :2] * link[:, None],
            "limit_edge": 0.5 * (L[i, 2:] + L[j, 2:]) * I[:, None]}
