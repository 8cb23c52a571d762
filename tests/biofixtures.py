"""Synthetic wood blocks with a constant wood frame for the transport accuracy tests.

The rod graph is the real one (packing, random phases, staggered REG); only the wood frame is
replaced by a constant one so that planar fronts and heat kernels have fixed principal axes.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

import wooddecay as wd
from wooddecay.sim import biology
from wooddecay.sim.transport import assemble

X, Y, Z = np.eye(3)
#: rows (e_r, e_t, e_l), all right-handed; the name is the world axis carrying that direction
FRAMES = {
    "l": np.array([Y, Z, X]),   # grain along x
    "r": np.array([Y, Z, X]),   # radial along y
    "t": np.array([-Z, Y, X]),  # tangential along y
}
AXIS = {"l": 0, "r": 1, "t": 1}

FISHER = """
[scene]
seed = 5
[[skeleton.node]]
id = "a"
position = [0.0, 0.0, 0.0]
profile = {{ kind = "polygon", points = [[{u0}, {v0}], [{u1}, {v0}], [{u1}, {v1}], [{u0}, {v1}]] }}
[[skeleton.node]]
id = "b"
position = [{length}, 0.0, 0.0]
parent = "a"
profile = {{ kind = "polygon", points = [[{u0}, {v0}], [{u1}, {v0}], [{u1}, {v1}], [{u0}, {v1}]] }}
[strands]
r_s = 0.005
rod_length = {rod}
[bsp]
cells = 0
[weakpoints]
k_W = 0.0
[fungi]
alpha_b0 = {alpha}
D_b = {D}
D_w = {D}
D_C = {D}
beta_b = 0.0
gamma_cb = 0.0
gamma_cw = 0.0
kappa = 0.0
[moisture]
D_M0 = {D}
k_in0 = 0.0
k_out0 = 0.0
"""


def block(length, width, thickness, rod, alpha=1.0, D=1e-3):
    """A straight block along x, cross-section width (world y) x thickness (world z)."""
    text = FISHER.format(u0=-width / 2, u1=width / 2, v0=-thickness / 2, v1=thickness / 2,
                         length=length, rod=rod, alpha=alpha, D=D)
    scene = wd.parse_scene(text, source="block.toml")
    return scene, wd.build_model(scene)


def constant_frame_setup(model, scene, direction):
    """BioSetup whose transport uses a constant wood frame (FRAMES[direction])."""
    setup = biology.prepare(model, scene)
    n = model.n_elements
    frames = np.broadcast_to(FRAMES[direction], (n, 3, 3)).copy()
    aniso = biology.tissue_table(scene, ("a_r", "a_t", "a_l"))[setup.tissue]
    kind = model.transport_kind[model.transport_edge_of]
    st = scene.strands
    op = assemble(model.centers, frames, model.particles[model.first_particle],
                  model.particles[model.first_particle + 1], np.pi * st.r_s**2 / st.phi_pack,
                  model.transport_indptr, model.transport_indices, kind == 1, aniso)
    setup = replace(setup, op=op)
    return replace(setup, bound=biology.stability_bound(setup))
