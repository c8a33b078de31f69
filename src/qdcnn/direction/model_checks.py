"""Checks of a loaded direction model's fitted attributes (type, range, shape, finiteness).

A model file is parsed into plain values (:func:`qdcnn.persistence.restore_estimator_state`);
this module checks each declared fitted attribute against what the estimator's own ``fit``
produces, so a tampered or damaged file is refused when it is loaded (one
:class:`~qdcnn.errors.InputError` naming the file and the attribute), never later on
every input. Estimators that restore their own state (the CNN classifiers) check it
themselves (:func:`qdcnn.models.weights.check_state_dict`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from typing import Any

import numpy as np

from qdcnn.errors import InputError

__all__ = ["check_estimator_params", "check_fitted_attributes"]

#: A rule returns what is wrong with the value (``None`` when it is fine).
_Rule = Callable[[Any, Any], "str | None"]
_DIRECTIONS = (0, 1, 2)
_ANGLE_PARAMS = {"arctan": 1, "minmax": 2, "identity": 0}


def check_fitted_attributes(estimator: Any, source: str | os.PathLike[str]) -> None:
    """Check every declared fitted attribute of ``estimator`` that has a rule.

    Raises
    ------
    InputError
        An attribute of the wrong type, range or shape, or a non-finite number where
        ``fit`` never leaves one (naming ``source`` and the attribute).
    """
    for name in getattr(estimator, "fitted_attributes", ()):
        rule = _RULES.get(name)
        problem = None if rule is None else rule(estimator, getattr(estimator, name))
        if problem is not None:
            raise InputError(source, f"fitted attribute {name!r} {problem} (a damaged model file)")


def check_estimator_params(estimator: Any) -> None:
    """Run the estimator's own parameter checks (those its ``fit`` runs), if it has them.

    A model file's parameters are set with ``set_params``, which checks nothing; an
    out-of-range value (``shots=-5``) would otherwise fail on every input.

    Raises
    ------
    ParameterError
        The estimator's own message naming the parameter.
    """
    check = getattr(estimator, "_check_params", None)
    if callable(check):
        check()


def _is_int(value: Any) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool
    )


def _direction(_: Any, value: Any) -> str | None:
    if not _is_int(value) or int(value) not in _DIRECTIONS:
        return f"is {value!r}, not a direction (0, 1 or 2)"
    return None


def _positive_int(_: Any, value: Any) -> str | None:
    if not _is_int(value) or int(value) < 1:
        return f"is {value!r}, not a positive integer"
    return None


def _finite(_: Any, value: Any) -> str | None:
    if not _is_number(value) or not math.isfinite(float(value)):
        return f"is {value!r}, not a finite number"
    return None


def _fraction_or_nan(_: Any, value: Any) -> str | None:
    if not _is_number(value) or not (math.isnan(float(value)) or 0.0 <= float(value) <= 1.0):
        return f"is {value!r}, not a fraction in [0, 1]"
    return None


def _array(
    value: Any, ndim: int, *, allow_nan: bool = False, size: int | None = None
) -> str | None:
    """What is wrong with ``value`` as a real ``ndim``-dimensional array."""
    if not isinstance(value, np.ndarray) or value.ndim != ndim:
        return f"is not a {ndim}-D array"
    if value.dtype.kind not in "iuf":
        return f"holds {value.dtype} values, not numbers"
    if size is not None and value.shape[-1] != size:
        return f"has shape {value.shape}, expected {size} values along its last axis"
    values = value[~np.isnan(value)] if allow_nan and value.dtype.kind == "f" else value
    if not np.all(np.isfinite(values)):
        return "holds NaN or infinite values"
    return None


def _class_prior(_: Any, value: Any) -> str | None:
    problem = _array(value, 1, size=len(_DIRECTIONS))
    if problem is None and (np.any(value < 0) or np.any(value > 1)):
        return "holds values outside [0, 1]"
    return problem


def _classes(_: Any, value: Any) -> str | None:
    problem = _array(value, 1)
    if problem is not None:
        return problem
    if value.size == 0 or len(set(value.tolist())) != value.size:
        return f"is {value.tolist()}, not distinct directions"
    if not set(value.tolist()) <= set(_DIRECTIONS):
        return f"is {value.tolist()}, not directions (0, 1, 2)"
    return None


def _angle_params(estimator: Any, value: Any) -> str | None:
    expected = _ANGLE_PARAMS.get(getattr(estimator, "angle_map", ""), None)
    if not isinstance(value, tuple) or not all(_is_number(v) for v in value):
        return f"is {value!r}, not a tuple of numbers"
    if expected is not None and len(value) != expected:
        return f"has {len(value)} values, angle_map={estimator.angle_map!r} needs {expected}"
    if not all(math.isfinite(float(v)) for v in value):
        return "holds NaN or infinite values"
    return None


def _accuracy_grid(_: Any, value: Any) -> str | None:
    return None if value is None else _array(value, 2, allow_nan=True)


def _weights(estimator: Any, value: Any) -> str | None:
    return _array(value, 1, size=getattr(estimator, "n_weights", None))


def _weight_history(estimator: Any, value: Any) -> str | None:
    if not isinstance(value, list):
        return "is not a list of weight arrays"
    for row in value:
        problem = _weights(estimator, row)
        if problem is not None:
            return f"has a row that {problem}"
    return None


def _number_list(_: Any, value: Any) -> str | None:
    if not isinstance(value, list) or not all(_is_number(v) for v in value):
        return "is not a list of numbers"
    return None if all(math.isfinite(float(v)) for v in value) else "holds NaN or infinite values"


def _scaler_params(estimator: Any, value: Any) -> str | None:
    problem = _array(value, 2, allow_nan=getattr(estimator, "scaling", "") == "none", size=2)
    if problem is None and value.shape != (2, 2):
        return f"has shape {value.shape}, expected (2, 2)"
    if problem is None and getattr(estimator, "scaling", "") != "none" and np.isnan(value).any():
        return "holds NaN values"
    return problem


def _columns(_: Any, value: Any) -> str | None:
    return _array(value, 1)


def _coef(estimator: Any, value: Any) -> str | None:
    mean = getattr(estimator, "mean_", None)
    return _array(value, 2, size=mean.size if isinstance(mean, np.ndarray) else None)


_RULES: dict[str, _Rule] = {
    "majority_class_": _direction,
    "n_features_in_": _positive_int,
    "centroid_": _finite,
    "margin_": _finite,
    "objective_": _finite,
    "train_accuracy_": _fraction_or_nan,
    "angle_params_": _angle_params,
    "class_prior_": _class_prior,
    "classes_": _classes,
    "accuracy_grid_": _accuracy_grid,
    "weights_": _weights,
    "initial_weights_": _weights,
    "weight_history_": _weight_history,
    "objective_history_": _number_list,
    "scaler_params_": _scaler_params,
    "fill_": _columns,
    "mean_": _columns,
    "scale_": _columns,
    "coef_": _coef,
    "intercept_": _columns,
}
