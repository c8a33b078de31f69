"""Cached constant tensors that are safe to reuse inside and outside ``torch.inference_mode``.

A tensor first made inside ``torch.inference_mode()`` (a prediction) is an *inference
tensor*: autograd refuses to save it, so a cache that handed it to a later training step
would fail there. Every constant the simulator caches is therefore made with inference
mode switched off.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache, wraps
from typing import Any, TypeVar

import torch

F = TypeVar("F", bound=Callable[..., Any])


def cached_constant(maxsize: int) -> Callable[[F], F]:
    """``functools.lru_cache(maxsize)`` whose results are made outside inference mode."""

    def decorate(fn: F) -> F:
        @lru_cache(maxsize=maxsize)
        @wraps(fn)
        def wrapped(*args: Any) -> Any:
            with torch.inference_mode(False):
                return fn(*args)

        return wrapped  # type: ignore[return-value]

    return decorate


def make_constant(make: Callable[[], Any]) -> Any:
    """``make()`` outside inference mode (for constants kept in an object's own cache)."""
    with torch.inference_mode(False):
        return make()
