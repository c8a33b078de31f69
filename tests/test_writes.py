"""Every file qdcnn writes goes through one writer (issue 23).

The writer modules, :mod:`qdcnn._fileio` (atomic files, :class:`AtomicTextFile`) and
:mod:`qdcnn.outputs` (:class:`OutputFolder`), write to a temporary name in the target's
folder, flush it to disk and rename it into place, never through a symbolic link, and turn
every ``OSError`` into one line. This test reads the source of every other module and fails
on a call that writes a file by itself: ``open`` for writing, ``write_text``,
``write_bytes``, ``savefig``, ``np.save*``, ``imwrite``, ``torch.save``, ``json.dump``,
``shutil.copy*``, ``tofile``, ``save_file``, an ``os.open`` for writing, or a video
container opened for writing. The few that cannot go through the writer are listed in
``ALLOWED`` with the reason.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src" / "qdcnn"
WRITER_MODULES = {"_fileio.py", "outputs.py"}

#: Calls named by their attribute or function name alone (any receiver).
WRITE_CALLS = {
    "write_text",
    "write_bytes",
    "savefig",
    "save",
    "savez",
    "savez_compressed",
    "savetxt",
    "imwrite",
    "dump",
    "copy",
    "copy2",
    "copyfile",
    "copyfileobj",
    "move",
    "tofile",
    "save_file",
    "to_csv",
}
#: Receivers whose ``write_text``/``write_bytes`` are :class:`qdcnn.outputs.OutputFolder`'s.
OUTPUT_FOLDERS = {"folder", "self.folder"}
WRITE_FLAGS = {"O_WRONLY", "O_RDWR", "O_CREAT", "O_APPEND", "O_TRUNC"}

#: (module, call) -> why it cannot go through the writer.
ALLOWED: dict[tuple[str, str], str] = {
    ("direction/feature_cache.py", "np.savez_compressed"): (
        "into an io.BytesIO; the bytes then go through atomic_write_bytes"
    ),
    ("data/video.py", "av.open mode 'w'"): (
        "FFmpeg writes by name: into a memory buffer, or a temporary sibling that is "
        "fsynced and renamed (outputs use OutputFolder.write_file)"
    ),
    ("data/video.py", "open mode 'rb+'"): (
        "reopens FFmpeg's finished temporary file only to fsync it before the rename"
    ),
    ("data/video.py", "cv2.VideoWriter"): (
        "OpenCV writes by name: into a temporary sibling (or scratch file) that is "
        "fsynced and renamed"
    ),
    ("experiments/noise/plot.py", "fig.savefig"): (
        "into an io.BytesIO; the bytes then go through atomic_write_bytes"
    ),
    ("direction/builtin.py", "model.save"): "not a file write: calls persistence.save_model",
    ("experiments/shadow_batch.py", "model.save"): (
        "not a file write: calls persistence.save_model"
    ),
    ("experiments/train_direction.py", "model.save"): (
        "not a file write: calls persistence.save_model"
    ),
}


def _name(node: ast.AST) -> str:
    try:
        return ast.unparse(node)
    except Exception:  # pragma: no cover - ast.unparse handles every expression
        return "?"


def _mode(call: ast.Call, position: int) -> str | None:
    node = call.args[position] if len(call.args) > position else None
    for kw in call.keywords:
        if kw.arg == "mode":
            node = kw.value
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    return None


def _writes(mode: str | None) -> bool:
    return mode is not None and any(c in mode for c in "wax+")


def _describe(call: ast.Call) -> str | None:
    """What kind of write ``call`` is, or ``None`` when it writes nothing."""
    func = call.func
    full = _name(func)
    last = func.attr if isinstance(func, ast.Attribute) else full
    receiver = _name(func.value) if isinstance(func, ast.Attribute) else ""
    if full in ("open", "io.open", "os.fdopen", "av.open"):
        mode = _mode(call, 1)
        return f"{full} mode {mode!r}" if _writes(mode) else None
    if full == "os.open":
        flags = {n.attr for n in ast.walk(call) if isinstance(n, ast.Attribute)}
        return "os.open for writing" if flags & WRITE_FLAGS else None
    if last in ("write_text", "write_bytes") and receiver in OUTPUT_FOLDERS:
        return None
    if last == "dump" and receiver != "json":
        return None
    if last in ("copy", "copy2", "move") and receiver != "shutil":
        return None
    if last == "save" and receiver not in ("np", "numpy", "torch"):
        return "model.save" if receiver == "model" else None
    if last in WRITE_CALLS:
        return full
    if full == "cv2.VideoWriter":
        return full
    return None


def write_calls() -> Iterator[tuple[str, int, str]]:
    """``(module, line, call)`` for every call that writes a file, outside the writers."""
    for path in sorted(SRC.rglob("*.py")):
        rel = path.relative_to(SRC).as_posix()
        if rel in WRITER_MODULES:
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.Call):
                what = _describe(node)
                if what is not None:
                    yield rel, node.lineno, what


def test_every_write_goes_through_the_writer() -> None:
    bare = [
        f"src/qdcnn/{rel}:{line}: {what}"
        for rel, line, what in write_calls()
        if (rel, what) not in ALLOWED
    ]
    assert not bare, "write these through qdcnn._fileio or qdcnn.outputs:\n" + "\n".join(bare)


def test_the_allow_list_has_no_stale_entries() -> None:
    used = {(rel, what) for rel, _line, what in write_calls()}
    assert set(ALLOWED) <= used, sorted(set(ALLOWED) - used)


def test_the_scan_finds_bare_writes() -> None:
    source = """
open(p, "w"); open(p, mode="ab"); p.write_text("x"); p.write_bytes(b"")
fig.savefig(p); np.save(p, a); cv2.imwrite(p, a); json.dump(d, fh); shutil.copy(a, b)
torch.save(s, p); os.open(p, os.O_WRONLY | os.O_CREAT)
open(p); open(p, "rb"); folder.write_text("a", "b"); json.dumps(d); os.open(p, os.O_RDONLY)
"""
    found = [_describe(n) for n in ast.walk(ast.parse(source)) if isinstance(n, ast.Call)]
    assert sorted(w for w in found if w) == sorted(
        [
            "open mode 'w'",
            "open mode 'ab'",
            "p.write_text",
            "p.write_bytes",
            "fig.savefig",
            "np.save",
            "cv2.imwrite",
            "json.dump",
            "shutil.copy",
            "torch.save",
            "os.open for writing",
        ]
    )
