"""Several networks of one recipe deciding together: a seed ensemble.

A :class:`~qdcnn.models.training.CNNDirectionClassifier` with ``ensemble=K`` trains K
networks of its recipe with seeds ``seed .. seed + K - 1`` (the runs that ``qdcnn
evaluate --seeds K`` scores one by one) and decides by majority vote (:func:`vote`); its
probabilities are the networks' mean. A model file keeps the first network's arrays
under their own names (so ``--from`` reads its trunk) and network ``k``'s under
``member{k}.`` (:func:`joined_arrays`, :func:`split_arrays`).
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn.errors import InputError

#: The most networks an ensemble may hold.
MAX_ENSEMBLE = 9


def vote(runs: NDArray[np.int64], n_classes: int = 3) -> NDArray[np.int64]:
    """Each frame's class given by most of ``runs`` ``(K, N)``; a tie goes to the
    earliest run's class among the tied ones (with three runs and three classes: the
    first run's)."""
    runs = np.atleast_2d(np.asarray(runs, dtype=np.int64))
    frames = np.arange(runs.shape[1])
    counts = np.zeros((runs.shape[1], n_classes), dtype=np.int64)
    for run in runs:
        np.add.at(counts, (frames, run), 1)
    most = counts.max(axis=1)
    out = np.full(runs.shape[1], -1, dtype=np.int64)
    for run in runs:
        pick = (out < 0) & (counts[frames, run] == most)
        out[pick] = run[pick]
    return out


def _prefix(k: int) -> str:
    return f"member{k}."


def joined_arrays(members: list[dict[str, NDArray[Any]]]) -> dict[str, NDArray[Any]]:
    """The networks' arrays in one mapping: the first's names as they are, network
    ``k``'s (``k >= 1``) prefixed ``member{k}.``."""
    out = dict(members[0])
    for k, arrays in enumerate(members[1:], start=1):
        out.update({_prefix(k) + name: value for name, value in arrays.items()})
    return out


def split_arrays(
    arrays: dict[str, NDArray[Any]], networks: int, source: str | os.PathLike[str]
) -> list[dict[str, NDArray[Any]]]:
    """:func:`joined_arrays` undone for ``networks`` networks.

    Raises
    ------
    InputError
        The file holds arrays of another number of networks (one line naming it).
    """
    parts: list[dict[str, NDArray[Any]]] = [{} for _ in range(networks)]
    for name, value in arrays.items():
        head, dot, rest = name.partition(".")
        k = int(head[6:]) if head.startswith("member") and head[6:].isdigit() and dot else 0
        if k >= networks:
            raise InputError(source, f"holds arrays of network {k + 1}, its header says {networks}")
        parts[k][rest if k else name] = value
    if any(not part for part in parts):
        raise InputError(source, f"holds arrays of fewer networks than its header's {networks}")
    return parts
