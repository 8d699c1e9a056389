"""The import graph of the project's packages: dependencies point one way, with no circles.

Every ``import`` statement is read from the source (top level, inside functions and under
``TYPE_CHECKING`` alike), plus ``importlib.import_module("...")`` calls with a literal name, so a
function-level import cannot hide a back edge or a circle. Allowed directions (issue 10)::

    harness -> agents -> (conceptfusion, planners)
    harness, tower_training, scenes -> sim_envs -> (planners, conceptfusion's base modules)
    planners -> conceptfusion's base modules
    conceptfusion -> nothing of the project outside itself
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("conceptfusion", "planners", "sim_envs", "agents", "tower_training", "harness", "scenes")

BASE = {"conceptfusion", "conceptfusion.errors", "conceptfusion.names", "conceptfusion.frames",
        "conceptfusion.cameras", "conceptfusion.io_utils", "conceptfusion.strict_json",
        "conceptfusion.tasks"}
"""Plain data types and utilities of the core that the simulator and planner packages may use."""

ALLOWED = {
    "conceptfusion": {"conceptfusion"},
    "planners": {"planners", "conceptfusion:base"},
    "sim_envs": {"sim_envs", "planners", "conceptfusion:base"},
    "agents": {"agents", "conceptfusion", "planners"},
    "tower_training": {"tower_training", "sim_envs", "conceptfusion", "planners"},
    "harness": {"harness", "agents", "sim_envs", "conceptfusion", "planners", "tower_training"},
    "scenes": {"scenes", "sim_envs", "planners", "conceptfusion:base"},
}
"""Top-level package -> what it may import (``conceptfusion:base``: only :data:`BASE`)."""


def _modules() -> dict[str, Path]:
    mods = {}
    for pkg in PACKAGES:
        for f in sorted((ROOT / pkg).rglob("*.py")):
            parts = f.relative_to(ROOT).with_suffix("").parts
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            mods[name] = f
    return mods


MODULES = _modules()


def _targets(name: str) -> list[str]:
    """The project modules that importing ``name`` executes (the module and its parent packages)."""
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(len(parts), 0, -1) if ".".join(parts[:i]) in MODULES]


def _imports(module: str, path: Path) -> list[tuple[str, int, list[str]]]:
    """(imported module, line, names taken from it) for every import in ``path``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno, []) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                src = ".".join(base + ([node.module] if node.module else []))
            else:
                src = node.module or ""
            names = [a.name for a in node.names]
            out.append((src, node.lineno, [n for n in names if f"{src}.{n}" not in MODULES]))
            out += [(f"{src}.{n}", node.lineno, []) for n in names if f"{src}.{n}" in MODULES]
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "import_module"
              and node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
            out.append((node.args[0].value, node.lineno, []))
    return out


def _graph() -> tuple[dict[str, set[str]], list[str], list[str]]:
    """Module edges; layering violations; private names taken across modules."""
    edges: dict[str, set[str]] = defaultdict(set)
    back, private = [], []
    for mod, path in MODULES.items():
        own_ancestors = set(_targets(mod)[1:])
        top = mod.split(".")[0]
        for src, line, names in _imports(mod, path):
            for target in _targets(src):
                if target == mod or target in own_ancestors:
                    continue
                edges[mod].add(target)
                t_top = target.split(".")[0]
                allowed = ALLOWED[top]
                ok = t_top in allowed or ("conceptfusion:base" in allowed and target in BASE)
                if not ok:
                    back.append(f"{path.relative_to(ROOT)}:{line} imports {target}")
                leaf = target.rpartition(".")[2]
                if leaf.startswith("_") and not leaf.startswith("__") and not mod.startswith(target.rpartition(".")[0] + "."):
                    private.append(f"{path.relative_to(ROOT)}:{line} imports private module {target}")
            if src in MODULES and src != mod:
                for n in names:
                    if n.startswith("_") and not n.startswith("__"):
                        private.append(f"{path.relative_to(ROOT)}:{line} imports private name {src}.{n}")
    return edges, back, private


def _cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in sorted(MODULES):
        if root in index:
            continue
        work = [(root, iter(sorted(edges.get(root, ()))))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(edges.get(w, ())))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[v])
                if low[v] == index[v]:
                    comp = []
                    while True:
                        w = stack.pop()
                        on.discard(w)
                        comp.append(w)
                        if w == v:
                            break
                    if len(comp) > 1:
                        out.append(sorted(comp))
    return out


def test_the_walker_sees_every_package_and_hidden_imports(tmp_path):
    edges, _, _ = _graph()
    assert {m.split(".")[0] for m in MODULES} == set(PACKAGES)
    assert sum(len(v) for v in edges.values()) > 100
    hidden = tmp_path / "hidden.py"
    hidden.write_text(
        "import importlib\n"
        "def f():\n"
        "    from sim_envs.scenes import episodes\n"
        "    from conceptfusion.names import _private\n"
        "    return importlib.import_module('agents.registry')\n"
    )
    found = {src: names for src, _, names in _imports("conceptfusion.hidden", hidden)}
    assert "sim_envs.scenes.episodes" in found and "agents.registry" in found
    assert found["conceptfusion.names"] == ["_private"]


def test_the_cycle_finder_finds_a_planted_circle():
    planted = {"conceptfusion.names": {"conceptfusion.errors"}, "conceptfusion.errors": {"conceptfusion.names"}}
    assert _cycles(planted) == [["conceptfusion.errors", "conceptfusion.names"]]


def test_dependencies_point_one_way():
    _, back, _ = _graph()
    assert not back, "imports against the package layering:\n" + "\n".join(back)


def test_no_import_circles():
    edges, _, _ = _graph()
    cycles = _cycles(edges)
    assert not cycles, "import circles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_only_public_names_cross_modules():
    _, _, private = _graph()
    assert not private, "private names used across modules:\n" + "\n".join(private)


@pytest.mark.parametrize("package", [p for p in MODULES if MODULES[p].name == "__init__.py"])
def test_every_package_says_what_it_holds(package):
    doc = ast.get_docstring(ast.parse(MODULES[package].read_text()))
    assert doc and len(doc.split()) >= 12, f"{package}/__init__.py: expected an opening docstring saying what it holds"
