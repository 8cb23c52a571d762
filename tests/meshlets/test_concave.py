"""Concave and elongated profiles (woodstock §8.1 on arbitrary cross-sections): the meshlets fill
a star, a C (its inner arc in a few long edges, and in many short ones as a scan's contour gives it)
and a 6:1 ellipse to their tips, and a part no strand can reach gets a note."""
from __future__ import annotations

import numpy as np
import pytest

import wooddecay as wd
from wooddecay.meshlets import checks
from wooddecay.meshlets.sweep import build_meshlets
from wooddecay.strands.profiles import narrow_area, polygon_area

R_S = 0.003


def star(r_out: float, r_in: float, arms: int = 5) -> list:
    a = np.pi / 2 + np.arange(2 * arms) * np.pi / arms
    r = np.where(np.arange(2 * arms) % 2 == 0, r_out, r_in)
    return np.column_stack([r * np.cos(a), r * np.sin(a)]).tolist()


def c_shape(r_out: float, r_in: float, n: int = 24) -> list:
    """A ring with a 90 degree gap, counter-clockwise."""
    a = np.linspace(np.pi / 4, 2 * np.pi - np.pi / 4, n)
    outer = np.column_stack([r_out * np.cos(a), r_out * np.sin(a)])
    inner = np.column_stack([r_in * np.cos(a[::-1]), r_in * np.sin(a[::-1])])
    return np.vstack([outer, inner]).tolist()


def arm(width: float) -> list:
    """A 60 mm square with a 50 mm arm of ``width`` on its right side."""
    h = width / 2
    return [[-0.03, -0.03], [0.03, -0.03], [0.03, -h], [0.08, -h], [0.08, h], [0.03, h], [0.03, 0.03],
            [-0.03, 0.03]]


PROFILES = {
    "star": {"kind": "polygon", "points": star(0.07, 0.03)},
    "C": {"kind": "polygon", "points": c_shape(0.06, 0.036)},
    "C of a scan": {"kind": "polygon", "points": c_shape(0.06, 0.036, n=96)},  # vertices r_s apart
    "ellipse 6:1": {"kind": "ellipse", "a": 0.09, "b": 0.015},
    "circle": {"kind": "circle", "radius": 0.06},
}


def prism(profile: dict, length: float = 0.3) -> wd.WoodModel:
    """The model of a straight prism of one profile along x."""
    return wd.build_model(wd.parse_scene({
        "scene": {"name": "prism", "seed": 1},
        "skeleton": {"node": [{"id": "a", "position": [0.0, 0.0, 0.1], "profile": profile},
                              {"id": "b", "position": [length, 0.0, 0.1], "parent": "a", "profile": profile}]},
        "strands": {"r_s": R_S, "rod_length": 10 * R_S},
        "rings": {"ring_width": 2 * R_S, "bark_thickness": 2 * R_S},
        "bsp": {"cells": 4},
        "time": {"days": 1, "frames": 1}}))


@pytest.mark.parametrize("name", list(PROFILES))
def test_meshlets_fill_concave_and_elongated_profiles(name):
    model = prism(PROFILES[name])
    mesh = build_meshlets(model)
    vol = checks.volumes(mesh)
    ref = checks.bark_volume(model)
    err = vol.sum() / ref - 1.0
    print(f"{name}: {mesh.count} meshlets, volume {vol.sum():.6f} m^3 against {ref:.6f} m^3, error {err:+.3%}")
    assert checks.closed_oriented(mesh).all() and (vol > 0).all()
    assert mesh.stats["hull_repairs"] == 0
    assert abs(err) < 5e-3
    assert model.notes == ()  # every part of these profiles is wider than a strand


def test_bark_volume_of_a_prism_is_its_area_times_length():
    model = prism(PROFILES["C"], length=0.3)
    area = polygon_area(np.array(PROFILES["C"]["points"]))
    assert checks.bark_volume(model) == pytest.approx(0.3 * area, rel=1e-12)


def test_narrow_area_of_an_arm_thinner_than_a_strand():
    """A 4 mm arm is narrower than a strand (2 r_s = 6 mm): all of it (50 mm x 4 mm) is out of
    reach; the square's convex corners ((1 - pi / 4) r_s^2 each) are smaller separate parts."""
    expected = 0.05 * 0.004
    got = narrow_area(np.array(arm(0.004)), R_S)
    print(f"narrow area {got * 1e6:.1f} mm^2, expected {expected * 1e6:.1f} mm^2")
    assert got == pytest.approx(expected, rel=0.05)
    assert narrow_area(np.array(arm(0.012)), R_S) < 4 * np.pi * R_S**2  # a 12 mm arm holds strands


def test_a_part_no_strand_reaches_gets_one_note_per_profile():
    model = prism({"kind": "polygon", "points": arm(0.004)})
    print("\n".join(model.notes))
    assert len(model.notes) == 2
    assert [n.split(":")[0] for n in model.notes] == ["skeleton.node[a].profile", "skeleton.node[b].profile"]
    assert all("a part of 2 cm^2 is narrower than a strand (2 r_s = 6 mm)" in n for n in model.notes)
