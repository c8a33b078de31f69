"""README's console examples print what README shows (``benchmarks/readme_examples.py``)."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "benchmarks" / "readme_examples.py"


def load_script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("readme_examples", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


examples = load_script()

TINY = """# A tool

Some text.

```console
$ tool one
first line
...
│ row   │ 0.5 │ 1.23 │

$ tool two --json
{"n": 3, "median_seconds": 0.01, "out": "/tmp/abc123/x"}
```

<!-- example: not run in CI (needs the recordings) -->

  ```console
  $ tool three
  big output
  ```
"""


def test_commands_outputs_and_markers_are_parsed() -> None:
    blocks = examples.parse_blocks(TINY)
    assert [len(b.commands) for b in blocks] == [2, 1]
    one, two = blocks[0].commands
    assert one.text == "tool one"
    assert one.expected == ["first line", "...", "│ row   │ 0.5 │ 1.23 │"]
    assert one.trailing_blank == 1
    assert two.expected[0].startswith('{"n": 3')
    assert blocks[0].skip_reason is None
    assert blocks[1].skip_reason == "needs the recordings"
    assert blocks[1].commands[0].expected == ["big output"]  # the block's indent is removed


def test_a_marker_needs_a_reason() -> None:
    for marker in ("<!-- example: not run in CI -->", "<!-- example: not run in CI () -->"):
        with pytest.raises(examples.ExampleFormatError, match="reason"):
            examples.parse_blocks(f"{marker}\n```console\n$ tool\n```\n")


def test_an_unclosed_block_is_an_error() -> None:
    with pytest.raises(examples.ExampleFormatError, match="never closed"):
        examples.parse_blocks("```console\n$ tool\n")


def test_timings_widths_and_temp_paths_are_masked() -> None:
    actual = [
        "first line",
        "┏━━━━━━━━┳━━━━━━━┳━━━━━━━━━┓",
        "┃ method ┃ value ┃ seconds ┃",
        "┡━━━━━━━━╇━━━━━━━╇━━━━━━━━━┩",
        "│ row    │ 0.5   │ 9.87    │",
        "└────────┴───────┴─────────┘",
    ]
    expected = ["first line", "...", "│ row   │ 0.5 │ 1.23 │", "..."]
    assert examples.compare(expected, actual).problems == []
    changed = ["first line", "...", "│ row   │ 0.6 │ 1.23 │", "..."]
    assert len(examples.compare(changed, actual).problems) == 1
    want = ['{"n": 3, "median_seconds": 0.01, "out": "/tmp/abc123/x"}']
    got = ['{"out": "/tmp/examples/x", "n": 3, "median_seconds": 2.5}']
    assert examples.compare(want, got).problems == []
    timing = examples.compare(["median 2.31 ms per image"], ["median 9 ms per image"])
    assert timing.problems == []


def test_missing_and_extra_lines_are_reported() -> None:
    assert examples.compare(["a", "b"], ["a"]).problems
    assert examples.compare(["a"], ["a", "b"]).problems
    assert examples.compare(["a", "..."], ["a", "b"]).problems == []
    assert examples.compare(["...", "c"], ["a", "b"]).problems
    assert examples.compare(['{"x": 1, ...'], ['{"x": 1, "y": 2}']).problems == []


def test_update_keeps_elisions_and_lines_that_still_match() -> None:
    expected = ["head 1.0 s", "...", "│ row │ 0.5 │"]
    actual = ["head 7.0 s", "noise", "│ row │ 0.6 │", "tail"]
    new, kept_shape = examples.updated_output(expected, actual)
    assert kept_shape
    assert new == ["head 1.0 s", "...", "│ row │ 0.6 │", "..."]
    new, kept_shape = examples.updated_output(["x", "a 1", "b"], ["note: new", "x", "a 2", "b"])
    assert (new, kept_shape) == (["note: new", "x", "a 2", "b"], True)
    new, kept_shape = examples.updated_output(["a"], ["b", "c"])
    assert (new, kept_shape) == (["b", "c"], False)


def test_update_rewrites_only_output_lines() -> None:
    text = "x\n```console\n$ tool\nold\n\n$ other\nsame\n```\n"
    blocks = examples.parse_blocks(text)
    outcomes = [
        examples.Outcome(blocks[0].commands[0], ["new"], ["differs"]),
        examples.Outcome(blocks[0].commands[1], ["same"], []),
    ]
    new_text = "x\n```console\n$ tool\nnew\n\n$ other\nsame\n```\n"
    assert examples.rewrite(text, blocks, outcomes) == new_text


def test_readme_marks_every_skipped_block_with_a_reason() -> None:
    blocks = examples.parse_blocks((REPO / "README.md").read_text(encoding="utf-8"))
    assert blocks, "README has console examples"
    assert all(b.skip_reason is None or b.skip_reason.strip() for b in blocks)


@pytest.mark.slow
def test_readme_examples_print_what_readme_shows(tmp_path: Path) -> None:
    for extra in ("torch", "qiskit_ibm_runtime"):
        if importlib.util.find_spec(extra) is None:
            pytest.skip(f"README's examples use every extra; {extra} is not installed")
    done = subprocess.run(
        [sys.executable, str(SCRIPT), "--check", "--cache", str(tmp_path / "cache")],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=1500,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr[-3000:]
