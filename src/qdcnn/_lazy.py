"""Lazy public names for the subpackages, in the manner of scikit-image's ``lazy_loader``.

A subpackage lists its public names by submodule; ``from qdcnn.data import FrameSet``
imports :mod:`qdcnn.data.frames` only then, so importing a subpackage stays cheap and the
optional extras (torch, qiskit) load only when a name that needs them is used.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, Sequence
from typing import Any


def attach(
    package: str, names: Mapping[str, Sequence[str]]
) -> tuple[Callable[[str], Any], Callable[[], list[str]], list[str]]:
    """``__getattr__``, ``__dir__`` and ``__all__`` for ``package``.

    Parameters
    ----------
    package : str
        The subpackage's ``__name__``.
    names : mapping of str to sequence of str
        Submodule (relative to ``package``) -> the public names it defines.
    """
    where = {name: module for module, items in names.items() for name in items}
    public = sorted(where)

    def __getattr__(name: str) -> Any:
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f"{package}.{where[name]}"), name)

    def __dir__() -> list[str]:
        return public

    return __getattr__, __dir__, public
