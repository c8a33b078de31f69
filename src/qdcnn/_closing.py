"""Objects that hold a resource until ``close()``, usable in a ``with`` block."""

from __future__ import annotations

from types import TracebackType
from typing import Self


class _WithBlock:
    """``with obj:`` gives ``obj``; leaving the block calls ``obj._leave_block(failed)``."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self._leave_block(failed=exc_type is not None)

    def _leave_block(self, *, failed: bool) -> None:
        raise NotImplementedError


class ClosesOnExit(_WithBlock):
    """Mixin: ``with obj:`` gives ``obj`` and calls ``obj.close()`` on the way out, error or not.

    A subclass defines :meth:`close`; one that must acquire something first overrides
    ``__enter__`` too.
    """

    def close(self) -> None:
        raise NotImplementedError

    def _leave_block(self, *, failed: bool) -> None:
        self.close()


class FinishesOnExit(_WithBlock):
    """Mixin: ``with obj:`` gives ``obj``; leaving normally calls ``obj.close()`` (finish the
    output), leaving on an exception ``obj.abort()`` (discard what is unfinished).
    """

    def close(self) -> object:
        raise NotImplementedError

    def abort(self) -> None:
        raise NotImplementedError

    def _leave_block(self, *, failed: bool) -> None:
        if failed:
            self.abort()
        else:
            self.close()
