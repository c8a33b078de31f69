"""Printed messages are escaped: square brackets in them survive."""

from __future__ import annotations

import pytest

from qdcnn.cli._common import err, report_error, report_note


@pytest.mark.parametrize(
    "message",
    ["frame[left].png: empty file (0 bytes)", "needs torch: pip install 'qdcnn[dnn]'"],
)
def test_brackets_in_messages_are_printed_as_written(message: str) -> None:
    with err.capture() as capture:
        report_error(message)
        report_note(message)
    assert capture.get() == f"error: {message}\nnote: {message}\n"
