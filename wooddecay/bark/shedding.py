"""Bark that sheds: plates bounded by cracks come off when their bond to the wood is gone (SPEC §10).

Every face of the sheet has a bond b in [0, 1] to the wood beneath, 1 at first. Per step of dt
days it weakens by ``shedding`` (per year) times the decay of its element, (1 - (H_c + H_l) / 2)
dt / 365.25, plus its wet/dry cycling, |dM| / (2 M_0) (a full swing from dry to M_0 and back is
one unit): bark loosens on rotting, weathering wood. A plate is a connected set of faces that
no crack separates; one of at most ``plate_area`` whose mean bond has reached 0 comes off. Its
bark elements (those lying on its faces) are cut from every other element: the REG pairs and the
strand links between them get integrity 0, so the failure pass separates them
(:mod:`wooddecay.sim.failure`) and the plate falls as a piece of debris.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

DAYS_PER_YEAR = 365.25


def weaken(bond: np.ndarray, rate: float, dt_days: float, H_c: np.ndarray, H_l: np.ndarray, dM: np.ndarray,
           M_0: np.ndarray) -> np.ndarray:
    """The bonds after a step (module docstring); ``H_c``, ``H_l``, ``dM``, ``M_0`` per face."""
    decay = (1.0 - 0.5 * (H_c + H_l)) * dt_days / DAYS_PER_YEAR
    cycles = np.abs(dM) / (2.0 * np.maximum(M_0, 1e-6))
    return bond - rate * (decay + cycles)


def plates(sheet, cracked: np.ndarray, shed: np.ndarray) -> np.ndarray:
    """(F,) plate label of every face still on (connected across edges no crack cuts), -1 shed."""
    ef = sheet.edge_faces
    keep = (ef[:, 1] >= 0) & ~cracked
    a, b = ef[keep, 0], ef[keep, 1]
    on = ~shed[a] & ~shed[b]
    F = sheet.n_faces
    g = sp.coo_matrix((np.ones(int(on.sum())), (a[on], b[on])), shape=(F, F)).tocsr()
    _, label = connected_components(g, directed=False)
    return np.where(shed, -1, label)


def falling(sheet, label: np.ndarray, bond: np.ndarray, plate_area: float) -> np.ndarray:
    """(F,) faces of the plates that come off now: at most ``plate_area`` and mean bond <= 0."""
    on = label >= 0
    n = int(label.max(initial=-1)) + 1
    area = np.bincount(label[on], weights=sheet.face_area[on], minlength=n)
    mean_bond = np.bincount(label[on], weights=(bond * sheet.face_area)[on], minlength=n) / np.maximum(area, 1e-300)
    off = (area <= plate_area) & (mean_bond <= 0.0)
    return on & off[np.maximum(label, 0)]


def cuts(model, sheet, label: np.ndarray, off: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """REG pairs (m,) and strand links (n,) to cut so that the plates of the faces ``off`` come
    loose: those between an element of such a plate and any element not in the same plate."""
    ef = sheet.element_face
    plate = np.full(model.n_elements, -1, dtype=np.int64)
    on = ef >= 0
    plate[on] = np.where(off[ef[on]], label[ef[on]], -1)
    i, j = model.reg_edges[:, 0], model.reg_edges[:, 1]
    edge_cut = (plate[i] != plate[j]) & ((plate[i] >= 0) | (plate[j] >= 0))
    e1 = model.coupling.link_next
    link_cut = (plate != plate[e1]) & ((plate >= 0) | (plate[e1] >= 0))
    return edge_cut, link_cut
