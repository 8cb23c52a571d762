"""Property tests: no input makes scene loading raise anything but a one-line InputError
(docs/model.md §1; wooddecay.scene.load through schema and validate)."""
from __future__ import annotations

import json
import math
import string

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from wooddecay import scene as P
from wooddecay.errors import InputError
from wooddecay.scene import parse_scene, parse_set_option

from .conftest import SKELETON


ALL_KEYS = sorted({name for table in P.PARAMS.values() for name in table}
                  | {"fungus", "activity", "day", "region", "kind", "space", "min", "max", "center", "radius",
                     "id", "which", "depth", "position", "force", "days", "node", "file", "scale", "format",
                     "profile", "parent", "anchored", "a", "b", "angle", "points"})
TOP_KEYS = sorted(set(P.PARAMS) | {"skeleton", "tissue", "inoculation", "load"} | set(P.TISSUES))
NAMES = st.sampled_from(ALL_KEYS + TOP_KEYS) | st.text(string.ascii_letters + string.digits + "_-", min_size=1,
                                                       max_size=8)

finite = st.floats(allow_nan=False, allow_infinity=False)
SCALARS = (st.integers(-10, 10) | st.integers() | st.floats() | finite.map(lambda x: x / 1e6)
           | st.booleans() | st.text(max_size=8) | st.sampled_from(["white", "brown", "draft", "final", "box",
                                                                     "sphere", "node", "end", "wound", "root",
                                                                     "tip", "wood", "world"]))


def near_valid(p: P.Param):
    """Values around a parameter's range (to get past validation and into later checks)."""
    if p.kind in ("float", "int"):
        lo = p.lo if p.lo is not None else -10.0
        hi = p.hi if p.hi is not None else 10.0
        pts = [lo, hi, (lo + hi) / 2]
        if p.default is not None:
            pts.append(p.default)
        base = st.sampled_from(pts) | st.floats(min_value=lo, max_value=hi)
        return base.map(lambda x: int(x) if p.kind == "int" else x)
    if p.kind == "enum":
        return st.sampled_from(p.choices)
    if p.kind == "vec3":
        return st.lists(finite, min_size=3, max_size=3)
    if p.kind == "list":
        return st.lists(st.tuples(st.floats(0, 400), st.floats(0.5, 2), st.floats(0, 0.4)).map(list), max_size=3)
    if p.kind == "bool":
        return st.booleans()
    return st.text(max_size=8)


def values(depth=2):
    if depth == 0:
        return SCALARS
    return st.one_of(SCALARS, st.lists(values(depth - 1), max_size=4),
                     st.dictionaries(NAMES, values(depth - 1), max_size=4))


@st.composite
def section_table(draw, sec):
    out = {}
    params = draw(st.lists(st.sampled_from(list(P.PARAMS[sec].values())), max_size=4, unique_by=lambda p: p.name))
    for p in params:
        out[p.name] = draw(near_valid(p) | values(1))
    if draw(st.booleans()):
        out.update(draw(st.dictionaries(NAMES, values(1), max_size=2)))
    return out


def region_strategy():
    v3 = st.lists(st.floats(-1, 1) | st.integers(-2, 2), min_size=3, max_size=3)
    pos = st.floats(0.001, 1)
    return st.one_of(
        st.fixed_dictionaries({"kind": st.just("box"), "min": v3, "max": v3}),
        st.fixed_dictionaries({"kind": st.just("sphere"), "center": v3, "radius": pos},
                              optional={"space": st.sampled_from(["world", "wood", "x"])}),
        st.fixed_dictionaries({"kind": st.just("node"), "id": st.sampled_from(["root", "tip", "x", 1]),
                               "radius": pos}),
        st.fixed_dictionaries({"kind": st.just("end"), "depth": pos},
                              optional={"which": st.sampled_from(["root", "tip", "mid"])}),
        st.fixed_dictionaries({"kind": st.just("wound"), "position": v3, "radius": pos, "depth": pos}),
        st.dictionaries(NAMES, values(1), max_size=4),
    )


@st.composite
def scene_documents(draw):
    doc: dict = {}
    if draw(st.integers(0, 9)) > 0:
        doc["skeleton"] = {"node": [
            {"id": "root", "position": [0, 0, 0], "profile": {"kind": "circle", "radius": 0.1}},
            {"id": "tip", "position": [0, 0, 1], "parent": "root", "profile": {"kind": "circle", "radius": 0.08}},
        ]}
        if draw(st.integers(0, 5)) == 0:
            doc["skeleton"].update(draw(st.dictionaries(NAMES, values(2), max_size=2)))
    for sec in draw(st.lists(st.sampled_from(list(P.PARAMS)), max_size=5, unique=True)):
        doc[sec] = draw(section_table(sec))
    if draw(st.booleans()):
        doc["tissue"] = draw(st.dictionaries(
            st.sampled_from(list(P.TISSUES)) | NAMES,
            st.dictionaries(st.sampled_from(sorted(P.TISSUE_KEYS)) | NAMES,
                            st.sampled_from(list(P.TISSUE_KEYS.values())).flatmap(near_valid) | values(1),
                            max_size=3) | values(1),
            max_size=3))
    if draw(st.booleans()):
        doc["inoculation"] = draw(st.lists(st.fixed_dictionaries(
            {"fungus": st.sampled_from(["white", "brown", "grey"]), "region": region_strategy()},
            optional={"activity": st.floats(0, 1.2) | values(0), "day": st.floats(-1, 100) | values(0),
                      "extra": values(1)}) | values(1), max_size=3))
    if draw(st.booleans()):
        doc["load"] = draw(st.lists(st.fixed_dictionaries(
            {"region": region_strategy(), "force": st.lists(st.floats(-10, 10), min_size=3, max_size=3) | values(1),
             "days": st.lists(st.floats(-1, 10), min_size=2, max_size=2) | values(1)}) | values(1), max_size=2))
    if draw(st.booleans()):
        doc.update(draw(st.dictionaries(NAMES, values(2), max_size=3)))
    return doc


def toml_string(text: str) -> str:
    """A TOML basic string (escapes for quotes, backslashes, control and non-ASCII characters)."""
    out = []
    for ch in text:
        c = ord(ch)
        if ch in '"\\':
            out.append("\\" + ch)
        elif 32 <= c < 127:
            out.append(ch)
        elif c <= 0xFFFF:
            out.append(f"\\u{c:04x}")
        else:
            out.append(f"\\U{c:08x}")
    return '"' + "".join(out) + '"'


def toml_key(k: str) -> str:
    return toml_string(k)


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return toml_string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(doc: dict) -> str:
    return "\n".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in doc.items()) + "\n"


def only_input_errors(fn, *args, **kw):
    try:
        fn(*args, **kw)
    except InputError as err:
        assert "\n" not in str(err) and err.file


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=300) | st.binary(max_size=300))
def test_fuzz_random_text_and_bytes(data):
    only_input_errors(parse_scene, data, source="fuzz.toml")


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.sampled_from(list("[]{}=\"'.,#\n \t-+_0123456789aeinftrus") + ALL_KEYS + TOP_KEYS),
                max_size=60).map(lambda parts: "".join(parts) + "\n" + SKELETON))
def test_fuzz_toml_like_text(text):
    only_input_errors(parse_scene, text, source="fuzz.toml")


@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(scene_documents())
def test_fuzz_random_documents(doc):
    text = to_toml(doc)
    try:
        s = parse_scene(text, source="fuzz.toml")
    except InputError as err:
        assert "\n" not in str(err) and err.file == "fuzz.toml"
        return
    json.dumps(s.to_dict(), allow_nan=False)
    assert len(s.hash) == 64


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(
    st.sampled_from([p.key for t in P.PARAMS.values() for p in t.values()]
                    + [f"tissue.{t}.{k}" for t in P.TISSUES for k in ("alpha_w0", "M_2", "mu_f")])
    | st.text(max_size=20),
    values(1), max_size=4))
def test_fuzz_overrides(over):
    only_input_errors(parse_scene, SKELETON, source="fuzz.toml", overrides=over)
    items = [f"{k}={toml_value(v)}" for k, v in over.items()]
    try:
        parsed = parse_set_option(items)
    except InputError as err:
        assert err.file == "<--set>"
        return
    only_input_errors(parse_scene, SKELETON, source="fuzz.toml", overrides=parsed)
