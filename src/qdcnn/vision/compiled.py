"""Which per-frame steps run as compiled Numba kernels, and the switch back to NumPy.

The kernel modules (:mod:`qdcnn.vision.block_kernels`, :mod:`qdcnn.vision.removal_kernels`)
are imported on first use, so start-up paths never import Numba. ``QDCNN_KERNELS=numpy``
selects the NumPy paths instead: the references the kernels are tested against, and what
the benchmarks compare them with.
"""

from __future__ import annotations

import importlib
import os
from functools import cache
from types import ModuleType

from qdcnn.errors import ParameterError

#: ``QDCNN_KERNELS=numpy`` runs the NumPy paths instead of the compiled kernels.
KERNELS_VARIABLE = "QDCNN_KERNELS"


def compiled(module: str) -> ModuleType | None:
    """The kernel module ``qdcnn.vision.<module>``, or None when Numba is missing (or
    does not import beside this NumPy) or ``QDCNN_KERNELS=numpy`` asks for the NumPy paths.

    Raises
    ------
    ParameterError
        ``QDCNN_KERNELS`` is set to something else than ``numba`` or ``numpy``.
    """
    choice = _environment_choice()
    if choice not in ("numba", "numpy"):
        raise ParameterError(KERNELS_VARIABLE, choice, "'numba' or 'numpy'")
    return None if choice == "numpy" else _imported(module)


def _environment_choice() -> str:
    """``QDCNN_KERNELS``, ``"numba"`` when unset, read on every call (tests and users may
    set it in the process). ``os.environ.get`` of an unset variable raises and catches two
    KeyErrors (0.9 us, a frame's detection calls it once); CPython's mapping behind
    ``os.environ`` is read directly where it has one."""
    data = getattr(os.environ, "_data", None)
    encodekey = getattr(os.environ, "encodekey", None)
    if data is None or encodekey is None:
        return os.environ.get(KERNELS_VARIABLE, "numba")
    value = data.get(encodekey(KERNELS_VARIABLE))
    return "numba" if value is None else str(os.environ.decodevalue(value))


@cache
def _imported(module: str) -> ModuleType | None:
    try:
        return importlib.import_module(f"qdcnn.vision.{module}")
    except ImportError as error:  # Numba missing, or refusing this NumPy: the NumPy paths
        if error.name is not None and error.name.partition(".")[0] != "numba":
            raise
        return None
