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
from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from qdcnn.errors import InputError, ParameterError

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


def has_shape(array: object, dims: str) -> bool:
    """Whether the shape of ``array`` (a NumPy array, a torch tensor, ...) matches ``dims``.

    Modelled on kornia's ``KORNIA_CHECK_SHAPE``: ``dims`` names the axes, comma-separated;
    a number is that exact size, a name (``N``, ``H``, ``B``) any size, and one ``*`` any
    number of axes at that place. ``|`` separates alternatives. ``"N,H,W,3"`` is a batch of
    RGB images, ``"H,W,3|H,W"`` an RGB or grey image, ``"*,3"`` three values on the last
    axis, ``"N,F,*"`` at least two axes.

    Examples
    --------
    >>> has_shape(np.zeros((2, 4, 4, 3)), "N,H,W,3"), has_shape(np.zeros((4, 4)), "H,W,3")
    (True, False)
    >>> has_shape(np.zeros(5), "*,5"), has_shape(np.zeros((2, 5)), "5|B,5")
    (True, True)
    """
    shape = tuple(int(n) for n in np.shape(array))  # type: ignore[call-overload]
    return any(_matches(shape, alternative) for alternative in dims.split("|"))


def _matches(shape: tuple[int, ...], dims: str) -> bool:
    names = [d.strip() for d in dims.split(",") if d.strip()]
    if "*" in names:
        cut = names.index("*")
        head, tail = names[:cut], names[cut + 1 :]
        if len(shape) < len(head) + len(tail):
            return False
        return _sizes_match(shape[: len(head)], head) and _sizes_match(
            shape[len(shape) - len(tail) :], tail
        )
    return len(shape) == len(names) and _sizes_match(shape, names)


def _sizes_match(shape: tuple[int, ...], names: list[str]) -> bool:
    pairs = zip(shape, names, strict=True)
    return all(not name.isdigit() or size == int(name) for size, name in pairs)


def shape_text(dims: str) -> str:
    """``dims`` of :func:`has_shape` as text: ``"H,W,3|H,W"`` is ``"(H, W, 3) or (H, W)"``.

    Examples
    --------
    >>> shape_text("N"), shape_text("H,W,3|H,W")
    ('(N,)', '(H, W, 3) or (H, W)')
    """
    parts = []
    for alternative in dims.split("|"):
        names = [d.strip() for d in alternative.split(",") if d.strip()]
        parts.append(f"({names[0]},)" if len(names) == 1 else "(" + ", ".join(names) + ")")
    return " or ".join(parts)


def check_shape(name: str, array: object, dims: str, allowed: str | None = None) -> None:
    """Raise :class:`ParameterError` unless ``array`` has the shape ``dims`` (:func:`has_shape`).

    The message names the shape given and ``allowed`` (default: ``shape`` and the ``dims``).

    Examples
    --------
    >>> check_shape("x", np.zeros((3, 2)), "B,2")
    >>> check_shape("x", np.zeros(3), "B,2")
    Traceback (most recent call last):
    ...
    qdcnn.errors.ParameterError: x='shape (3,)' is invalid: shape (B, 2)
    """
    if not has_shape(array, dims):
        shape = tuple(int(n) for n in np.shape(array))  # type: ignore[call-overload]
        raise ParameterError(name, f"shape {shape}", allowed or f"shape {shape_text(dims)}")


def check_input_shape(source: str, array: object, dims: str, expected: str | None = None) -> None:
    """Raise :class:`~qdcnn.errors.InputError` for input data (an image, a mask, a table)
    unless ``array`` has the shape ``dims`` (:func:`has_shape`).

    The message says what was ``expected`` (default: ``shape`` and the ``dims``) and the
    shape given.

    Examples
    --------
    >>> check_input_shape("mask", np.zeros((2, 2, 3)), "H,W", "a 2-D mask (H, W)")
    Traceback (most recent call last):
    ...
    qdcnn.errors.InputError: mask: expected a 2-D mask (H, W), got shape (2, 2, 3)
    """
    if not has_shape(array, dims):
        shape = tuple(int(n) for n in np.shape(array))  # type: ignore[call-overload]
        wanted = expected or f"shape {shape_text(dims)}"
        raise InputError(source, f"expected {wanted}, got shape {shape}")


def check_feature_pairs(
    X: object,
    feature_columns: Sequence[int] | None = None,
    n_features_in: int | None = None,
    name: str = "X",
) -> NDArray[np.float64]:
    """Two feature columns of a table ``X`` as a float array ``(N, 2)`` (NaN kept).

    Parameters
    ----------
    X : array_like, shape (N, F)
        Samples; the two-input classifiers read ``[slope_left, slope_right]``.
    feature_columns : pair of int or None
        ``None`` requires ``F == 2``; a pair picks those two columns of a wider ``X``
        (for example ``(0, 1)`` for the slopes of a feature table with extra columns).
    n_features_in : int or None
        Number of columns seen in ``fit``; ``X`` must have as many.
    name : str
        Name of ``X`` in error messages.

    Examples
    --------
    >>> check_feature_pairs([[1.0, 2.0, 3.0]], (2, 0)).tolist()
    [[3.0, 1.0]]
    """
    try:
        arr = np.asarray(X, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(name, f"<{type(X).__name__}>", "a numeric array (N, 2)") from None
    check_shape(name, arr, "N,F", "a 2-D array (N, F)")
    f = arr.shape[1]
    if n_features_in is not None and f != n_features_in:
        raise ParameterError(name, f"<{f} features>", f"{n_features_in} features, as in fit")
    if feature_columns is None:
        if f != 2:
            raise ParameterError(
                name,
                f"<{f} features>",
                "exactly 2 features [slope_left, slope_right]; "
                "pass feature_columns=(i, j) to pick two columns of a wider table",
            )
        return arr
    cols = tuple(feature_columns)
    ok = len(cols) == 2 and all(_is_int(c) and -f <= int(c) < f for c in cols)
    if not ok or int(cols[0]) % f == int(cols[1]) % f:
        raise ParameterError("feature_columns", feature_columns, f"two distinct indices of {f}")
    return arr[:, [int(c) for c in cols]]


def check_direction_labels(y: object, n_samples: int, n_classes: int = 3) -> NDArray[np.int64]:
    """Class labels as ``int64`` indices ``0 .. n_classes - 1`` (directions: 0 left,
    1 straight, 2 right), one per sample.

    Examples
    --------
    >>> check_direction_labels([2, 0, 1], 3).tolist()
    [2, 0, 1]
    """
    arr = np.asarray(y)
    check_shape("y", arr, str(n_samples))
    allowed = ", ".join(map(str, range(n_classes - 1))) + f" or {n_classes - 1}"
    if not np.issubdtype(arr.dtype, np.number) or arr.dtype == np.bool_:
        raise ParameterError("y", f"<{arr.dtype} array>", f"class indices {allowed}")
    if n_samples and not np.all(np.isin(arr, np.arange(n_classes))):
        raise ParameterError("y", f"<values {np.unique(arr)[:6].tolist()}>", allowed)
    return arr.astype(np.int64)
