"""Batch work over files that keeps going past bad items and never loses finished results.

Each item either yields its result or a :class:`Failure` with a one-line reason;
callers stream results as they come (masks are written and JSON lines printed
per item), so an interrupted or partly failing run keeps everything finished.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Generic, TypeVar

from qdcnn.errors import OutputError, QdcnnError

_T = TypeVar("_T")
_R = TypeVar("_R")


@dataclass(frozen=True)
class Failure:
    """An item that could not be processed, with a one-line reason."""

    file: str
    error: str

    def to_dict(self) -> dict[str, str]:
        return {"file": self.file, "error": self.error}


@dataclass(frozen=True)
class Outcome(Generic[_T, _R]):
    """The result of one item, or its failure."""

    item: _T
    result: _R | None = None
    failure: Failure | None = None


def run_batch(
    items: Iterable[_T], work: Callable[[_T], _R], name: Callable[[_T], str] = str
) -> Iterator[Outcome[_T, _R]]:
    """Apply ``work`` to each item; qdcnn errors and OS errors become failures, others propagate.

    Only the errors qdcnn raises on purpose (bad files, bad rows, bad values)
    and operating-system errors are caught, so a programming error still stops
    the run loudly instead of being reported as a bad file. An :class:`OutputError`
    (a read-only or full disk, a link in the way) is no item's fault and would fail every
    later item the same way: it ends the batch.
    """
    for item in items:
        try:
            yield Outcome(item, result=work(item))
        except OutputError:
            raise
        except QdcnnError as exc:
            yield Outcome(item, failure=Failure(name(item), _one_line(exc, name(item))))
        except OSError as exc:
            yield Outcome(item, failure=Failure(name(item), f"{name(item)}: {exc.strerror or exc}"))


def _one_line(exc: Exception, source: str) -> str:
    text = " ".join(str(exc).split())
    return text if source in text else f"{source}: {text}"
