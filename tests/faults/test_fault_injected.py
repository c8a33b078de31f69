"""A disk that fails at the last step of a write (the rename), without root: injected errors.

Every write ends by renaming a temporary file onto its target. Here ``os.replace`` of a
temporary name raises ``EROFS`` or ``ENOSPC`` while a command writes its finished outputs
again: exit 2, one ``error:`` line with the system's reason, no traceback, the finished
outputs byte for byte as they were, and the temporary file removed. This runs where
``tmpfs`` cannot be mounted (test_fault_disks.py needs root), and reaches the clean-up
after a write that succeeded, which a full or read-only file system never does.
"""

from __future__ import annotations

import errno
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from fault_support import (
    COMMANDS,
    TEMPORARY,
    Command,
    Inputs,
    assert_one_error,
    build_inputs,
    invoke,
    invoke_ok,
    output_path,
    snapshot,
    temporaries,
)

WRITERS = [c for c in COMMANDS if c.output != "cache"]
ERRORS = {errno.EROFS: "read-only file system", errno.ENOSPC: "no space left on device"}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    return build_inputs(tmp_path_factory)


@contextmanager
def failing_renames(code: int, under: Path) -> Iterator[None]:
    """``os.replace`` of a temporary file fails with ``code`` (anywhere: the output and the
    caches; a rename relative to a folder descriptor counts when that folder is ``under``)."""
    real = os.replace

    def replace(src: Any, dst: Any, *args: Any, **kwargs: Any) -> None:
        folder = kwargs.get("src_dir_fd")
        where = os.readlink(f"/proc/self/fd/{folder}") if folder is not None else os.fspath(src)
        if TEMPORARY.match(os.path.basename(os.fspath(src))) and str(under) in where:
            raise OSError(code, os.strerror(code), os.fspath(dst))
        real(src, dst, *args, **kwargs)

    os.replace = replace
    try:
        yield
    finally:
        os.replace = real


#: Every writer with both errors (one for those whose --force empties the folder first).
CASES = [(c, e) for c in WRITERS for e in sorted(ERRORS) if not (c.empties and e == errno.ENOSPC)]


@pytest.mark.parametrize(
    ("command", "code"), CASES, ids=[f"{c.name}-{errno.errorcode[e]}" for c, e in CASES]
)
def test_a_failed_rename_leaves_finished_outputs_and_no_temporary(
    command: Command, code: int, inputs: Inputs, tmp_path: Path
) -> None:
    out = output_path(command, tmp_path / "disk")
    invoke_ok(command.args(inputs, out))
    finished = snapshot(out)
    with failing_renames(code, tmp_path / "disk"):
        res = invoke([*command.args(inputs, out), *command.rewrite])
    line = assert_one_error(res, 2, tmp_path / "disk")
    assert ERRORS[code] in line
    if not command.empties:
        assert snapshot(out) == finished
    assert not temporaries(tmp_path / "disk")
