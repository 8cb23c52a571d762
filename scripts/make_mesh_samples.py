"""Regenerate the samples of ``wooddecay/samples/meshes/``: ``bent_log.obj``, a bent, knotty
spruce log as an artist would model it (1.2 m along an arch of 4 m radius, 0.13-0.15 m radius with
bark noise and four knots; cut square at both ends; placed off the origin, lying on z = 0, as in
a set), and ``bent_log_scan.ply``, the same log as a scanner sees it: SCAN_POINTS points on its
surface with SCAN_NOISE of noise, none on its underside within 2 cm of the ground; and
``forked_branch.glb``, a fallen forked branch (:func:`forked_branch`).

Deterministic (fixed seed). Run: ``python scripts/make_mesh_samples.py``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from wooddecay.strands.point_cloud import closed_tube

OUT = Path(__file__).resolve().parent.parent / "wooddecay" / "samples" / "meshes"
AROUND, ALONG = 48, 40  # vertices around a ring, rings along the log
LENGTH, BEND = 1.2, 4.0  # m: along the centreline, radius of its bend
PLACE = np.array([2.0, -1.0, 0.0])  # where the log's root end sits in the artist's set
SCAN_POINTS, SCAN_NOISE = 6000, 0.001  # points, m
FORK_PLACE = np.array([0.5, 1.5, 0.0])  # where the forked branch's cut end sits
#: our z-up coordinates -> glTF's y-up (as wooddecay.export.gltf writes)
Z_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def bent_log(seed: int = 5):
    """Vertices (n, 3) and triangles (m, 3) of the log (module docstring)."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, LENGTH, ALONG)
    phi = (s - LENGTH / 2) / BEND  # an arch in the x-z plane: the log rests on its two ends
    centre = np.stack([BEND * np.sin(phi), np.zeros_like(s), -BEND * (1.0 - np.cos(phi))], axis=1)
    tangent = np.stack([np.cos(phi), np.zeros_like(s), -np.sin(phi)], axis=1)
    side = np.array([0.0, 1.0, 0.0])
    up = np.cross(tangent, side)  # +z at the middle
    theta = np.linspace(0.0, 2 * np.pi, AROUND, endpoint=False)
    radius = 0.15 - 0.02 * s[:, None] / LENGTH + 0.004 * np.sin(3 * theta + 2.0 * s[:, None])
    radius = radius + 0.002 * rng.standard_normal((ALONG, AROUND))
    for ks, kt in zip(rng.uniform(0.2, 1.0, 4), rng.uniform(0.0, 2 * np.pi, 4)):  # knots: bumps of 2 cm
        dt = np.angle(np.exp(1j * (theta[None, :] - kt)))
        radius = radius + 0.02 * np.exp(-((s[:, None] - ks) / 0.04) ** 2 - (dt / 0.25) ** 2)
    vertices, faces = tube(centre, side, up, radius)
    vertices[:, 2] -= vertices[:, 2].min()  # on the ground
    return vertices + PLACE, faces


def tube(centre, side, up, radius):
    """A closed tube through the rings ``centre[i] + radius[i, j] (cos theta_j side + sin theta_j
    up[i])`` (``radius`` (rings, around)), capped at both ends: vertices and triangles."""
    along, around = radius.shape
    theta = np.linspace(0.0, 2 * np.pi, around, endpoint=False)
    ring = (np.cos(theta)[None, :, None] * np.broadcast_to(side, (along, 3))[:, None, :]
            + np.sin(theta)[None, :, None] * up[:, None, :])
    return closed_tube(centre[:, None, :] + radius[:, :, None] * ring, centre[0], centre[-1])


def straight(start, direction, length, r0, r1, rings=24, around=32):
    """A straight tube from ``start`` along ``direction`` tapering from radius r0 to r1."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    side = np.cross([0.0, 0.0, 1.0], d)
    side /= np.linalg.norm(side)
    s = np.linspace(0.0, length, rings)
    radius = np.repeat((r0 + (r1 - r0) * s / length)[:, None], around, axis=1)
    return tube(np.asarray(start) + s[:, None] * d, side, np.repeat(np.cross(d, side)[None], rings, 0), radius)


def forked_branch():
    """A fallen forked branch as a glTF artist would hand it over (FORK_PLACE, lying on z = 0):
    a stem 1.1 m long tapering from 6 to 3.5 cm radius and a side branch 0.5 m long (3.5 to 2 cm)
    leaving it 0.45 m from its cut end at 40 degrees, both on the ground; one closed body (their
    boolean union)."""
    import trimesh

    stem = trimesh.Trimesh(*straight([0.0, 0.0, 0.06], [1.0, 0.0, 0.0], 1.1, 0.06, 0.035))
    a = np.radians(40.0)
    side = trimesh.Trimesh(*straight([0.45, 0.0, 0.05], [np.cos(a), np.sin(a), -0.03], 0.5, 0.035, 0.02))
    for m in (stem, side):
        if m.volume < 0:
            m.invert()
    union = trimesh.boolean.union([stem, side], engine="manifold")
    union.apply_translation(FORK_PLACE - [0.0, 0.0, union.bounds[0, 2]])
    return union


def write_obj(path: Path, vertices, faces) -> None:
    lines = ["# wooddecay sample: a bent, knotty log (scripts/make_mesh_samples.py); units: metres"]
    lines += [f"v {x:.4f} {y:.4f} {z:.4f}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def main() -> None:
    import trimesh

    OUT.mkdir(parents=True, exist_ok=True)
    v, f = bent_log()
    mesh = trimesh.Trimesh(v, f, process=False)
    if mesh.volume < 0:
        f = f[:, ::-1]
        mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.volume > 0
    write_obj(OUT / "bent_log.obj", v, f)
    print(f"wrote {OUT / 'bent_log.obj'}: {len(v)} vertices, {len(f)} faces, volume {mesh.volume:.5f} m^3")
    rng = np.random.default_rng(11)
    pts, _ = trimesh.sample.sample_surface(mesh, 2 * SCAN_POINTS, seed=11)
    pts = pts[pts[:, 2] > 0.02][:SCAN_POINTS] + SCAN_NOISE * rng.standard_normal((SCAN_POINTS, 3))
    trimesh.PointCloud(np.round(pts, 4)).export(OUT / "bent_log_scan.ply")
    print(f"wrote {OUT / 'bent_log_scan.ply'}: {len(pts)} points")
    fork = forked_branch()
    assert fork.is_watertight and fork.volume > 0
    trimesh.Trimesh(fork.vertices @ Z_TO_Y_UP.T, fork.faces).export(OUT / "forked_branch.glb")
    print(f"wrote {OUT / 'forked_branch.glb'}: {len(fork.faces)} faces, volume {fork.volume:.5f} m^3 (y-up)")


if __name__ == "__main__":
    main()
