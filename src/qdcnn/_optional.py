"""Guards for optional heavy dependencies (qiskit, qiskit-aer, torch, dask).

Modelled on ``qiskit_machine_learning/optionals.py``: the package imports without
the extras; code that needs one calls the matching ``require_*`` function at the
point of use, which returns the module or raises :class:`MissingExtraError` naming
the extra to install.
"""

from __future__ import annotations

import importlib
import importlib.util
from types import ModuleType

from qdcnn.errors import MissingExtraError

_EXTRA_OF = {
    "qiskit": "quantum",
    "qiskit_aer": "quantum",
    "qiskit_machine_learning": "quantum",
    "qiskit_qasm3_import": "quantum",
    "qiskit_ibm_runtime": "quantum",
    "torch": "dnn",
    "av": "video",
    "dask": "dask",
    "distributed": "dask",
}


def has_module(name: str) -> bool:
    """Return whether ``name`` can be imported, without importing it."""
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def require(name: str, purpose: str) -> ModuleType:
    """Import and return module ``name`` or raise :class:`MissingExtraError`.

    Parameters
    ----------
    name : str
        Top-level module, one of ``qiskit``, ``qiskit_aer``,
        ``qiskit_machine_learning``, ``torch``, ``dask``.
    purpose : str
        What needs it, for the message (for example ``"the Aer backend"``).
    """
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        raise MissingExtraError(name.replace("_", "-"), _EXTRA_OF[name], purpose) from exc


def has_torch() -> bool:
    """Whether torch (the ``dnn`` extra) is installed."""
    return has_module("torch")


def has_gpu() -> bool:
    """Whether torch is installed and sees a CUDA or Apple MPS device."""
    if not has_torch():
        return False
    import torch

    mps = getattr(torch.backends, "mps", None)
    return bool(torch.cuda.is_available() or (mps is not None and mps.is_available()))
