"""Input checks that only quantum code needs (the generic ones are in :mod:`qdcnn._validation`).

A noise argument is accepted by what it does, not by its class: any object that follows
the :class:`~qdcnn.quantum.noise.GateNoise` protocol (:func:`~qdcnn.quantum.noise.is_noise`;
a :class:`~qdcnn.quantum.noise.NoiseSpec`, device noise, or a new noise model), so that new
noise models are taken wherever a ``NoiseSpec`` is.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.utils.validation import check_is_fitted

from qdcnn._validation import has_shape
from qdcnn.errors import ParameterError
from qdcnn.quantum.noise import is_noise

__all__ = ["check_fitted_models", "check_noise", "is_noise", "shared_noise"]

#: a noise argument's declared type (``NoiseSpec | None``, ``GateNoise | None``, ...)
N = TypeVar("N")


def check_noise(noise: N, name: str = "noise") -> N:
    """Return ``noise`` (typed as given) if it is ``None`` or a noise model
    (:func:`is_noise`), else raise.

    Examples
    --------
    >>> from qdcnn.quantum.noise import NoiseSpec
    >>> check_noise(NoiseSpec("bit-flip", 0.1)).label()
    'bit-flip:0.1'
    >>> check_noise("bit-flip:0.1")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    qdcnn.errors.ParameterError: noise='bit-flip:0.1' is invalid: a noise model ...
    """
    if noise is None or is_noise(noise):
        return noise
    raise ParameterError(
        name, noise, "a noise model (a qdcnn.quantum.noise.GateNoise such as NoiseSpec) or None"
    )


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
        if not has_shape(idx, "N") or not (idx.size == 0 or np.issubdtype(idx.dtype, np.integer)):
            raise ParameterError(f"models[{i}] rows", f"<{idx.dtype} {idx.shape}>", "row indices")
        out.append((idx.astype(np.intp), estimator))
    return out


def shared_noise(estimators: Sequence[Any], noise: N | None) -> N | None:
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
