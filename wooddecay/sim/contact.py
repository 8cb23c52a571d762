"""Contact between detached components and against colliders (woodstock §5.4, Eqs. 3-7; SPEC §4).

Capsules. Rod element i is a capsule of radius r_i around the segment from particle
``first_particle[i]`` to ``first_particle[i] + 1``. For elements i, j of different components with
closest points at parameters s on i and t on j, dist(i, j) the distance of those points and n_ij the
unit direction from i to j:

    phi_ij = max((r_i + r_j) - dist(i, j), 0)      (Eq. 3)
    F_i = -k_col phi_ij^2 n_ij,   F_j = -F_i        (Eq. 4)

Elements that share a particle (a strand split between components) are never a pair: their axes
meet at that particle. The closest-point helpers take a points array and row indices (no array
views inside the kernels).

Implicit penalty. At dt = 0.01 s an explicit quadratic penalty is unstable, so Eq. 4 is applied as
an XPBD compliant constraint C = phi with the secant compliance alpha = 1 / (k_col phi). One XPBD
step from lambda = 0 gives

    dlambda = phi / (W + alpha / dt^2) = k_col phi^2 dt^2 / (1 + W k_col phi dt^2),
    W = sum_k w_k g_k^2,   g = (1 - s, s) on the particles of i, (1 - t, t) on those of j,

and moves particle k of i by -w_k g_k dlambda n_ij and particle k of j by +w_k g_k dlambda n_ij. The
constraint force dlambda / dt^2 tends to phi / alpha = k_col phi^2 at rest: the force of Eq. 4
(a particle resting on the ground settles at phi = sqrt(m g / k_col)). Pairs are projected together
(Jacobi): the corrections of each pair are computed independently, then every particle sums its
own in a fixed order and divides by the number of active contacts it takes part in (constraint
averaging). Colliders use the same step per particle along the collider normal, with
phi = particle_radius - sd (sd the signed distance to the solid) and W = w_p, one collider after
the other.

Friction (Eqs. 5-7), on positions. Eq. 7 scales the velocity by 1 - min(1, mu_f |dF| dt /
(m max(|v|, eps))). Multiplied by dt it acts on the displacement of the substep. The substep
(:func:`wooddecay.sim.mechanics.substep`) applies it per particle after all normal steps of a
projection, colliders and pairs (:func:`particle_friction`): a particle that they moved by push
takes back

    d_t <- d_t - min(1, mu_f |push| / max(|d_t|, eps dt)) d_t

of the part d_t of its displacement since the start of the substep normal to push. |push| stands
for |dF| dt^2 / m, the normal force of the particle's contacts rather than the particle-capsule
force of Eqs. 5-6: once Eq. 3 is resolved a particle of i lies at r_i + r_j from the axis of j,
so phi_ikj = max(r_j - dist(p_ik, j), 0) of Eq. 5 vanishes and resting contacts would slide
freely. Friction is static below the cone (a particle on an incline with tan(angle) < mu_f stays,
and so does a capsule lying across two others) and kinetic above it (it slides with
g (sin - mu_f cos)); both are tested. Applied after the normal steps it sees the tangential part
of every push: applied inside each contact's own step (until the seventh debris session), it
acted before the other contacts' pushes of the same Jacobi projection, and a capsule across two
others on a 20 degree slope crept at 0.1 mm/s (docs/decisions.md).

Depenetration and restitution. A particle's collider correction may remove all the penetration
made in this substep and at most ``max_push`` (v_depenetration dt) of the penetration it started
the substep with (:func:`_allowed`). A pair's correction is bounded only within its protected
overlap (``protect`` of :func:`project_contacts`): the overlap beyond phi_rest it had when its
elements fell into different components (shrinkage or a deformation had brought them closer than
at rest), which shrinks by max_push per projection whatever loads the pair, so capsules that
overlap when their connection breaks part gently, while a new or loaded penetration is resolved at
once (a cap on every pair's correction also bounded the force a resting pair carries, to
v_depenetration / (W dt), about 1 N: heavy pieces sank into each other). After the velocity
update, every contact touched in the substep loses its separating normal velocity
(:func:`contact_velocities`, :func:`collider_velocities`; restitution 0): the position step that
resolves a penetration would otherwise turn it into an outward velocity (a bounce that grows
with k_col).

Rest overlap. Capsules of neighbouring strands overlap in the intact wood (strands converge
between profiles: up to 1.5 r_s at rest spacing). That overlap is the wood's own volume, not an
interpenetration: when a crack separates the two elements, pushing it out would drive the pieces
apart against friction for ever (the capped push moves a piece by its contact particle's share of
its mass per substep, less than ground friction takes back), feeding a jitter that never
settles. So a pair's phi counts only beyond ``phi_rest``, its overlap at the rest positions
(:func:`pair_overlaps`, zero for elements that were apart): broken pieces fit back together as
they were, and every other contact is the plain Eq. 3.

Broad phase. :func:`candidate_pairs` bins element centres in a uniform hash grid (Teschner et al.
2003) of cell h = max(length + 2 r) + margin, so the partners of an element lie in the 27 cells
around its own. A counting sort orders the elements by bucket, each bucket by the lower bound of
the element boxes (segment bounds grown by r + margin / 2) along the axis where boxes are thinnest.
Each element visits its own cell and the 13 cells after it (every pair once), skips buckets whose
bounding box misses its box and, in a bucket, the entries outside the sweep window on that axis.
Two passes run in parallel over elements (count, then fill), each writing only its own rows; the
count pass keeps up to KEPT partners per element, so the fill pass mostly copies.

Determinism. Every parallel loop writes only its own element, pair or particle; sums over a
particle's contacts run in a fixed order (CSR of particle -> pair incidences by pair index). Results
are bit-identical for any thread count. The ``*_reference`` functions are the plain numpy/scipy
versions the tests compare against.

Colliders: a float64 table (k, COLLIDER_COLUMNS), one solid obstacle per row, unused columns 0;
particles are kept outside each at a clearance of their radius:

    PLANE     [0, px, py, pz, nx, ny, nz, 0, 0, 0]   a point, the unit normal (solid opposite n)
    BOX       [1, x0, y0, z0, x1, y1, z1, 0, 0, 0]   axis-aligned, min and max corners
    SPHERE    [2, cx, cy, cz, R,  0,  0,  0, 0, 0]   centre, radius
    CYLINDER  [3, ax, ay, az, bx, by, bz, R, 0, 0]   axis end points, radius; flat end caps
"""
from __future__ import annotations

import numba as nb
import numpy as np
from scipy.spatial import cKDTree

PLANE, BOX, SPHERE, CYLINDER = 0, 1, 2, 3
#: columns of a collider row: the kind, then up to 8 parameters (module docstring)
COLLIDER_COLUMNS = 10
#: parameters used by each kind
COLLIDER_PARAMS = {PLANE: 6, BOX: 6, SPHERE: 4, CYLINDER: 7}

#: squared lengths (m^2) at or below this are degenerate (a point)
TINY = 1e-30
#: segments with sin^2(angle) at or below this are parallel
PARALLEL = 1e-12
#: partners per element the broad phase's count pass keeps for its fill pass
KEPT = 8
#: own cell first, then the 13 neighbour cells lexicographically after it
_OFFSETS = np.array([(0, 0, 0)] + [(a, b, c) for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)
                                   if (a, b, c) > (0, 0, 0)], dtype=np.int64)


def collider_row(kind: int, *params: float) -> np.ndarray:
    """One collider row (module docstring); a plane's normal is normalised."""
    if kind not in COLLIDER_PARAMS or len(params) != COLLIDER_PARAMS[kind]:
        raise ValueError(f"collider kind {kind} takes {COLLIDER_PARAMS.get(kind)} parameters, got {len(params)}")
    row = np.zeros(COLLIDER_COLUMNS)
    row[0] = kind
    row[1:1 + len(params)] = params
    if kind == PLANE:
        row[4:7] /= np.linalg.norm(row[4:7])
    return row


# ----------------------------------------------------------------------------- closest points


@nb.njit(cache=True, inline="always")
def _clamp01(v):
    return min(max(v, 0.0), 1.0)


@nb.njit(cache=True, inline="always")
def _sub(X, i, j):
    """X[i] - X[j] as scalars (rows of a (m, 3) array: no views, no allocation)."""
    return X[i, 0] - X[j, 0], X[i, 1] - X[j, 1], X[i, 2] - X[j, 2]


@nb.njit(cache=True, inline="always")
def closest_point_segment(X, p, a, b):
    """Parameter t in [0, 1] of the point of segment X[a] X[b] closest to X[p] (rows of X; 0 for
    a degenerate segment)."""
    dx, dy, dz = _sub(X, b, a)
    dd = dx * dx + dy * dy + dz * dz
    if dd <= TINY:
        return 0.0
    vx, vy, vz = _sub(X, p, a)
    return _clamp01((vx * dx + vy * dy + vz * dz) / dd)


@nb.njit(cache=True, inline="always")
def closest_segment_segment(X, p1, q1, p2, q2):
    """Parameters (s, t) of the closest points X[p1] + s (X[q1] - X[p1]) and X[p2] + t (X[q2] - X[p2])
    (rows of X; Ericson, Real-Time Collision Detection §5.1.9). Degenerate segments reduce to
    point-segment; parallel ones (sin^2 of the angle <= PARALLEL) take s at the middle of the
    overlap of segment 2 projected on segment 1, so a contact along parallel capsules acts at its
    centre."""
    d1x, d1y, d1z = _sub(X, q1, p1)
    d2x, d2y, d2z = _sub(X, q2, p2)
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    if a <= TINY:
        return 0.0, closest_point_segment(X, p1, p2, q2)
    if e <= TINY:
        return closest_point_segment(X, p2, p1, q1), 0.0
    rx, ry, rz = _sub(X, p1, p2)
    b = d1x * d2x + d1y * d2y + d1z * d2z
    c = d1x * rx + d1y * ry + d1z * rz
    f = d2x * rx + d2y * ry + d2z * rz
    den = a * e - b * b
    if den <= PARALLEL * a * e:
        s0 = -c / a
        s1 = (b - c) / a
        s = _clamp01(0.5 * (max(min(s0, s1), 0.0) + min(max(s0, s1), 1.0)))
    else:
        s = _clamp01((b * f - c * e) / den)
    t = (b * s + f) / e
    if t < 0.0:
        return closest_point_segment(X, p2, p1, q1), 0.0
    if t > 1.0:
        return closest_point_segment(X, q2, p1, q1), 1.0
    return s, t


@nb.njit(cache=True, inline="always")
def _gap(X, p1, q1, p2, q2, s, t):
    """(X[p2] + t d2) - (X[p1] + s d1): from the point at s on segment 1 to the point at t on 2."""
    d1x, d1y, d1z = _sub(X, q1, p1)
    d2x, d2y, d2z = _sub(X, q2, p2)
    return (X[p2, 0] + t * d2x - (X[p1, 0] + s * d1x), X[p2, 1] + t * d2y - (X[p1, 1] + s * d1y),
            X[p2, 2] + t * d2z - (X[p1, 2] + s * d1z))


@nb.njit(cache=True, inline="always")
def _perp(ux, uy, uz):
    """A unit vector perpendicular to the non-zero u: u x e_k, e_k its least aligned axis."""
    ax, ay, az = abs(ux), abs(uy), abs(uz)
    if ax <= ay and ax <= az:
        vx, vy, vz = 0.0, uz, -uy
    elif ay <= az:
        vx, vy, vz = -uz, 0.0, ux
    else:
        vx, vy, vz = uy, -ux, 0.0
    m = np.sqrt(vx * vx + vy * vy + vz * vz)
    return vx / m, vy / m, vz / m


@nb.njit(cache=True, inline="always")
def capsule_contact(X, p1, q1, r1, p2, q2, r2):
    """(s, t, nx, ny, nz, phi) of the capsules of radii r1, r2 around segments X[p1] X[q1] and
    X[p2] X[q2]: closest parameters, unit normal from 1 to 2 and penetration phi (Eq. 3). When the
    axes touch (distance <= 1e-12 (r1 + r2)) the normal is d1 x d2, or perpendicular to the axes
    when they are parallel, turned towards centre 2."""
    s, t = closest_segment_segment(X, p1, q1, p2, q2)
    nx, ny, nz = _gap(X, p1, q1, p2, q2, s, t)
    dist = np.sqrt(nx * nx + ny * ny + nz * nz)
    if dist > 1e-12 * (r1 + r2):
        return s, t, nx / dist, ny / dist, nz / dist, max(r1 + r2 - dist, 0.0)
    d1x, d1y, d1z = _sub(X, q1, p1)
    d2x, d2y, d2z = _sub(X, q2, p2)
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    cx, cy, cz = d1y * d2z - d1z * d2y, d1z * d2x - d1x * d2z, d1x * d2y - d1y * d2x
    cc = cx * cx + cy * cy + cz * cz
    if cc > PARALLEL * a * e and a > TINY and e > TINY:
        m = np.sqrt(cc)
        nx, ny, nz = cx / m, cy / m, cz / m
    elif a > TINY:
        nx, ny, nz = _perp(d1x, d1y, d1z)
    elif e > TINY:
        nx, ny, nz = _perp(d2x, d2y, d2z)
    else:
        nx, ny, nz = 0.0, 0.0, 1.0
    ox, oy, oz = _sub(X, p2, p1)
    qx, qy, qz = _sub(X, q2, q1)
    if nx * (ox + qx) + ny * (oy + qy) + nz * (oz + qz) < 0.0:
        nx, ny, nz = -nx, -ny, -nz
    return s, t, nx, ny, nz, max(r1 + r2 - dist, 0.0)


def _clamp01_ref(v):
    return np.clip(v, 0.0, 1.0)


def _dot(u, v):
    return u[:, 0] * v[:, 0] + u[:, 1] * v[:, 1] + u[:, 2] * v[:, 2]


def closest_point_segment_reference(p, a, b):
    """Vectorised :func:`closest_point_segment` (rows are points and segments)."""
    d = b - a
    dd = _dot(d, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(dd <= TINY, 0.0, _clamp01_ref(_dot(p - a, d) / dd))


def closest_segment_segment_reference(p1, q1, p2, q2):
    """Vectorised :func:`closest_segment_segment` (rows are segment pairs)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, b, c, f = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2), _dot(d1, r), _dot(d2, r)
    den = a * e - b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        s0, s1 = -c / a, (b - c) / a
        s_par = _clamp01_ref(0.5 * (np.maximum(np.minimum(s0, s1), 0.0) + np.minimum(np.maximum(s0, s1), 1.0)))
        s = np.where(den <= PARALLEL * a * e, s_par, _clamp01_ref((b * f - c * e) / den))
        t = (b * s + f) / e
    s = np.where(t < 0.0, closest_point_segment_reference(p2, p1, q1),
                 np.where(t > 1.0, closest_point_segment_reference(q2, p1, q1), s))
    t = _clamp01_ref(t)
    s_deg1 = np.where(e <= TINY, closest_point_segment_reference(p2, p1, q1), s)
    t = np.where(e <= TINY, 0.0, t)
    s = np.where(a <= TINY, 0.0, s_deg1)
    t = np.where(a <= TINY, closest_point_segment_reference(p1, p2, q2), t)
    return s, t


def _perp_reference(u):
    k = np.argmin(np.abs(u), axis=1)
    axis = np.eye(3)[k]
    v = np.cross(u, axis)
    return v / np.linalg.norm(v, axis=1)[:, None]


def capsule_contact_reference(p1, q1, r1, p2, q2, r2):
    """Vectorised :func:`capsule_contact`: (s, t, n (m, 3), phi)."""
    s, t = closest_segment_segment_reference(p1, q1, p2, q2)
    d1, d2 = q1 - p1, q2 - p2
    diff = (p2 + t[:, None] * d2) - (p1 + s[:, None] * d1)
    dist = np.sqrt(_dot(diff, diff))
    a, e = _dot(d1, d1), _dot(d2, d2)
    cr = np.cross(d1, d2)
    cc = _dot(cr, cr)
    with np.errstate(divide="ignore", invalid="ignore"):
        fall = np.where((cc > PARALLEL * a * e)[:, None] & (a > TINY)[:, None] & (e > TINY)[:, None],
                        cr / np.sqrt(cc)[:, None],
                        np.where((a > TINY)[:, None], _perp_reference(d1),
                                 np.where((e > TINY)[:, None], _perp_reference(d2), [0.0, 0.0, 1.0])))
        o = (p2 - p1) + (q2 - q1)
        fall = np.where((_dot(fall, o) < 0.0)[:, None], -fall, fall)
        n = np.where((dist > 1e-12 * (r1 + r2))[:, None], diff / dist[:, None], fall)
    return s, t, n, np.maximum(r1 + r2 - dist, 0.0)


# ----------------------------------------------------------------------------- broad phase


@nb.njit(cache=True, inline="always")
def _bucket(cx, cy, cz, mask):
    return ((cx * 73856093) ^ (cy * 19349663) ^ (cz * 83492791)) & mask


@nb.njit(parallel=True, cache=True)
def _element_boxes(x, first_particle, radius, grow, center, box, ext):
    """Per element: segment centre, bounds grown by r + ``grow`` (lo, hi) and length + 2 r."""
    for e in nb.prange(len(first_particle)):
        a = first_particle[e]
        dx, dy, dz = _sub(x, a + 1, a)
        ext[e] = np.sqrt(dx * dx + dy * dy + dz * dz) + 2.0 * radius[e]
        g = radius[e] + grow
        for k in range(3):
            center[e, k] = 0.5 * (x[a, k] + x[a + 1, k])
            box[e, k] = min(x[a, k], x[a + 1, k]) - g
            box[e, 3 + k] = max(x[a, k], x[a + 1, k]) + g


@nb.njit(cache=True)
def _hash_grid(center, box, axis, h, cell, bucket, start, order):
    """Cells of side h, then a counting sort of the elements by the hash bucket of their cell,
    each bucket sorted by box lower bound along ``axis`` (ties: element order). Fills ``cell``,
    ``bucket``, ``start`` (n_buckets + 1, zeros on entry) and ``order``; returns the grid dims."""
    n = len(center)
    mask = len(start) - 2
    lx, ly, lz = center[:, 0].min(), center[:, 1].min(), center[:, 2].min()
    dx = dy = dz = 1
    for e in range(n):
        cx = int(np.floor((center[e, 0] - lx) / h))
        cy = int(np.floor((center[e, 1] - ly) / h))
        cz = int(np.floor((center[e, 2] - lz) / h))
        cell[e, 0], cell[e, 1], cell[e, 2] = cx, cy, cz
        dx, dy, dz = max(dx, cx + 1), max(dy, cy + 1), max(dz, cz + 1)
        bucket[e] = _bucket(cx, cy, cz, mask)
        start[bucket[e]] += 1
    for b in range(mask + 1):
        start[b + 1] += start[b]
    for e in range(n - 1, -1, -1):  # start[b] ends as the first slot of bucket b
        start[bucket[e]] -= 1
        order[start[bucket[e]]] = e
    for b in range(mask + 1):
        lo, hi = start[b], start[b + 1]
        if hi - lo > 32:  # crowded bucket: merge sort (stable)
            members = order[lo:hi].copy()
            order[lo:hi] = members[np.argsort(box[members, axis], kind="mergesort")]
            continue
        for u in range(lo + 1, hi):  # insertion sort (stable)
            e = order[u]
            w = u - 1
            while w >= lo and box[order[w], axis] > box[e, axis]:
                order[w + 1] = order[w]
                w -= 1
            order[w + 1] = e
    return dx, dy, dz


@nb.njit(parallel=True, cache=True)
def _sorted_segments(first_particle, component, order, box, cell, dims, box_s, comp_s, fp_s, key_s):
    """Gather into grid order: boxes, component, first particle and linear cell key."""
    for a in nb.prange(len(order)):
        e = order[a]
        comp_s[a], fp_s[a] = component[e], first_particle[e]
        for k in range(6):
            box_s[a, k] = box[e, k]
        key_s[a] = (cell[e, 0] * dims[1] + cell[e, 1]) * dims[2] + cell[e, 2]


@nb.njit(cache=True, inline="always")
def _apart(box_u, u, box_v, v):
    """Boxes (lo, hi) row u of box_u and row v of box_v do not overlap."""
    return (box_u[u, 0] > box_v[v, 3] or box_u[u, 3] < box_v[v, 0] or box_u[u, 1] > box_v[v, 4]
            or box_u[u, 4] < box_v[v, 1] or box_u[u, 2] > box_v[v, 5] or box_u[u, 5] < box_v[v, 2])


@nb.njit(cache=True, inline="always")
def _overlap(box_u, u, box_v, v):
    """not _apart, without short-circuit branches."""
    return ((box_u[u, 0] <= box_v[v, 3]) & (box_u[u, 3] >= box_v[v, 0]) & (box_u[u, 1] <= box_v[v, 4])
            & (box_u[u, 4] >= box_v[v, 1]) & (box_u[u, 2] <= box_v[v, 5]) & (box_u[u, 5] >= box_v[v, 2]))


@nb.njit(parallel=True, cache=True)
def _bucket_boxes(box, start, out):
    """Bounding box of the element boxes of each bucket (empty: inverted, overlaps nothing)."""
    for b in nb.prange(len(start) - 1):
        for k in range(3):
            out[b, k] = np.inf
            out[b, 3 + k] = -np.inf
        for m in range(start[b], start[b + 1]):
            for k in range(3):
                out[b, k] = min(out[b, k], box[m, k])
                out[b, 3 + k] = max(out[b, 3 + k], box[m, 3 + k])


@nb.njit(cache=True, inline="always")
def _lower_bound(box, axis, lo, hi, value):
    """First m in [lo, hi) with box[m, axis] >= value (the range is sorted on that column)."""
    while lo < hi:
        mid = (lo + hi) // 2
        if box[mid, axis] < value:
            lo = mid + 1
        else:
            hi = mid
    return lo


@nb.njit(parallel=True, cache=True)
def _pairs_pass(x, radius, box, bucket_box, comp, fp, elem, key, start, dims, axis, width, margin,
                counts, kept, base, out, fill):
    """Count (fill=False) or write (fill=True) the pairs owned by each element, in grid order:
    partners after it in its own cell and those of its 13 forward cells. A pair in reach has
    overlapping ``box`` (segment bounds grown by r + margin / 2): a bucket whose ``bucket_box``
    misses the element's box is skipped whole, and in a bucket (sorted by box lower bound along
    ``axis``, no box wider than ``width`` there) only the window of lower bounds in
    [lo - width, hi] is visited. The exact test is the capsule gap. The count pass keeps the first
    KEPT partners of each element in ``kept``; the fill pass copies them and searches again only
    for elements with more."""
    mask = len(start) - 2
    for a in nb.prange(len(box)):
        if fill and counts[a] <= KEPT:
            for k in range(counts[a]):
                out[base[a] + k, 0] = min(elem[a], kept[a, k])
                out[base[a] + k, 1] = max(elem[a], kept[a, k])
            continue
        k = 0
        lo, hi = box[a, axis], box[a, 3 + axis]
        ca, pa = comp[a], fp[a]
        cx, cy, cz = key[a] // (dims[1] * dims[2]), (key[a] // dims[2]) % dims[1], key[a] % dims[2]
        for o in range(len(_OFFSETS)):
            u = cx + _OFFSETS[o, 0]
            v = cy + _OFFSETS[o, 1]
            w = cz + _OFFSETS[o, 2]
            if u < 0 or u >= dims[0] or v < 0 or v >= dims[1] or w < 0 or w >= dims[2]:
                continue
            b = _bucket(u, v, w, mask)
            if o == 0:
                m0 = a + 1
            elif _apart(bucket_box, b, box, a):
                continue
            else:
                m0 = _lower_bound(box, axis, start[b], start[b + 1], lo - width)
            nkey = (u * dims[1] + v) * dims[2] + w
            for m in range(m0, start[b + 1]):
                if box[m, axis] > hi:
                    break
                # one well-predicted branch: & evaluates every test (most entries fail one at random)
                pm = fp[m]
                if not ((comp[m] != ca) & (key[m] == nkey) & (abs(pm - pa) > 1) & _overlap(box, m, box, a)):
                    continue
                s, t = closest_segment_segment(x, pa, pa + 1, pm, pm + 1)
                ex, ey, ez = _gap(x, pa, pa + 1, pm, pm + 1, s, t)
                lim = radius[elem[a]] + radius[elem[m]] + margin
                if ex * ex + ey * ey + ez * ez < lim * lim:
                    if fill:
                        out[base[a] + k, 0] = min(elem[a], elem[m])
                        out[base[a] + k, 1] = max(elem[a], elem[m])
                    elif k < KEPT:
                        kept[a, k] = elem[m]
                    k += 1
        if not fill:
            counts[a] = k


@nb.njit(parallel=True, cache=True)
def _sort_pairs(raw, indptr, out):
    """``raw`` (rows i < j) into ``out`` sorted lexicographically: a counting sort by i (``indptr``
    (n + 1,) zeros on entry), then each row by j."""
    n = len(indptr) - 1
    for q in range(len(raw)):
        indptr[raw[q, 0]] += 1
    for i in range(n):
        indptr[i + 1] += indptr[i]
    for q in range(len(raw) - 1, -1, -1):
        i = raw[q, 0]
        indptr[i] -= 1
        out[indptr[i], 0] = i
        out[indptr[i], 1] = raw[q, 1]
    for i in nb.prange(n):
        lo, hi = indptr[i], indptr[i + 1]
        if hi - lo > 32:  # crowded row
            out[lo:hi, 1].sort()
            continue
        for u in range(lo + 1, hi):  # insertion sort
            v = out[u, 1]
            w = u - 1
            while w >= lo and out[w, 1] > v:
                out[w + 1, 1] = out[w, 1]
                w -= 1
            out[w + 1, 1] = v


def candidate_pairs(x, first_particle, radius, component, margin) -> np.ndarray:
    """(k, 2) int64 element pairs i < j, sorted lexicographically, with component[i] !=
    component[j], no shared particle, and capsule gap dist(i, j) < r_i + r_j + margin (Eq. 3 with a
    margin, so the pairs can be reused over the substeps of a step).

    A pair in reach has centres closer than the cell h (module docstring). Every array is allocated
    here with numpy and filled by the kernels: large allocations inside numba kernels page-faulted
    on every call (several ms at 50k elements)."""
    n = len(first_particle)
    if n < 2 or np.all(component == component[0]):
        return np.zeros((0, 2), dtype=np.int64)
    center, box, ext = np.empty((n, 3)), np.empty((n, 6)), np.empty(n)
    slack = 1e-9 * (float(np.abs(x).max()) + margin)  # the box tests only prune: never below round-off
    _element_boxes(x, first_particle, radius, 0.5 * margin + slack, center, box, ext)
    h = float(ext.max()) + margin
    if h <= 0.0:  # points of radius 0: nothing is closer than 0
        return np.zeros((0, 2), dtype=np.int64)
    widths = box[:, 3:] - box[:, :3]
    axis = int(np.argmin(widths.sum(axis=0)))  # the thinnest boxes: the sweep prunes most
    width = float(widths[:, axis].max()) + slack
    start = np.zeros((1 << max(1, (n // 2).bit_length())) + 1, dtype=np.int64)  # >= n / 2 buckets
    cell, bucket, order = np.empty((n, 3), dtype=np.int64), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64)
    dims = np.array(_hash_grid(center, box, axis, h, cell, bucket, start, order), dtype=np.int64)
    if float(np.prod(dims.astype(np.float64))) >= 2.0**62:
        raise ValueError(f"hash grid of {dims} cells of {h} m: linear cell keys overflow")
    box_s, comp_s, fp_s, key_s = (np.empty((n, 6)), np.empty(n, dtype=np.int64), np.empty(n, dtype=np.int64),
                                  np.empty(n, dtype=np.int64))
    _sorted_segments(first_particle, component, order, box, cell, dims, box_s, comp_s, fp_s, key_s)
    bucket_box = np.empty((len(start) - 1, 6))
    _bucket_boxes(box_s, start, bucket_box)
    args = (x, radius, box_s, bucket_box, comp_s, fp_s, order, key_s, start, dims, axis, width, float(margin))
    counts, kept = np.empty(n, dtype=np.int64), np.empty((n, KEPT), dtype=np.int64)
    _pairs_pass(*args, counts, kept, counts, np.zeros((0, 2), dtype=np.int64), False)
    base = np.concatenate(([0], np.cumsum(counts)))
    raw, out = np.empty((base[-1], 2), dtype=np.int64), np.empty((base[-1], 2), dtype=np.int64)
    _pairs_pass(*args, counts, kept, base, raw, True)
    _sort_pairs(raw, np.zeros(n + 1, dtype=np.int64), out)
    return out


def candidate_pairs_reference(x, first_particle, radius, component, margin) -> np.ndarray:
    """scipy/numpy version of :func:`candidate_pairs`: cKDTree on the centres, vectorised capsule gap."""
    n = len(first_particle)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    pa, pb = x[first_particle], x[first_particle + 1]
    half = 0.5 * np.linalg.norm(pb - pa, axis=1)
    h = (2.0 * half.max() + 2.0 * radius.max() + margin) * (1.0 + 1e-9)
    cand = cKDTree(0.5 * (pa + pb)).query_pairs(h, output_type="ndarray").astype(np.int64)
    i, j = cand[:, 0], cand[:, 1]
    keep = (component[i] != component[j]) & (np.abs(first_particle[i] - first_particle[j]) > 1)
    i, j = i[keep], j[keep]
    s, t = closest_segment_segment_reference(pa[i], pb[i], pa[j], pb[j])
    d = (pa[j] + t[:, None] * (pb[j] - pa[j])) - (pa[i] + s[:, None] * (pb[i] - pa[i]))
    lim = radius[i] + radius[j] + margin
    keep = _dot(d, d) < lim * lim
    out = np.sort(np.stack([i[keep], j[keep]], axis=1), axis=1)
    return out[np.lexsort((out[:, 1], out[:, 0]))]


# ----------------------------------------------------------------------------- capsule contacts


@nb.njit(cache=True, inline="always")
def _dlambda(phi, W, k_col, dt2):
    """XPBD multiplier of C = phi with compliance alpha = 1 / (k_col phi): phi / (W + alpha / dt^2)."""
    return k_col * phi * phi * dt2 / (1.0 + W * k_col * phi * dt2)


@nb.njit(cache=True, inline="always")
def _allowed(ph, ph_prev, max_push):
    """Largest correction of a penetration ph that had been ph_prev at the start of the substep:
    all the penetration made in this substep, and at most max_push of the one it started with."""
    return max(ph - max(ph_prev - max_push, 0.0), 0.0)


@nb.njit(cache=True, inline="always")
def _friction_step(dx, dy, dz, nx, ny, nz, normal, mu, floor):
    """Eq. 7 on a displacement: the tangential part d_t of (dx, dy, dz) (normal n) times
    min(1, mu normal / max(|d_t|, floor)), the part friction takes back."""
    dn = dx * nx + dy * ny + dz * nz
    tx, ty, tz = dx - dn * nx, dy - dn * ny, dz - dn * nz
    mag = np.sqrt(tx * tx + ty * ty + tz * tz)
    if mag <= 0.0:
        return 0.0, 0.0, 0.0
    c = min(1.0, mu * normal / max(mag, floor))
    return c * tx, c * ty, c * tz


@nb.njit(parallel=True, cache=True)
def _pair_multipliers(x, w_p, first_particle, radius, pairs, phi_rest, protect, k_col, dt, max_push, pc, phi):
    """Per pair: penetration phi (Eq. 3) beyond the pair's rest overlap ``phi_rest`` and ``pc`` =
    (e, dlambda, s, t), e the correction per unit w_k g_k of j's particles (i's: -e): dlambda n_ij
    (dlambda 0, e 0 if inactive). The relative correction W dlambda is capped at max_push, or
    with ``protect`` (k,) (not (0,)) at phi - protect after lowering the pair's protected overlap
    to max(min(protect, phi) - max_push, 0) (written back)."""
    dt2 = dt * dt
    for q in nb.prange(len(pairs)):
        i, j = pairs[q, 0], pairs[q, 1]
        a, b = first_particle[i], first_particle[j]
        s, t, nx, ny, nz, ph = capsule_contact(x, a, a + 1, radius[i], b, b + 1, radius[j])
        ph -= phi_rest[q]
        W = (w_p[a] * (1.0 - s) * (1.0 - s) + w_p[a + 1] * s * s + w_p[b] * (1.0 - t) * (1.0 - t)
             + w_p[b + 1] * t * t)
        phi[q] = ph
        dl = _dlambda(ph, W, k_col, dt2) if ph > 0.0 and W > 0.0 else 0.0  # W = 0: both pinned
        cap = max_push
        if len(protect) > 0:
            protect[q] = max(min(protect[q], ph) - max_push, 0.0)
            cap = max(ph - protect[q], 0.0)
        if W * dl > cap:  # depenetration cap
            dl = cap / W
        pc[q, 0], pc[q, 1], pc[q, 2] = dl * nx, dl * ny, dl * nz
        pc[q, 3], pc[q, 4], pc[q, 5] = dl, s, t


@nb.njit(cache=True)
def _incidences(pairs, first_particle, active, indptr, inc):
    """CSR particle -> incidences q * 4 + slot of the ``active`` pairs, increasing q in each row
    (a counting sort; ``indptr`` (P + 1,) zeros on entry, ``inc`` (4 len(active),))."""
    for q in active:
        a, b = first_particle[pairs[q, 0]], first_particle[pairs[q, 1]]
        for p in (a, a + 1, b, b + 1):
            indptr[p] += 1
    for p in range(len(indptr) - 1):
        indptr[p + 1] += indptr[p]
    for u in range(len(active) - 1, -1, -1):  # indptr[p] ends as the first slot of row p
        q = active[u]
        a, b = first_particle[pairs[q, 0]], first_particle[pairs[q, 1]]
        parts = (a, a + 1, b, b + 1)
        for k in range(3, -1, -1):
            indptr[parts[k]] -= 1
            inc[indptr[parts[k]]] = q * 4 + k


@nb.njit(parallel=True, cache=True)
def _gather(x, w_p, force, indptr, inc, pc, dt):
    """Per particle, over its incidences (pair q, slot k) in CSR order: x += mean of the
    corrections -+ w g_k e_q (- on i's particles, slots 0-1; e_q = pc[q, :3]), force += sum of
    g_k dlambda_q / dt^2 (dlambda_q = pc[q, 3])."""
    dt2 = dt * dt
    for p in nb.prange(len(x)):
        lo, hi = indptr[p], indptr[p + 1]
        if hi == lo:
            continue
        ax = ay = az = f = 0.0
        for e in range(lo, hi):
            q, k = inc[e] // 4, inc[e] % 4
            u = pc[q, 4] if k < 2 else pc[q, 5]
            g = u if k % 2 else 1.0 - u
            c = (-1.0 if k < 2 else 1.0) * w_p[p] * g
            ax += c * pc[q, 0]
            ay += c * pc[q, 1]
            az += c * pc[q, 2]
            f += g * pc[q, 3] / dt2
        cnt = hi - lo
        x[p, 0] += ax / cnt
        x[p, 1] += ay / cnt
        x[p, 2] += az / cnt
        force[p] += f


def _rows(x_prev) -> np.ndarray:
    return np.zeros((0, 3)) if x_prev is None else x_prev


def _rest(phi_rest, k: int) -> np.ndarray:
    return np.zeros(k) if phi_rest is None else np.ascontiguousarray(phi_rest, dtype=np.float64)


@nb.njit(parallel=True, cache=True)
def _overlaps(x, first_particle, radius, pairs, out):
    for q in nb.prange(len(pairs)):
        i, j = pairs[q, 0], pairs[q, 1]
        a, b = first_particle[i], first_particle[j]
        out[q] = capsule_contact(x, a, a + 1, radius[i], b, b + 1, radius[j])[5]


def pair_overlaps(x, first_particle, radius, pairs) -> np.ndarray:
    """(k,) overlap phi (Eq. 3) of each capsule pair of ``pairs`` at the positions ``x``."""
    out = np.empty(len(pairs))
    _overlaps(x, first_particle, radius, pairs, out)
    return out


def project_contacts(x, w_p, first_particle, radius, pairs, k_col, dt, force,
                     max_push: float = np.inf, touched=None, phi_rest=None, protect=None) -> tuple[int, float]:
    """One Jacobi XPBD projection of the capsule contacts of ``pairs`` (k, 2) (element pairs i, j
    as from :func:`candidate_pairs`; Eqs. 3-4, module docstring).

    Moves ``x`` (P, 3) in place (particles with w_p = 0 never move) and adds to ``force`` (P,) the
    normal force magnitude g_k dlambda / dt^2 each particle receives. ``max_push`` caps a pair's
    relative correction per projection (a depenetration speed times dt: capsules that overlap when
    their connection breaks, up to 1.5 r_s at rest spacing, part gently instead of exploding).
    Friction is not part of it (:func:`particle_friction`, after all normal steps). ``touched`` (k,)
    bool, if given, is or-ed with the pairs that had phi > 0 (for :func:`contact_velocities`).
    ``phi_rest`` (k,), if given, is each pair's overlap in the rest state (:func:`pair_overlaps`
    of the rest positions, module docstring "Rest overlap"); phi counts only beyond it.
    ``protect`` (k,), if given, replaces that cap: each pair's protected overlap beyond
    phi_rest (the overlap it had when its elements separated, module docstring "Depenetration"),
    first lowered in place to max(min(protect, phi) - max_push, 0), so that it shrinks by
    ``max_push`` per projection whatever loads the pair; the correction may remove all the
    penetration beyond it. Returns (number of pairs with phi > 0, largest phi), measured on the positions before the
    projection; k_col <= 0 means no contact: nothing changes and (0, 0.0) is returned."""
    if k_col <= 0.0 or len(pairs) == 0:
        return 0, 0.0
    pc, phi = np.empty((len(pairs), 6)), np.empty(len(pairs))
    prot = np.zeros(0) if protect is None else protect
    _pair_multipliers(x, w_p, first_particle, radius, pairs, _rest(phi_rest, len(pairs)), prot, float(k_col),
                      float(dt), float(max_push), pc, phi)
    if touched is not None:
        touched |= phi > 0.0
    active = np.flatnonzero(phi > 0.0)
    indptr, inc = np.zeros(len(x) + 1, dtype=np.int64), np.empty(4 * len(active), dtype=np.int64)
    _incidences(pairs, first_particle, active, indptr, inc)
    _gather(x, w_p, force, indptr, inc, pc, float(dt))
    return len(active), float(phi.max())


def _pair_geometry_reference(x, w_p, first_particle, radius, pairs):
    """Per pair: particles (k, 4), weights g (k, 4), inverse masses (k, 4), W, n, phi."""
    a, b = first_particle[pairs[:, 0]], first_particle[pairs[:, 1]]
    s, t, n, phi = capsule_contact_reference(x[a], x[a + 1], radius[pairs[:, 0]], x[b], x[b + 1], radius[pairs[:, 1]])
    parts = np.stack([a, a + 1, b, b + 1], axis=1)
    g = np.stack([1.0 - s, s, 1.0 - t, t], axis=1)
    w = w_p[parts]
    return parts, g, w, np.sum(w * g * g, axis=1), n, phi


def _friction_reference(d, n, normal, mu, floor):
    """Vectorised :func:`_friction_step` (rows)."""
    tang = d - _dot(d, n)[:, None] * n
    mag = np.sqrt(_dot(tang, tang))
    with np.errstate(divide="ignore", invalid="ignore"):
        c = np.where(mag > 0.0, np.minimum(1.0, mu * normal / np.maximum(mag, floor)), 0.0)
    return c[:, None] * tang


def _jacobi_reference(y, parts, g, w, e, dl=None, force=None, dt=1.0):
    """Add to the rows of ``y`` the mean over each particle's pairs of -+ w g e (module
    docstring); ``force`` += sum of g dl / dt^2."""
    c = np.array([-1.0, -1.0, 1.0, 1.0]) * w * g
    acc = np.zeros_like(y)
    np.add.at(acc, parts.ravel(), (c[:, :, None] * e[:, None, :]).reshape(-1, 3))
    cnt = np.bincount(parts.ravel(), minlength=len(y))
    hit = cnt > 0
    y[hit] += acc[hit] / cnt[hit, None]
    if force is not None:
        fsum = np.zeros(len(y))
        np.add.at(fsum, parts.ravel(), (g * dl[:, None] / (dt * dt)).ravel())
        force[hit] += fsum[hit]


def _points_reference(y, parts, g):
    """Contact points' relative (j minus i) value of the rows of ``y``."""
    return np.einsum("kj,kjc->kc", g * [-1.0, -1.0, 1.0, 1.0], y[parts])


def project_contacts_reference(x, w_p, first_particle, radius, pairs, k_col, dt, force,
                               max_push: float = np.inf, touched=None, phi_rest=None,
                               protect=None) -> tuple[int, float]:
    """numpy version of :func:`project_contacts`."""
    if k_col <= 0.0 or len(pairs) == 0:
        return 0, 0.0
    parts, g, w, W, n, phi = _pair_geometry_reference(x, w_p, first_particle, radius, pairs)
    rest = _rest(phi_rest, len(pairs))
    phi = phi - rest
    if touched is not None:
        touched |= phi > 0.0
    act = phi > 0.0
    if protect is not None:
        protect[:] = np.maximum(np.minimum(protect, phi) - max_push, 0.0)
    parts, g, w, W, n, ph = parts[act], g[act], w[act], W[act], n[act], phi[act]
    dt2 = dt * dt
    dl = np.where(W > 0.0, k_col * ph * ph * dt2 / (1.0 + W * k_col * ph * dt2), 0.0)  # W = 0: both pinned
    cap = np.full(len(dl), float(max_push))
    if protect is not None:
        cap = np.maximum(ph - protect[act], 0.0)
    over = W * dl > cap
    dl[over] = cap[over] / W[over]
    _jacobi_reference(x, parts, g, w, dl[:, None] * n, dl, force, dt)
    return int(act.sum()), float(phi.max())


@nb.njit(parallel=True, cache=True)
def _pair_separation(x, v, w_p, first_particle, radius, pairs, touched, pc, sep):
    """Per touched pair, at the positions ``x``: ``pc`` = (n_ij, -v_n / W, s, t) and sep = True
    where the pair separates at v_n = n_ij . (v_j(t) - v_i(s)) > 0."""
    for q in nb.prange(len(pairs)):
        sep[q] = False
        if not touched[q]:
            continue
        i, j = pairs[q, 0], pairs[q, 1]
        a, b = first_particle[i], first_particle[j]
        s, t, nx, ny, nz, _ = capsule_contact(x, a, a + 1, radius[i], b, b + 1, radius[j])
        W = (w_p[a] * (1.0 - s) * (1.0 - s) + w_p[a + 1] * s * s + w_p[b] * (1.0 - t) * (1.0 - t)
             + w_p[b + 1] * t * t)
        vn = 0.0
        for k, c in ((0, nx), (1, ny), (2, nz)):
            vn += c * ((1.0 - t) * v[b, k] + t * v[b + 1, k] - (1.0 - s) * v[a, k] - s * v[a + 1, k])
        if vn > 0.0 and W > 0.0:
            sep[q] = True
            pc[q, 0], pc[q, 1], pc[q, 2] = -vn / W * nx, -vn / W * ny, -vn / W * nz
            pc[q, 3], pc[q, 4], pc[q, 5] = 0.0, s, t


def contact_velocities(v, x, w_p, first_particle, radius, pairs, touched) -> int:
    """Inelastic capsule contacts (restitution 0, module docstring "Depenetration"): for every
    pair with ``touched`` (k,) set (phi > 0 in a projection of this substep), the separating
    relative normal velocity v_n = n_ij . (v_j(t) - v_i(s)) > 0 at the end positions ``x`` is
    removed by the velocity step -+ w_k g_k (v_n / W) n_ij, Jacobi-averaged per particle like the
    position step. Changes ``v`` (P, 3) in place; returns the number of pairs changed."""
    if len(pairs) == 0 or not touched.any():
        return 0
    pc, sep = np.empty((len(pairs), 6)), np.empty(len(pairs), dtype=np.bool_)
    _pair_separation(x, v, w_p, first_particle, radius, pairs, touched, pc, sep)
    active = np.flatnonzero(sep)
    indptr, inc = np.zeros(len(x) + 1, dtype=np.int64), np.empty(4 * len(active), dtype=np.int64)
    _incidences(pairs, first_particle, active, indptr, inc)
    _gather(v, w_p, np.zeros(len(x)), indptr, inc, pc, 1.0)
    return len(active)


def contact_velocities_reference(v, x, w_p, first_particle, radius, pairs, touched) -> int:
    """numpy version of :func:`contact_velocities`."""
    if len(pairs) == 0 or not touched.any():
        return 0
    parts, g, w, W, n, _ = _pair_geometry_reference(x, w_p, first_particle, radius, pairs)
    vn = _dot(_points_reference(v, parts, g), n)
    sep = touched & (vn > 0.0) & (W > 0.0)
    _jacobi_reference(v, parts[sep], g[sep], w[sep], (-vn[sep] / W[sep])[:, None] * n[sep])
    return int(sep.sum())


# ----------------------------------------------------------------------------- friction after the normal steps


@nb.njit(parallel=True, cache=True)
def _particle_friction(x, x_start, x_prev, mu, floor):
    for p in nb.prange(len(x)):
        px, py, pz = x[p, 0] - x_start[p, 0], x[p, 1] - x_start[p, 1], x[p, 2] - x_start[p, 2]
        push = np.sqrt(px * px + py * py + pz * pz)
        if push <= 0.0:
            continue
        fx, fy, fz = _friction_step(x[p, 0] - x_prev[p, 0], x[p, 1] - x_prev[p, 1], x[p, 2] - x_prev[p, 2],
                                    px / push, py / push, pz / push, push, mu, floor)
        x[p, 0] -= fx
        x[p, 1] -= fy
        x[p, 2] -= fz


def particle_friction(x, x_start, x_prev, mu: float, floor: float) -> None:
    """Friction of Eq. 7 on positions, after all normal contact steps of a projection (module
    docstring "Friction"): every particle that the normal steps moved, by push = x - ``x_start``
    (colliders and capsule pairs together), takes back min(1, mu |push| / max(|d_t|, ``floor``))
    of the part d_t of its displacement since ``x_prev`` (the start of the substep) normal to
    push. Changes ``x`` (P, 3) in place; per particle, so race-free and deterministic."""
    if mu > 0.0 and len(x):
        _particle_friction(x, x_start, x_prev, float(mu), float(floor))


def particle_friction_reference(x, x_start, x_prev, mu: float, floor: float) -> None:
    """numpy version of :func:`particle_friction`."""
    if not (mu > 0.0 and len(x)):
        return
    push = x - x_start
    mag = np.sqrt(_dot(push, push))
    on = mag > 0.0
    n = push[on] / mag[on, None]
    x[on] -= _friction_reference(x[on] - x_prev[on], n, mag[on], mu, floor)


# ----------------------------------------------------------------------------- colliders


@nb.njit(cache=True)
def collider_distance(colliders, c, px, py, pz):
    """(sd, nx, ny, nz): signed distance of point p to the solid of collider row c (negative
    inside) and the unit outward normal of the closest surface point. Inside a box the nearest
    face wins (ties: x before y before z, min side first)."""
    kind = int(colliders[c, 0])
    ax, ay, az = colliders[c, 1], colliders[c, 2], colliders[c, 3]  # point, min corner, centre, end
    bx, by, bz = colliders[c, 4], colliders[c, 5], colliders[c, 6]  # normal, max corner, end
    if kind == PLANE:
        return (px - ax) * bx + (py - ay) * by + (pz - az) * bz, bx, by, bz
    if kind == BOX:
        dx, dy, dz = px - min(max(px, ax), bx), py - min(max(py, ay), by), pz - min(max(pz, az), bz)
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d > 0.0:
            return d, dx / d, dy / d, dz / d
        depth = (px - ax, bx - px, py - ay, by - py, pz - az, bz - pz)
        f = 0
        for k in range(1, 6):
            if depth[k] < depth[f]:
                f = k
        sgn = 1.0 if f % 2 else -1.0
        return -depth[f], sgn * (f // 2 == 0), sgn * (f // 2 == 1), sgn * (f // 2 == 2)
    if kind == SPHERE:
        dx, dy, dz = px - ax, py - ay, pz - az
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        if d > 0.0:
            return d - bx, dx / d, dy / d, dz / d
        return -bx, 0.0, 0.0, 1.0
    # CYLINDER from a to b: axial coordinate t along u, radial distance rho
    ux, uy, uz = bx - ax, by - ay, bz - az
    h = np.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / h, uy / h, uz / h
    vx, vy, vz = px - ax, py - ay, pz - az
    t = vx * ux + vy * uy + vz * uz
    rx, ry, rz = vx - t * ux, vy - t * uy, vz - t * uz
    rho = np.sqrt(rx * rx + ry * ry + rz * rz)
    if rho > 0.0:
        ex, ey, ez = rx / rho, ry / rho, rz / rho
    else:
        ex, ey, ez = _perp(ux, uy, uz)
    dr = rho - colliders[c, 7]
    if t < 0.5 * h:
        dz, cx, cy, cz = -t, -ux, -uy, -uz
    else:
        dz, cx, cy, cz = t - h, ux, uy, uz
    if dr > 0.0 or dz > 0.0:
        a, b = max(dr, 0.0), max(dz, 0.0)
        d = np.sqrt(a * a + b * b)
        return d, (a * ex + b * cx) / d, (a * ey + b * cy) / d, (a * ez + b * cz) / d
    if dr > dz:
        return dr, ex, ey, ez
    return dz, cx, cy, cz


@nb.njit(parallel=True, cache=True)
def _colliders_kernel(x, x_prev, w_p, particle_radius, colliders, k_col, dt, max_push, force, n_active, pen,
                      touched):
    """Per particle, collider after collider: the XPBD step of phi = particle_radius - sd, its
    correction capped at max_push, or at :func:`_allowed` with the start-of-substep positions
    ``x_prev`` ((0, 3): none); ``touched`` (P, k) (or (0, k)) set where phi > 0."""
    dt2 = dt * dt
    for p in nb.prange(len(x)):
        na = 0
        mp = 0.0
        for c in range(len(colliders)):
            sd, nx, ny, nz = collider_distance(colliders, c, x[p, 0], x[p, 1], x[p, 2])
            ph = particle_radius[p] - sd
            if ph <= 0.0:
                continue
            na += 1
            mp = max(mp, ph)
            if len(touched) > 0:
                touched[p, c] = True
            dl = _dlambda(ph, w_p[p], k_col, dt2)
            cap = max_push
            if len(x_prev) > 0:
                sd0 = collider_distance(colliders, c, x_prev[p, 0], x_prev[p, 1], x_prev[p, 2])[0]
                cap = _allowed(ph, particle_radius[p] - sd0, max_push)
            if w_p[p] * dl > cap:
                dl = cap / w_p[p]
            x[p, 0] += w_p[p] * dl * nx
            x[p, 1] += w_p[p] * dl * ny
            x[p, 2] += w_p[p] * dl * nz
            force[p] += dl / dt2
        n_active[p] = na
        pen[p] = mp


@nb.njit(parallel=True, cache=True)
def _collider_separation(x, v, w_p, colliders, touched, changed):
    """Per particle and touched collider: remove the outward normal velocity at the end position."""
    for p in nb.prange(len(x)):
        changed[p] = False
        if w_p[p] == 0.0:
            continue
        for c in range(len(colliders)):
            if not touched[p, c]:
                continue
            _, nx, ny, nz = collider_distance(colliders, c, x[p, 0], x[p, 1], x[p, 2])
            vn = v[p, 0] * nx + v[p, 1] * ny + v[p, 2] * nz
            if vn > 0.0:
                v[p, 0] -= vn * nx
                v[p, 1] -= vn * ny
                v[p, 2] -= vn * nz
                changed[p] = True


def _check_colliders(colliders):
    """Shape, kinds, unit plane normals and cylinders of positive length."""
    if colliders.ndim != 2 or colliders.shape[1] != COLLIDER_COLUMNS:
        raise ValueError(f"colliders must be (k, {COLLIDER_COLUMNS}), got {colliders.shape}")
    kind = colliders[:, 0]
    if not np.isin(kind, list(COLLIDER_PARAMS)).all():
        raise ValueError(f"collider kinds must be in {sorted(COLLIDER_PARAMS)}")
    if not np.allclose(np.linalg.norm(colliders[kind == PLANE, 4:7], axis=1), 1.0, atol=1e-9):
        raise ValueError("plane normals must be unit vectors")
    cyl = colliders[kind == CYLINDER]
    if not (np.linalg.norm(cyl[:, 4:7] - cyl[:, 1:4], axis=1) > 0.0).all():
        raise ValueError("cylinder end points must differ")


def project_colliders(x, w_p, particle_radius, colliders, k_col, dt, force, max_push: float = np.inf,
                      x_prev=None, touched=None) -> tuple[int, float]:
    """Keep each particle outside every collider at clearance ``particle_radius`` (P,): per
    particle, one collider after the other, phi = particle_radius - sd and the secant-compliance
    XPBD step along the collider normal with W = w_p (module docstring). Moves ``x`` in place,
    adds the normal force dlambda / dt^2 to ``force``. ``max_push`` caps each correction; with the
    start-of-substep positions ``x_prev`` (P, 3) it caps only the removal of the penetration the
    particle had there; friction follows all normal steps
    (:func:`particle_friction`). ``touched`` (P, k) bool, if given, is set where phi > 0 (for
    :func:`collider_velocities`). Returns (number of particle-collider contacts with phi > 0,
    largest phi); k_col <= 0 or no colliders: nothing, (0, 0.0)."""
    if k_col <= 0.0 or len(colliders) == 0 or len(x) == 0:
        return 0, 0.0
    _check_colliders(colliders)
    n_active, pen = np.empty(len(x), dtype=np.int64), np.empty(len(x))
    hit = np.zeros((0, len(colliders)), dtype=np.bool_) if touched is None else touched
    _colliders_kernel(x, _rows(x_prev), w_p, particle_radius, colliders, float(k_col), float(dt), float(max_push),
                      force, n_active, pen, hit)
    return int(n_active.sum()), float(pen.max())


def collider_velocities(v, x, w_p, colliders, touched) -> int:
    """Inelastic collider contacts (restitution 0): every free particle removes the outward
    normal velocity max(v . n, 0) n of each collider it ``touched`` (P, k) in this substep, the
    normal taken at its end position ``x``, collider after collider. Changes ``v`` in place;
    returns the number of particles changed."""
    if len(colliders) == 0 or len(x) == 0 or not touched.any():
        return 0
    changed = np.empty(len(x), dtype=np.bool_)
    _collider_separation(x, v, w_p, colliders, touched, changed)
    return int(changed.sum())


def collider_velocities_reference(v, x, w_p, colliders, touched) -> int:
    """numpy version of :func:`collider_velocities`."""
    if len(colliders) == 0 or len(x) == 0 or not touched.any():
        return 0
    changed = np.zeros(len(x), dtype=bool)
    for c, row in enumerate(colliders):
        _, n = collider_distance_reference(row, x)
        vn = _dot(v, n)
        sel = touched[:, c] & (w_p > 0.0) & (vn > 0.0)
        v[sel] -= vn[sel, None] * n[sel]
        changed |= sel
    return int(changed.sum())


def collider_distance_reference(row, p):
    """Vectorised :func:`collider_distance`: (sd (m,), n (m, 3))."""
    kind = int(row[0])
    if kind == PLANE:
        n = np.broadcast_to(row[4:7], p.shape)
        return _dot(p - row[1:4], n), n
    if kind == BOX:
        d = p - np.clip(p, row[1:4], row[4:7])
        dist = np.sqrt(_dot(d, d))
        depth = np.concatenate([p - row[1:4], row[4:7] - p], axis=1)[:, [0, 3, 1, 4, 2, 5]]
        f = np.argmin(depth, axis=1)
        n_in = np.zeros_like(p)
        n_in[np.arange(len(p)), f // 2] = np.where(f % 2 == 1, 1.0, -1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            out = dist > 0.0
            return np.where(out, dist, -depth.min(axis=1)), np.where(out[:, None], d / dist[:, None], n_in)
    if kind == SPHERE:
        d = p - row[1:4]
        dist = np.sqrt(_dot(d, d))
        with np.errstate(divide="ignore", invalid="ignore"):
            return dist - row[4], np.where((dist > 0.0)[:, None], d / dist[:, None], [0.0, 0.0, 1.0])
    u = row[4:7] - row[1:4]
    h = np.sqrt(u @ u)
    u = u / h
    v = p - row[1:4]
    t = v[:, 0] * u[0] + v[:, 1] * u[1] + v[:, 2] * u[2]
    r = v - t[:, None] * u
    rho = np.sqrt(_dot(r, r))
    with np.errstate(divide="ignore", invalid="ignore"):
        er = np.where((rho > 0.0)[:, None], r / rho[:, None], _perp_reference(u[None])[0])
        dr = rho - row[7]
        low = t < 0.5 * h
        dz = np.where(low, -t, t - h)
        ec = np.where(low[:, None], -u, u)
        a, b = np.maximum(dr, 0.0), np.maximum(dz, 0.0)
        d = np.sqrt(a * a + b * b)
        n_out = (a[:, None] * er + b[:, None] * ec) / d[:, None]
    outside = (dr > 0.0) | (dz > 0.0)
    sd = np.where(outside, d, np.maximum(dr, dz))
    n = np.where(outside[:, None], n_out, np.where((dr > dz)[:, None], er, ec))
    return sd, n


def project_colliders_reference(x, w_p, particle_radius, colliders, k_col, dt, force, max_push: float = np.inf,
                                x_prev=None, touched=None) -> tuple[int, float]:
    """numpy version of :func:`project_colliders`."""
    if k_col <= 0.0 or len(colliders) == 0 or len(x) == 0:
        return 0, 0.0
    _check_colliders(colliders)
    dt2 = dt * dt
    n_active, pen = 0, 0.0
    for c, row in enumerate(colliders):
        sd, n = collider_distance_reference(row, x)
        ph = particle_radius - sd
        act = ph > 0.0
        if not act.any():
            continue
        if touched is not None:
            touched[act, c] = True
        n_active += int(act.sum())
        pen = max(pen, float(ph[act].max()))
        w, ph, n = w_p[act], ph[act], n[act]
        dl = k_col * ph * ph * dt2 / (1.0 + w * k_col * ph * dt2)
        cap = np.full(len(dl), float(max_push))
        if x_prev is not None:
            prev = particle_radius[act] - collider_distance_reference(row, x_prev[act])[0]
            cap = np.maximum(ph - np.maximum(prev - max_push, 0.0), 0.0)
        over = w * dl > cap
        dl[over] = cap[over] / w[over]
        x[act] += (w * dl)[:, None] * n
        force[act] += dl / dt2
    return n_active, pen
