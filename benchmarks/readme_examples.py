"""Run README.md's ```console examples and compare their printed output with what README shows.

From the repository root:

    python benchmarks/readme_examples.py --check     # exit 1 and list every mismatch
    python benchmarks/readme_examples.py --update    # rewrite README's outputs from fresh runs
    python benchmarks/readme_examples.py --list      # the blocks, and which are not run

After a change to any command's output, run ``--update`` and read ``git diff README.md``:
it rewrites only the output lines that differ, keeps ``...`` elisions, and says on stderr
when it had to replace a whole output (a block whose elided shape no longer fits).

The format (``tests/test_readme_examples.py`` checks ``--check`` in the full CI session):

- In a ```console block, a line starting with ``$ `` is a command (run with bash); the lines
  after it, up to the next command, are its expected stdout and stderr, interleaved.
- A line ``...`` stands for any number of output lines (``--update`` adds one at the end
  when an elided output goes on past README's last line); a line ending in `` ...`` matches any
  line that starts with what comes before it.
- Blocks run in README order in one scratch folder, so files made by one block are there for
  the next. The folder holds the inputs some examples use (``in/``, ``rec/``, ``model.pkl``:
  see ``make_inputs``), and a ``shared`` link beside it points at ``../shared`` of the
  repository, so ``../shared/data`` paths resolve as they do from the repository root.
- A block right after ``<!-- example: not run in CI (REASON) -->`` is not run; the reason is
  required (a marker without one is an error).
- What is not deterministic is masked before comparing: numbers in table columns named
  seconds, ms, frames / s or time; a number followed by ``ms``, ``s`` or ``frames/s``; JSON
  values whose key ends in ``seconds``, ``_ms``, ``ms_per_frame`` or ``fps``; the scratch
  folder's absolute path (shown as ``/tmp/examples``). Runs of spaces and of table rules are
  compared as one, so a Rich table's column widths do not matter.
- Progress lines (``progress: ...`` and per-epoch lines) are dropped: on a terminal they are
  bars that vanish, and how many there are depends on the machine's speed.
- ``qdcnn`` and ``python`` are this interpreter's (``python -m qdcnn``), with the repository's
  ``src`` first on ``PYTHONPATH``; ``QDCNN_CACHE`` is a scratch cache (``--cache DIR`` reuses
  one), ``COLUMNS=100`` fixes Rich's width.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
README = REPO / "README.md"
DISPLAY_ROOT = "/tmp/examples"
COLUMNS = "100"
COMMAND_TIMEOUT_S = 900
MAX_INSERTED = 3  # new lines (a note, say) recognised as such before a line README shows

FENCE_OPEN = re.compile(r"^(?P<indent>\s*)```console\s*$")
FENCE_CLOSE = re.compile(r"^\s*```\s*$")
MARKER = re.compile(r"^\s*<!--\s*example:\s*not run in CI\s*(?:\((?P<reason>.*)\))?\s*-->\s*$")
ANY_MARKER = re.compile(r"^\s*<!--\s*example:")
TIMING_HEADER = re.compile(r"seconds|\bms\b|frames / s|frames/s|\btime\b", re.IGNORECASE)
TIMING_TEXT = re.compile(r"\b\d+(?:\.\d+)?(?=\s?(?:ms|s|frames ?/ ?s)\b)")
TIMING_KEY = re.compile(r"(seconds|_ms|ms_per_frame|fps|frames_per_second)$")
TEMP_PREFIX = re.compile(r"/tmp/[^/\s'\"]+")
RULES = re.compile(r"([━─═]+)")
SPACES = re.compile(r"\s+")
TABLE_CHARS = "┏┃┡│└"
PROGRESS = re.compile(r"^progress: | epoch \d+/\d+ loss ")


@dataclass
class Command:
    """One ``$ `` line and the output README shows for it."""

    line_no: int  # 0-based index of the ``$ `` line in README
    text: str
    expected: list[str] = field(default_factory=list)
    trailing_blank: int = 0


@dataclass
class Block:
    """One ```console block: its commands, where it is and whether CI runs it."""

    start: int  # 0-based index of the opening fence
    indent: str
    commands: list[Command]
    skip_reason: str | None = None


class ExampleFormatError(ValueError):
    """README's examples break the format above (a marker without a reason, an open fence)."""


def parse_blocks(text: str) -> list[Block]:
    """Every ```console block of a README-like text, in order."""
    lines = text.splitlines()
    blocks = []
    i = 0
    while i < len(lines):
        opened = FENCE_OPEN.match(lines[i])
        if not opened:
            i += 1
            continue
        end = _closing_fence(lines, i)
        indent = opened.group("indent")
        body = [(n, _dedent(lines[n], indent)) for n in range(i + 1, end)]
        blocks.append(Block(i, indent, _commands(body), _skip_reason(lines, i)))
        i = end + 1
    return blocks


def _closing_fence(lines: list[str], start: int) -> int:
    for n in range(start + 1, len(lines)):
        if FENCE_CLOSE.match(lines[n]):
            return n
    raise ExampleFormatError(f"README.md:{start + 1}: ```console block is never closed")


def _dedent(line: str, indent: str) -> str:
    return line[len(indent) :] if line.startswith(indent) else line.lstrip()


def _skip_reason(lines: list[str], fence: int) -> str | None:
    """The reason of a ``not run in CI`` marker on the last non-blank line before the fence."""
    n = fence - 1
    while n >= 0 and not lines[n].strip():
        n -= 1
    if n < 0 or not ANY_MARKER.match(lines[n]):
        return None
    marker = MARKER.match(lines[n])
    reason = marker.group("reason") if marker else None
    if not reason or not reason.strip():
        raise ExampleFormatError(
            f"README.md:{n + 1}: an example marker must read "
            "'<!-- example: not run in CI (REASON) -->' with a reason"
        )
    return reason.strip()


def _commands(body: list[tuple[int, str]]) -> list[Command]:
    commands: list[Command] = []
    for n, line in body:
        if line.startswith("$ "):
            commands.append(Command(n, line[2:]))
        elif commands:
            commands[-1].expected.append(line)
        elif line.strip():
            raise ExampleFormatError(f"README.md:{n + 1}: output before the block's first command")
    for command in commands:
        while command.expected and not command.expected[-1].strip():
            command.expected.pop()
            command.trailing_blank += 1
    return commands


# --- masking and comparing -------------------------------------------------------------------


def timing_cells(actual: list[str]) -> list[set[int]]:
    """Per output line, the Rich table cells that hold a timing (by the table's header)."""
    masked: list[set[int]] = []
    header: list[str] = []
    columns: set[int] = set()
    in_header = False
    for line in actual:
        stripped = line.strip()
        if stripped.startswith("┃"):
            cells = stripped.split("┃")
            header = header if in_header else [""] * len(cells)
            header = [h + " " + c for h, c in zip(header, cells, strict=False)]
            columns = {i for i, h in enumerate(header) if TIMING_HEADER.search(h)}
            in_header = True
        else:
            in_header = False
        masked.append(columns if stripped.startswith("│") else set())
        if stripped.startswith("└"):
            columns = set()
    return masked


def normalise(line: str, cells: set[int] = frozenset()) -> str:  # type: ignore[assignment]
    """The line as compared: timings, temp paths, widths and JSON timing values masked."""
    json_form = _masked_json(line)
    return json_form if json_form is not None else normalise_text(line, cells)


def normalise_text(line: str, cells: set[int] = frozenset()) -> str:  # type: ignore[assignment]
    """The line as compared when it is not a JSON object."""
    if cells:
        parts = line.split("│")
        line = "│".join("<t>" if i in cells else p for i, p in enumerate(parts))
    line = TEMP_PREFIX.sub("<tmp>", line)
    line = TIMING_TEXT.sub("<t>", line)
    line = RULES.sub(lambda m: m.group(1)[0], line)
    return SPACES.sub(" ", line).strip()


def _masked_json(line: str) -> str | None:
    stripped = line.strip()
    if not (stripped.startswith("{") and stripped.endswith("}")):
        return None
    try:
        item = json.loads(stripped)
    except ValueError:
        return None
    return json.dumps(_mask_values(item), sort_keys=True)


def _mask_values(item: Any, key: str = "") -> Any:
    if isinstance(item, dict):
        return {k: _mask_values(v, k) for k, v in item.items()}
    if isinstance(item, list):
        return [_mask_values(v, key) for v in item]
    if TIMING_KEY.search(key) and isinstance(item, int | float):
        return "<t>"
    if isinstance(item, str):
        return TEMP_PREFIX.sub("<tmp>", item)
    return item


def skeleton(line: str) -> str:
    """The normalised line with every number blanked: which actual line a stale one stands for."""
    return re.sub(r"\d+(?:\.\d+)?", "#", normalise(line))


def _is_ellipsis(line: str) -> bool:
    return line.strip() == "..."


def line_matches(expected: str, actual: str, cells: set[int]) -> bool:
    if expected.rstrip().endswith(" ...") and not _is_ellipsis(expected):
        prefix = normalise_text(expected.rstrip()[: -len("...")], cells)
        return normalise_text(actual, cells).startswith(prefix)
    return normalise(expected, cells) == normalise(actual, cells)


@dataclass
class Comparison:
    """Which actual line each expected line stands for, and what differs."""

    pairs: dict[int, int]  # expected index -> actual index (literal lines only)
    inserted: dict[int, list[int]]  # expected index -> new actual lines just before it
    problems: list[str]
    aligned: bool  # False when the elided shape no longer fits the output


def compare(expected: list[str], actual: list[str]) -> Comparison:
    """Match README's expected lines (with ``...`` gaps) against a command's actual output."""
    cells = timing_cells(actual)
    pairs: dict[int, int] = {}
    inserted: dict[int, list[int]] = {}
    problems: list[str] = []
    pos = 0
    gap = False
    for i, want in enumerate(expected):
        if _is_ellipsis(want):
            gap = True
            continue
        j = _find(want, actual, cells, pos, gap)
        if j is None:
            problems.append(f"expected line not in the output: {want.strip()}")
            return Comparison(pairs, inserted, problems, aligned=False)
        later = None if gap else _inserted_before(want, actual, cells, j)
        if later is not None:
            inserted[i] = list(range(j, later))
            problems.append(f"new output line(s) before '{want.strip()}': {actual[j].strip()}")
            j = later
        if not line_matches(want, actual[j], cells[j]):
            problems.append(f"README: {want.strip()}\n      now: {actual[j].strip()}")
        pairs[i] = j
        pos, gap = j + 1, False
    if not gap and pos < len(actual):
        problems.append(f"{len(actual) - pos} more output line(s): {actual[pos].strip()} ...")
    return Comparison(pairs, inserted, problems, aligned=True)


def _inserted_before(want: str, actual: list[str], cells: list[set[int]], j: int) -> int | None:
    """Where ``want`` is found a few lines after ``j`` when ``actual[j]`` is not it (new lines)."""
    if line_matches(want, actual[j], cells[j]):
        return None
    for k in range(j + 1, min(j + 1 + MAX_INSERTED, len(actual))):
        if line_matches(want, actual[k], cells[k]):
            return k
    return None


def _find(want: str, actual: list[str], cells: list[set[int]], pos: int, gap: bool) -> int | None:
    if not gap:
        return pos if pos < len(actual) else None
    for j in range(pos, len(actual)):
        if line_matches(want, actual[j], cells[j]):
            return j
    shape = skeleton(want)
    for j in range(pos, len(actual)):
        if skeleton(actual[j]) == shape:
            return j
    return None


def updated_output(expected: list[str], actual: list[str]) -> tuple[list[str], bool]:
    """README's lines with the stale ones replaced; False when the whole output was replaced."""
    result = compare(expected, actual)
    has_gap = any(_is_ellipsis(line) for line in expected)
    n_inserted = sum(len(lines) for lines in result.inserted.values())
    if not result.aligned or (not has_gap and len(expected) + n_inserted != len(actual)):
        return list(actual), False
    cells = timing_cells(actual)
    pairs = result.pairs
    stale = {i for i, j in pairs.items() if not line_matches(expected[i], actual[j], cells[j])}
    for table in _tables(expected):
        if stale & table:  # the whole table from one run, so its columns line up
            stale |= table & result.pairs.keys()
    new = []
    for i, line in enumerate(expected):
        new += [actual[j] for j in result.inserted.get(i, [])]
        new.append(actual[pairs[i]] if i in stale else line)
    if has_gap and result.pairs and max(result.pairs.values()) + 1 < len(actual):
        if not _is_ellipsis(new[-1]):
            new.append("...")  # the output goes on past README's last line
    return new, True


def _tables(lines: list[str]) -> list[set[int]]:
    """Index sets of README's Rich tables: box-drawn lines, with an indented title above them."""
    tables: list[set[int]] = []
    current: set[int] = set()
    for i, line in enumerate(lines):
        if line.strip()[:1] in TABLE_CHARS:
            if not current and i > 0 and lines[i - 1].startswith(" ") and lines[i - 1].strip():
                current.add(i - 1)
            current.add(i)
        elif current:
            tables.append(current)
            current = set()
    return tables + ([current] if current else [])


# --- running ---------------------------------------------------------------------------------


def make_inputs(work: Path, env: dict[str, str]) -> None:
    """The inputs of README's Safety examples: a folder of bad images, a recording with bad rows."""
    import numpy as np

    from qdcnn.data.images import write_image

    rng = np.random.default_rng(0)
    images = work / "in"
    images.mkdir()
    write_image(images / "road.png", rng.integers(0, 255, (160, 320, 3), dtype=np.uint8))
    write_image(images / "tiny.png", np.zeros((3, 3, 3), np.uint8))
    (images / "corrupt.png").write_bytes(b"\x89PNG\r\n\x1a\n not really a png")
    (images / "empty.png").write_bytes(b"")
    (images / "notes.txt").write_text("not an image\n", encoding="utf-8")
    recording = work / "rec"
    synth = f"qdcnn synth --preset track1 --n 120 --seed 3 --layout udacity --out {recording}"
    subprocess.run(["bash", "-c", synth], cwd=work, env=env, check=True, capture_output=True)
    _break_rows(recording / "driving_log.csv")
    (work / "model.pkl").write_bytes(b"\x80\x04\x95\x10\x00\x00\x00\x00\x00\x00\x00}\x94.")


def _break_rows(csv_file: Path) -> None:
    """Row 6's steering becomes text and row 10 names an image that is not there."""
    rows = csv_file.read_text(encoding="utf-8").splitlines()
    header = 1 if rows[0].lower().startswith("center") else 0
    six, ten = rows[header + 5].split(","), rows[header + 9].split(",")
    six[3] = "abc"
    ten[0] = "IMG/missing.jpg"
    rows[header + 5], rows[header + 9] = ",".join(six), ",".join(ten)
    csv_file.write_text("\n".join(rows) + "\n", encoding="utf-8")


def scratch_environment(root: Path, cache: Path) -> dict[str, str]:
    """PATH with this interpreter's ``qdcnn`` and ``python``; fixed width; a scratch cache."""
    bin_dir = root / "bin"
    bin_dir.mkdir(exist_ok=True)
    python = f'"{sys.executable}"'
    for name, target in (("qdcnn", f"{python} -m qdcnn"), ("python", python)):
        script = bin_dir / name
        script.write_text(f'#!/bin/sh\nexec {target} "$@"\n', encoding="utf-8")
        script.chmod(0o755)
    env = dict(os.environ)
    env.update(
        PATH=f"{bin_dir}{os.pathsep}{env.get('PATH', '')}",
        PYTHONPATH=os.pathsep.join(p for p in (str(REPO / "src"), env.get("PYTHONPATH")) if p),
        QDCNN_CACHE=str(cache),
        COLUMNS=COLUMNS,
        LINES="50",
        PYTHONUNBUFFERED="1",
        TERM="dumb",
        NO_COLOR="1",
    )
    env.pop("FORCE_COLOR", None)
    return env


def prepare_scratch(root: Path, env: dict[str, str]) -> Path:
    """``root/work`` with the examples' inputs, ``benchmarks`` linked, ``root/shared`` linked."""
    work = root / "work"
    work.mkdir()
    (work / "benchmarks").symlink_to(REPO / "benchmarks")
    shared = REPO.parent / "shared"
    if shared.exists():
        (root / "shared").symlink_to(shared)
    make_inputs(work, env)
    return work


def run_command(command: str, work: Path, env: dict[str, str]) -> list[str]:
    """The command's stdout and stderr lines, the scratch path shown as DISPLAY_ROOT."""
    done = subprocess.run(
        ["bash", "-c", command],
        cwd=work,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        timeout=COMMAND_TIMEOUT_S,
        check=False,
    )
    text = done.stdout.replace(str(work.resolve()), DISPLAY_ROOT).replace(str(work), DISPLAY_ROOT)
    return [line.rstrip() for line in text.splitlines() if not PROGRESS.search(line)]


@dataclass
class Outcome:
    command: Command
    actual: list[str]
    problems: list[str]


def run_blocks(blocks: list[Block], work: Path, env: dict[str, str]) -> list[Outcome]:
    outcomes = []
    for block in blocks:
        if block.skip_reason is not None:
            continue
        for command in block.commands:
            actual = run_command(command.text, work, env)
            problems = compare(command.expected, actual).problems
            print(f"{'ok  ' if not problems else 'DIFF'} {command.text[:90]}", file=sys.stderr)
            outcomes.append(Outcome(command, actual, problems))
    return outcomes


def rewrite(text: str, blocks: list[Block], outcomes: list[Outcome]) -> str:
    """README with each run command's output lines replaced by the updated ones."""
    lines = text.splitlines()
    by_line = {o.command.line_no: o for o in outcomes}
    indent_of = {c.line_no: b.indent for b in blocks for c in b.commands}
    for line_no in sorted(by_line, reverse=True):
        outcome = by_line[line_no]
        command = outcome.command
        new, kept_shape = updated_output(command.expected, outcome.actual)
        if not kept_shape:
            print(f"note: replaced the whole output of: {command.text}", file=sys.stderr)
        indent = indent_of[line_no]
        first, count = line_no + 1, len(command.expected)
        lines[first : first + count] = [(indent + s).rstrip() if s else "" for s in new]
    return "\n".join(lines) + "\n"


def report(blocks: list[Block], outcomes: list[Outcome]) -> int:
    for block in blocks:
        if block.skip_reason is not None:
            print(f"not run (README.md:{block.start + 1}): {block.skip_reason}")
    failed = [o for o in outcomes if o.problems]
    for outcome in failed:
        print(f"\nREADME.md:{outcome.command.line_no + 1}: $ {outcome.command.text}")
        for problem in outcome.problems:
            print(f"  {problem}")
    print(f"\n{len(outcomes) - len(failed)} of {len(outcomes)} commands match README.md")
    return 1 if failed else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--check", action="store_true", help="exit 1 listing mismatches")
    mode.add_argument("--update", action="store_true", help="rewrite README's outputs")
    mode.add_argument("--list", action="store_true", help="list the blocks, run nothing")
    parser.add_argument("--readme", type=Path, default=README)
    parser.add_argument("--cache", type=Path, help="QDCNN_CACHE to use (default: a scratch one)")
    args = parser.parse_args(argv)
    text = args.readme.read_text(encoding="utf-8")
    blocks = parse_blocks(text)
    if args.list:
        for block in blocks:
            state = f"not run: {block.skip_reason}" if block.skip_reason else "run"
            print(f"README.md:{block.start + 1}: {len(block.commands)} command(s), {state}")
        return 0
    with tempfile.TemporaryDirectory(prefix="qdcnn-ex-") as tmp:
        root = Path(tmp)
        env = scratch_environment(root, args.cache or root / "cache")
        work = prepare_scratch(root, env)
        outcomes = run_blocks(blocks, work, env)
    if args.update:
        args.readme.write_text(rewrite(text, blocks, outcomes), encoding="utf-8")
        print(f"updated {args.readme}", file=sys.stderr)
        return 0
    return report(blocks, outcomes)


if __name__ == "__main__":
    sys.exit(main())
