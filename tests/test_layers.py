"""The import rules of docs/architecture.md ("Layers"), checked on every module of the package.

Every ``import`` statement counts, function-local ones included; imports under
``if TYPE_CHECKING:`` are annotations only and may name the solvers' setup types from a lower
layer's point of view (``wood.py`` names ``BioSetup``). A module may import its own package and
the layers below it, never one above; the scene reaches no module under ``strands/``, ``bark/``,
``sim/``, ``meshlets/`` or ``export/``; and the module graph has no cycle.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "wooddecay"

#: each layer may import the layers before it in this list (and its own); ``scene`` and
#: ``blender_addon`` are apart: the add-on imports nothing of the package, the scene only the
#: base and ``wood`` (its one constant of time)
LAYERS = (
    ("base", {"errors", "atomic", "arrays", "fmath", "quaternion", "species", "unionfind", "version"}),
    ("strands", {"strands"}),
    ("wood", {"wood"}),
    ("bark", {"bark"}),
    ("sim", {"sim"}),
    ("meshlets", {"meshlets"}),
    ("export", {"export"}),
    ("scene", {"scene"}),
    ("model", {"model"}),
    ("stages", {"budget", "addon", "render", "bake", "scene_docs"}),
    ("studies", {"studies", "batch"}),
    ("gallery", {"gallery"}),
    ("cli", {"cli", "__init__", "__main__"}),
)
#: what the scene may import (it is read by ``model`` and the orchestration only)
SCENE_MAY_IMPORT = {"base", "strands", "wood", "scene"}
#: layers that must never see the scene
SCENE_FREE = {"strands", "wood", "bark", "sim", "meshlets", "export"}


def _layer(top: str) -> int | None:
    for i, (_, members) in enumerate(LAYERS):
        if top in members:
            return i
    return None


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == "TYPE_CHECKING") or (
        isinstance(t, ast.Attribute) and t.attr == "TYPE_CHECKING")


def imports(path: Path) -> list[tuple[int, str]]:
    """(line, absolute module) of every runtime import of the package in ``path``."""
    tree = ast.parse(path.read_text("utf-8"))
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and _is_type_checking(node):
            skip.update(id(n) for b in node.body for n in ast.walk(b))
    out = []
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] == "wooddecay"]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod.split(".")[0] != "wooddecay":
                continue
            # ``from . import x`` names submodules
            out += [(node.lineno, f"{mod}.{a.name}") if _is_module(f"{mod}.{a.name}") else (node.lineno, mod)
                    for a in node.names]
    return out


def _is_module(mod: str) -> bool:
    p = PACKAGE.parent.joinpath(*mod.split("."))
    return p.with_suffix(".py").is_file() or (p / "__init__.py").is_file()


def _top(mod: str) -> str:
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


MODULES = sorted(p for p in PACKAGE.rglob("*.py") if "blender_addon" not in p.parts)


def test_every_module_has_a_layer():
    missing = sorted({_top(_module_name(p)) for p in MODULES if _layer(_top(_module_name(p))) is None})
    assert not missing, f"modules outside every layer of tests/test_layers.py LAYERS: {missing}"


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_point_down(path: Path):
    me = _top(_module_name(path))
    mine = _layer(me)
    bad = []
    for line, mod in imports(path):
        them = _top(mod)
        if mod == "wooddecay":  # the public API: for the front ends and the studies only
            if LAYERS[mine][0] not in ("studies", "gallery", "cli"):
                bad.append(f"{path.relative_to(PACKAGE)}:{line} imports the package root")
            continue
        theirs = _layer(them)
        if LAYERS[mine][0] == "scene":
            ok = LAYERS[theirs][0] in SCENE_MAY_IMPORT
        elif LAYERS[theirs][0] == "scene":
            ok = LAYERS[mine][0] not in SCENE_FREE
        else:
            ok = theirs <= mine
        if not ok:
            bad.append(f"{path.relative_to(PACKAGE)}:{line} ({LAYERS[mine][0]}) imports {mod} ({LAYERS[theirs][0]})")
    assert not bad, "\n".join(bad)


def test_no_import_cycles():
    graph = {_module_name(p): {m for _, m in imports(p) if _is_module(m)} for p in MODULES}
    state: dict[str, int] = {}
    cycles = []

    def visit(m: str, stack: list[str]) -> None:
        state[m] = 1
        for n in sorted(graph.get(m, ())):
            if n == m or n not in graph:
                continue
            if state.get(n) == 1:
                cycles.append(" -> ".join(stack[stack.index(n):] + [n]) if n in stack else f"{m} -> {n}")
            elif n not in state:
                visit(n, stack + [n])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not cycles, "import cycles:\n" + "\n".join(cycles)


def test_rule_checker_sees_a_violation(tmp_path):
    """The checker reads function-local imports and skips TYPE_CHECKING blocks."""
    f = PACKAGE / "sim" / "_layers_probe.py"
    f.write_text("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..export import usd\n"
                 "def f():\n    from ..meshlets import skin\n", "utf-8")
    try:
        assert [m for _, m in imports(f)] == ["wooddecay.meshlets.skin"]
    finally:
        f.unlink()
