"""Time from a mesh or scan to the wood model, per sample of samples/meshes/: reading and
slicing it into a skeleton (``load_scene``: mesh_input / point_cloud and mesh_skeleton) and
building the model (``build_model``), plus the skeleton's node count.

    python benchmarks/mesh_input.py [REPEAT]      (default 5)

Prints ``name value unit`` lines, each the median of REPEAT runs after a warm-up, with its spread.
"""
from __future__ import annotations

import statistics
import sys

import wooddecay as wd

from timing import SAMPLES, spread, times

SCENES = ("bent_log", "bent_log_scan", "forked_branch")


def main() -> None:
    repeat = int(sys.argv[1]) if len(sys.argv) > 1 else 5
    for name in SCENES:
        path = SAMPLES / "meshes" / f"{name}.toml"
        scene = wd.load_scene(path)
        load = times(lambda: wd.load_scene(path), repeat)
        build = times(lambda: wd.build_model(scene), max(1, repeat // 2))
        print(f"{name}_nodes {len(scene.skeleton.ids)}")
        print(f"{name}_mesh_to_skeleton_s {statistics.median(load):.3f} s {spread(load)}")
        print(f"{name}_build_model_s {statistics.median(build):.3f} s {spread(build)}")


if __name__ == "__main__":
    main()
