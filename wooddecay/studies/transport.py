"""Transport accuracy studies on synthetic wood blocks (docs/model.md §7; used by tests and benchmarks).

The rod graph is the real one (packing, random phases, staggered REG); only the wood frame is
replaced by a constant one so that planar fronts and heat kernels have fixed principal axes.

* :func:`heat_kernel_ratio`: a point release of R_b (no growth); the slope of its variance along
  the direction over 2 D a_dir (1 is exact).
* :func:`fisher_speed_ratio`: R_b with H_c = 1, no defence, open moisture window is Fisher-KPP;
  the planar front's speed over 2 sqrt(alpha D a_dir), fitted over t in [17, 34] / alpha with
  Bramson's log correction (an ideal 1D finite-difference solver gives 0.993 on that window), at
  a resolution q = h sqrt(alpha / D_dir) of the element spacing h in front widths.
* :func:`front_resolution`: that q for the decay fronts of a scene's model, and
  :func:`wooddecay.sim.fronts.lattice_speed_ratio` the speed a 1D lattice of spacing h gives a front at q: a pulled
  front runs ahead of the continuum's on a coarse graph, since its leading edge jumps h at once.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..wood import WoodModel
from ..model import build_model
from ..scene.schema import TISSUE_DEFAULTS, TISSUE_KEYS
from ..sim import biology
from ..sim.state import initial_state
from ..sim.transport import assemble
from . import scene_template

X, Y, Z = np.eye(3)
#: rows (e_r, e_t, e_l), all right-handed; the name is the world axis carrying that direction
FRAMES = {
    "l": np.array([Y, Z, X]),   # grain along x
    "r": np.array([Y, Z, X]),   # radial along y
    "t": np.array([-Z, Y, X]),  # tangential along y
}
AXIS = {"l": 0, "r": 1, "t": 1}


def block_scene(length, width, thickness, rod, alpha=1.0, D=1e-3):
    """``scenes/transport.toml`` as a straight block along x, cross-section width (world y) x
    thickness (world z), rod length ``rod``, growth rate ``alpha`` and diffusivities ``D``."""
    u0, u1, v0, v1 = -width / 2, width / 2, -thickness / 2, thickness / 2
    profile = {"kind": "polygon", "points": [[u0, v0], [u1, v0], [u1, v1], [u0, v1]]}
    nodes = [{"id": "a", "position": [0.0, 0.0, 0.0], "profile": profile},
             {"id": "b", "position": [length, 0.0, 0.0], "parent": "a", "profile": profile}]
    values = {"strands.rod_length": rod, "fungi.alpha_b0": alpha, "fungi.D_b": D, "fungi.D_w": D, "fungi.D_C": D,
              "moisture.D_M0": D}
    # every tissue alike (the tissue defaults off), so the block is one homogeneous medium
    alike = {f"tissue.{t}.{k}": values.get(TISSUE_KEYS[k].key, TISSUE_KEYS[k].default)
             for t, table in TISSUE_DEFAULTS.items() for k in table}
    return scene_template("transport", {**values, **alike}, nodes)


def block(length, width, thickness, rod, alpha=1.0, D=1e-3):
    """The scene of :func:`block_scene` and its model."""
    scene = block_scene(length, width, thickness, rod, alpha, D)
    return scene, build_model(scene)


def constant_frame_model(model: WoodModel, scene, direction):
    """``model`` whose biology transport uses a constant wood frame (FRAMES[direction])."""
    setup = model.bio
    n = model.n_elements
    frames = np.broadcast_to(FRAMES[direction], (n, 3, 3)).copy()
    aniso = model.materials.table(("a_r", "a_t", "a_l"))[setup.tissue]
    kind = model.transport_kind[model.transport_edge_of]
    st = scene.strands
    op = assemble(model.centers, frames, model.particles[model.first_particle],
                  model.particles[model.first_particle + 1], np.pi * st.r_s**2 / st.phi_pack,
                  model.transport_indptr, model.transport_indices, kind == 1, aniso)
    setup = replace(setup, op=op)
    return replace(model, bio=replace(setup, bound=biology.stability_bound(setup)))


#: principal factors a_dir of the default [transport] section
A_DIR = {"l": 4.0, "r": 0.25, "t": 1.0}


def heat_kernel_ratio(direction: str, D: float = 1e-3, t_end: float = 0.6) -> tuple[float, int]:
    """(measured d var/dt) / (2 D a_dir) for a point release in a 0.8 x 0.24 x 0.24 m block, and
    the clamp count (0 expected)."""
    scene, model = block(0.8, 0.24, 0.24, 0.015, alpha=0.0, D=D)
    model = constant_frame_model(model, scene, direction)
    setup = model.bio
    axis = AXIS[direction]
    c = model.centers
    i0 = int(np.argmin(np.linalg.norm(c - [0.4, 0.0, 0.0], axis=1)))
    s = initial_state(model)
    s.R_b[:] = 0.0
    s.R_b[i0] = 1.0
    V = setup.op.volume
    x = c[:, axis] - c[i0, axis]
    ts, vs = [], []
    while s.t_days < t_end - 1e-12:
        biology.step(model, s, 0.01)
        w = V * s.R_b / np.sum(V * s.R_b)
        mu = np.sum(w * x)
        ts.append(s.t_days)
        vs.append(np.sum(w * (x - mu) ** 2))
    ts, vs = np.array(ts), np.array(vs)
    late = ts >= t_end / 3  # after the release has spread over a few neighbours
    return float(np.polyfit(ts[late], vs[late], 1)[0] / (2 * D * A_DIR[direction])), s.clamp_count


#: element spacing h of the Fisher blocks: the rod length of the block along the grain, 2 r_s
#: (the template's r_s 5 mm) across it
FISHER_SPACING = 0.01
#: front resolution q of the Fisher blocks unless asked for another: resolved fronts
FISHER_Q = {"l": 0.2, "r": 0.25, "t": 0.25}


def fisher_speed_ratio(direction: str, alpha: float = 1.0, q: float | None = None,
                       alpha_dt: float = 0.1) -> tuple[float, int]:
    """(fitted front speed) / (2 sqrt(alpha D_dir)) and the clamp count (module docstring), for a
    front whose width sqrt(D_dir / alpha) is the element spacing over ``q`` (default FISHER_Q),
    in biology steps of ``alpha_dt`` / alpha."""
    a = A_DIR[direction]
    D_dir = alpha * (FISHER_SPACING / (FISHER_Q[direction] if q is None else q)) ** 2
    if direction == "l":
        scene, model = block(4.0, 0.05, 0.05, FISHER_SPACING, alpha, D_dir / a)
    else:  # two elements along the grain: the front is uniform along x, so more add only copies
        scene, model = block(0.03, 3.4, 0.04, 0.015, alpha, D_dir / a)
    model = constant_frame_model(model, scene, direction)
    setup = model.bio
    x = model.centers[:, AXIS[direction]]
    x = x - x.min()
    s = initial_state(model)
    s.R_b[:] = np.where(x < 0.2, 1.0, 0.0)
    V = setup.op.volume
    area = V.sum() / x.max()
    ts, X = [], []
    while s.t_days < 34.0 / alpha - 1e-9:
        biology.step(model, s, alpha_dt / alpha)
        ts.append(s.t_days)
        X.append(np.sum(V * s.R_b) / area)
    ts, X = np.array(ts), np.array(X)
    late = ts >= 17.0 / alpha
    corrected = X + 1.5 * np.sqrt(D_dir / alpha) * np.log(alpha * ts)
    v = np.polyfit(ts[late], corrected[late], 1)[0]
    return float(v / (2 * np.sqrt(alpha * D_dir))), s.clamp_count


def front_resolution(model: WoodModel) -> dict[str, dict[str, float]]:
    """Per fungus ("white", "brown") and direction (l, r, t) the median over the elements of q =
    h sqrt(g / (D a_dir)): h the element spacing (the rod length along the grain, 2 r_s across
    it), g the fastest linear growth at a front's leading edge (Eqs. 8-9 at R -> 0 on sound wood
    in an open moisture window without defence: alpha_w0 (lambda_l + lambda_c) / (K_c + 1) for
    white rot, alpha_b0 for brown), D the fungus' diffusivity and a_dir the transport factor."""
    p = model.materials.per_element
    growth = {"white": (p("alpha_w0") * (p("lambda_l") + p("lambda_c")) / (p("K_c") + 1.0), p("D_w")),
              "brown": (p("alpha_b0"), p("D_b"))}
    h = {"l": model.rest_length, "r": 2.0 * model.r_s, "t": 2.0 * model.r_s}
    a = {d: p(f"a_{d}") for d in ("l", "r", "t")}
    return {f: {d: float(np.median(h[d] * np.sqrt(g / (D * a[d])))) for d in ("l", "r", "t")}
            for f, (g, D) in growth.items()}
