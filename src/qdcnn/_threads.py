"""One-thread sections for small numerical work.

BLAS and OpenMP thread pools pay off on large arrays; on the many tiny matrix
products of the simulators and on a few dozen points for scikit-learn's k-means
they cost far more than the work (a 300-circuit noisy VQC run: about 9 ms with
one BLAS thread, 40-280 ms with two on a busy 2-core machine).
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from functools import cache
from typing import Any


@cache
def _controller() -> Any:
    from threadpoolctl import ThreadpoolController  # type: ignore[import-untyped]

    return ThreadpoolController()


def single_thread() -> AbstractContextManager[Any]:
    """Context in which BLAS and OpenMP use one thread."""
    return _controller().limit(limits=1)
