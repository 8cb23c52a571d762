"""Result of the kinetic Delaunay sweep: events, snapshots and replay (woodstock §8.1; docs/model.md §5).

Events are of the kinds of :data:`KIND_NAMES`:

* ``flip``    four sites become co-circular: the in-circle certificate of an edge changes sign;
* ``hull``    three consecutive hull sites become collinear: the convex hull changes;
* ``insert``  a strand begins at a section; ``delete``: a strand ends at a section;
* ``section`` every input section is an event too (the motion changes there);
* ``repair``  the sites re-triangulated from scratch (:mod:`.delaunay`).

Symbolic-like perturbation. Coincident sites (two strands through one point), collinear and
co-circular sets (grids, circles) are broken by a tiny deterministic index-based displacement:
every predicate sees P_i(d) + eta h u_i, with h the extent of the branch's sites, eta = ETA = 1e-8
(>> tau, so the perturbation is resolved by the predicates) and u_i = rho_i (cos(i phi),
sin(i phi)) with the golden angle phi and rho_i = 0.5 + 0.5 frac(i / golden ratio)
(:func:`perturbation`; :meth:`KineticResult.predicate_positions_at` gives these positions).
Coincident sites therefore become sites ~1e-8 h apart and never crash the structure; co-circular
ties resolve the same way on every run. Coordinates are first centred and scaled by h (the DT is
similarity-invariant).
"""
from __future__ import annotations

from bisect import bisect_right
from dataclasses import dataclass, field

import numpy as np

from ... import fmath as fm

KIND_NAMES = ("section", "flip", "hull", "insert", "delete", "repair")
SECTION, FLIP, HULL, INSERT, DELETE, REPAIR = range(6)
#: kinds whose event stores a full snapshot instead of the changes
SNAPSHOT_KINDS = (SECTION, REPAIR)
#: relative index-based perturbation of the sites (see the module docstring)
ETA = 1e-8

_GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))
_INV_PHI = (np.sqrt(5.0) - 1.0) / 2.0


def perturbation(n):
    """(n, 2) index-based displacements u_i of the sites (see the module docstring)."""
    i = np.arange(n, dtype=float)
    rho = 0.5 + 0.5 * np.mod(i * _INV_PHI, 1.0)
    return np.stack([rho * fm.cos(i * _GOLDEN_ANGLE), rho * fm.sin(i * _GOLDEN_ANGLE)], axis=1)


def canon_triangle(a, b, c):
    """Rotation of the counter-clockwise triangle (a, b, c) that starts at its smallest index."""
    if a < b and a < c:
        return (a, b, c)
    if b < c:
        return (b, c, a)
    return (c, a, b)


def _as_array(tris):
    if not tris:
        return np.zeros((0, 3), dtype=np.int64)
    return np.array(sorted(tris), dtype=np.int64)


@dataclass
class KineticResult:
    """Output of :func:`~.delaunay.sweep`: the kinetic Delaunay triangulation of one branch (§8.1).

    Events are listed in order of d_t (``d_events``, non-decreasing) with their ``kinds`` (codes of
    :data:`KIND_NAMES`); every input section is an event of kind ``section`` whose triangulation is
    stored (``section_event[k]`` is its event index), as is that of a ``repair`` (a rebuild from
    scratch, see :mod:`.delaunay`); any other event stores the real triangles it removed and added
    (``changes``), so a triangulation is the last snapshot plus a replay.

    Triangles are (T, 3) int arrays of site indices, counter-clockwise, rotated to start at their
    smallest index and sorted; triangles touching the infinite vertex are never reported. The
    combinatorial structure is constant between events.

    At a section d_k the sites alive at k are inserted first (``insert`` events), then the section
    snapshot (all sites alive at k), then the sites whose run ends at k are deleted (``delete``).
    """

    d: np.ndarray
    P: np.ndarray
    alive: np.ndarray
    d_events: np.ndarray
    kinds: np.ndarray
    section_event: np.ndarray
    snapshot_event: np.ndarray
    counts: dict
    eta: float
    tau: float
    centre: np.ndarray
    scale: float
    _removed: list = field(repr=False)
    _added: list = field(repr=False)
    _snapshots: dict = field(repr=False)

    @property
    def n_sites(self) -> int:
        return self.P.shape[1]

    @property
    def n_events(self) -> int:
        return len(self.d_events)

    def changes(self, e):
        """(removed, added) real triangles of event e, each (k, 3)."""
        return _as_array(self._removed[e]), _as_array(self._added[e])

    def triangulation(self, e) -> np.ndarray:
        """The triangulation right after event e (valid until event e + 1)."""
        e = int(e)
        if not 0 <= e < self.n_events:
            raise IndexError(f"event {e} out of range [0, {self.n_events})")
        k = int(np.searchsorted(self.snapshot_event, e, side="right")) - 1
        e0 = int(self.snapshot_event[k])
        cur = set(self._snapshots[e0])
        for j in range(e0 + 1, e + 1):
            cur.difference_update(self._removed[j])
            cur.update(self._added[j])
        return _as_array(cur)

    def event_at(self, t) -> int:
        """Index of the event whose triangulation is valid at d_t = t.

        At an input section exactly, its snapshot (all sites alive there); elsewhere the last event
        with d_e <= t.
        """
        t = float(t)
        if t < self.d[0] or t > self.d[-1]:
            raise ValueError(f"d_t = {t} outside the branch [{self.d[0]}, {self.d[-1]}]")
        k = int(np.searchsorted(self.d, t))
        if k < len(self.d) and self.d[k] == t:
            return int(self.section_event[k])
        return bisect_right(self.d_events, t) - 1

    def triangles_at(self, t) -> np.ndarray:
        """Delaunay triangles of the sites alive at d_t = t (counter-clockwise site indices)."""
        return self.triangulation(self.event_at(t))

    def alive_at(self, t) -> np.ndarray:
        """Boolean (n,) mask of the sites present at d_t = t (between sections: alive at both ends)."""
        k, s = self._piece(t)
        if s == 0.0:
            return self.alive[k].copy()
        return self.alive[k] & self.alive[k + 1]

    def positions_at(self, t) -> np.ndarray:
        """(n, 2) sites at d_t = t (linear between sections, unperturbed); NaN where not alive."""
        k, s = self._piece(t)
        if s == 0.0:
            X = self.P[k].astype(float).copy()
        else:
            X = (1.0 - s) * self.P[k] + s * self.P[k + 1]
        X[~self.alive_at(t)] = np.nan
        return X

    def predicate_positions_at(self, t) -> np.ndarray:
        """(n, 2) sites as the predicates see them: centred, scaled by the extent and perturbed by
        index (module docstring); NaN where not alive. The triangulation is exactly Delaunay for
        these (up to the hysteresis tau)."""
        X = (self.positions_at(t) - self.centre) / self.scale
        return X + self.eta * perturbation(self.n_sites)

    def _piece(self, t):
        t = float(t)
        if t < self.d[0] or t > self.d[-1]:
            raise ValueError(f"d_t = {t} outside the branch [{self.d[0]}, {self.d[-1]}]")
        k = int(np.searchsorted(self.d, t, side="right")) - 1
        if k >= len(self.d) - 1 or self.d[k] == t:
            return min(k, len(self.d) - 1), 0.0
        return k, (t - self.d[k]) / (self.d[k + 1] - self.d[k])

    def iter_events(self):
        """Yield (e, d_e, kind, removed, added) in order; removed/added are lists of tuples.

        For a section or repair event, ``removed`` is None and ``added`` the full snapshot.
        """
        for e in range(self.n_events):
            if int(self.kinds[e]) in SNAPSHOT_KINDS:
                yield e, float(self.d_events[e]), int(self.kinds[e]), None, list(self._snapshots[e])
            else:
                yield e, float(self.d_events[e]), int(self.kinds[e]), self._removed[e], self._added[e]

    def iter_triangulations(self):
        """Yield (e, d_e, triangles) for every event by incremental replay (no per-event rebuild)."""
        cur = set()
        for e, de, kind, rem, add in self.iter_events():
            if rem is None:
                cur = set(add)
            else:
                cur.difference_update(rem)
                cur.update(add)
            yield e, de, _as_array(cur)
