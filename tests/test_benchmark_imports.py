"""The benchmark scripts stay outside the test suite, but what they import from qdcnn must
exist: a renamed or removed library function otherwise breaks them silently."""

from __future__ import annotations

import ast
import importlib
import importlib.util
from pathlib import Path

import pytest

from qdcnn.errors import MissingExtraError

pytestmark = pytest.mark.base  # runs in the base-install job too

BENCHMARKS = sorted((Path(__file__).parents[1] / "benchmarks").glob("*.py"))


def qdcnn_imports(script: Path) -> list[tuple[str, str]]:
    """(module, name) for every ``from qdcnn... import name`` in ``script``."""
    tree = ast.parse(script.read_text(encoding="utf-8"))
    return [
        (node.module, alias.name)
        for node in ast.walk(tree)
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("qdcnn")
        for alias in node.names
    ]


def imported(module: str) -> object:
    """The module, or a skip when it needs an extra this install lacks."""
    try:
        return importlib.import_module(module)
    except MissingExtraError as exc:
        pytest.skip(str(exc))


def test_there_are_benchmarks() -> None:
    assert len(BENCHMARKS) >= 5


@pytest.mark.parametrize("script", BENCHMARKS, ids=lambda p: p.name)
def test_benchmark_imports_exist(script: Path) -> None:
    missing = [
        f"{module}.{name}"
        for module, name in qdcnn_imports(script)
        if not hasattr(imported(module), name)
        and importlib.util.find_spec(f"{module}.{name}") is None
    ]
    assert not missing, f"{script.name} imports names qdcnn no longer has: {missing}"
