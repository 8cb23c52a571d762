"""The size of a bake, estimated from the scene alone before anything large is allocated (docs/model.md §7).

Strands per cross-section follow the packing rule of the strand stage, floor(phi_pack A / (pi
r_s^2)) (docs/model.md §2), so the rod elements of a skeleton edge of length L between profiles of areas
A_a and A_b number about phi_pack (A_a + A_b) / 2 / (pi r_s^2) x L / rod_length. The rest scale
with the elements, by ratios measured on the samples (:data:`PER_ELEMENT`): REG edges, meshlet
faces, output bytes per frame and the bake's peak resident memory, on top of the libraries'
:data:`BASE_BYTES`. ``benchmarks/budget.py`` prints the estimate against the built model and the
measured peak of each sample's bake.

:func:`check` refuses a scene whose estimated peak exceeds the memory available (or a given
limit) with one line naming the key that drives the size, before the bake writes anything.
"""
from __future__ import annotations

import os
from dataclasses import asdict, dataclass

import numpy as np

from .errors import InputError

#: per rod element, measured on the samples (benchmarks/budget.py, 8-day bakes of 4 and 24 frames):
#: REG edges (5.4-6.0), meshlet faces (39-43), bytes of the USD stage per frame (70-110) and of the
#: GLB with the stage's frame-independent part (300-430), peak resident bytes of a bake (42-47 KB)
#: and per frame held (160)
PER_ELEMENT = {"reg_edges": 6.0, "meshlet_faces": 42.0, "usd_frame_bytes": 110.0, "glb_bytes": 450.0,
               "peak_bytes": 55e3, "peak_frame_bytes": 200.0}
#: peak resident bytes of a bake of a few elements (Python, numpy, numba, usd-core, scipy: 290 MB)
BASE_BYTES = 330 * 2**20


@dataclass(frozen=True)
class Estimate:
    """Sizes of a bake of one scene (module docstring)."""

    strands: int
    elements: int
    reg_edges: int
    meshlet_faces: int
    output_bytes: int
    peak_bytes: int

    def as_dict(self) -> dict:
        return asdict(self)


def estimate(scene) -> Estimate:
    """The :class:`Estimate` of ``scene`` (a validated :class:`wooddecay.scene.Scene`), from its
    skeleton, ``[strands]`` and ``[time] frames`` only: microseconds for any size."""
    skel, st = scene.skeleton, scene.strands
    area = np.array([p.area for p in skel.profiles])
    per_strand = np.pi * st.r_s**2
    strands = np.floor(st.phi_pack * area / per_strand)
    child = np.flatnonzero(skel.parent >= 0)
    parent = skel.parent[child]
    length = np.linalg.norm(skel.positions[child] - skel.positions[parent], axis=1)
    elements = float(np.sum(0.5 * (strands[child] + strands[parent]) * np.maximum(length / st.rod_length, 1.0)))
    roots = float(strands[skel.parent < 0].sum())
    e = PER_ELEMENT
    frames = int(scene.time.frames)
    return Estimate(
        strands=int(roots), elements=int(round(elements)), reg_edges=int(round(e["reg_edges"] * elements)),
        meshlet_faces=int(round(e["meshlet_faces"] * elements)),
        output_bytes=int(round(elements * (e["usd_frame_bytes"] * frames + e["glb_bytes"]))),
        peak_bytes=int(round(BASE_BYTES + elements * (e["peak_bytes"] + e["peak_frame_bytes"] * frames))))


def available_bytes() -> int:
    """Memory this process may still take: ``MemAvailable`` of /proc/meminfo, else the physical
    memory (os.sysconf)."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))


def _size(n: float) -> str:
    if n >= 2**30:
        return f"{n / 2**30:.1f} GB"
    return f"{n / 2**20:.0f} MB" if n >= 2**20 else f"{n / 2**10:.0f} KB"


def check(scene, limit: int | None = None) -> Estimate:
    """The estimate of ``scene``; raises :class:`InputError` (one line: the scene file, the key
    that drives the size, the estimate and the limit) when its peak exceeds ``limit`` bytes or,
    without one, the memory available now."""
    est = estimate(scene)
    cap, what = (limit, "the --max-memory limit") if limit is not None else (available_bytes(), "the memory available")
    if est.peak_bytes > cap:
        st = scene.strands
        raise InputError(scene.source, "strands.r_s", f"{st.r_s:g} m with rod_length {st.rod_length:g} m gives about "
                         f"{est.elements:.3g} rod elements, an estimated peak of {_size(est.peak_bytes)}, over "
                         f"{what} ({_size(cap)}); raise strands.r_s or strands.rod_length")
    return est
