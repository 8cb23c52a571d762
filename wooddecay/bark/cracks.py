"""Bark cracks on the sheet (woodification §5 after Iben and O'Brien 2006; docs/model.md §10).

Stress. The bark is a thin layer bonded to the wood; its loading strain eps per face is the
growth strain of the rings (woodification §4, :mod:`.sheet`) plus its drying shrinkage
S S_T (M_0 - M)^+ (woodstock Eq. 16 on the bark tissue), weighted by [bark] growth and drying.
The species pattern gives the loading its orientation: sigma_inf = eps (P_t t t^T + P_l l l^T)
(woodification Fig. 10: vertical, horizontal or mixed stress). A crack relieves the stress across
it: each face keeps a shadow tensor S = sum over crack edges of w n n^T (n the edge's normal in
the sheet, w = exp(-|r.n| / shadow) max(0, 1 - |r.t| / L) for the face centroid at r from the
edge's midpoint, t its direction and L its length: the along-crack hat of consecutive edges sums
to one beside a straight crack and fades within one edge past its tip), and its stress is
sigma = Pi sigma_inf Pi with Pi = I - clip(S, 0, 1) (eigenvalues clipped): beside a crack only
the stress along it remains (traction-free crack faces); the stress returns over the shadow
length, the shear lag of a film on a substrate, which sets the crack spacing.

Separation and cracking. Per vertex the separation tensor is the mean of the tensile parts of the
stresses of its faces (Iben and O'Brien's separation tensor, without their force split); where
its largest eigenvalue, times (1 + tip_gain) at the tip of a crack (the extra stress at tips that
makes cracks grow rather than multiply), exceeds the vertex's threshold and every neighbour's
excess, a crack edge is inserted perpendicular to its eigenvector: the vertex's edge best aligned
with the crack direction (within 60 degrees), on both sides for a new crack, forward for a tip.
The new edges cast their shadows and the search repeats until no vertex cracks. All of it is
array code in a fixed order: the result does not depend on threads.

Crack components are connected sets of crack edges; a crack vertex's width is ``crack_width``
times min(1, d / taper), d the distance along its crack to the nearer end (cracks open most in
the middle, woodification §5), with noise; its depth is ``crack_depth`` times the width, at most
the bark thickness.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numba as nb
import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra

from .. import fmath as fm
from .sheet import branch_trees

#: a crack edge follows the crack direction within 60 degrees
ALIGN = 0.5
#: a crack narrows over this many sheet edges towards its tips
TAPER_EDGES = 5.0
#: share of a crack's length within 30 degrees of the grain counts as along the grain
ALONG_GRAIN = fm.cos(np.radians(30.0))


@dataclass(eq=False)
class CrackState:
    """What changes on the sheet: cracked edges and each face's shadow tensor (S_tt, S_ll, S_tl)."""

    cracked: np.ndarray  # (E,) bool
    shadow: np.ndarray  # (F, 3)

    @classmethod
    def empty(cls, sheet) -> "CrackState":
        return cls(cracked=np.zeros(len(sheet.edges), dtype=bool), shadow=np.zeros((sheet.n_faces, 3)))


def loading(sheet, eps: np.ndarray) -> np.ndarray:
    """sigma_inf (F, 3) as (tt, ll, tl) for the faces' loading strains ``eps``."""
    P_t, P_l = sheet.pattern
    return np.stack([eps * P_t, eps * P_l, np.zeros_like(eps)], 1)


def eig2(T: np.ndarray):
    """Eigenvalues (larger, smaller) and the unit eigenvector of the larger of symmetric 2x2
    tensors given as (N, 3) rows (tt, ll, tl): mean +- hypot((tt - ll) / 2, tl) and the angle
    atan2(2 tl, tt - ll) / 2, one tensor per iteration. :func:`eig2_reference` is its numpy twin,
    2.2x slower on the tree's 830,660 faces (its sheet at 1 r_s), where it was 8% of a drying bake (docs/decisions.md,
    "Bark eigenpairs in numba")."""
    T = np.ascontiguousarray(T, dtype=np.float64)
    l1, l2, e = np.empty(len(T)), np.empty(len(T)), np.empty((len(T), 2))
    _eig2(T, l1, l2, e)
    return l1, l2, e


@nb.njit(parallel=True, cache=True)
def _eig2(T, l1, l2, e):
    """:func:`eig2` into ``l1``, ``l2``, ``e``."""
    for i in nb.prange(len(T)):
        a, d, b = T[i, 0], T[i, 1], T[i, 2]
        mean, half = 0.5 * (a + d), math.hypot(0.5 * (a - d), b)
        l1[i], l2[i] = mean + half, mean - half
        theta = 0.5 * math.atan2(2.0 * b, a - d)
        e[i, 0], e[i, 1] = math.cos(theta), math.sin(theta)


def eig2_reference(T: np.ndarray):
    """Plain-numpy :func:`eig2`."""
    a, d, b = T[:, 0], T[:, 1], T[:, 2]
    mean, half = 0.5 * (a + d), fm.hypot(0.5 * (a - d), b)
    theta = 0.5 * fm.arctan2(2.0 * b, a - d)
    return mean + half, mean - half, np.stack([fm.cos(theta), fm.sin(theta)], 1)


def _from_eig(l1, l2, e):
    """(N, 3) tensors with eigenvalues l1 along e and l2 across it."""
    c, s = e[:, 0], e[:, 1]
    return np.stack([l1 * c * c + l2 * s * s, l1 * s * s + l2 * c * c, (l1 - l2) * c * s], 1)


def _mul(A, B):
    """Products of 2x2 matrices given as (N, 4) rows (00, 01, 10, 11)."""
    return np.stack([A[:, 0] * B[:, 0] + A[:, 1] * B[:, 2], A[:, 0] * B[:, 1] + A[:, 1] * B[:, 3],
                     A[:, 2] * B[:, 0] + A[:, 3] * B[:, 2], A[:, 2] * B[:, 1] + A[:, 3] * B[:, 3]], 1)


def relieved(sigma_inf: np.ndarray, shadow: np.ndarray) -> np.ndarray:
    """sigma = Pi sigma_inf Pi, Pi = I - clip(S, 0, 1) (module docstring). The eigenpairs come
    from :func:`eig2`, the products from a numba kernel in :func:`relieved_reference`'s order:
    the same bits without its (N, 4) temporaries."""
    l1, l2, e = eig2(shadow)
    out = np.empty((len(l1), 3))
    _relieved(l1, l2, e, sigma_inf, out)
    return out


@nb.njit(inline="always", cache=True)
def _positive(x):
    """np.maximum(x, 0.0), a negative zero included (+0.0)."""
    return x if x > 0.0 else 0.0


@nb.njit(inline="always", cache=True)
def _clip01(x):
    """np.clip(x, 0.0, 1.0), a negative zero included (+0.0)."""
    return 1.0 if x > 1.0 else _positive(x)


@nb.njit(parallel=True, cache=True)
def _relieved(l1, l2, e, sg, out):
    """:func:`relieved` from the eigenpairs of the shadows, one face per iteration."""
    for i in nb.prange(len(l1)):
        c, s = e[i, 0], e[i, 1]
        p1 = 1.0 - _clip01(l1[i])
        p2 = 1.0 - _clip01(l2[i])
        a0, a3, a1 = p1 * c * c + p2 * s * s, p1 * s * s + p2 * c * c, (p1 - p2) * c * s  # Pi: 00, 11, 01 = 10
        b0, b1, b3 = sg[i, 0], sg[i, 2], sg[i, 1]
        m0, m1 = a0 * b0 + a1 * b1, a0 * b1 + a1 * b3  # Pi sigma_inf
        m2, m3 = a1 * b0 + a3 * b1, a1 * b1 + a3 * b3
        o1, o2 = m0 * a1 + m1 * a3, m2 * a0 + m3 * a1  # (Pi sigma_inf) Pi
        out[i, 0] = m0 * a0 + m1 * a1
        out[i, 1] = m2 * a1 + m3 * a3
        out[i, 2] = 0.5 * (o1 + o2)


def relieved_reference(sigma_inf: np.ndarray, shadow: np.ndarray) -> np.ndarray:
    l1, l2, e = eig2(shadow)
    Pi = _from_eig(1.0 - np.clip(l1, 0.0, 1.0), 1.0 - np.clip(l2, 0.0, 1.0), e)
    Pm = Pi[:, [0, 2, 2, 1]]
    out = _mul(_mul(Pm, sigma_inf[:, [0, 2, 2, 1]]), Pm)
    return np.stack([out[:, 0], out[:, 3], 0.5 * (out[:, 1] + out[:, 2])], 1)


def tensile(sigma: np.ndarray) -> np.ndarray:
    """(N, 3) tensile parts (positive eigenvalues only) of the stresses ``sigma``."""
    l1, l2, e = eig2(sigma)
    out = np.empty((len(l1), 3))
    _tensile(l1, l2, e, out)
    return out


@nb.njit(parallel=True, cache=True)
def _tensile(l1, l2, e, out):
    """:func:`tensile` from the eigenpairs, in :func:`_from_eig`'s order."""
    for i in nb.prange(len(l1)):
        c, s = e[i, 0], e[i, 1]
        p1, p2 = _positive(l1[i]), _positive(l2[i])
        out[i, 0] = p1 * c * c + p2 * s * s
        out[i, 1] = p1 * s * s + p2 * c * c
        out[i, 2] = (p1 - p2) * c * s


def tensile_reference(sigma: np.ndarray) -> np.ndarray:
    l1, l2, e = eig2(sigma)
    return _from_eig(np.maximum(l1, 0.0), np.maximum(l2, 0.0), e)


def separation(sheet, plus: np.ndarray, vertices: np.ndarray | None = None) -> np.ndarray:
    """(V, 3) mean of the faces' tensile stresses ``plus`` around each vertex (of ``vertices``
    only, when given: the same values, row by row). Summed face after face in the order of
    ``vertex_faces``: the bits of :func:`separation_reference`, without its (V, K, 3) gather."""
    vertices = np.arange(len(sheet.vertex_faces)) if vertices is None else vertices
    out = np.empty((len(vertices), 3))
    _separation(sheet.vertex_faces, plus, vertices, out)
    return out


@nb.njit(parallel=True, cache=True)
def _separation(vertex_faces, plus, vertices, out):
    """:func:`separation` into ``out``, one vertex per iteration (race-free)."""
    for t in nb.prange(len(vertices)):
        v = vertices[t]
        s0 = s1 = s2 = 0.0
        n = 0
        for k in range(vertex_faces.shape[1]):
            f = vertex_faces[v, k]
            a0 = plus[f, 0] if f >= 0 else 0.0
            a1 = plus[f, 1] if f >= 0 else 0.0
            a2 = plus[f, 2] if f >= 0 else 0.0
            if k == 0:  # numpy's sum starts from the first term, not from +0 (the sign of a zero)
                s0, s1, s2 = a0, a1, a2
            else:
                s0, s1, s2 = s0 + a0, s1 + a1, s2 + a2
            n += f >= 0
        n = max(n, 1)
        out[t, 0], out[t, 1], out[t, 2] = s0 / n, s1 / n, s2 / n


def separation_reference(sheet, plus: np.ndarray, vertices: np.ndarray | None = None) -> np.ndarray:
    vf = sheet.vertex_faces if vertices is None else sheet.vertex_faces[vertices]
    valid = vf >= 0
    total = np.where(valid[..., None], plus[np.maximum(vf, 0)], 0.0).sum(1)
    return total / np.maximum(valid.sum(1), 1)[:, None]


def crack_degree(sheet, cracked: np.ndarray) -> np.ndarray:
    """Crack edges at each vertex."""
    return np.bincount(sheet.edges[cracked].ravel(), minlength=len(sheet.phi))


def _outgoing(sheet, v: np.ndarray):
    """Incident edges of vertices ``v`` (K columns, -1 padded) and their unit directions from v."""
    ve = sheet.vertex_edges[v]
    k = np.maximum(ve, 0)
    sign = np.where(sheet.edges[k, 0] == v[:, None], 1.0, -1.0)
    return ve, sheet.edge_dir[k] * sign[..., None]


def _new_edges(sheet, st: CrackState, deg: np.ndarray, l1: np.ndarray, e1: np.ndarray, tip_gain: float) -> np.ndarray:
    """The crack edges one search inserts (module docstring), sorted, unique; ``deg`` the crack
    edges at each vertex, ``l1``, ``e1`` the largest eigenvalue and its eigenvector of each
    vertex's separation tensor."""
    excess = l1 * (1.0 + tip_gain * (deg == 1)) - sheet.threshold
    excess[deg >= 2] = -np.inf
    over = np.flatnonzero(excess > 0.0)
    other = sheet.vertex_nbrs[over]
    nbr = np.where(other >= 0, excess[np.maximum(other, 0)], -np.inf)
    cand = over[excess[over] >= nbr.max(1, initial=-np.inf)]
    if len(cand) == 0:
        return np.zeros(0, dtype=np.int64)
    edges, u = _outgoing(sheet, cand)
    free = (edges >= 0) & ~st.cracked[np.maximum(edges, 0)]
    c = np.stack([-e1[cand, 1], e1[cand, 0]], 1)
    # a tip continues away from its crack edge
    tip = deg[cand] == 1
    crack_dir = np.where(st.cracked[np.maximum(edges, 0)][..., None] & (edges >= 0)[..., None], u, 0.0).sum(1)
    flip = tip & ((c * crack_dir).sum(1) > 0.0)
    c[flip] *= -1.0
    score = (u * c[:, None, :]).sum(-1)
    ahead = ~tip[:, None] | ((u * crack_dir[:, None, :]).sum(-1) < 0.0)
    picks = []
    for sgn, allowed in ((1.0, np.ones(len(cand), dtype=bool)), (-1.0, ~tip)):
        sc = np.where(free & ahead & allowed[:, None], sgn * score, -np.inf)
        k = np.argmax(sc, axis=1)
        ok = sc[np.arange(len(cand)), k] >= ALIGN
        picks.append(edges[np.arange(len(cand)), k][ok])
    return np.unique(np.concatenate(picks))


def cast_shadows(sheet, st: CrackState, new: np.ndarray, shadow_length: float) -> np.ndarray:
    """Add the shadows of the crack edges ``new`` to the faces near them (module docstring):
    every face whose centroid lies within REACH shadow lengths plus an edge length ``h`` of an
    edge's midpoint (periodically around the branch) and has a weight there, found in the sheet's
    :class:`~.sheet.FaceGrid`; returns those faces (sorted). The edges add in the order of their
    branch, then of ``new``, and the weights take numpy's exp: the bits of
    :func:`cast_shadows_reference`, which visits every face within reach (12.5x the time on the log,
    ``benchmarks/bark.py``; 13x the faces on the tree)."""
    g = sheet.face_grid
    eb = sheet.vertex_branch[sheet.edges[new, 0]]
    order = np.argsort(eb, kind="stable")
    new, eb = new[order], eb[order]
    P = sheet.period[eb]
    qx = sheet.edge_mid[new, 0] % P
    qy = np.clip(sheet.edge_mid[new, 1] - g.y0[eb], 0.0, None)
    args = (new, eb, qx, qy, sheet.edge_mid, sheet.edge_dir, sheet.edge_length, sheet.face_xy, sheet.period, g.x,
            g.y, g.y0, g.wx, g.wy, g.nx, g.ny, g.base, g.ptr, g.faces, REACH * shadow_length + sheet.h,
            shadow_length)
    none_i, none_f = np.zeros(0, dtype=np.int64), np.zeros(0)
    n = _strip_pairs(*args, False, none_i, none_i, none_f, none_f)
    edge, face, arg, hat = np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64), np.empty(n), np.empty(n)
    _strip_pairs(*args, True, edge, face, arg, hat)
    _accumulate(new[edge], face, fm.exp(arg) * hat, sheet.edge_dir, st.shadow)
    touched = np.zeros(sheet.n_faces, dtype=np.bool_)
    touched[face] = True
    return np.flatnonzero(touched)


#: faces further than this many shadow lengths (plus an edge) from a crack edge get no shadow
REACH = 4.0


@nb.njit(cache=True)
def _strip_pairs(new, eb, qx, qy, mid, edir, elen, face_xy, period, gx, gy, y0, wx, wy, nx, ny, base, ptr, faces,
                 reach, shadow_length, fill, edge, face, arg, hat):
    """The (edge, face) pairs of :func:`cast_shadows` with a weight, edge after edge; with
    ``fill`` written to ``edge`` (position in ``new``), ``face``, ``arg`` (the exponent
    -|r.n| / shadow_length) and ``hat`` (1 - |r.t| / l); returns their count. The faces of an
    edge are those of the cells over its strip (within its length along it, where the hat is
    positive, and ``reach`` across) that lie within ``reach`` of the query point (qx, qy),
    periodically in x, tested as a periodic KD-tree tests it."""
    r2 = reach * reach
    n = 0
    for t in range(len(new)):
        k, b = new[t], eb[t]
        per = period[b]
        half = 0.5 * per
        t0, t1 = edir[k, 0], edir[k, 1]
        n0, n1 = -t1, t0
        Lk = elen[k]
        my = mid[k, 1] - y0[b]
        across = reach + abs(qy[t] - my)
        ex = Lk * abs(t0) + across * abs(n0)
        ey = Lk * abs(t1) + across * abs(n1)
        lo_y = max(my - ey, qy[t] - reach)
        hi_y = min(my + ey, qy[t] + reach)
        if hi_y < lo_y:
            continue
        iy0 = max(int(math.floor(lo_y / wy)), 0)
        iy1 = min(int(math.floor(hi_y / wy)), ny[b] - 1)
        mx = qx[t]
        ix0 = int(math.floor((mx - ex) / wx[b]))
        ix1 = int(math.floor((mx + ex) / wx[b]))
        if ix1 - ix0 + 1 >= nx[b]:
            ix0, ix1 = 0, nx[b] - 1
        for iy in range(iy0, iy1 + 1):
            for ixr in range(ix0, ix1 + 1):
                c = base[b] + iy * nx[b] + ixr % nx[b]
                for p in range(ptr[c], ptr[c + 1]):
                    f = faces[p]
                    dx = gx[f] - mx
                    if dx < -half:
                        dx += per
                    elif dx > half:
                        dx -= per
                    dy = gy[f] - qy[t]
                    if dx * dx + dy * dy > r2:
                        continue
                    rx = (face_xy[f, 0] - mid[k, 0] + half) % per - half
                    ry = face_xy[f, 1] - mid[k, 1]
                    h = 1.0 - abs(rx * t0 + ry * t1) / Lk
                    if h <= 0.0:
                        continue
                    if fill:
                        edge[n], face[n] = t, f
                        arg[n] = -abs(rx * n0 + ry * n1) / shadow_length
                        hat[n] = h
                    n += 1
    return n


@nb.njit(cache=True)
def _accumulate(edge, face, w, edir, shadow):
    """shadow[face] += w n n^T pair after pair, in order (n the normal of the crack edge)."""
    for p in range(len(face)):
        n0, n1 = -edir[edge[p], 1], edir[edge[p], 0]
        f = face[p]
        shadow[f, 0] += w[p] * (n0 * n0)
        shadow[f, 1] += w[p] * (n1 * n1)
        shadow[f, 2] += w[p] * (n0 * n1)


def cast_shadows_reference(sheet, st: CrackState, new: np.ndarray, shadow_length: float) -> np.ndarray:
    """:func:`cast_shadows` with numpy and a periodic KD-tree of each branch's faces; returns
    every face within reach, with a weight or not."""
    touched = [np.zeros(0, dtype=np.int64)]
    reach = REACH * shadow_length + sheet.h
    trees = branch_trees(sheet.period, sheet.face_branch, sheet.face_xy)
    eb = sheet.vertex_branch[sheet.edges[new, 0]]
    for b in np.unique(eb):
        tree, rows, y0 = trees[int(b)]
        sel = new[eb == b]
        P = sheet.period[b]
        mids = np.stack([sheet.edge_mid[sel, 0] % P, np.clip(sheet.edge_mid[sel, 1] - y0, 0.0, None)], 1)
        hits = tree.query_ball_point(mids, reach)
        cnt = np.array([len(x) for x in hits])
        if cnt.sum() == 0:
            continue
        f = rows[np.concatenate([np.sort(np.asarray(x, dtype=np.int64)) for x in hits])]
        k = np.repeat(sel, cnt)
        r = sheet.face_xy[f] - sheet.edge_mid[k]
        r[:, 0] = (r[:, 0] + 0.5 * P) % P - 0.5 * P
        t = sheet.edge_dir[k]
        n = np.stack([-t[:, 1], t[:, 0]], 1)
        w = fm.exp(-np.abs((r * n).sum(1)) / shadow_length) * np.clip(
            1.0 - np.abs((r * t).sum(1)) / sheet.edge_length[k], 0.0, None)
        add = w[:, None] * np.stack([n[:, 0] ** 2, n[:, 1] ** 2, n[:, 0] * n[:, 1]], 1)
        np.add.at(st.shadow, f, add)
        touched.append(f)
    return np.unique(np.concatenate(touched))


def grow(sheet, st: CrackState, eps: np.ndarray, tip_gain: float, shadow_length: float,
         max_searches: int = 1000) -> int:
    """Insert crack edges under the loading strains ``eps`` (F,) until no vertex cracks (module
    docstring); returns the number of edges inserted. After each search only the faces the new
    shadows reached and their vertices are evaluated again (the rest are unchanged)."""
    total = 0
    sigma_inf = loading(sheet, eps)
    plus = tensile(relieved(sigma_inf, st.shadow))
    l1, _, e1 = eig2(separation(sheet, plus))
    deg = crack_degree(sheet, st.cracked)
    for _ in range(max_searches):
        new = _new_edges(sheet, st, deg, l1, e1, tip_gain)
        if len(new) == 0:
            break
        st.cracked[new] = True
        deg += np.bincount(sheet.edges[new].ravel(), minlength=len(deg))
        faces = cast_shadows(sheet, st, new, shadow_length)
        plus[faces] = tensile(relieved(sigma_inf[faces], st.shadow[faces]))
        verts = np.unique(sheet.faces[faces].ravel())
        l1[verts], _, e1[verts] = eig2(separation(sheet, plus, verts))
        total += len(new)
    return total


def components(sheet, cracked: np.ndarray):
    """Crack components: (the cracked edges, the component of each, their count)."""
    ce = np.flatnonzero(cracked)
    if len(ce) == 0:
        return ce, np.zeros(0, dtype=np.int64), 0
    nv = len(sheet.phi)
    a, b = sheet.edges[ce, 0], sheet.edges[ce, 1]
    g = sp.coo_matrix((np.ones(len(ce)), (a, b)), shape=(nv, nv)).tocsr()
    _, label = connected_components(g, directed=False)
    _, comp = np.unique(label[a], return_inverse=True)
    return ce, comp.ravel(), int(comp.max()) + 1


def widths(sheet, cracked: np.ndarray, crack_width: float) -> np.ndarray:
    """(V,) crack width at each vertex (0 off the cracks): ``crack_width`` min(1, d / taper), d the
    distance along the crack to its nearer end (module docstring)."""
    out = np.zeros(len(sheet.phi))
    ce = np.flatnonzero(cracked)
    if len(ce) == 0:
        return out
    nv = len(sheet.phi)
    a, b = sheet.edges[ce, 0], sheet.edges[ce, 1]
    g = sp.coo_matrix((sheet.edge_length[ce], (a, b)), shape=(nv, nv)).tocsr()
    deg = np.bincount(np.concatenate([a, b]), minlength=nv)
    ends = np.flatnonzero(deg == 1)
    taper = TAPER_EDGES * sheet.h
    on = deg > 0
    if len(ends):
        d = dijkstra(g, directed=False, indices=ends, min_only=True)
    else:
        d = np.full(nv, np.inf)
    out[on] = crack_width * np.minimum(1.0, d[on] / taper) * sheet.width_noise[on]
    return out


def statistics(sheet, cracked: np.ndarray) -> dict:
    """Crack count (components), total length (m) and the share of it within 30 degrees of the
    grain."""
    ce, _, count = components(sheet, cracked)
    length = float(sheet.edge_length[ce].sum())
    along = float(sheet.edge_length[ce][np.abs(sheet.edge_dir[ce, 1]) >= ALONG_GRAIN].sum())
    return {"bark_crack_count": count, "bark_crack_length_m": round(length, 6),
            "bark_crack_along_grain": round(along / length, 6) if length > 0 else 0.0}
