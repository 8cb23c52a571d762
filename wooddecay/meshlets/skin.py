"""Per-frame meshlet vertices by blend skinning over the elements that share them (docs/model.md §5).

Woodstock §8.3: the meshlets follow the simulated rods. A meshlet vertex x_0 is shared in the rest
partition by the elements whose cells meet there (:class:`~wooddecay.meshlets.sweep.Meshlets`,
``skin_*``: candidates c with weights w_c and rest local coordinates l_c = R_c0^T (x_0 - c_c0)).
At a frame, the copy owned by element o moves to

    x = sum_c w_c (c_c + R_c S_c l_c) / sum_c w_c,

over the candidates still connected to o: o itself, its neighbours along the strand while the
link between them holds (the lower of the two is intact, ``element_ok``), the elements joined to o
by an intact REG connection (``edge_ok[:, 0]``), and, where no REG edge joins the two, those in o's
connected component. c_c is the element's current midpoint, R_c its rotation (the quaternion q),
S_c = diag(phi_c, phi_c, l_c / l_c0) stretches along the element with its segment (drying shrinkage,
Eq. 17) and across it by phi_c, the brown-rot shrinkage of its length and offsets
(:func:`wooddecay.sim.coupling.shrink_factor`, ``lateral``). A failed element (stretch off) no
longer spans its two particles, which may belong to different pieces: it is placed from its
first particle without stretching along it (l_c = l_c0), c_c = p_a + R_c (0, 0, l_c0 / 2), and so stays with the strand part before it, as its component does. Consumed wood
dwindles: the copies owned by o are finally drawn towards o's own centre, x <- c_o + s_o (x - c_o),
with s_o = ``scale`` (:func:`wooddecay.sim.coupling.crumble_scale`: 0 once o crumbled), so a
crumbled element's meshlet is gone and its neighbours' faces around it are the cavity's walls. A
copy none of whose candidates is still connected to o (o need not be one: a corner of o's cell
skinned by its neighbours) follows o rigidly, x = c_o + R_o R_o0^T (x_0 - c_o0), with o's fields. Connected meshlets keep sharing their vertices (no gap); across a broken
connection each side follows only its own elements, so the crack opens cleanly. Fields (H_c, H_l,
M, ...) per element are interpolated with the same weights: smooth inside a piece, discontinuous
across a crack.

:func:`rest_skinning` computes w_c and l_c from the rest partition (again for its bark moved onto
a source surface, :mod:`wooddecay.meshlets.conform`), a numba kernel with the numpy twin
:func:`rest_skinning_reference`. :func:`skin` is the numba kernel (parallel
over vertices, each writes its own rows: race-free and deterministic); :func:`skin_reference` is
the plain-numpy twin used by the tests. :func:`frame_arrays` skins one
:class:`~wooddecay.sim.driver.Frame` (points and its six fields), as both exporters do.
"""
from __future__ import annotations

from dataclasses import replace

import numba as nb
import numpy as np

from ..wood import WoodModel
from ..quaternion import conj_np, rotate, rotate_np
from ..sim.coupling import crumble_scale, shrink_factor
from ..sim.state import FIELDS
from ..strands.reg import edge_between

#: link kinds of a (vertex, candidate) pair, besides a REG edge index >= 0
ALWAYS, BY_COMPONENT, STRAND = -1, -2, -3


def rest_skinning(model: WoodModel, points, skin_indptr, skin_element):
    """Rest skinning of ``points`` over their candidate elements (CSR ``skin_indptr``,
    ``skin_element``): the weights w_c = 1 / (|x_0 - c_c0|^2 + r_s^2) normalised per vertex, the
    rest local coordinates l_c (module docstring) and the weighted ring age. A numba kernel,
    parallel over vertices (each writes its own rows); :func:`rest_skinning_reference` is its
    numpy twin (the same weights and ring ages bit for bit, l_c within rounding)."""
    K = len(skin_element)
    weight, local, ring = np.empty(K), np.empty((K, 3)), np.empty(len(points))
    _rest_kernel(skin_indptr, np.ascontiguousarray(points, dtype=np.float64), skin_element, model.centers,
                 model.rest_quat, model.ring_age, model.r_s * model.r_s, weight, local, ring)
    return weight, local, ring


@nb.njit(parallel=True, cache=True)
def _rest_kernel(indptr, points, cand, centers, rest_quat, ring_age, r2, weight, local, ring):
    for v in nb.prange(len(indptr) - 1):
        wsum = 0.0
        for k in range(indptr[v], indptr[v + 1]):
            c = cand[k]
            rx, ry, rz = points[v, 0] - centers[c, 0], points[v, 1] - centers[c, 1], points[v, 2] - centers[c, 2]
            w = 1.0 / ((rx * rx + ry * ry + rz * rz) + r2)
            weight[k] = w
            wsum += w
            local[k, 0], local[k, 1], local[k, 2] = rotate(rest_quat[c, 0], -rest_quat[c, 1], -rest_quat[c, 2],
                                                           -rest_quat[c, 3], rx, ry, rz)
        acc = 0.0
        for k in range(indptr[v], indptr[v + 1]):
            weight[k] = weight[k] / wsum
            acc += weight[k] * ring_age[cand[k]]
        ring[v] = acc


def rest_skinning_reference(model: WoodModel, points, skin_indptr, skin_element):
    """Plain-numpy twin of :func:`rest_skinning`."""
    vrow = np.repeat(np.arange(len(points)), np.diff(skin_indptr))
    rel = points[vrow] - model.centers[skin_element]
    w = 1.0 / ((rel * rel).sum(1) + model.r_s * model.r_s)
    wsum = np.bincount(vrow, weights=w, minlength=len(points))
    weight = w / wsum[vrow]
    local = rotate_np(conj_np(model.rest_quat[skin_element]), rel)
    ring = np.bincount(vrow, weights=weight * model.ring_age[skin_element], minlength=len(points))
    return weight, local, ring


def links(model: WoodModel, mesh) -> np.ndarray:
    """Per skinning pair (``mesh.skin_element``): ALWAYS for the owner, STRAND for its strand
    neighbours, the REG edge joining owner and candidate, or BY_COMPONENT where none does."""
    rows = np.repeat(np.arange(len(mesh.points)), np.diff(mesh.skin_indptr))
    o = mesh.vertex_element[rows]
    c = mesh.skin_element
    strand = (model.strand[o] == model.strand[c]) & (np.abs(o - c) == 1)
    edge, found = edge_between(model.reg_edges, model.n_elements, o, c)
    out = np.where(found, edge, BY_COMPONENT)
    return np.where(o == c, ALWAYS, np.where(strand, STRAND, out)).astype(np.int64)


def _accept(link, o, c, component, edge_ok, element_ok):
    return ((link == ALWAYS) | ((link == STRAND) & element_ok[np.minimum(o, c)])
            | ((link >= 0) & edge_ok[np.maximum(link, 0), 0]) | ((link == BY_COMPONENT) & (component[c] == component[o])))


def _centres(model: WoodModel, x, q, element_ok):
    """Per element the centre its meshlet is placed about: the midpoint of its particles, or for a
    failed element p_a + R (0, 0, l_0 / 2) (module docstring)."""
    fp, l0 = model.first_particle, model.rest_length
    a, b = x[fp], x[fp + 1]
    rigid = a + rotate_np(q, np.stack([np.zeros_like(l0), np.zeros_like(l0), 0.5 * l0], 1))
    return np.where(element_ok[:, None], 0.5 * (a + b), rigid)


def skin_reference(model: WoodModel, mesh, link, x, q, component, edge_ok, element_ok, scale, fields, lateral=None):
    """Plain-numpy twin of :func:`skin` (same maths, vectorised over skinning pairs)."""
    lateral = np.ones(model.n_elements) if lateral is None else lateral
    V = len(mesh.points)
    cnt = np.diff(mesh.skin_indptr)
    rows = np.repeat(np.arange(V), cnt)
    o, c = mesh.vertex_element[rows], mesh.skin_element
    ok = _accept(link, o, c, component, edge_ok, element_ok)
    fp = model.first_particle[c]
    a, b = x[fp], x[fp + 1]
    intact = element_ok[c]
    l0 = model.rest_length[c]
    stretch = np.where(intact, np.linalg.norm(b - a, axis=1) / l0, 1.0)
    across = lateral[c]
    local = mesh.skin_local * np.stack([across, across, stretch], 1)
    local[:, 2] += np.where(intact, 0.0, 0.5 * l0)
    p = np.where(intact[:, None], 0.5 * (a + b), a) + rotate_np(q[c], local)
    w = np.where(ok, mesh.skin_weight, 0.0)
    wsum = np.bincount(rows, weights=w, minlength=V)
    pts = np.stack([np.bincount(rows, weights=w * p[:, k], minlength=V) for k in range(3)], 1)
    f = np.stack([np.bincount(rows, weights=w * fields[c, k], minlength=V)
                  for k in range(fields.shape[1])], 1)
    own = mesh.vertex_element
    centre = _centres(model, x, q, element_ok)[own]
    alone = wsum == 0.0
    rest = rotate_np(conj_np(model.rest_quat[own[alone]]), mesh.points[alone] - model.centers[own[alone]])
    pts[alone] = centre[alone] + rotate_np(q[own[alone]], rest)
    f[alone] = fields[own[alone]]
    wsum[alone] = 1.0
    return centre + scale[own, None] * (pts / wsum[:, None] - centre), f / wsum[:, None]


@nb.njit(parallel=True, cache=True)
def _skin_kernel(indptr, owner, cand, weight, local, link, first_particle, rest_length, x, q,
                 component, edge_ok, element_ok, scale, lateral, fields, points, centers, rest_quat, out_p, out_f):
    for v in nb.prange(len(owner)):
        o = owner[v]
        px = py = pz = 0.0
        wsum = 0.0
        nf = fields.shape[1]
        acc = np.zeros(nf)
        for k in range(indptr[v], indptr[v + 1]):
            c = cand[k]
            lk = link[k]
            if lk == ALWAYS:
                ok = True
            elif lk == STRAND:
                ok = element_ok[min(o, c)]
            elif lk >= 0:
                ok = edge_ok[lk, 0]
            else:
                ok = component[c] == component[o]
            if not ok:
                continue
            w = weight[k]
            f = first_particle[c]
            ax, ay, az = x[f, 0], x[f, 1], x[f, 2]
            bx, by, bz = x[f + 1, 0], x[f + 1, 1], x[f + 1, 2]
            if element_ok[c]:
                s = np.sqrt((bx - ax) ** 2 + (by - ay) ** 2 + (bz - az) ** 2) / rest_length[c]
                lz = local[k, 2] * s
                cx, cy, cz = 0.5 * (ax + bx), 0.5 * (ay + by), 0.5 * (az + bz)
            else:
                lz = local[k, 2] + 0.5 * rest_length[c]
                cx, cy, cz = ax, ay, az
            rx, ry, rz = rotate(q[c, 0], q[c, 1], q[c, 2], q[c, 3], local[k, 0] * lateral[c], local[k, 1] * lateral[c], lz)
            px += w * (cx + rx)
            py += w * (cy + ry)
            pz += w * (cz + rz)
            for j in range(nf):
                acc[j] += w * fields[c, j]
            wsum += w
        f = first_particle[o]
        if element_ok[o]:
            ox, oy, oz = 0.5 * (x[f, 0] + x[f + 1, 0]), 0.5 * (x[f, 1] + x[f + 1, 1]), 0.5 * (x[f, 2] + x[f + 1, 2])
        else:
            rx, ry, rz = rotate(q[o, 0], q[o, 1], q[o, 2], q[o, 3], 0.0, 0.0, 0.5 * rest_length[o])
            ox, oy, oz = x[f, 0] + rx, x[f, 1] + ry, x[f, 2] + rz
        if wsum == 0.0:  # no candidate still joined to o: o's own rigid motion
            q0 = rest_quat[o]
            dx, dy, dz = rotate(q0[0], -q0[1], -q0[2], -q0[3], points[v, 0] - centers[o, 0],
                                points[v, 1] - centers[o, 1], points[v, 2] - centers[o, 2])
            rx, ry, rz = rotate(q[o, 0], q[o, 1], q[o, 2], q[o, 3], dx, dy, dz)
            px, py, pz = ox + rx, oy + ry, oz + rz
            for j in range(nf):
                acc[j] = fields[o, j]
            wsum = 1.0
        s = scale[o]
        out_p[v, 0] = ox + s * (px / wsum - ox)
        out_p[v, 1] = oy + s * (py / wsum - oy)
        out_p[v, 2] = oz + s * (pz / wsum - oz)
        for j in range(nf):
            out_f[v, j] = acc[j] / wsum


def skin(model: WoodModel, mesh, link, x, q, component, edge_ok, element_ok, scale, fields, lateral=None):
    """Skinned vertex positions (V, 3) and fields (V, k) of per-element ``fields`` (n, k) for the
    rod state (particles ``x``, quaternions ``q``, ``component``, ``edge_ok``, ``element_ok``),
    the meshlet sizes ``scale`` (n,) and the elements' sizes across their axis ``lateral`` (n,;
    none: 1)."""
    lateral = np.ones(model.n_elements) if lateral is None else np.ascontiguousarray(lateral, dtype=np.float64)
    fields = np.ascontiguousarray(fields, dtype=np.float64).reshape(model.n_elements, -1)
    out_p = np.empty((len(mesh.points), 3))
    out_f = np.empty((len(mesh.points), fields.shape[1]))
    _skin_kernel(mesh.skin_indptr, mesh.vertex_element, mesh.skin_element, mesh.skin_weight,
                 mesh.skin_local, link, model.first_particle, model.rest_length, x, q, component,
                 edge_ok, element_ok, np.ascontiguousarray(scale, dtype=np.float64), lateral, fields,
                 np.ascontiguousarray(mesh.points, dtype=np.float64), model.centers, model.rest_quat, out_p, out_f)
    return out_p, out_f


def frame_arrays(model: WoodModel, mesh, link, frame, offset=None):
    """Skinned points (V, 3) and fields (V, 6, in the order of ``FIELDS``) of one frame; without
    mechanics (empty ``frame.mech``) the rest pose. Crumbled wood dwindles in both; brown-rotted
    wood shrinks across its elements with the rods (``lateral``), so not in the rest pose. ``offset``
    (V, 3) moves the rest positions first (the bark's grooves, :mod:`wooddecay.export.bark_surface`)."""
    if offset is not None and offset.any():
        rows = np.repeat(np.arange(len(mesh.points)), np.diff(mesh.skin_indptr))
        local = mesh.skin_local + rotate_np(conj_np(model.rest_quat[mesh.skin_element]), offset[rows])
        mesh = replace(mesh, skin_local=local)
    fields = np.stack([frame.fields[f] for f in FIELDS], axis=1)
    scale = crumble_scale(model.coupling, frame.fields["H_c"], frame.fields["H_l"])
    if frame.mech:
        m = frame.mech
        return skin(model, mesh, link, m["x"], m["q"], m["component"], m["edge_ok"], m["element_ok"], scale, fields,
                    shrink_factor(model.coupling, frame.fields["H_c"]))
    n = model.n_elements
    return skin(model, mesh, link, model.particles, model.rest_quat, np.zeros(n, dtype=np.int64),
                np.ones((model.n_edges, 3), dtype=bool), np.ones(n, dtype=bool), scale, fields)
