"""The package's layers import one way, and no module imports itself back through others.

cli -> experiments -> direction / runtime -> models, pipeline -> vision -> quantum -> data
-> config, outputs, persistence -> _validation, errors. Function-level (lazy) imports count:
a layer may delay an import, not reverse it.
"""

from __future__ import annotations

import ast
from collections import defaultdict
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "qdcnn"

RANK = {
    "__main__": 10,
    "cli": 9,
    "experiments": 8,
    "direction": 7,
    "runtime": 7,
    "models": 6,
    "pipeline": 6,
    "vision": 5,
    "quantum": 4,
    "data": 3,
    "config": 2,
    "classes": 2,
    "outputs": 2,
    "persistence": 2,
    "batch": 2,
    "_closing": 1,
    "_fileio": 1,
    "_lazy": 1,
    "_optional": 1,
    "_threads": 1,
    "_validation": 1,
    "errors": 1,
}
FORBIDDEN = {("runtime", "direction"), ("quantum", "data")}


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return ".".join(("qdcnn", *parts)).removesuffix(".__init__")


def _imports(path: Path, modules: set[str]) -> set[str]:
    """The qdcnn modules ``path`` imports: ``from pkg import sub`` counts as ``pkg.sub``."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("qdcnn"):
            subs = {f"{node.module}.{a.name}" for a in node.names} & modules
            found.update(subs)
            if len(subs) < len(node.names):
                found.add(node.module)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("qdcnn"))
    return found


def _graph() -> dict[str, set[str]]:
    modules = {_module_name(p): p for p in SRC.rglob("*.py")}
    graph: dict[str, set[str]] = defaultdict(set)
    for name, path in modules.items():
        for target in _imports(path, set(modules)):
            if target in modules and target != name:
                graph[name].add(target)
    return graph


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_every_top_level_module_has_a_layer() -> None:
    tops = {_layer(_module_name(p)) for p in SRC.rglob("*.py")} - {""}
    assert tops <= set(RANK), sorted(tops - set(RANK))


def test_no_module_imports_a_layer_above_it() -> None:
    wrong = []
    for module, targets in _graph().items():
        for target in targets:
            low, high = _layer(module), _layer(target)
            if not low or not high or low == high:
                continue
            if RANK[high] > RANK[low] or (low, high) in FORBIDDEN:
                wrong.append(f"{module} -> {target}")
    assert not wrong, "\n".join(sorted(wrong))


def _cycle_from(start: str, graph: dict[str, set[str]]) -> list[str] | None:
    stack: list[tuple[str, list[str]]] = [(start, [start])]
    seen: set[str] = set()
    while stack:
        node, path = stack.pop()
        for nxt in graph.get(node, ()):
            if nxt == start:
                return [*path, start]
            if nxt not in seen:
                seen.add(nxt)
                stack.append((nxt, [*path, nxt]))
    return None


@pytest.mark.parametrize("package", ["quantum", "data", "vision", "models", "direction", "runtime"])
def test_no_import_cycle_inside_a_package(package: str) -> None:
    graph = _graph()
    members = sorted(m for m in graph if _layer(m) == package)
    cycles = [c for m in members if (c := _cycle_from(m, graph)) is not None]
    assert not cycles, " | ".join(" -> ".join(c) for c in cycles)
