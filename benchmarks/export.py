"""The export of a bake: the stage's and the glTF's size and time, and how the stage's layout
writes the frames (docs/architecture.md "USD stage").

    python benchmarks/export.py [BAKE_DIR] [REPEATS]
                      (default: bakes samples/log.toml into a temporary folder first, about
                      5 minutes; 3 repeats)

From the frames a bake of samples/log.toml saved (``BAKE_DIR/.bake/frame_*.npz``) the stage and
the glTF are written REPEATS times into a temporary folder. Prints ``name value unit`` lines:
elements, frames, pieces, usd_mb, bytes_per_element_frame, export_usd_s and export_gltf_s (medians
with their spread), glb_mb; then, over the frames after the first, the share of pieces whose
transform, points or H_c indices each frame writes, and the largest distance of a written point
from the frame's skinned point (bounded by point_tolerance).
"""
from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import wooddecay as wd
from wooddecay.bake import bake, load_frame
from wooddecay.export.usd import POINT_TOLERANCE
from wooddecay.export.wood_read import wood_at, wood_meshes
from wooddecay.export.bark_surface import frame_bark
from wooddecay.meshlets import skin
from wooddecay.meshlets.visibility import NEVER, exposure

from timing import SAMPLES, spread


def written_shares(stage, n_frames: int) -> dict[str, float]:
    """Per attribute, the share of (piece, frame) pairs after the first frame that write a new value."""
    from pxr import UsdGeom

    counts = {"transform": 0, "points": 0, "H_c": 0}
    pieces = wood_meshes(stage)
    for prim in pieces:
        attrs = {"transform": prim.GetAttribute("xformOp:transform"), "points": prim.GetAttribute("points"),
                 "H_c": UsdGeom.PrimvarsAPI(prim).GetPrimvar("H_c").GetIndicesAttr()}
        for name, attr in attrs.items():
            values = [attr.Get(float(t)) for t in range(n_frames)]
            counts[name] += sum(values[t] != values[t - 1] for t in range(1, n_frames))
    return {k: v / (len(pieces) * (n_frames - 1)) for k, v in counts.items()}


def main(folder: str | None = None, repeats: int = 3) -> None:
    from pxr import Usd

    scene = wd.load_scene(SAMPLES / "log.toml")
    with tempfile.TemporaryDirectory() as tmp:
        if folder is None:
            folder = str(Path(tmp) / "bake")
            bake(scene, folder)
        model = wd.build_model(scene)
        mesh = wd.build_meshlets(model)
        frames = [load_frame(p) for p in sorted((Path(folder) / ".bake").glob("frame_*.npz"))]
        t_usd, t_glb = [], []
        for _ in range(repeats):
            t0 = time.perf_counter()
            usd = wd.export_usd(Path(tmp) / "log.usdc", model, mesh, frames)
            t_usd.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            glb = wd.export_gltf(Path(tmp) / "log.glb", model, mesh, frames[-1], frames=frames,
                                 point_tolerance=POINT_TOLERANCE)
            t_glb.append(time.perf_counter() - t0)
        stage = Usd.Stage.Open(str(usd))
        size = usd.stat().st_size
        print(f"elements {model.n_elements} -")
        print(f"frames {len(frames)} -")
        print(f"pieces {len(wood_meshes(stage))} -")
        print(f"usd_mb {size / 1e6:.2f} MB")
        print(f"bytes_per_element_frame {size / (model.n_elements * len(frames)):.0f} B")
        print(f"export_usd_s {statistics.median(t_usd):.2f} s {spread(t_usd)}")
        print(f"glb_mb {glb.stat().st_size / 1e6:.2f} MB")
        print(f"export_gltf_s {statistics.median(t_glb):.2f} s {spread(t_glb)}")
        for name, share in written_shares(stage, len(frames)).items():
            print(f"written_{name} {share:.3f} of piece-frames")
        link = skin.links(model, mesh)
        used = np.unique(mesh.faces[exposure(model, mesh, frames) != NEVER])
        gap = 0.0
        for fr in frames:
            P, _ = skin.frame_arrays(model, mesh, link, fr, frame_bark(model, mesh, fr)[2])
            gap = max(gap, float(np.linalg.norm(wood_at(stage, float(fr.index))["points"] - P[used], axis=1).max()))
        print(f"point_error_max {gap * 1e3:.3f} mm (point_tolerance {POINT_TOLERANCE * 1e3:g} mm)")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 and sys.argv[1] != "-" else None,
         int(sys.argv[2]) if len(sys.argv) > 2 else 3)
