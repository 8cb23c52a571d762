"""Rod elements: staggered sampling of strand centrelines, frames and wood-local coordinates.

Woodstock §5 (opening), Fig. 3b; docs/model.md §2. A strand's centreline is a cubic B-spline through its
control points (chord-length parameter). Rod particles are placed along it by arc length at
``rod_length`` spacing with a random phase per strand, so element boundaries of neighbouring
strands do not line up (the "randomly subdivided strand group"); the first and last elements
are between 0.5 and 1.5 ``rod_length`` long. A strand a clamp holds also has a particle on the
clamp plane; the elements inside the clamp may be shorter (they do not move). An element is two
consecutive particles.

Per element: rest length, rest orientation (material frame d1, d2, d3 with d3 along the segment,
d1 carried by parallel transport along the strand), the wood frame (e_r, e_t, e_l): e_l along
the segment, e_r away from the branch centreline, e_t = e_l x e_r, and the position of the
element in its skeleton edge (the two nodes and the fraction t between them).
"""
from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from scipy.interpolate import make_interp_spline

from .strands import StrandSet

#: dense samples per rod length used to tabulate the spline's arc length
ARC_SAMPLES_PER_ROD = 8


@dataclass(frozen=True, eq=False)
class Sampling:
    """Particles and elements of all strands (CSR by strand)."""

    particles: np.ndarray  # (n_p, 3)
    particle_offsets: np.ndarray  # (n_strands + 1,)
    element_offsets: np.ndarray  # (n_strands + 1,)
    strand: np.ndarray  # (n_e,) strand of each element
    first_particle: np.ndarray  # (n_e,) element e joins particles first_particle[e] and +1
    cp: np.ndarray  # (n_e,) control point (row of StrandSet) at the start of the element's edge
    t: np.ndarray  # (n_e,) fraction along that edge (control point cp -> cp + 1)
    u: np.ndarray  # (n_p,) spline parameter of each particle (chord length along the control points)
    cut: np.ndarray  # (n_strands,) particle on the clamp plane, counted along the strand; -1: none


#: a strand's particle on the clamp plane lies up to this fraction of a rod length beyond it (by
#: the strand's rod phase): element ends of every strand on one exact plane are a degenerate event
#: of the meshlets' kinetic sweep (docs/decisions.md, "A clamp is a plane")
CLAMP_SPREAD = 0.0025


def arc_positions(length: float, rod_length: float, phase: float, cut: float = -1.0) -> np.ndarray:
    """Particle arc positions on a strand of ``length``: 0, phase + k L (kept >= L/2 from both
    ends), length. ``phase`` in [0, 1) of a rod length. A ``cut`` in (0, length) is a particle
    too (the clamp plane, :func:`sample_strands`): the rod breaks then keep L/2 from it as well,
    counted from it, so the elements beyond it are as long as anywhere else."""
    if 0.0 < cut < length:
        ahead = arc_positions(cut, rod_length, phase)
        return np.concatenate([ahead, cut + arc_positions(length - cut, rod_length, phase)[1:]])
    first = phase * rod_length
    k = np.arange(int(np.ceil(length / rod_length)) + 2)
    b = first + k * rod_length
    b = b[(b >= 0.5 * rod_length) & (b <= length - 0.5 * rod_length)]
    return np.concatenate([[0.0], b, [length]])


def sample_strands(strands: StrandSet, rod_length: float, rng: np.random.Generator,
                   cp_s: np.ndarray | None = None, cut_s: np.ndarray | None = None) -> Sampling:
    """Sample every strand's B-spline into rod particles (one Python iteration per strand).

    ``cut_s`` (per strand, NaN for none) puts a particle where the strand's distance to the root
    (linear in the spline parameter between the control points' ``cp_s``) reaches that value, plus
    up to :data:`CLAMP_SPREAD` rod lengths: the plane a clamp holds every strand at (docs/model.md §7). ``Sampling.cut`` is its index on the
    strand: the strand's length when the strand ends before the plane, -1 without a cut."""
    phases = rng.uniform(0.0, 1.0, strands.count)
    cut_s = np.full(strands.count, np.nan) if cut_s is None else cut_s
    parts, p_counts, cps, ts, us, cuts = [], [], [], [], [], []
    for k in range(strands.count):
        o0, o1 = strands.offsets[k], strands.offsets[k + 1]
        P = strands.xyz[o0:o1]
        u_cp = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
        spline = make_interp_spline(u_cp, P, k=min(3, len(P) - 1))
        n_dense = max(16, int(np.ceil(u_cp[-1] / rod_length * ARC_SAMPLES_PER_ROD)) + 1)
        uu = np.linspace(0.0, u_cp[-1], n_dense)
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(spline(uu), axis=0), axis=1))])
        cut = -1.0
        if not np.isnan(cut_s[k]):
            cut = float(np.interp(np.interp(cut_s[k], cp_s[o0:o1], u_cp), uu, arc)) + CLAMP_SPREAD * rod_length * phases[k]
        u_p = np.interp(arc_positions(arc[-1], rod_length, phases[k], cut), arc, uu)
        cuts.append(-1 if np.isnan(cut_s[k]) else len(u_p) - 1 if cut >= arc[-1]
                    else int(np.searchsorted(u_p, np.interp(cut, arc, uu))))
        parts.append(spline(u_p))
        us.append(u_p)
        p_counts.append(len(u_p))
        u_mid = 0.5 * (u_p[1:] + u_p[:-1])
        seg = np.clip(np.searchsorted(u_cp, u_mid, side="right") - 1, 0, len(P) - 2)
        cps.append(o0 + seg)
        ts.append((u_mid - u_cp[seg]) / (u_cp[seg + 1] - u_cp[seg]))
    p_counts = np.array(p_counts, dtype=np.int64)
    e_counts = p_counts - 1
    particle_offsets = np.concatenate([[0], np.cumsum(p_counts)]).astype(np.int64)
    element_offsets = np.concatenate([[0], np.cumsum(e_counts)]).astype(np.int64)
    strand = np.repeat(np.arange(strands.count), e_counts)
    local = np.arange(element_offsets[-1]) - element_offsets[strand]
    return Sampling(
        particles=np.concatenate(parts),
        particle_offsets=particle_offsets,
        element_offsets=element_offsets,
        strand=strand,
        first_particle=particle_offsets[strand] + local,
        cp=np.concatenate(cps).astype(np.int64),
        t=np.concatenate(ts),
        u=np.concatenate(us),
        cut=np.array(cuts, dtype=np.int64),
    )


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def reject(v: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Component of ``v`` orthogonal to unit ``axis`` (row-wise)."""
    return v - np.sum(v * axis, axis=-1, keepdims=True) * axis


@nb.njit(cache=True, inline="always")
def _transport_one(d1, t0, t1):
    """Minimal rotation of d1 taking unit t0 to unit t1 (Rodrigues, k = t0 x t1)."""
    kx = t0[1] * t1[2] - t0[2] * t1[1]
    ky = t0[2] * t1[0] - t0[0] * t1[2]
    kz = t0[0] * t1[1] - t0[1] * t1[0]
    c = t0[0] * t1[0] + t0[1] * t1[1] + t0[2] * t1[2]
    kd = kx * d1[0] + ky * d1[1] + kz * d1[2]
    f = kd / (1.0 + c) if c > -1.0 + 1e-12 else 0.0
    return (
        d1[0] * c + (ky * d1[2] - kz * d1[1]) + kx * f,
        d1[1] * c + (kz * d1[0] - kx * d1[2]) + ky * f,
        d1[2] * c + (kx * d1[1] - ky * d1[0]) + kz * f,
    )


@nb.njit(parallel=True, cache=True)
def transport_frames_numba(offsets, tangent, d1_start):
    """d1 per element by parallel transport along each strand (strands in parallel; each
    strand writes only its own rows, so the kernel is race-free and deterministic)."""
    d1 = np.empty_like(tangent)
    for k in nb.prange(len(offsets) - 1):
        o0, o1 = offsets[k], offsets[k + 1]
        if o1 == o0:
            continue
        d1[o0, 0], d1[o0, 1], d1[o0, 2] = d1_start[k, 0], d1_start[k, 1], d1_start[k, 2]
        for e in range(o0 + 1, o1):
            x, y, z = _transport_one(d1[e - 1], tangent[e - 1], tangent[e])
            # re-orthonormalise against round-off drift
            dot = x * tangent[e, 0] + y * tangent[e, 1] + z * tangent[e, 2]
            x -= dot * tangent[e, 0]
            y -= dot * tangent[e, 1]
            z -= dot * tangent[e, 2]
            n = np.sqrt(x * x + y * y + z * z)
            d1[e, 0], d1[e, 1], d1[e, 2] = x / n, y / n, z / n
    return d1


def transport_frames_reference(offsets: np.ndarray, tangent: np.ndarray, d1_start: np.ndarray) -> np.ndarray:
    """Plain numpy reference of :func:`transport_frames_numba` (Rodrigues' formula)."""
    d1 = np.empty_like(tangent)
    for k in range(len(offsets) - 1):
        o0, o1 = offsets[k], offsets[k + 1]
        if o1 == o0:
            continue
        d1[o0] = d1_start[k]
        for e in range(o0 + 1, o1):
            t0, t1 = tangent[e - 1], tangent[e]
            axis = np.cross(t0, t1)
            c = np.dot(t0, t1)
            v = d1[e - 1] * c + np.cross(axis, d1[e - 1]) + axis * np.dot(axis, d1[e - 1]) / (1.0 + c)
            v = v - np.dot(v, t1) * t1
            d1[e] = v / np.linalg.norm(v)
    return d1


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (w, x, y, z) of rotation matrices (n, 3, 3) (columns = rotated basis)."""
    m = R
    tr = m[:, 0, 0] + m[:, 1, 1] + m[:, 2, 2]
    cand = np.stack(
        [
            np.stack([1 + tr, m[:, 2, 1] - m[:, 1, 2], m[:, 0, 2] - m[:, 2, 0], m[:, 1, 0] - m[:, 0, 1]], -1),
            np.stack([m[:, 2, 1] - m[:, 1, 2], 1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2], m[:, 0, 1] + m[:, 1, 0], m[:, 0, 2] + m[:, 2, 0]], -1),
            np.stack([m[:, 0, 2] - m[:, 2, 0], m[:, 0, 1] + m[:, 1, 0], 1 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2], m[:, 1, 2] + m[:, 2, 1]], -1),
            np.stack([m[:, 1, 0] - m[:, 0, 1], m[:, 0, 2] + m[:, 2, 0], m[:, 1, 2] + m[:, 2, 1], 1 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2]], -1),
        ],
        axis=1,
    )  # 4 candidate (unnormalised) quaternions; the one with the largest norm is best conditioned
    diag = np.stack([1 + tr, 1 + m[:, 0, 0] - m[:, 1, 1] - m[:, 2, 2], 1 - m[:, 0, 0] + m[:, 1, 1] - m[:, 2, 2], 1 - m[:, 0, 0] - m[:, 1, 1] + m[:, 2, 2]], -1)
    q = cand[np.arange(len(m)), np.argmax(diag, axis=1)]
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    return q * np.where(q[:, :1] < 0, -1.0, 1.0)


@dataclass(frozen=True, eq=False)
class ElementGeometry:
    centers: np.ndarray  # (n, 3)
    rest_length: np.ndarray  # (n,)
    rest_quat: np.ndarray  # (n, 4) material frame (d1, d2, d3), w first
    frames: np.ndarray  # (n, 3, 3) rows e_r, e_t, e_l
    s: np.ndarray  # (n,) distance to the root along the skeleton
    wood_frames: np.ndarray  # (n, 3, 3) rows e_R, e_T, e_L of the cross-section (:func:`radial_frames`)


def element_geometry(samp: Sampling, node_a: np.ndarray, node_b: np.ndarray, edge_t: np.ndarray,
                     positions: np.ndarray, node_frames: np.ndarray, node_s: np.ndarray) -> ElementGeometry:
    """Frames and centreline positions of elements lying at fraction ``edge_t`` of the skeleton
    edges node_a -> node_b."""
    pa = samp.particles[samp.first_particle]
    pb = samp.particles[samp.first_particle + 1]
    d = pb - pa
    length = np.linalg.norm(d, axis=1)
    e_l = d / length[:, None]
    t = edge_t[:, None]
    axis_point = (1.0 - t) * positions[node_a] + t * positions[node_b]
    edge_len = np.linalg.norm(positions[node_b] - positions[node_a], axis=1)
    U = _unit((1.0 - t) * node_frames[node_a, 0] + t * node_frames[node_b, 0])
    centers = 0.5 * (pa + pb)
    on_axis = 1e-9 * max(float(length.mean()), 1e-300)
    T = _unit((1.0 - t) * node_frames[node_a, 2] + t * node_frames[node_b, 2])
    first = samp.element_offsets[:-1]  # every strand has at least one element
    d1_all = transport_frames_numba(samp.element_offsets, e_l, _unit(reject(U[first], e_l[first])))
    d2 = np.cross(e_l, d1_all)
    R = np.stack([d1_all, d2, e_l], axis=-1)  # columns d1, d2, d3
    return ElementGeometry(
        centers=centers,
        rest_length=length,
        rest_quat=matrix_to_quaternion(R),
        frames=radial_frames(centers, axis_point, U, e_l, on_axis),
        s=node_s[node_a] + edge_t * edge_len,
        wood_frames=radial_frames(centers, axis_point, U, T, on_axis),
    )


def radial_frames(centers: np.ndarray, axis_point: np.ndarray, U: np.ndarray, axis: np.ndarray,
                  on_axis: float) -> np.ndarray:
    """Frames (rows e_r, e_t, e_l) about the unit ``axis`` of each element: e_r from its axis point
    to its centre across the axis (``U`` there for a centre within ``on_axis`` of it), e_t = e_l x
    e_r. About the strand's own direction they are ``frames``; about the skeleton's tangent
    ``wood_frames``, the cross-section's frame, which does not follow the strand's wander between
    the profiles: a cross-section's elements share e_L, so shrinkage gains taken in it (Eq. 16) are
    the first-order length change of the REG offsets under one strain field, and wood that dries
    evenly with S_R = S_T shrinks without straining a connection (docs/decisions.md, "Shrinkage in
    the cross-section's frame")."""
    radial = reject(centers - axis_point, axis)
    tiny = np.linalg.norm(radial, axis=1) < on_axis
    radial[tiny] = reject(U[tiny], axis[tiny])
    e_r = _unit(radial)
    return np.stack([e_r, np.cross(axis, e_r), axis], axis=1)
