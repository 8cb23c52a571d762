"""Compare two USD stages (``wooddecay diff``; docs/architecture.md "CLI").

:func:`compare_usd` returns the list of :class:`Difference` between stage ``a`` and stage ``b``:

* layer metadata (upAxis, metersPerUnit, time codes per second, start and end time codes, default
  prim) and customLayerData;
* prim paths and their types (prims only in one stage);
* per prim: the authored attributes, their value types and ``interpolation`` metadata, their time
  samples, and their values at every time sample (or the default value): numbers compared as
  arrays with |a - b| <= atol + rtol |b|, reporting the largest absolute and relative error;
  anything else (tokens, strings, topology counts) exactly;
* relationships (e.g. material bindings) by their targets.

Stages of two formats (a bake of an older wooddecay against one of this) are compared by what
they hold: the layer metadata without the keys that say how it was written, and the wood of each
at every frame as one mesh in the bake's order (:func:`wooddecay.export.wood_read.wood_at`:
world points, faces, every primvar flattened), under the same tolerances.

A file that cannot be opened, or a stage of a newer format than this wooddecay reads
(customLayerData ``format_version``, :func:`wooddecay.export.usd.stage_format`; a stage without it
is format 1), raises :class:`~wooddecay.errors.InputError` (exit 2 in the CLI).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class Difference:
    path: str  # prim or attribute path ("" for the layer)
    what: str  # short kind: metadata, prim, type, attribute, interpolation, samples, value
    detail: str
    max_abs: float = 0.0
    max_rel: float = 0.0

    def __str__(self) -> str:
        numeric = self.what == "value" and (self.max_abs or self.max_rel)
        err = f"  (max abs {self.max_abs:.3g}, max rel {self.max_rel:.3g})" if numeric else ""
        return f"{self.what:<13} {self.path or '<layer>'}: {self.detail}{err}"


def _open(path):
    from pxr import Tf, Usd

    p = Path(path)
    if not p.is_file():
        raise InputError(str(p), "", "no such USD file")
    try:
        stage = Usd.Stage.Open(str(p))
    except Tf.ErrorException as err:
        raise InputError(str(p), "", f"not a readable USD file: {str(err).splitlines()[-1].strip()}") from None
    if stage is None:
        raise InputError(str(p), "", "not a readable USD file")
    from .usd import stage_format

    return stage, stage_format(stage.GetRootLayer().customLayerData, p)  # a newer stage is refused


def _as_array(v):
    try:
        a = np.asarray(v)
    except Exception:
        return None
    if a.dtype.kind in "fiub" and a.size == np.asarray(a, dtype=float).size:
        return a.astype(float)
    return None


def _compare_values(path, va, vb, rtol, atol, where, out):
    a, b = _as_array(va), _as_array(vb)
    if a is None or b is None:
        if va != vb:
            out.append(Difference(path, "value", f"{where}: {str(va)[:60]!r} != {str(vb)[:60]!r}"))
        return
    if a.shape != b.shape:
        out.append(Difference(path, "value", f"{where}: shape {a.shape} != {b.shape}"))
        return
    if a.size == 0:
        return
    d = np.abs(a - b)
    bad = ~(d <= atol + rtol * np.abs(b))
    if bad.any():
        rel = d / np.maximum(np.abs(b), 1e-300)
        out.append(Difference(path, "value", f"{where}: {int(bad.sum())} of {a.size} values differ",
                              float(d.max()), float(rel[np.isfinite(rel)].max(initial=0.0))))


def compare_usd(a, b, rtol: float = 1e-6, atol: float = 1e-9) -> list[Difference]:
    """Differences between the USD files ``a`` and ``b`` (module docstring)."""
    from pxr import Usd, UsdGeom

    (sa, fa), (sb, fb) = _open(a), _open(b)
    out: list[Difference] = []
    meta = (("upAxis", UsdGeom.GetStageUpAxis), ("metersPerUnit", UsdGeom.GetStageMetersPerUnit),
            ("timeCodesPerSecond", Usd.Stage.GetTimeCodesPerSecond),
            ("startTimeCode", Usd.Stage.GetStartTimeCode), ("endTimeCode", Usd.Stage.GetEndTimeCode),
            ("defaultPrim", lambda s: s.GetRootLayer().defaultPrim))
    for name, get in meta:
        if get(sa) != get(sb):
            out.append(Difference("", "metadata", f"{name} {get(sa)!r} != {get(sb)!r}"))
    ca, cb = dict(sa.GetRootLayer().customLayerData), dict(sb.GetRootLayer().customLayerData)
    if fa != fb:
        for k in WRITING:
            ca.pop(k, None)
            cb.pop(k, None)
    for k in sorted(set(ca) | set(cb)):
        if k not in ca or k not in cb:
            out.append(Difference("", "metadata", f"customLayerData[{k}] only in {'a' if k in ca else 'b'}"))
        else:
            _compare_values("", ca[k], cb[k], rtol, atol, f"customLayerData[{k}]", out)
    if fa != fb:
        _compare_wood(sa, sb, a, b, rtol, atol, out)
        return out
    pa = {str(p.GetPath()): p for p in sa.Traverse()}
    pb = {str(p.GetPath()): p for p in sb.Traverse()}
    for path in sorted(set(pa) ^ set(pb)):
        out.append(Difference(path, "prim", f"only in {'a' if path in pa else 'b'}"))
    for path in sorted(set(pa) & set(pb)):
        xa, xb = pa[path], pb[path]
        if xa.GetTypeName() != xb.GetTypeName():
            out.append(Difference(path, "type", f"{xa.GetTypeName()} != {xb.GetTypeName()}"))
            continue
        _compare_prim(xa, xb, rtol, atol, out)
    return out


def _compare_prim(xa, xb, rtol, atol, out):
    aa = {at.GetName(): at for at in xa.GetAuthoredAttributes()}
    ab = {at.GetName(): at for at in xb.GetAuthoredAttributes()}
    base = str(xa.GetPath())
    for name in sorted(set(aa) ^ set(ab)):
        out.append(Difference(f"{base}.{name}", "attribute", f"only in {'a' if name in aa else 'b'}"))
    for name in sorted(set(aa) & set(ab)):
        ta, tb = aa[name], ab[name]
        path = f"{base}.{name}"
        if ta.GetTypeName() != tb.GetTypeName():
            out.append(Difference(path, "type", f"{ta.GetTypeName()} != {tb.GetTypeName()}"))
            continue
        ia, ib = ta.GetMetadata("interpolation"), tb.GetMetadata("interpolation")
        if ia != ib:
            out.append(Difference(path, "interpolation", f"{ia} != {ib}"))
        sa_, sb_ = ta.GetTimeSamples(), tb.GetTimeSamples()
        if list(sa_) != list(sb_):
            out.append(Difference(path, "samples", f"{len(sa_)} time samples != {len(sb_)}"))
            continue
        if not sa_:
            _compare_values(path, ta.Get(), tb.Get(), rtol, atol, "default", out)
        for t in sa_:
            _compare_values(path, ta.Get(t), tb.Get(t), rtol, atol, f"time {t:g}", out)
    ra = {r.GetName(): [str(t) for t in r.GetTargets()] for r in xa.GetAuthoredRelationships()}
    rb = {r.GetName(): [str(t) for t in r.GetTargets()] for r in xb.GetAuthoredRelationships()}
    for name in sorted(set(ra) | set(rb)):
        if ra.get(name) != rb.get(name):
            out.append(Difference(f"{base}.{name}", "relationship", f"{ra.get(name)} != {rb.get(name)}"))


#: customLayerData keys that say how a stage is written, not what it holds
WRITING = ("format_version", "point_tolerance", "field_step")


def _compare_wood(sa, sb, a, b, rtol, atol, out):
    """Stages of two formats: the wood of each (:func:`wooddecay.export.wood_read.wood_at`)
    compared array by array at every frame."""
    from .wood_read import wood_at

    start, end = int(sa.GetStartTimeCode()), int(sa.GetEndTimeCode())
    for t in range(start, end + 1):
        wa, wb = wood_at(sa, t, a), wood_at(sb, t, b)
        for name in sorted(set(wa) ^ set(wb)) if t == start else ():
            out.append(Difference(f"wood.{name}", "attribute", f"only in {'a' if name in wa else 'b'}"))
        for name in sorted(set(wa) & set(wb)):
            _compare_values(f"wood.{name}", wa[name], wb[name], rtol, atol, f"time {t:g}", out)
