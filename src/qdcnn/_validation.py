"""One shared module of input checks, each raising one error type per mistake.

Modelled on ``kornia/core/check.py``: every public function validates one kind of
value and either returns it (converted to the plain Python type) or raises
:class:`~qdcnn.errors.ParameterError` whose message names the parameter, the value
given and what is allowed. Booleans are never accepted as numbers.

Examples
--------
>>> check_int("folds", 5, 2, 100)
5
>>> check_int("folds", True, 2, 100)
Traceback (most recent call last):
...
qdcnn.errors.ParameterError: folds=True is invalid: an integer in [2, 100]
>>> check_choice("edges", "rgb", ("grey", "rgb"))
'rgb'
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from qdcnn.errors import ParameterError

#: Largest seed numpy's ``default_rng`` and torch's ``manual_seed`` both accept.
MAX_SEED = 2**32 - 1


def _is_int(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool | np.bool_)


def _is_number(value: object) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )


def check_int(name: str, value: object, lo: int | None = None, hi: int | None = None) -> int:
    """``value`` as an ``int`` if it is an integer in ``[lo, hi]`` (open ends when ``None``)."""
    ok = _is_int(value)
    if ok and lo is not None and int(value) < lo:  # type: ignore[call-overload]
        ok = False
    if ok and hi is not None and int(value) > hi:  # type: ignore[call-overload]
        ok = False
    if not ok:
        raise ParameterError(name, value, _int_range(lo, hi))
    return int(value)  # type: ignore[call-overload]


def _int_range(lo: int | None, hi: int | None) -> str:
    if lo is not None and hi is not None:
        return f"an integer in [{lo}, {hi}]"
    if lo is not None:
        return f"an integer >= {lo}"
    if hi is not None:
        return f"an integer <= {hi}"
    return "an integer"


def check_float(
    name: str,
    value: object,
    lo: float = -math.inf,
    hi: float = math.inf,
    *,
    open_lo: bool = False,
    open_hi: bool = False,
) -> float:
    """``value`` as a finite ``float`` in the interval from ``lo`` to ``hi``.

    ``open_lo`` / ``open_hi`` exclude the end points.
    """
    ok = _is_number(value) and math.isfinite(float(value))  # type: ignore[arg-type]
    if ok:
        v = float(value)  # type: ignore[arg-type]
        ok = (v > lo if open_lo else v >= lo) and (v < hi if open_hi else v <= hi)
    if not ok:
        left = "(" if open_lo else "["
        right = ")" if open_hi else "]"
        raise ParameterError(name, value, f"a finite number in {left}{lo:g}, {hi:g}{right}")
    return float(value)  # type: ignore[arg-type]


def check_probability(name: str, value: object) -> float:
    """``value`` as a ``float`` if it is a probability in [0, 1]."""
    if not (_is_number(value) and math.isfinite(float(value)) and 0 <= float(value) <= 1):  # type: ignore[arg-type]
        raise ParameterError(name, value, "a probability in [0, 1]")
    return float(value)  # type: ignore[arg-type]


def check_bool(name: str, value: object) -> bool:
    """``value`` if it is ``True`` or ``False`` (numpy booleans included)."""
    if not isinstance(value, bool | np.bool_):
        raise ParameterError(name, value, "True or False")
    return bool(value)


def check_seed(name: str, value: object) -> int:
    """A seed: an integer in ``[0, 2**32 - 1]``."""
    return check_int(name, value, 0, MAX_SEED)


def check_choice(name: str, value: object, choices: Iterable[str]) -> str:
    """``value`` if it is one of ``choices``."""
    options = tuple(choices)
    if not isinstance(value, str) or value not in options:
        raise ParameterError(name, value, "one of " + ", ".join(map(repr, options)))
    return value


def check_odd(name: str, value: object, lo: int = 1, hi: int = 255) -> int:
    """An odd integer in ``[lo, hi]`` (filter apertures)."""
    if not (_is_int(value) and lo <= int(value) <= hi and int(value) % 2 == 1):  # type: ignore[call-overload]
        raise ParameterError(name, value, f"an odd integer in [{lo}, {hi}]")
    return int(value)  # type: ignore[call-overload]


def check_shots(value: object, name: str = "shots", hi: int = 10**9) -> int:
    """Shots per circuit: an integer in ``[1, hi]``."""
    return check_int(name, value, 1, hi)


def check_optional_shots(value: object, name: str = "shots") -> int | None:
    """``None`` (exact probabilities) or :func:`check_shots`."""
    return None if value is None else check_shots(value, name)
