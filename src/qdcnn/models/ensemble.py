"""Several networks of one recipe deciding together: a seed ensemble.

A :class:`~qdcnn.models.training.CNNDirectionClassifier` with ``ensemble=K`` trains K
networks of its recipe, network ``k`` with seed :func:`member_seed` (``seed + 1000 k``),
each exactly as a one-network classifier of that seed, and decides by the mean of their
class probabilities (a soft vote: the decision is the mean's most probable class, so it
agrees with the probabilities it reports). A model file keeps the first network's arrays
under their own names (so ``--from`` reads its trunk) and network ``k``'s under
``member{k}.`` (:func:`joined_arrays`, :func:`split_arrays`).
"""

from __future__ import annotations

import os
from typing import Any

from numpy.typing import NDArray

from qdcnn.errors import InputError

#: The most networks an ensemble may hold.
MAX_ENSEMBLE = 9
#: How far apart the networks' seeds are (:func:`member_seed`).
MEMBER_SEED_STRIDE = 1000


def member_seed(seed: int, k: int) -> int:
    """The seed of network ``k`` of an ensemble seeded ``seed``: a run that collapses starts
    again with the next seeds (``restarts``) and ``--seeds`` retrains with ``seed + 1``, ...,
    so the networks' seeds are :data:`MEMBER_SEED_STRIDE` apart, where neither reaches."""
    return seed + k * MEMBER_SEED_STRIDE


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
