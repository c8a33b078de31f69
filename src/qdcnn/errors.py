"""Exceptions with one-line messages that name the offending file, row or parameter."""

from __future__ import annotations

from os import PathLike


class QdcnnError(Exception):
    """Base class of every error qdcnn raises on purpose.

    Errors pickle with their attributes (``source``, ``reason``, ``row`` ...), so they
    travel to and from worker processes whatever their constructor takes.
    """

    def __reduce__(self) -> tuple[object, ...]:
        return (_rebuild, (type(self), self.args, dict(self.__dict__)))


def _rebuild(
    cls: type[QdcnnError], args: tuple[object, ...], state: dict[str, object]
) -> QdcnnError:
    """An error unpickled: its message and attributes, without calling its constructor."""
    exc = cls.__new__(cls)
    exc.args = args
    exc.__dict__.update(state)
    return exc


class InputError(QdcnnError, ValueError):
    """A file, a CSV row or another piece of input data is unusable.

    Parameters
    ----------
    source : str or path-like
        What is wrong: a file path, or ``"<file>:row <n>"`` for a row of a table.
    reason : str
        Why, in a few words (no trailing period).

    Examples
    --------
    >>> str(InputError("IMG/a.jpg", "not a readable image"))
    'IMG/a.jpg: not a readable image'
    """

    def __init__(self, source: str | PathLike[str], reason: str) -> None:
        self.source = str(source)
        self.reason = " ".join(reason.split())
        super().__init__(f"{self.source}: {self.reason}")


class OutputError(InputError):
    """An output cannot be written: a read-only or full file system, a file, link or device in
    the way, no permission. Unlike a bad input it ends the whole run (every later output
    would fail the same way), as one line naming the output and the system's reason.
    """


class ParameterError(QdcnnError, ValueError):
    """A parameter value is out of its meaningful range.

    The message names the parameter, the value given and what is allowed.
    """

    def __init__(self, name: str, value: object, allowed: str) -> None:
        self.name = name
        self.value = value
        super().__init__(f"{name}={value!r} is invalid: {allowed}")


class OptionConflict(QdcnnError, ValueError):
    """Two options were given that cannot apply together; the message names both.

    Examples
    --------
    >>> str(OptionConflict("--exact", "--shots", "exact probabilities use no shots"))
    '--exact and --shots cannot be used together: exact probabilities use no shots'
    """

    def __init__(self, first: str, second: str, reason: str) -> None:
        self.options = (first, second)
        super().__init__(f"{first} and {second} cannot be used together: {reason}")


class MissingExtraError(QdcnnError, ImportError):
    """An optional dependency is needed but not installed; the message names the extra."""

    def __init__(self, package: str, extra: str, purpose: str) -> None:
        self.package = package
        self.extra = extra
        pin = " (pin torch==2.13.0 in the same command for the CPU build)"
        hint = pin if extra == "dnn" else ""
        super().__init__(
            f"{purpose} needs {package}, which is not installed: pip install 'qdcnn[{extra}]'{hint}"
        )
