"""The size estimate of wooddecay/budget.py against the built model and the measured peak memory
of a short bake of each sample (a child process; its ru_maxrss).

    python benchmarks/budget.py [--frames N] [SCENE ...]        (default: the tiny, log, board, trunk and tree samples)

Prints per scene ``name value unit`` lines: elements_estimate / elements_built, reg_edges
estimate / built, meshlet faces estimate / built, output MB
estimate / written, peak_estimate_mb, peak_measured_mb and peak_ratio (measured / estimated; the
tests hold it in (0.5, 1) on tiny), and the estimate's own time. The bake runs 8 days in 4 frames
(settling, meshing and export as in a full bake; the frames' share of the peak is small).
"""
from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import wooddecay as wd
from wooddecay import budget

from timing import SAMPLES

ARGS = {"time.days": 8.0, "time.frames": 4}


#: runs the bake given as its arguments in a child and prints that child's peak (ru_maxrss, KiB):
#: a wrapper per bake, since RUSAGE_CHILDREN keeps the largest child of a process
WRAPPER = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
           "print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); print(r.stderr[-300:])")


def peak_of_bake(scene_path: Path) -> tuple[int, dict]:
    """Peak resident bytes of ``wooddecay bake`` on ``scene_path`` (:data:`ARGS`) and its summary."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "wooddecay.cli", "bake", str(scene_path), "-o", tmp, "--days",
               str(ARGS["time.days"]), "--frames", str(ARGS["time.frames"])]
        out = subprocess.run([sys.executable, "-c", WRAPPER, *cmd], capture_output=True, text=True).stdout
        code, kib = out.split("\n", 1)[0].split()
        if code != "0":
            raise SystemExit(f"{scene_path}: bake failed: {out}")
        return int(kib) * 1024, json.loads((Path(tmp) / "summary.json").read_text("utf-8"))


def main(paths: list[Path]) -> None:
    for path in paths:
        scene = wd.load_scene(path, ARGS)
        t0 = time.perf_counter()
        est = budget.estimate(scene)
        est_s = time.perf_counter() - t0
        model = wd.build_model(scene)
        peak, summary = peak_of_bake(path)
        name = scene.name
        written = sum(o["bytes"] for o in summary["outputs"].values())
        print(f"{name}_elements {est.elements} / {model.n_elements} estimate / built")
        print(f"{name}_reg_edges {est.reg_edges} / {model.n_edges} estimate / built")
        print(f"{name}_meshlet_faces {est.meshlet_faces} / {summary['counts']['meshlet_faces']} estimate / built")
        print(f"{name}_output_mb {est.output_bytes / 2**20:.1f} / {written / 2**20:.1f} MB estimate / written")
        print(f"{name}_peak_estimate_mb {est.peak_bytes / 2**20:.0f} MB")
        print(f"{name}_peak_measured_mb {peak / 2**20:.0f} MB")
        print(f"{name}_peak_ratio {peak / est.peak_bytes:.2f} - (measured / estimated)")
        print(f"{name}_estimate_seconds {est_s:.2e} s")
        sys.stdout.flush()


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--frames" in args:  # the frames' share of the peak and of the outputs
        i = args.index("--frames")
        ARGS["time.frames"] = int(args[i + 1])
        del args[i:i + 2]
    names = args or [str(SAMPLES / f"{n}.toml") for n in ("tiny", "log", "board", "trunk", "tree")]
    main([Path(n) for n in names])
