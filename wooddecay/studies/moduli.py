"""The homogenised moduli of the rod bundle and their calibration to a species (docs/model.md §4
"Species moduli"; ``benchmarks/moduli.py``, ``tests/studies/test_moduli.py``).

A specimen is clear wood built by the real pipeline (``scenes/specimen.toml``): a straight block
along world x whose skeleton runs ``offset`` beside it, so that its wood frame is nearly the same
everywhere (e_L = x, e_R = y, e_T = z). At rest the Gauss-Newton Hessian of the rods' energies
(:func:`wooddecay.sim.implicit.hessian`) is their exact stiffness K, and K is linear in the six
stiffness parameters of :class:`~wooddecay.species.RodModuli` (:data:`PARAMETERS`): K = sum_i p_i
K_i, each K_i the Hessian with that parameter 1 and the others 0.

Each modulus is read as a testing machine reads it, from the converged bundle (K u = f solved
exactly):

* E_a: a uniform traction sigma on the two faces normal to a, pulling them apart (uniaxial
  stress; the other faces free); E_a = sigma / eps_aa.
* G_ab: shear tractions tau on the faces normal to a (along b) and on those normal to b (along
  a), balanced; G_ab = tau / gamma_ab, gamma_ab = du_a/dx_b + du_b/dx_a.

A face's traction is shared equally by its particles: the strands' end particles on the end
faces, the particles within r_s / 2 of a side face on the sides. The strain is the symmetric part
of the affine fit u = c + H x to the particles' displacements in the middle half of the specimen
along every loaded direction (St Venant: away from where the load goes in). Rigid motions are
left free; the loads are balanced and K is regularised by 1e-10 of its (unit, scaled) diagonal.
K u = f is solved by conjugate gradients with the implicit step's preconditioner
(:mod:`wooddecay.sim.precondition`) to a relative residual of 1e-8.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..model import build_model
from ..sim import implicit, precondition
from ..sim.mechanics import MechSetup, MechState, RegSweep, base_stiffness
from ..sim.state import initial_state
from ..species import RodModuli
from ..wood import WoodModel
from . import scene_template

#: the stiffness parameters K is linear in, in :class:`~wooddecay.species.RodModuli` order
PARAMETERS = RodModuli._fields
#: world axis of each material direction in a specimen
AXIS = {"L": 0, "R": 1, "T": 2}
#: traction (Pa) of the load cases; K is linear, so it only sets the displacements' size
TRACTION = 1e6
#: relative residual of the conjugate gradients (the moduli agree with 1e-10 to 1e-7 on the 10k
#: element specimen)
TOLERANCE = 1e-8
#: added to the unit diagonal of the scaled K: holds the rigid motions the balanced loads leave free
REGULARISATION = 1e-10


@dataclass(frozen=True, eq=False)
class Specimen:
    """Clear wood at rest: its model, its rods, its length along L and the area of its faces
    normal to L, R and T."""

    model: WoodModel
    setup: MechSetup
    ms: MechState
    area: np.ndarray  # (3,) m^2

    @property
    def x(self) -> np.ndarray:
        return self.model.particles


def _built(profile: dict, length: float, r_s: float, rod_length: float, area) -> Specimen:
    nodes = [{"id": "a", "position": [0.0, 0.0, 0.0], "profile": profile},
             {"id": "b", "position": [float(length), 0.0, 0.0], "parent": "a", "profile": profile}]
    model = build_model(scene_template("specimen", {"strands.r_s": r_s, "strands.rod_length": rod_length}, nodes))
    state = initial_state(model, rods=True)
    return Specimen(model, model.mech, state.mech, np.asarray(area, dtype=np.float64))


def specimen(r_s: float, rod_length: float, size=(0.6, 0.2, 0.2), offset: float = 1.0) -> Specimen:
    """The block of ``size`` (along L, R, T in m) at strand radius ``r_s`` and rod length
    ``rod_length``, its skeleton ``offset`` (m) from its middle along -R (module docstring)."""
    length, a, b = size
    square = [[offset - a / 2, -b / 2], [offset + a / 2, -b / 2], [offset + a / 2, b / 2], [offset - a / 2, b / 2]]
    return _built({"kind": "polygon", "points": square}, length, r_s, rod_length, (a * b, length * b, length * a))


def branch(r_s: float, rod_length: float, radius: float = 0.05, length: float = 0.6) -> Specimen:
    """A round branch of ``radius`` and ``length`` along x around its own pith: its wood frame
    turns about the axis, so only its moduli along the grain are read (:func:`along_grain`)."""
    return _built({"kind": "circle", "radius": radius}, length, r_s, rod_length, (np.pi * radius * radius, 0.0, 0.0))


def with_moduli(setup: MechSetup, model: WoodModel, p: RodModuli) -> MechSetup:
    """``setup`` with the stiffnesses :func:`wooddecay.sim.mechanics.base_stiffness` derives from ``p``."""
    n = model.n_elements
    k = base_stiffness(model, np.full(n, p.E), np.full(n, p.G), tuple(p[2:]))
    sw = setup.sweep
    sweep = RegSweep.of(sw.ptr, sw.order, setup.edges, setup.edge_rest, setup.edge_length, k.k_conn0, k.k_pb0, k.k_pt0)
    return replace(setup, k_stretch=k.k_stretch, k_shear=k.k_shear, joint_kb=k.joint_kb, joint_kt=k.joint_kt,
                   sweep=sweep, central_share=k.central_share, offset_share=k.offset_share)


def parts(spec: Specimen) -> list[sp.csr_matrix]:
    """K_i, one per :data:`PARAMETERS` (module docstring)."""
    out = []
    for i in range(len(PARAMETERS)):
        p = RodModuli(*(1.0 if j == i else 0.0 for j in range(len(PARAMETERS))))
        out.append(implicit.hessian(with_moduli(spec.setup, spec.model, p), spec.ms))
    return out


def _face(spec: Specimen, axis: int, side: int) -> np.ndarray:
    """The particles a face's traction acts on (module docstring)."""
    x, setup = spec.x, spec.setup
    if axis == 0:
        off = spec.model.element_offsets
        return setup.fp[off[:-1]] if side < 0 else setup.fp[off[1:] - 1] + 1
    c, half = x[:, axis], 0.5 * spec.model.r_s
    return np.flatnonzero(c <= c.min() + half) if side < 0 else np.flatnonzero(c >= c.max() - half)


def _traction(spec: Specimen, f: np.ndarray, axis: int, direction: int, t: float) -> None:
    """Add the traction +-t along ``direction`` on the two faces normal to ``axis``."""
    for side in (-1, 1):
        p = _face(spec, axis, side)
        f[p, direction] += side * t * spec.area[axis] / len(p)


def _bending(spec: Specimen, f: np.ndarray, slope: float) -> None:
    """Add the end tractions sigma = +-slope y (Pa, y from each end's centroid along R) of a pure
    bending moment about T."""
    for side in (-1, 1):
        p = _face(spec, 0, side)
        y = spec.x[p, 1] - spec.x[p, 1].mean()
        f[p, 0] += side * slope * y * spec.area[0] / len(p)


def _middle(spec: Specimen, axes: tuple[int, ...]) -> np.ndarray:
    """The particles in the middle half of the specimen along each of ``axes``."""
    x = spec.x
    lo, hi = x.min(axis=0), x.max(axis=0)
    middle = np.ones(len(x), dtype=bool)
    for ax in axes:
        quarter = 0.25 * (hi[ax] - lo[ax])
        middle &= (x[:, ax] > lo[ax] + quarter) & (x[:, ax] < hi[ax] - quarter)
    return middle


def _gradient(spec: Specimen, u: np.ndarray, axes: tuple[int, ...]) -> np.ndarray:
    """H (3, 3), H[i, j] = du_i/dx_j of the affine fit in the middle half along ``axes``."""
    middle = _middle(spec, axes)
    x = spec.x[middle]
    X = np.column_stack([np.ones(len(x)), x - x.mean(axis=0)])
    return np.linalg.lstsq(X, u[middle], rcond=None)[0][1:].T


def _curvature(spec: Specimen, u: np.ndarray) -> float:
    """d eps_LL / dy: the coefficient of x y in the fit of u_x by 1, x, y, z, x y over the middle
    half along L."""
    middle = _middle(spec, (0,))
    x = spec.x[middle] - spec.x[middle].mean(axis=0)
    X = np.column_stack([np.ones(len(x)), x, x[:, 0] * x[:, 1]])
    return float(np.linalg.lstsq(X, u[middle, 0], rcond=None)[0][4])


def _solver(spec: Specimen, K: sp.spmatrix):
    """f (P, 3) -> the particles' displacements u (P, 3) with K u = f (module docstring)."""
    setup, ms = spec.setup, spec.ms
    P, n = setup.n_particles, setup.n_elements
    strand, position = precondition.strand_of_blocks(setup)
    A, scale, modes = implicit.scaled(K, precondition.rigid_modes(setup, ms, precondition.aggregates(setup, ms)))
    A = (A + REGULARISATION * sp.identity(A.shape[0])).tocsr()
    M = precondition.two_level(A, strand, position, modes)

    def solve(f: np.ndarray) -> np.ndarray:
        y, info = spla.cg(A, np.concatenate([f.ravel(), np.zeros(3 * n)]) * scale, rtol=TOLERANCE,
                          maxiter=20000, M=M)
        if info != 0:
            raise RuntimeError(f"the specimen's solve did not converge ({info})")
        return (y * scale)[:3 * P].reshape(P, 3)

    return solve


def along_grain(spec: Specimen, K: sp.spmatrix) -> dict[str, float]:
    """E_L (Pa) of ``spec`` under ``K`` stretched (uniaxial traction on its ends, as in
    :func:`measure`) and bent (pure bending about T by end tractions linear in R: E_L = slope /
    (d eps_LL / dy)), as ``E_L`` and ``E_L_bend``."""
    solve = _solver(spec, K)
    P = spec.setup.n_particles
    f = np.zeros((P, 3))
    _traction(spec, f, 0, 0, TRACTION)
    stretched = TRACTION / _gradient(spec, solve(f), (0,))[0, 0]
    f = np.zeros((P, 3))
    _bending(spec, f, TRACTION)
    return {"E_L": stretched, "E_L_bend": TRACTION / _curvature(spec, solve(f))}


def measure(spec: Specimen, K: sp.spmatrix) -> dict[str, float]:
    """E_L, E_R, E_T, G_LR, G_LT, G_RT (Pa) of ``spec`` under the stiffness ``K`` (module docstring)."""
    solve = _solver(spec, K)
    P = spec.setup.n_particles
    out = {}
    for d, a in AXIS.items():
        f = np.zeros((P, 3))
        _traction(spec, f, a, a, TRACTION)
        out[f"E_{d}"] = TRACTION / _gradient(spec, solve(f), (a,))[a, a]
    for pair in ("LR", "LT", "RT"):
        a, b = AXIS[pair[0]], AXIS[pair[1]]
        f = np.zeros((P, 3))
        _traction(spec, f, a, b, TRACTION)
        _traction(spec, f, b, a, TRACTION)
        H = _gradient(spec, solve(f), (a, b))
        out[f"G_{pair}"] = TRACTION / (H[a, b] + H[b, a])
    return out


def assemble(K_parts: list[sp.spmatrix], p: RodModuli) -> sp.csr_matrix:
    """sum_i p_i K_i."""
    return sum((v * K for v, K in zip(p, K_parts) if v != 0.0), sp.csr_matrix(K_parts[0].shape)).tocsr()


def calibrate(specimens: list[Specimen], target: dict[str, float], iterations: int = 15
              ) -> tuple[RodModuli, list[dict[str, float]]]:
    """The :class:`RodModuli` whose specimens' moduli match :data:`FITTED` of ``target`` in the
    least-squares sense of their logarithms over all ``specimens``: Gauss-Newton in log p (steps of
    at most 0.7, halved while they do not bring the moduli closer, until one is below 1e-3; the
    least-norm step where p has more freedom than the moduli), the Jacobian by forward
    differences of STEP on the first specimen, taken for all (each modulus is homogeneous of
    degree 1 in p, and log moduli against log p are close to linear and to the same at every
    resolution). What moves what (the 9 mm specimen): the strand's E sets E_L, the offset's b_R, b_T
    and b_L set E_R, E_T and the two LR and LT shears, the central a_R and a_T split those
    shears. The strand's G moves no homogenised modulus (it shears and twists a strand against its
    own orientation): it stays E (G_LR + G_LT) / (2 E_L), the strand's own; a_L stays 0 (b_L does
    what it does without tying the shears to E_L). Returns p and the specimens' moduli at p."""
    K_parts = [parts(s) for s in specimens]
    goal = np.tile(np.log([target[k] for k in FITTED]), len(specimens))
    g = (target["G_LR"] + target["G_LT"]) / (2.0 * target["E_L"])

    def rods(q: np.ndarray) -> RodModuli:
        E, a_R, a_T, b_R, b_T, b_L = np.exp(q)
        return RodModuli(E, g * E, a_R, a_T, 0.0, b_R, b_T, b_L)

    def logs(q: np.ndarray, which: list[int]) -> np.ndarray:
        p = rods(q)
        got = [measure(specimens[i], assemble(K_parts[i], p)) for i in which]
        return np.log([m[k] for m in got for k in FITTED])

    everything = list(range(len(specimens)))
    G = 0.5 * (target["G_LR"] + target["G_LT"])
    q = np.log([target["E_L"], 0.02 * target["E_L"], 0.02 * target["E_L"], 0.4 * target["E_R"],
                0.4 * target["E_T"], 0.4 * G])
    y = logs(q, everything)
    for _ in range(iterations):
        y0 = y[:len(FITTED)]
        J = np.column_stack([(logs(q + STEP * e, [0]) - y0) / STEP for e in np.eye(len(q))])
        dq = np.clip(np.linalg.lstsq(np.tile(J, (len(specimens), 1)), goal - y, rcond=None)[0], -0.7, 0.7)
        for _ in range(4):  # halve a step that does not bring the moduli closer
            y_new = logs(q + dq, everything)
            if np.sum((y_new - goal) ** 2) < np.sum((y - goal) ** 2):
                break
            dq = 0.5 * dq
        else:
            break
        q, y = q + dq, y_new
        if np.abs(dq).max() < 1e-3:
            break
    p = rods(q)
    return p, [measure(s, assemble(Kp, p)) for s, Kp in zip(specimens, K_parts)]


#: forward-difference step in log p of :func:`calibrate`'s first Jacobian
STEP = 0.05
#: the moduli :func:`calibrate` fits (G_RT: docs/limits.md, "Rolling shear")
FITTED = ("E_L", "E_R", "E_T", "G_LR", "G_LT")
