"""Finished evaluation units in the cache, so a stopped ``qdcnn evaluate`` resumes.

One unit is one (method, fold, seed, test recording): its test predictions (ints, frame
order), the hyperparameters chosen and the epochs run, as one JSON file written
atomically (:func:`qdcnn._fileio.atomic_write_text`; never pickle). Units are keyed
like the lane features (:func:`qdcnn.direction.features.cache_dir`): by the data's
fingerprints, every setting that changes the result and the code fingerprint, so a
rerun with the same arguments reads back what is done and adding a seed or a method
computes only what is new. An unreadable entry is a miss.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn import __version__
from qdcnn._fileio import write_cache_entry
from qdcnn.direction.features import cache_dir, code_fingerprint
from qdcnn.direction.protocol import FoldStore

__all__ = ["UnitStore", "unit_key"]


def unit_key(**parts: Any) -> str:
    """A cache key of everything that makes a unit's result (JSON of ``parts`` and the code)."""
    payload = json.dumps(
        {**parts, "version": __version__, "code": code_fingerprint()}, sort_keys=True, default=str
    )
    return hashlib.sha256(payload.encode()).hexdigest()[:32]


@dataclass(frozen=True)
class UnitStore(FoldStore):
    """The units of one (method, seed, data, settings) ``key``, one file per fold.

    ``enabled=False`` (``--no-cache``) reads and writes nothing.
    """

    key: str
    enabled: bool = True

    def path(self, fold: int | str) -> Path:
        return cache_dir() / "evaluate" / f"unit-{self.key}-{fold}.json"

    def get(self, fold: int | str) -> tuple[NDArray[np.int64], dict[str, Any], int] | None:
        if not self.enabled:
            return None
        try:
            entry = json.loads(self.path(fold).read_text(encoding="utf-8"))
            predictions = np.asarray(entry["predictions"], dtype=np.int64)
            chosen, epochs = dict(entry["chosen"]), int(entry["epochs_run"])
        except (OSError, ValueError, KeyError, TypeError):
            return None
        if predictions.ndim != 1:
            return None
        return predictions, chosen, epochs

    def put(
        self, fold: int | str, predictions: NDArray[np.int64], chosen: dict[str, Any], epochs: int
    ) -> None:
        if not self.enabled:
            return
        entry = {
            "predictions": np.asarray(predictions, dtype=np.int64).tolist(),
            "chosen": chosen,
            "epochs_run": int(epochs),
        }
        # the cache only saves time: a read-only cache is not an error
        write_cache_entry(self.path(fold), json.dumps(entry, default=_plain).encode())


def _plain(value: Any) -> Any:
    """NumPy scalars in chosen hyperparameters as plain numbers."""
    return value.item() if hasattr(value, "item") else str(value)
