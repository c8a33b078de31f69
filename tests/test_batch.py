"""The batch runner keeps going past bad items but never hides programming errors."""

from __future__ import annotations

import pytest

from qdcnn.batch import Failure, run_batch
from qdcnn.errors import InputError, ParameterError


def work(x: int) -> int:
    if x == 2:
        raise InputError(f"item{x}", "broken")
    if x == 3:
        raise ParameterError("size", x, "something else")
    if x == 4:
        raise FileNotFoundError(2, "No such file or directory")
    return x * 10


def test_failures_are_collected_and_the_rest_processed() -> None:
    outcomes = list(run_batch(range(6), work, name=lambda i: f"item{i}"))
    assert [o.result for o in outcomes] == [0, 10, None, None, None, 50]
    assert [o.failure for o in outcomes if o.failure] == [
        Failure("item2", "item2: broken"),
        Failure("item3", "item3: size=3 is invalid: something else"),
        Failure("item4", "item4: No such file or directory"),
    ]


def test_programming_errors_propagate() -> None:
    def buggy(_: int) -> int:
        raise ZeroDivisionError("bug")

    with pytest.raises(ZeroDivisionError):
        list(run_batch([1], buggy))
