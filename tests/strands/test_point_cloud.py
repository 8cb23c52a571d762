"""Wood from a scan (wooddecay.strands.point_cloud; ``[skeleton] points``, ``wooddecay init
--from-points``): PLY, XYZ, LAS and LAZ read alike, the lofted surface of a scanned cylinder and of
a scanned C-shaped (not star-shaped) log against the truth, the sample scan against the mesh it was
taken from, and bad clouds."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from wooddecay.scene import load_scene
from wooddecay.strands.mesh_input import load_mesh, surface_distance
from wooddecay.strands.mesh_skeleton import mesh_skeleton
from wooddecay.strands.point_cloud import loft, read_points

from ..conftest import refused_in_one_line

SAMPLES = Path(__file__).resolve().parent.parent.parent / "wooddecay" / "samples" / "meshes"
R, LENGTH = 0.1, 0.8


def scan(n: int = 8000, noise: float = 0.0005, seed: int = 3) -> np.ndarray:
    """Points on a cylinder (radius R, LENGTH along x from the origin) and its end faces."""
    m = trimesh.creation.cylinder(radius=R, height=LENGTH, sections=128)
    m.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
    m.apply_translation([LENGTH / 2, 0.0, R])
    pts, _ = trimesh.sample.sample_surface(m, n, seed=seed)
    return pts + noise * np.random.default_rng(seed).standard_normal(pts.shape)


def write_las(path: Path, pts: np.ndarray) -> None:
    import laspy

    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([1e-4, 1e-4, 1e-4])
    header.offsets = pts.min(axis=0)
    las = laspy.LasData(header)
    las.x, las.y, las.z = pts[:, 0], pts[:, 1], pts[:, 2]
    las.write(str(path))


@pytest.mark.parametrize("suffix", [".ply", ".xyz", ".las", ".laz"])
def test_formats_read_the_same_points(tmp_path, suffix):
    pts = np.round(scan(1000), 4)
    path = tmp_path / f"scan{suffix}"
    if suffix == ".ply":
        trimesh.PointCloud(pts).export(path)
    elif suffix == ".xyz":
        path.write_text("# x y z intensity\n" + "\n".join(f"{x} {y} {z} 7" for x, y, z in pts))
    else:
        write_las(path, pts)
    assert np.allclose(read_points(path), pts, atol=1e-4)


def test_lofted_cylinder_matches_the_cylinder():
    """A scanned cylinder lofts into a closed surface within 1% of its volume and 2 mm of its
    side; its skeleton runs along the axis from end to end."""
    mi = loft(scan(), resolution=0.008, source="scan")
    mesh = mi.mesh
    assert mesh.is_watertight and mesh.volume > 0
    assert mesh.volume == pytest.approx(np.pi * R * R * LENGTH, rel=0.01)
    side = np.random.default_rng(1).uniform([0.05, -np.pi], [LENGTH - 0.05, np.pi], size=(300, 2))
    on = np.column_stack([side[:, 0], R * np.cos(side[:, 1]), R + R * np.sin(side[:, 1])])
    assert surface_distance(mesh, on, 0.01).max() < 0.002
    skel = mesh_skeleton(mi, 0.008)
    assert np.allclose(skel.positions[:, 1:], [0.0, R], atol=2e-3)
    assert skel.positions[0, 0] < 0.01 and skel.positions[-1, 0] > LENGTH - 0.01


def horseshoe_scan(n: int = 20000, noise: float = 0.0005, seed: int = 3):
    """Points on a log 0.8 m long whose section is a C (a ring of radii 0.1 and 0.05 m open over
    80 degrees: no point inside it sees all of its boundary), and the section's area."""
    from wooddecay.strands import profiles

    ang = np.radians(np.linspace(40.0, 320.0, 200))
    ring = np.vstack([0.1 * np.column_stack([np.cos(ang), np.sin(ang)]),
                      0.05 * np.column_stack([np.cos(ang[::-1]), np.sin(ang[::-1])])])
    rng = np.random.default_rng(seed)
    q = profiles.resample_closed(ring, 4000)[rng.integers(0, 4000, n)]
    pts = np.column_stack([rng.uniform(0.0, LENGTH, n), q[:, 0], q[:, 1] + 0.1])
    return pts + noise * rng.standard_normal(pts.shape), profiles.polygon_area(ring)


@pytest.mark.slow
def test_scanned_c_shaped_log_keeps_its_hollow(tmp_path):
    """The C's slabs are closed by a disc (not star-shaped): the lofted surface holds the log's
    volume within 3% (the farthest point per angle, filling the hollow, holds 44% more), and the
    meshlets of the scene's model within 2%."""
    from wooddecay.meshlets import checks
    from wooddecay.meshlets.sweep import build_meshlets
    from wooddecay.model import build_model

    pts, area = horseshoe_scan()
    mi = loft(pts, resolution=0.008, source="scan")
    print(mi.repairs[0], f"volume {mi.mesh.volume / (area * LENGTH) - 1:+.2%}")
    assert mi.mesh.is_watertight and mi.mesh.volume == pytest.approx(area * LENGTH, rel=0.03)
    assert int(mi.repairs[0].split("(")[1].split()[0]) >= 49  # all but the end slabs (cut faces)
    trimesh.PointCloud(pts).export(tmp_path / "c.ply")
    (tmp_path / "c.toml").write_text('[scene]\nname = "c"\nseed = 1\n[skeleton]\npoints = "c.ply"\n'
                                     '[strands]\nr_s = 0.008\nrod_length = 0.05\n[time]\ndays = 1\n')
    volume = checks.volumes(build_meshlets(build_model(load_scene(tmp_path / "c.toml")))).sum()
    print(f"meshlets {volume / (area * LENGTH) - 1:+.2%}")
    assert volume == pytest.approx(area * LENGTH, rel=0.02)


@pytest.mark.slow
def test_sample_scan_against_the_mesh_it_came_from():
    """samples/meshes/bent_log_scan.toml: the meshlets built from 6,000 scanned points fill the
    original mesh's volume within 2% and their bark lies on average within r_s of it."""
    from wooddecay.meshlets import checks
    from wooddecay.meshlets.sweep import FACE_BARK, build_meshlets
    from wooddecay.model import build_model

    scene = load_scene(SAMPLES / "bent_log_scan.toml")
    truth = load_mesh(SAMPLES / "bent_log.obj").mesh
    meshlets = build_meshlets(build_model(scene))
    volume = checks.volumes(meshlets).sum()
    bark = np.unique(meshlets.faces[meshlets.face_kind == FACE_BARK])
    d = surface_distance(truth, meshlets.points[bark], scene.strands.r_s)
    print(f"scan: meshlets {volume:.5f} m^3 vs mesh {truth.volume:.5f} m^3, bark to mesh mean {1e3 * d.mean():.1f} mm, "
          f"p99 {1e3 * np.percentile(d, 99):.1f} mm, max {1e3 * d.max():.1f} mm")
    assert volume == pytest.approx(truth.volume, rel=0.02)
    assert d.mean() < scene.strands.r_s


def test_bad_clouds_are_one_line_and_write_nothing(tmp_path):
    pts = scan(2000)
    cases = {"few.xyz": "\n".join(f"{x} {y} {z}" for x, y, z in pts[:50]),
             "nan.xyz": "\n".join(f"{x} {y} {z}" for x, y, z in pts) + "\nnan 0 0\n",
             "short_row.xyz": "\n".join(f"{x} {y} {z}" for x, y, z in pts) + "\n1 2\n",
             "scan.e57": "not a format we read",
             "half.xyz": "\n".join(f"{x} {y} {z}" for x, y, z in pts[pts[:, 1] > 0.02]),
             "garbage.las": "LASF but not really"}
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
    target = tmp_path / "out" / "s.toml"
    target.parent.mkdir()
    for name in [*cases, "missing.ply"]:
        refused_in_one_line(["init", str(target), "--from-points", str(tmp_path / name)], target)
    refused_in_one_line(["init", str(target), "--from-points", str(tmp_path / "nan.xyz")], target, process=True)
