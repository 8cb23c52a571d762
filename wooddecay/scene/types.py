"""The frozen scene: :class:`Scene` and its read-only containers (docs/model.md §1).

A :class:`Scene` is what :func:`wooddecay.scene.load_scene` hands on: every value validated and
resolved (defaults, overrides, quality preset). Its sections are :class:`Section` namespaces
(``scene.strands.r_s``); tissue overrides, inoculations, loads and colliders are
:class:`FrozenMap` s. Everything is read-only and picklable, and :attr:`Scene.hash` identifies
the resolved scene (the USD stage records it).
"""
from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any, Iterator

from wooddecay.errors import did_you_mean
from wooddecay.scene.schema import FORMAT_UNDECLARED, SECTIONS, TISSUE_DEFAULTS, TISSUE_KEYS
from wooddecay.strands.rings import TISSUES


class FrozenMap(Mapping):
    """A read-only, picklable mapping."""

    __slots__ = ("_d",)

    def __init__(self, data: Mapping | Sequence = ()):
        object.__setattr__(self, "_d", dict(data))

    def __getitem__(self, key: str) -> Any:
        return self._d[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self._d)

    def __len__(self) -> int:
        return len(self._d)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"{type(self).__name__} is read-only")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"{type(self).__name__} is read-only")

    def __reduce__(self):
        return (type(self), (self._d,))

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self._d!r})"

    def as_dict(self) -> dict:
        """A plain, JSON-able copy (tuples become lists, nested maps become dicts)."""
        return {k: _jsonable(v) for k, v in self._d.items()}


class Section(FrozenMap):
    """One parameter section as a read-only attribute namespace: ``scene.strands.r_s``."""

    __slots__ = ("_name",)

    def __init__(self, name: str, data: Mapping):
        object.__setattr__(self, "_name", name)
        super().__init__(data)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        try:
            return self._d[name]
        except KeyError:
            raise AttributeError(f"[{self._name}] has no parameter {name!r}"
                                 f"{did_you_mean(name, self._d)}") from None

    def __dir__(self):
        return list(super().__dir__()) + list(self._d)

    def __reduce__(self):
        return (type(self), (self._name, self._d))

    def __repr__(self) -> str:
        return f"Section[{self._name}]({self._d!r})"


def _jsonable(v: Any) -> Any:
    if isinstance(v, Mapping):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, Path):
        return str(v)
    return v


@dataclass(frozen=True, eq=False)
class Scene:
    """A validated scene; every value resolved (defaults, overrides, quality preset).

    Sections are read-only namespaces (``scene.fungi.alpha_w0``, ``scene.time.days``,
    ``scene.strands.as_dict()``). Compare scenes by :attr:`hash`.
    """

    name: str
    seed: int
    quality: str
    description: str
    path: Path | None
    base_dir: Path
    source: str
    skeleton: Any  # wooddecay.strands.skeleton.Skeleton
    strands: Section
    rings: Section
    bsp: Section
    weakpoints: Section
    transport: Section
    fungi: Section
    moisture: Section
    climate: Section
    wood: Section
    mechanics: Section
    time: Section
    bark: Section
    export: Section
    tissues: FrozenMap  # tissue -> FrozenMap of overrides (all four tissues present)
    inoculations: tuple[FrozenMap, ...]
    loads: tuple[FrozenMap, ...]
    colliders: tuple[FrozenMap, ...]
    #: the scene file's format (``[scene] format``); how the file was read, not part of :attr:`hash`
    format: int = FORMAT_UNDECLARED

    def section(self, name: str) -> Section:
        """The :class:`Section` called ``name`` (``scene`` gives format/name/seed/quality/description)."""
        if name == "scene":
            return Section("scene", {"format": self.format, "name": self.name, "seed": self.seed,
                                     "quality": self.quality, "description": self.description})
        if name not in SECTIONS:
            raise KeyError(name)
        return getattr(self, name)

    def param(self, key: str) -> Any:
        """Resolved value of a dotted key, e.g. ``scene.param("fungi.alpha_w0")``."""
        section, _, name = key.partition(".")
        try:
            return self.section(section)[name]
        except KeyError:
            raise KeyError(f"no parameter {key!r}") from None

    def tissue_param(self, tissue: str, name: str) -> Any:
        """Value of ``name`` (``alpha_w0`` or ``fungi.alpha_w0``) in ``tissue``: its override,
        else the section value, with the tissue's default (:data:`TISSUE_DEFAULTS`) applied."""
        if tissue not in self.tissues:
            raise KeyError(f"unknown tissue {tissue!r}; tissues are {', '.join(TISSUES)}")
        section, dot, bare = name.rpartition(".")
        if bare not in TISSUE_KEYS or (dot and TISSUE_KEYS[bare].section != section):
            raise KeyError(f"{name!r} is not a per-tissue parameter")
        over = self.tissues[tissue]
        if bare in over:
            return over[bare]
        value = getattr(self, TISSUE_KEYS[bare].section)[bare]
        default = TISSUE_DEFAULTS.get(tissue, {}).get(bare)
        if default is None:
            return value
        return value * default.value if default.relative else default.value

    def to_dict(self) -> dict:
        """The resolved scene as plain JSON-able data (values after the quality preset; not meant
        to be fed back as a scene file). The file's ``format`` is left out: it says how the file
        was read, not what is simulated, so :attr:`hash` (and the caches and stages that record
        it) is the same whether a scene declares ``format = 1`` or not."""
        out: dict[str, Any] = {
            "scene": {"name": self.name, "seed": self.seed, "quality": self.quality,
                      "description": self.description},
            "skeleton": _skeleton_dict(self.skeleton),
        }
        for sec in SECTIONS:
            if sec != "scene":
                out[sec] = getattr(self, sec).as_dict()
        out["tissue"] = self.tissues.as_dict()
        out["inoculation"] = [m.as_dict() for m in self.inoculations]
        out["load"] = [m.as_dict() for m in self.loads]
        out["collider"] = [m.as_dict() for m in self.colliders]
        out["path"] = None if self.path is None else str(self.path)
        out["base_dir"] = str(self.base_dir)
        return out

    @cached_property
    def hash(self) -> str:
        """sha256 (hex) of the canonical JSON of :meth:`to_dict` without paths (scene path,
        base directory, skeleton source file)."""
        return _digest(self._hashed())

    @cached_property
    def settle_hash(self) -> str:
        """:attr:`hash` without the keys the settled rods do not depend on: [time], [export], [climate], [bark],
        the [[inoculation]]s (they set the fungal activity R_w, R_b, which the rods never see) and
        the scene's name and description (the key of the settled-state cache,
        :mod:`wooddecay.sim.settled`)."""
        return _digest(self._identity_free(("time", "export", "climate", "bark", "inoculation")))

    @cached_property
    def model_hash(self) -> str:
        """:attr:`hash` without the keys the built model's geometry and solvers do not depend on:
        [time], [export] and the scene's name and description (variants of a batch that differ
        only there share one built model, :func:`wooddecay.model.retimed`)."""
        return _digest(self._identity_free(("time", "export")))

    def _identity_free(self, sections: tuple[str, ...]) -> dict:
        """:meth:`_hashed` without ``sections`` and the scene's name and description."""
        d = self._hashed()
        for key in sections:
            d.pop(key)
        d["scene"] = {k: v for k, v in d["scene"].items() if k not in ("name", "description")}
        return d

    def _hashed(self) -> dict:
        d = self.to_dict()
        d.pop("path", None)
        d.pop("base_dir", None)
        d["skeleton"].pop("source", None)
        for (section, key), value in NEUTRAL_DEFAULTS.items():
            if d[section].get(key) == value:
                del d[section][key]
        return d


#: keys added after format 1 whose default is what every scene did before them, or that change only
#: how the outputs are written: at that value they stay out of the hashes, so earlier bakes,
#: settled caches and resumable checkpoints still match
NEUTRAL_DEFAULTS = {("mechanics", "solver"): "xpbd", ("mechanics", "residual_tolerance"): 0.01,
                    ("export", "point_tolerance"): 2e-4, ("export", "field_step"): 2e-3}


def _digest(d: dict) -> str:
    text = json.dumps(d, sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def _skeleton_dict(skel: Any) -> dict:
    nodes = []
    ids = list(skel.ids)
    for i, nid in enumerate(ids):
        prof = skel.profiles[i]
        pd: dict[str, Any] = {"kind": prof.kind}
        pd.update({str(k): float(v) for k, v in prof.params})
        if prof.kind == "polygon":
            pd["points"] = [[float(a), float(b)] for a, b in prof.polygon]
        par = int(skel.parent[i])
        nodes.append({
            "id": nid,
            "position": [float(x) for x in skel.positions[i]],
            "parent": None if par < 0 else ids[par],
            "profile": pd,
            "anchored": bool(skel.anchored[i]),
        })
    return {"source": str(skel.source), "nodes": nodes}
