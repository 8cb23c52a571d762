"""Regions of the wood: where an inoculation starts or a load pulls (docs/model.md §3 "Inoculation",
§4 "Loads"; woodstock Fig. 17).

A region is a box or sphere in world or wood-local coordinates (r, phi, s), a sphere around a
skeleton node, a log end (elements within ``depth`` of the root, or of a branch's tip, along the
skeleton) or a bark wound (a sphere on the surface, restricted to bark distance < depth). A
region selects the elements whose centre lies in it.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .. import fmath as fm


def _wood_cartesian(wood_coords: np.ndarray) -> np.ndarray:
    r, phi, s = wood_coords.T
    return np.stack([r * fm.cos(phi), r * fm.sin(phi), s], axis=1)


def region_mask(model, region: Mapping) -> np.ndarray:
    """(n,) bool: the elements of ``model`` whose centre lies in ``region`` (module docstring)."""
    kind = region["kind"]
    wood = region.get("space", "world") == "wood"
    if kind == "box":
        x = model.wood_coords if wood else model.centers
        lo, hi = np.asarray(region["min"]), np.asarray(region["max"])
        return np.all((x >= lo) & (x <= hi), axis=1)
    if kind == "sphere":
        if wood:
            x = _wood_cartesian(model.wood_coords)
            r, phi, s = region["center"]
            c = np.array([r * fm.cos(phi), r * fm.sin(phi), s])
        else:
            x, c = model.centers, np.asarray(region["center"])
        return np.linalg.norm(x - c, axis=1) <= region["radius"]
    if kind == "node":
        skel = model.skeleton
        c = skel.positions[skel.ids.index(str(region["id"]))]
        return np.linalg.norm(model.centers - c, axis=1) <= region["radius"]
    if kind == "end":
        s = model.wood_coords[:, 2]
        if region.get("which", "root") == "root":
            return s <= region["depth"]
        s_end = np.zeros(model.n_branches)
        np.maximum.at(s_end, model.branch, s)
        return s_end[model.branch] - s <= region["depth"]
    if kind == "wound":
        near = np.linalg.norm(model.centers - np.asarray(region["position"]), axis=1) <= region["radius"]
        return near & (model.bark_distance <= region["depth"])
    raise ValueError(f"unknown region kind {kind!r}")  # the scene validator rules this out
