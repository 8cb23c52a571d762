"""Meshlet build and per-frame skinning on a sample scene (woodstock §8.1, §8.3).

Prints ``name value unit`` lines:
    meshing_elements <n>          rod elements (one meshlet each)
    meshing_seconds <v> s         wall time of ``wd.build_meshlets`` (one run; kinetic sweeps and
                                  assembly), the target for samples/tree.toml is <= 60 s
    meshlets_per_s <v> 1/s        meshlets built per second
    meshing_faces / meshing_vertices   size of the shells
    meshing_closed_fraction       closed and oriented meshlets (must be 1)
    closed_check_seconds <v> s    ``checks.closed_oriented`` over all meshlets (median of 3, spread)
    meshing_volume_error          sum of meshlet volumes against the bark's, relative
    narrow_notes_seconds <v> s    the build's check for profile parts narrower than a strand
                                  (ellipse and polygon profiles; best of 3)
    skin_seconds <v> s            one frame of skinning positions and six fields (best of 3)
Usage: python benchmarks/meshing.py [samples/tree.toml]
"""
from __future__ import annotations

import statistics
import sys
import time

import numpy as np

import wooddecay as wd
from wooddecay.meshlets import checks, skin

from wooddecay.model import narrow_notes

from timing import SAMPLES, best, spread, times


def main(path: str = str(SAMPLES / "tree.toml")) -> None:
    scene = wd.load_scene(path)
    model = wd.build_model(scene)
    t0 = time.perf_counter()
    mesh = wd.build_meshlets(model)
    sec = time.perf_counter() - t0
    closed = checks.closed_oriented(mesh)
    link = skin.links(model, mesh)
    fields = np.random.default_rng(0).random((model.n_elements, 6))
    args = (model.particles, model.rest_quat, np.zeros(model.n_elements, dtype=np.int64),
            np.ones((model.n_edges, 3), dtype=bool), np.ones(model.n_elements, dtype=bool),
            np.ones(model.n_elements), fields)
    t_skin = best(lambda: skin.skin(model, mesh, link, *args))
    t_closed = times(lambda: checks.closed_oriented(mesh), 3)
    print(f"meshing_scene {scene.name}")
    print(f"meshing_elements {model.n_elements}")
    print(f"meshing_seconds {sec:.3f} s")
    print(f"meshlets_per_s {mesh.count / sec:.1f} 1/s")
    print(f"meshing_faces {mesh.n_faces}")
    print(f"meshing_vertices {len(mesh.points)}")
    print(f"meshing_closed_fraction {closed.mean():.6f}")
    print(f"closed_check_seconds {statistics.median(t_closed):.3f} s {spread(t_closed)}")
    print(f"meshing_volume_error {checks.volumes(mesh).sum() / checks.bark_volume(model) - 1.0:+.2e}")
    print(f"meshing_events {mesh.stats}")
    print(f"narrow_notes_seconds {best(lambda: narrow_notes(scene.skeleton, scene.strands.r_s)):.4f} s")
    print(f"skin_seconds {t_skin:.4f} s")


if __name__ == "__main__":
    main(*sys.argv[1:])
