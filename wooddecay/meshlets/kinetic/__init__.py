"""Kinetic 2D Delaunay triangulation of a branch's strand sites along d_t (woodstock §8.1; docs/model.md §5).

For one branch, strand i crosses the cross-section at d_t in the site P_i(d_t) (branch frame, 2D),
sampled at the sections ``d[0] < d[1] < ... < d[S-1]`` and linear in d_t between two of them
(§8.1: "we represent each P_i(d_t) piecewise linearly between successive cross-sections"). The
paper tracks the Voronoi partition of P(d_t) with Guibas et al. [1992]; this package carries its
dual, the Delaunay triangulation DT(P(d_t)), along d_t with discrete events:

* :mod:`.certificates`: the in-circle, hull and flatness certificates of the edges, polynomials in
  the local parameter of a piece, and their event times;
* :mod:`.roots`: the sign-changing roots of those polynomials (monotone bisection);
* :mod:`.delaunay`: the triangulation (a closed sphere with a vertex at infinity) and :func:`sweep`;
* :mod:`.result`: :class:`KineticResult`, the events in order of d_t with snapshots and replay.

Cost: O(1) flips and five edge certificate recomputations (numba; each with the flatness of the
edge's two triangles) per event with a binary heap of event times (stale entries are skipped by
version numbers); O(n) per section (all certificates are recomputed because the velocities change
there, and the triangulation is snapshotted).
"""
from .certificates import incircle_coefficients
from .delaunay import sweep
from .result import FLIP, HULL, REPAIR, SECTION, KineticResult, perturbation
from .roots import first_positive_time, sign_change_roots

__all__ = ["FLIP", "HULL", "REPAIR", "SECTION", "KineticResult", "first_positive_time", "incircle_coefficients",
           "perturbation", "sign_change_roots", "sweep"]
