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
    rest_skinning_seconds <v> s   the rest skinning weights and local coordinates of every meshlet
                                  vertex: the numba kernel, its numpy twin and their ratio
                                  (medians of 5 alternating pairs, spread)
    winding_seconds <v> s         winding numbers of 20,000 points about their meshlets (the
                                  junction walls' test): kernel, numpy twin, ratio (likewise)
Usage: python benchmarks/meshing.py [samples/tree.toml]
"""
from __future__ import annotations

import statistics
import sys
import time

import numpy as np

import wooddecay as wd
from wooddecay.meshlets import checks, junction, skin

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
    rest = (mesh.points, mesh.skin_indptr, mesh.skin_element)
    pair("rest_skinning", lambda: skin.rest_skinning(model, *rest), lambda: skin.rest_skinning_reference(model, *rest))
    rng = np.random.default_rng(0)
    elements = rng.integers(0, mesh.count, 20_000)
    probes = model.centers[elements] + rng.normal(scale=model.r_s, size=(len(elements), 3))
    pair("winding", lambda: junction._winding(mesh, elements, probes),
         lambda: junction._winding_reference(mesh, elements, probes))


def pair(name: str, kernel, reference, repeat: int = 5) -> None:
    """Alternating timings of ``kernel`` and ``reference`` (after one warm-up call of each):
    medians with their spread, and the median of the per-pair ratios."""
    kernel(), reference()
    tk, tr = [], []
    for _ in range(repeat):
        tk += times(kernel, 1)
        tr += times(reference, 1)
    ratios = [r / k for k, r in zip(tk, tr)]
    print(f"{name}_seconds {statistics.median(tk):.4f} s {spread(tk)}")
    print(f"{name}_reference_seconds {statistics.median(tr):.4f} s {spread(tr)}")
    print(f"{name}_speedup {statistics.median(ratios):.1f} x {spread(ratios)}")


if __name__ == "__main__":
    main(*sys.argv[1:])
