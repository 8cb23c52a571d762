"""Debug view of the strand group as USD BasisCurves (woodstock Fig. 3b).

``write_strands_usd(path, model)`` writes one linear, non-periodic ``BasisCurves`` prim
``/World/<scene name>/Strands`` with one curve per strand through its particles. Per vertex it
carries ``widths`` (= 2 r_s of the strand's elements), the integer ``tissue`` (0 bark, 1 sapwood,
2 heartwood, 3 pith), the float ``ring`` age in years from the pith and a ``displayColor`` by
tissue. A particle takes the values of the element it starts; the last particle of a strand,
which starts none, those of the strand's last element. The stage is Z up with metres as units.

All arrays are built with numpy from the model's CSR offsets (no Python loop over particles or
elements). The file is written atomically: the stage is exported to a hidden temporary file in
the same folder that keeps the real extension last (USD picks the format from the suffix), then
renamed over ``path``. The folder must exist (USD would create missing ones silently); a bad
path or a failed write raises :class:`~wooddecay.errors.InputError`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..wood import WoodModel
from . import stage as stage_mod

#: display colour per tissue index (bark, sapwood, heartwood, pith), linear-ish RGB in [0, 1]
TISSUE_COLORS = np.array([
    [0.23, 0.14, 0.08],   # bark: dark brown
    [0.93, 0.86, 0.58],   # sapwood: pale yellow
    [0.55, 0.25, 0.15],   # heartwood: reddish brown
    [0.45, 0.05, 0.05],   # pith: dark red
], dtype=np.float32)

def vertex_element(model: WoodModel) -> np.ndarray:
    """Index of the element whose values each particle takes (length ``n_particles``).

    Particle j of strand k (local index i) takes element ``element_offsets[k] + min(i, n_k - 1)``
    where n_k is the strand's element count.
    """
    p_off = np.asarray(model.particle_offsets, dtype=np.int64)
    e_off = np.asarray(model.element_offsets, dtype=np.int64)
    n_part = np.diff(p_off)
    n_elem = np.diff(e_off)
    strand_of = np.repeat(np.arange(len(n_part)), n_part)
    local = np.arange(int(p_off[-1]), dtype=np.int64) - p_off[strand_of]
    local = np.minimum(local, np.maximum(n_elem[strand_of] - 1, 0))
    return e_off[strand_of] + local


def check_usd_path(path) -> Path:
    """``path`` as a Path after checking it can name a strands USD file (suffix, folder)."""
    return stage_mod.check_usd_path(path, "strands")


def write_strands_usd(path, model) -> Path:
    """Write the strands of ``model`` as USD BasisCurves to ``path`` (.usda, .usdc or .usd).

    Raises
    ------
    InputError
        For a bad path (:func:`check_usd_path`) or when the file cannot be written.
    """
    from pxr import Gf, Sdf, UsdGeom, Vt

    path = check_usd_path(path)

    p_off = np.asarray(model.particle_offsets, dtype=np.int64)
    e_off = np.asarray(model.element_offsets, dtype=np.int64)
    counts = np.diff(p_off).astype(np.int32)
    if not np.array_equal(counts.astype(np.int64), np.diff(e_off) + 1):
        raise ValueError("each strand must have one more particle than elements")
    points = np.ascontiguousarray(model.particles, dtype=np.float32)
    src = vertex_element(model)
    tissue = np.asarray(model.tissue)[src].astype(np.int32)
    ring = np.asarray(model.ring_age)[src].astype(np.float32)
    widths = (2.0 * np.asarray(model.radius)[src]).astype(np.float32)
    colors = TISSUE_COLORS[np.clip(tissue, 0, len(TISSUE_COLORS) - 1)]

    stage, root = stage_mod.new_stage(model.info.name)
    curves = UsdGeom.BasisCurves.Define(stage, f"{root}/Strands")
    curves.CreateTypeAttr(UsdGeom.Tokens.linear)
    curves.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
    curves.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy(counts))
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    curves.CreateWidthsAttr(Vt.FloatArray.FromNumpy(widths))
    curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    if len(points):
        lo, hi = points.min(axis=0), points.max(axis=0)
        r = float(widths.max()) / 2.0
        curves.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*(lo - r).tolist()), Gf.Vec3f(*(hi + r).tolist())]))

    pv = UsdGeom.PrimvarsAPI(curves)
    pv.CreatePrimvar("tissue", Sdf.ValueTypeNames.IntArray, UsdGeom.Tokens.vertex).Set(
        Vt.IntArray.FromNumpy(tissue))
    pv.CreatePrimvar("ring", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex).Set(
        Vt.FloatArray.FromNumpy(ring))
    color = curves.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex)
    color.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(colors)))

    return stage_mod.export_atomic(stage, path, "strands")
