"""No function in the package is longer than MAX_LINES lines (def line to last line,
docstring included), so each one can be read at a glance."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "src" / "qdcnn"
MAX_LINES = 80


def long_functions(root: Path, limit: int) -> list[str]:
    """``path:line name (n lines)`` of every function or method under ``root`` longer
    than ``limit`` lines, nested ones included."""
    found = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                lines = (node.end_lineno or node.lineno) - node.lineno + 1
                if lines > limit:
                    where = path.relative_to(root.parent)
                    found.append(f"{where}:{node.lineno} {node.name} ({lines} lines)")
    return found


def test_the_package_is_there() -> None:
    assert (PACKAGE / "__init__.py").is_file()


def test_the_measure_counts_def_to_last_line(tmp_path: Path) -> None:
    body = "\n".join(f"    x{i} = {i}" for i in range(4))
    source = f"def short():\n{body}\n\n\ndef one_more():\n{body}\n    y = 0\n"
    (tmp_path / "m.py").write_text(source)
    assert long_functions(tmp_path, 5) == [f"{tmp_path.name}/m.py:8 one_more (6 lines)"]


def test_no_function_is_longer_than_80_lines() -> None:
    too_long = long_functions(PACKAGE, MAX_LINES)
    assert not too_long, f"functions over {MAX_LINES} lines:\n" + "\n".join(too_long)
