"""Input checks that only quantum code needs (the generic ones are in :mod:`qdcnn._validation`).

A noise argument is accepted by what it does, not by its class: a
:class:`~qdcnn.quantum.noise.NoiseSpec`, or any noise object that says whether it is
ideal and names itself (``is_ideal`` and ``label()``, which every noise model of
:mod:`qdcnn.quantum` has, device noise included), so that new noise models are taken
wherever a ``NoiseSpec`` is.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.utils.validation import check_is_fitted

from qdcnn.errors import ParameterError
from qdcnn.quantum.noise import NoiseSpec

__all__ = ["check_fitted_models", "check_noise", "is_noise", "shared_noise"]


def is_noise(value: object) -> bool:
    """Whether ``value`` is a noise model: a NoiseSpec, or an object with ``is_ideal`` and
    a callable ``label``."""
    if isinstance(value, NoiseSpec):
        return True
    return hasattr(value, "is_ideal") and callable(getattr(value, "label", None))


def check_noise(noise: object, name: str = "noise") -> Any:
    """Return ``noise`` if it is ``None`` or a noise model (:func:`is_noise`), else raise.

    Examples
    --------
    >>> check_noise(NoiseSpec("bit-flip", 0.1)).label()
    'bit-flip:0.1'
    >>> check_noise("bit-flip:0.1")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    qdcnn.errors.ParameterError: noise='bit-flip:0.1' is invalid: a noise model ...
    """
    if noise is not None and not is_noise(noise):
        raise ParameterError(
            name,
            noise,
            "a noise model (qdcnn.quantum.noise.NoiseSpec or one with "
            "is_ideal and label()) or None",
        )
    return noise


def check_fitted_models(
    cls: type, models: Sequence[tuple[ArrayLike, Any]]
) -> list[tuple[NDArray[np.intp], Any]]:
    """``(rows, estimator)`` pairs for a batched prediction: fitted ``cls`` instances and
    1-D integer row indices."""
    out = []
    for i, item in enumerate(models):
        if not isinstance(item, tuple | list) or len(item) != 2:
            raise ParameterError(f"models[{i}]", item, "a (rows, estimator) pair")
        rows, estimator = item
        if not isinstance(estimator, cls):
            raise ParameterError(
                f"models[{i}]", f"<{type(estimator).__name__}>", f"a fitted {cls.__name__}"
            )
        check_is_fitted(estimator)
        idx = np.asarray(rows)
        if idx.ndim != 1 or not (idx.size == 0 or np.issubdtype(idx.dtype, np.integer)):
            raise ParameterError(f"models[{i}] rows", f"<{idx.dtype} {idx.shape}>", "row indices")
        out.append((idx.astype(np.intp), estimator))
    return out


def shared_noise(estimators: Sequence[Any], noise: object) -> Any:
    """The one noise of a batched run: ``noise`` if given, else the estimators' own ``noise``
    (which must then be the same for all)."""
    if noise is not None:
        return check_noise(noise)
    own = [e.noise for e in estimators]
    if any(n != own[0] for n in own[1:]):
        raise ParameterError(
            "noise", None, "a noise for the run: the models' own noise settings differ"
        )
    return own[0] if own else None
