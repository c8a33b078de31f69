"""Shot sampling with exactly the statistics of measuring a circuit.

Measuring ``shots`` copies of a state in the computational basis gives counts
that are multinomial with the outcome probabilities (binomial for one qubit).
These functions draw those counts for a whole batch at once from a seeded
:class:`numpy.random.Generator`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import check_shots


def as_generator(seed: int | np.random.Generator | None) -> np.random.Generator:
    """A :class:`numpy.random.Generator` from a seed, or the generator itself."""
    return seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)


def sample_counts(
    probs: NDArray[np.float64], shots: int, rng: int | np.random.Generator | None = None
) -> NDArray[np.int64]:
    """Counts per outcome for each circuit, shape ``(B, d)``, summing to ``shots``.

    Parameters
    ----------
    probs : ndarray, shape (B, d)
        Exact outcome probabilities per circuit.
    shots : int
        Measurements per circuit.
    rng : int, Generator or None
        Seed or generator.
    """
    shots = check_shots(shots)
    gen = as_generator(rng)
    p = np.clip(np.asarray(probs, dtype=np.float64), 0.0, 1.0)
    if p.shape[-1] == 2:
        ones = gen.binomial(shots, p[:, 1] / (p[:, 0] + p[:, 1]))
        return np.stack([shots - ones, ones], axis=1).astype(np.int64)
    p = p / p.sum(axis=1, keepdims=True)
    return gen.multinomial(shots, p).astype(np.int64)


def sample_probabilities(
    probs: NDArray[np.float64], shots: int, rng: int | np.random.Generator | None = None
) -> NDArray[np.float64]:
    """Shot-estimated probabilities: :func:`sample_counts` divided by ``shots``."""
    return sample_counts(probs, shots, rng) / float(shots)
