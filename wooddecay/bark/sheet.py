"""The bark sheet: each branch's bark surface as a triangle mesh in its (phi, s) parameters.

woodification §5 runs its crack model on the surface mesh of the tree; ours is the bark of the
wood model. Per branch the sheet is a grid around and along the branch: ``n_phi`` columns at the
angle phi of the wood-local coordinates (r, phi, s) (the meshlets' ``wood`` and the elements'
``wood_coords`` use the same angle), rows every ``h`` along s, each vertex moved at random by up
to a quarter of ``h`` and each quad split along a random diagonal, so crack paths along the edges
are not tied to a lattice. The grid closes around the branch (column ``n_phi`` is column 0).

Lengths on the sheet are those of the bark: a step dphi at arc s spans dphi P(s) / (2 pi), P the
perimeter of the profile interpolated between the branch's nodes. Directions are kept in the
local (t, l) frame: t around the branch (e_t), l along it (e_l, the grain).

Per face the sheet holds the growth strain of the bark (woodification §4): the circumferential
expansion of the outer rings over the bark's life, the fraction of the radius grown in the last
``bark_years`` years of the ring record (Weibull rate of Eq. 2 with the year noise, as the rings
of :mod:`wooddecay.strands.rings`), scaled by the eccentric growth factor (1 + e n.y) of Eq. 3.
Per vertex it holds the crack threshold with coherent noise (where cracks start), stretched along
the grain for fissures and across it for bands; per face the bark's initial bond to the wood, with
noise of the size of a plate (where bark comes off first, :mod:`.shedding`).

Elements: each face reads moisture and health from the nearest bark element of its branch (any
element of the branch where it has no bark), and keeps that element's shrinkage S S_T and M_0. The bark layer is every element whose capsule reaches
into the bark (bark distance below the bark thickness plus r_s): those elements carry the
meshlets' bark faces, and they hold together as a layer where the bark tissue alone does not (on
the log 162 of its 398 bark elements have no REG pair with another bark element, 8 of the 800 in
the layer); each belongs to the face it lies under (its plate, :mod:`.shedding`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..wood import WoodModel
from .. import fmath as fm
from ..strands.profiles import polygon_perimeter
from ..strands.rings import BARK

#: (P_t, P_l): the pattern's share of a strain along t (around) and l (along the grain)
PATTERNS = {"fissures": (1.0, 0.25), "plates": (1.0, 0.8), "bands": (0.25, 1.0), "none": (1.0, 1.0)}
#: threshold-noise feature size in sheet edges (across, along) per pattern
NOISE_CELLS = {"fissures": (4.0, 16.0), "plates": (5.0, 5.0), "bands": (16.0, 4.0), "none": (6.0, 6.0)}
JITTER = 0.25
#: relative noise on crack widths (woodification §5)
WIDTH_NOISE = 0.3
#: relative noise on the bark's initial bond to the wood (features of the plates' size)
BOND_NOISE = 0.5
#: side of a :class:`FaceGrid` cell in sheet edges h
GRID_CELLS = 2.0


@dataclass(frozen=True, eq=False)
class BarkSheet:
    """Structure of arrays over the sheet's vertices (V), faces (F) and edges (E) of all branches."""

    h: float  # target edge length (m)
    vertex_branch: np.ndarray  # (V,)
    phi: np.ndarray  # (V,) angle in the node frame
    s: np.ndarray  # (V,) distance to the root along the skeleton
    perimeter: np.ndarray  # (V,) P(s) of the vertex's row
    faces: np.ndarray  # (F, 3)
    face_branch: np.ndarray  # (F,)
    face_xy: np.ndarray  # (F, 2) centroid in the branch's flat coordinates (x around, y = s)
    face_area: np.ndarray  # (F,) m^2
    face_element: np.ndarray  # (F,) element it reads M, H_c, H_l from
    shrinkage: np.ndarray  # (F,) S S_T of that element's tissue (woodstock Eq. 16, tangential)
    M_0: np.ndarray  # (F,) M_0 of that element's tissue
    growth: np.ndarray  # (F,) growth strain (woodification §4)
    edges: np.ndarray  # (E, 2) a < b
    edge_faces: np.ndarray  # (E, 2) faces on either side (-1 on the sheet's ends)
    edge_dir: np.ndarray  # (E, 2) unit direction a -> b in (t, l)
    edge_length: np.ndarray  # (E,) m
    edge_mid: np.ndarray  # (E, 2) midpoint in flat coordinates
    vertex_edges: np.ndarray  # (V, K) incident edges, -1 padded
    vertex_nbrs: np.ndarray  # (V, K) the other ends of those edges, -1 padded
    vertex_faces: np.ndarray  # (V, K) incident faces, -1 padded
    threshold: np.ndarray  # (V,) crack threshold with noise
    bond: np.ndarray  # (F,) initial bond of the bark to the wood, with noise at the plates' scale
    width_noise: np.ndarray  # (V,) factor on a crack's width there
    period: np.ndarray  # (n_branches,) flat width around each branch (m), 0 without a sheet
    pattern: tuple[float, float]  # (P_t, P_l)
    element_face: np.ndarray  # (n_elements,) face an element of the bark layer lies under, -1 otherwise
    face_grid: "FaceGrid"  # the face centroids in cells (:func:`face_grid`)

    @property
    def n_faces(self) -> int:
        return len(self.faces)


def recent_growth(Q: np.ndarray, bark_years: int) -> float:
    """Fraction of a section's radius grown in its last ``bark_years`` years, from its cumulative
    normalised ring radii Q (Q_0 = 0 at the pith, Q_Y = 1 at the bark)."""
    years = len(Q) - 1
    return float(1.0 - Q[max(years - int(bark_years), 0)])


def _value_noise(u: np.ndarray, v: np.ndarray, period_u: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth value noise in [0, 1] at lattice coordinates (u, v), periodic in u with
    ``period_u`` cells."""
    nv = int(np.floor(v.max(initial=0.0))) + 2
    lattice = rng.random((nv, period_u))
    i0, j0 = np.floor(v).astype(np.int64), np.floor(u).astype(np.int64)
    fv, fu = v - i0, u - j0
    fv, fu = fv * fv * (3 - 2 * fv), fu * fu * (3 - 2 * fu)
    j0, j1 = j0 % period_u, (j0 + 1) % period_u
    a = lattice[i0, j0] * (1 - fu) + lattice[i0, j1] * fu
    b = lattice[i0 + 1, j0] * (1 - fu) + lattice[i0 + 1, j1] * fu
    return a * (1 - fv) + b * fv


def _padded(rows: np.ndarray, values: np.ndarray, n: int) -> np.ndarray:
    """(n, K) table of ``values`` grouped by ``rows`` (ascending within a row), -1 padded."""
    order = np.lexsort((values, rows))
    rows, values = rows[order], values[order]
    count = np.bincount(rows, minlength=n)
    out = np.full((n, max(int(count.max(initial=0)), 1)), -1, dtype=np.int64)
    start = np.concatenate([[0], np.cumsum(count)[:-1]])
    out[rows, np.arange(len(rows)) - start[rows]] = values
    return out


def _branch_chain(skel, topo, b: int) -> tuple[np.ndarray, np.ndarray] | None:
    """The skeleton nodes of branch ``b`` in order along it, after its parent's node where it
    has one, and their distances s to the root; None for a branch without nodes or length."""
    nodes = np.flatnonzero(topo.branch == b)
    if len(nodes) == 0:
        return None
    first = nodes[np.argmin(topo.s[nodes])]
    chain = nodes[np.argsort(topo.s[nodes], kind="stable")]
    if skel.parent[first] >= 0:
        chain = np.concatenate([[skel.parent[first]], chain])
    s_n = topo.s[chain].astype(float)
    if s_n[-1] - s_n[0] <= 0.0:
        return None
    return chain, s_n


def _branch_grid(s_n: np.ndarray, perim: np.ndarray, h: float, rng: np.random.Generator):
    """The grid of one branch (module docstring) over its nodes at ``s_n`` with profile
    perimeters ``perim``: the number of columns n_phi, each vertex's jittered phi and s and the
    perimeter P(s) of its row, and the faces, each quad split along a random diagonal."""
    n_phi = max(8, int(round(perim.max() / h)))
    n_s = max(2, int(np.ceil((s_n[-1] - s_n[0]) / h)) + 1)
    jj, ii = np.meshgrid(np.arange(n_phi), np.arange(n_s))
    jit = rng.uniform(-JITTER, JITTER, (2, n_s, n_phi))
    jit[1, [0, -1]] = 0.0  # the ends stay at the ends
    phi = (2 * np.pi * (jj + jit[0]) / n_phi).ravel()
    s = (s_n[0] + (ii + jit[1]) * (s_n[-1] - s_n[0]) / (n_s - 1)).ravel()
    P = np.interp(s, s_n, perim)
    q = (ii[:-1] * n_phi + jj[:-1]).ravel()
    a, bq = q, ii[:-1].ravel() * n_phi + (jj[:-1].ravel() + 1) % n_phi
    c, d = a + n_phi, bq + n_phi
    flip = rng.random(len(q)) < 0.5
    f1 = np.where(flip[:, None], np.stack([a, bq, d], 1), np.stack([a, bq, c], 1))
    f2 = np.where(flip[:, None], np.stack([a, d, c], 1), np.stack([bq, d, c], 1))
    return n_phi, phi, s, P, np.vstack([f1, f2])


def _branch_fields(bark, pattern: str, up: np.ndarray, recent: np.ndarray, s_n: np.ndarray, phi: np.ndarray,
                   s: np.ndarray, n_phi: int, h: float, eccentricity: float, rng: np.random.Generator):
    """Per vertex of one branch (nodes at ``s_n`` with their ``up2d`` directions ``up`` and
    :func:`recent_growth` ``recent``): the growth strain (woodification §4) scaled by the
    eccentric factor (1 + e n.y) of Eq. 3, the crack threshold with value noise stretched by the
    pattern (:data:`NOISE_CELLS`), and the bond with noise of the size of a plate."""
    up_v = np.stack([np.interp(s, s_n, up[:, k]) for k in (0, 1)], 1)
    ecc = 1.0 + eccentricity * (fm.cos(phi) * up_v[:, 0] + fm.sin(phi) * up_v[:, 1])
    g_v = float(bark.growth) * np.interp(s, s_n, recent) * ecc
    cu, cv = NOISE_CELLS[pattern]
    period_u = max(1, int(round(n_phi / cu)))
    noise = _value_noise(phi / (2 * np.pi) * period_u, (s - s_n[0]) / (cv * h), period_u, rng)
    thr = float(bark.threshold) * (1.0 + float(bark.noise) * (2.0 * noise - 1.0))
    cells = max(1.0, np.sqrt(float(bark.plate_area)) / h)
    period_b = max(1, int(round(n_phi / cells)))
    b_v = 1.0 + BOND_NOISE * (2.0 * _value_noise(phi / (2 * np.pi) * period_b, (s - s_n[0]) / (cells * h),
                                                  period_b, rng) - 1.0)
    return g_v, thr, b_v


def _flat(phi: np.ndarray, s: np.ndarray, P: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(t, l) displacement from vertex a to vertex b (arrays), metric of the bark."""
    dphi = (phi[b] - phi[a] + np.pi) % (2 * np.pi) - np.pi
    return np.stack([dphi * 0.5 * (P[a] + P[b]) / (2 * np.pi), s[b] - s[a]], -1)


def _face_geometry(phi, s, P, faces, fb, period):
    """Each face's area on the bark and its centroid in its branch's flat coordinates (x around,
    modulo the branch's ``period``, y = s)."""
    e01, e02 = _flat(phi, s, P, faces[:, 0], faces[:, 1]), _flat(phi, s, P, faces[:, 0], faces[:, 2])
    area = 0.5 * np.abs(e01[:, 0] * e02[:, 1] - e01[:, 1] * e02[:, 0])
    x0 = (phi[faces[:, 0]] % (2 * np.pi)) * period[fb] / (2 * np.pi)
    face_xy = np.stack([(x0 + (e01[:, 0] + e02[:, 0]) / 3.0) % period[fb], s[faces[:, 0]] + (e01[:, 1] + e02[:, 1]) / 3.0], 1)
    return area, face_xy


def _sheet_edges(phi, s, P, faces, vb, period):
    """The edges of ``faces`` (a < b, sorted), the faces on either side (-1 on the sheet's
    ends), their (t, l) vectors a -> b, lengths and midpoints in flat coordinates."""
    he = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    hf = np.tile(np.arange(len(faces)), 3)
    edges, inv = np.unique(he, axis=0, return_inverse=True)
    inv = inv.ravel()
    order = np.argsort(inv, kind="stable")
    edge_faces = np.full((len(edges), 2), -1, dtype=np.int64)
    first = np.searchsorted(inv[order], np.arange(len(edges)))
    edge_faces[:, 0] = hf[order][first]
    second = first + 1
    has2 = (second < len(inv)) & (inv[order][np.minimum(second, len(inv) - 1)] == np.arange(len(edges)))
    edge_faces[has2, 1] = hf[order][second[has2]]
    d = _flat(phi, s, P, edges[:, 0], edges[:, 1])
    length = np.linalg.norm(d, axis=1)
    eb = vb[edges[:, 0]]
    xa = (phi[edges[:, 0]] % (2 * np.pi)) * period[eb] / (2 * np.pi)
    edge_mid = np.stack([(xa + 0.5 * d[:, 0]) % period[eb], s[edges[:, 0]] + 0.5 * d[:, 1]], 1)
    return edges, edge_faces, d, length, edge_mid


def build_sheet(model: WoodModel, bark, recent: np.ndarray, eccentricity: float, rng: np.random.Generator) -> BarkSheet:
    """The sheet of ``model`` (module docstring) for the resolved [bark] section ``bark``;
    ``recent`` per skeleton node is :func:`recent_growth` of its profile's rings."""
    skel, topo = model.skeleton, model.topology
    h = float(bark.spacing) * model.r_s
    pattern = str(bark.pattern)
    perim = np.array([polygon_perimeter(p.polygon) for p in skel.profiles])
    parts = []
    v_off = 0
    period = np.zeros(topo.n_branches)
    for b in range(topo.n_branches):
        found = _branch_chain(skel, topo, b)
        if found is None:
            continue
        chain, s_n = found
        period[b] = float(np.mean(perim[chain]))
        n_phi, phi, s, P, faces = _branch_grid(s_n, perim[chain], h, rng)
        g_v, thr, b_v = _branch_fields(bark, pattern, topo.up2d[chain], recent[chain], s_n, phi, s, n_phi, h,
                                       eccentricity, rng)
        parts.append((b, phi, s, P, faces + v_off, g_v, thr, b_v))
        v_off += len(phi)
    if not parts:
        return _empty(h, pattern, period, model.n_elements)
    vb = np.concatenate([np.full(len(p[1]), p[0]) for p in parts])
    phi, s, P = (np.concatenate([p[k] for p in parts]) for k in (1, 2, 3))
    faces = np.vstack([p[4] for p in parts])
    g_v, thr, b_v = (np.concatenate([p[k] for p in parts]) for k in (5, 6, 7))
    fb = vb[faces[:, 0]]
    area, face_xy = _face_geometry(phi, s, P, faces, fb, period)
    edges, edge_faces, d, length, edge_mid = _sheet_edges(phi, s, P, faces, vb, period)
    nv = len(phi)
    vertex_edges = _padded(edges.ravel(), np.repeat(np.arange(len(edges)), 2), nv)
    vertex_nbrs = np.where(vertex_edges >= 0, edges[np.maximum(vertex_edges, 0)].sum(-1) - np.arange(nv)[:, None], -1)
    vertex_faces = _padded(faces.ravel(), np.repeat(np.arange(len(faces)), 3), nv)
    face_element, element_face = _element_maps(model, fb, face_xy, period)
    mat = model.materials.per_element
    return BarkSheet(h=h, vertex_branch=vb, phi=phi, s=s, perimeter=P, faces=faces, face_branch=fb,
                     face_xy=face_xy, face_area=area, face_element=face_element,
                     shrinkage=(mat("S") * mat("S_T"))[face_element], M_0=mat("M_0")[face_element],
                     growth=g_v[faces].mean(1),
                     edges=edges, edge_faces=edge_faces, edge_dir=d / length[:, None], edge_length=length,
                     edge_mid=edge_mid, vertex_edges=vertex_edges, vertex_nbrs=vertex_nbrs,
                     vertex_faces=vertex_faces, threshold=thr,
                     bond=b_v[faces].mean(1),
                     width_noise=1.0 + WIDTH_NOISE * rng.uniform(-1.0, 1.0, nv), period=period,
                     pattern=PATTERNS[pattern], element_face=element_face,
                     face_grid=face_grid(period, fb, face_xy, GRID_CELLS * h))


@dataclass(frozen=True, eq=False)
class FaceGrid:
    """The face centroids bucketed per branch in cells of about ``cell`` square, periodic around
    the branch (:mod:`.cracks` finds the faces near a crack edge in them). Cell (b, iy, ix), ix
    around, iy along, is ``base[b] + iy nx[b] + ix``; its faces are ``faces[ptr[c]:ptr[c + 1]]``,
    ascending. Columns split the branch's period evenly (width ``wx[b]``), rows are ``wy`` apart
    from the branch's lowest centroid ``y0[b]``."""

    x: np.ndarray  # (F,) centroid x modulo the branch's period
    y: np.ndarray  # (F,) centroid y above y0 of its branch
    y0: np.ndarray  # (B,)
    wx: np.ndarray  # (B,)
    wy: float
    nx: np.ndarray  # (B,) columns, 0 on a branch without faces
    ny: np.ndarray  # (B,) rows
    base: np.ndarray  # (B,)
    ptr: np.ndarray  # (cells + 1,)
    faces: np.ndarray  # (F,)


def face_grid(period: np.ndarray, branch: np.ndarray, xy: np.ndarray, cell: float) -> FaceGrid:
    """:class:`FaceGrid` of the face centroids ``xy`` on their ``branch``."""
    B = len(period)
    has = np.bincount(branch, minlength=B) > 0
    y0 = np.full(B, np.inf)
    np.minimum.at(y0, branch, xy[:, 1])
    y0[~has] = 0.0
    y = xy[:, 1] - y0[branch]
    span = np.zeros(B)
    np.maximum.at(span, branch, y)
    nx = np.where(has, np.maximum(np.floor(period / cell), 1.0), 0.0).astype(np.int64)
    ny = np.where(has, np.floor(span / cell) + 1.0, 0.0).astype(np.int64)
    wx = np.where(nx > 0, period / np.maximum(nx, 1), 1.0)
    base = np.concatenate([[0], np.cumsum(nx * ny)[:-1]]).astype(np.int64)
    x = xy[:, 0] % np.where(period > 0, period, 1.0)[branch]
    ix = np.minimum((x / wx[branch]).astype(np.int64), nx[branch] - 1)
    iy = np.minimum((y / cell).astype(np.int64), ny[branch] - 1)
    c = base[branch] + iy * nx[branch] + ix
    order = np.argsort(c, kind="stable")
    ptr = np.concatenate([[0], np.cumsum(np.bincount(c, minlength=int((nx * ny).sum())))]).astype(np.int64)
    return FaceGrid(x=x, y=y, y0=y0, wx=wx, wy=float(cell), nx=nx, ny=ny, base=base, ptr=ptr,
                    faces=order.astype(np.int64))


def branch_trees(period: np.ndarray, branch: np.ndarray, xy: np.ndarray) -> dict:
    """Per branch a KD-tree of the points ``xy`` (flat coordinates) on it, periodic around the
    branch: ``{branch: (tree, rows, lowest s)}``."""
    out = {}
    for b in np.unique(branch):
        rows = np.flatnonzero(branch == b)
        span = float(np.ptp(xy[rows, 1])) + 1.0
        pts = np.stack([xy[rows, 0] % period[b], xy[rows, 1] - xy[rows, 1].min()], 1)
        out[int(b)] = (cKDTree(pts, boxsize=[period[b], 4.0 * span]), rows, float(xy[rows, 1].min()))
    return out


def query(trees, branch: np.ndarray, xy: np.ndarray, period: np.ndarray) -> np.ndarray:
    """Row of the nearest tree point on the same branch for each of ``xy`` (-1 without one)."""
    out = np.full(len(xy), -1, dtype=np.int64)
    for b in np.unique(branch):
        if int(b) not in trees:
            continue
        tree, rows, y0 = trees[int(b)]
        sel = np.flatnonzero(branch == b)
        pts = np.stack([xy[sel, 0] % period[b], np.clip(xy[sel, 1] - y0, 0.0, None)], 1)
        _, k = tree.query(pts)
        out[sel] = rows[k]
    return out


def element_xy(model: WoodModel, period: np.ndarray) -> np.ndarray:
    """The elements' flat sheet coordinates (x around their branch, s)."""
    wc = model.wood_coords
    return np.stack([(wc[:, 1] % (2 * np.pi)) * period[model.branch] / (2 * np.pi), wc[:, 2]], 1)


def _element_maps(model: WoodModel, fb, face_xy, period):
    """Each face's element (nearest bark element of its branch, else nearest element) and the face
    over each element of the bark layer (module docstring)."""
    n = model.n_elements
    exy = element_xy(model, period)
    bark = model.tissue == BARK
    face_element = np.full(len(fb), -1, dtype=np.int64)
    for pick in (bark, np.ones(n, dtype=bool)):  # the branch's bark, else any of its elements
        need = face_element < 0
        rows = np.flatnonzero(pick)
        if not need.any() or len(rows) == 0:
            continue
        have = np.isin(fb, np.unique(model.branch[rows])) & need
        trees = branch_trees(period, model.branch[rows], exy[rows])
        k = query(trees, fb[have], face_xy[have], period)
        face_element[have] = np.where(k >= 0, rows[np.maximum(k, 0)], -1)
    element_face = np.full(n, -1, dtype=np.int64)
    layer = model.bark_distance < model.bark_thickness + model.r_s
    rows = np.flatnonzero(layer & (period[model.branch] > 0))
    if len(rows):
        trees = branch_trees(period, fb, face_xy)
        element_face[rows] = query(trees, model.branch[rows], exy[rows], period)
    return face_element, element_face


def _empty(h, pattern, period, n_elements) -> BarkSheet:
    z2, zi = np.zeros((0, 2)), np.zeros(0, dtype=np.int64)
    return BarkSheet(h=h, vertex_branch=zi, phi=np.zeros(0), s=np.zeros(0), perimeter=np.zeros(0),
                     faces=np.zeros((0, 3), dtype=np.int64), face_branch=zi, face_xy=z2, face_area=np.zeros(0),
                     face_element=zi, shrinkage=np.zeros(0), M_0=np.zeros(0), growth=np.zeros(0),
                     edges=np.zeros((0, 2), dtype=np.int64),
                     edge_faces=np.zeros((0, 2), dtype=np.int64), edge_dir=z2, edge_length=np.zeros(0),
                     edge_mid=z2, vertex_edges=np.zeros((0, 1), dtype=np.int64),
                     vertex_nbrs=np.zeros((0, 1), dtype=np.int64),
                     vertex_faces=np.zeros((0, 1), dtype=np.int64), threshold=np.zeros(0), bond=np.zeros(0),
                     width_noise=np.zeros(0), period=period, pattern=PATTERNS[pattern],
                     element_face=np.full(n_elements, -1, dtype=np.int64),
                     face_grid=face_grid(period, zi, z2, GRID_CELLS * h))
