"""A trained direction model, its file format and its training.

A :class:`DirectionModel` is a fitted estimator of a registered method
(:mod:`qdcnn.direction.methods`) together with the pipeline settings that made its
inputs. It is saved in the project's one data-only format (:mod:`qdcnn.persistence`):
the method, config, estimator parameters and training summary in the JSON header, the
fitted arrays as safetensors. Loading rebuilds the estimator through the registry and
sets only its declared fitted attributes; nothing in a file can run code.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn.config import PipelineConfig
from qdcnn.data.labels import DIRECTIONS, class_balance
from qdcnn.direction.methods import DirectionMethod, TrainingOptions, get_method
from qdcnn.direction.model_checks import check_estimator_params, check_fitted_attributes
from qdcnn.direction.protocol import fit_with_search
from qdcnn.errors import InputError, ParameterError, QdcnnError
from qdcnn.persistence import (
    DIRECTION_MODEL_KIND,
    DIRECTION_MODEL_VERSION,
    estimator_state,
    load_model,
    restore_estimator_state,
    save_model,
)

__all__ = [
    "DirectionModel",
    "default_config",
    "train_direction_model",
]

KIND = DIRECTION_MODEL_KIND
FORMAT_VERSION = DIRECTION_MODEL_VERSION


def default_config() -> PipelineConfig:
    """The default settings (:meth:`PipelineConfig.udacity`), kept for existing callers."""
    return PipelineConfig()


@dataclass
class DirectionModel:
    """A fitted direction classifier and the pipeline settings of its inputs.

    Attributes
    ----------
    method : str
        Registered method name.
    config : PipelineConfig
        Settings that produced the training inputs (and must produce new ones).
    estimator : estimator
        The fitted classifier.
    trained_on : str
        The dataset spec it was trained on.
    summary : dict
        Training frames, class balance, training accuracy and chosen hyperparameters.
    """

    method: str
    config: PipelineConfig
    estimator: Any
    trained_on: str
    summary: dict[str, Any] = field(default_factory=dict)

    @property
    def info(self) -> DirectionMethod:
        return get_method(self.method)

    @property
    def grouping(self) -> str | None:
        """The lane grouping whose features the model reads (``None`` for frame models)."""
        return self.info.grouping

    def _as_inputs(self, inputs: ArrayLike) -> NDArray[Any]:
        """Frames as given; lane features as a float 2-D table (one frame's row included)."""
        x = np.asarray(inputs)
        return np.atleast_2d(x.astype(np.float64)) if self.info.inputs == "lanes" else x

    def predict(self, inputs: ArrayLike) -> NDArray[np.int64]:
        """Directions (0 left, 1 straight, 2 right) of lane features ``(N, F)`` or frames."""
        return np.asarray(self.estimator.predict(self._as_inputs(inputs)), dtype=np.int64)

    def predict_proba(self, inputs: ArrayLike) -> NDArray[np.float64] | None:
        """Class probabilities ``(N, 3)``, or ``None`` when the estimator has none."""
        if not hasattr(self.estimator, "predict_proba"):
            return None
        return np.asarray(self.estimator.predict_proba(self._as_inputs(inputs)), dtype=np.float64)

    def predict_with_proba(
        self, inputs: ArrayLike
    ) -> tuple[NDArray[np.int64], NDArray[np.float64] | None]:
        """:meth:`predict` and :meth:`predict_proba` together, in one classifier run when the
        estimator offers ``predict_with_proba`` (the same values either way)."""
        both = getattr(self.estimator, "predict_with_proba", None)
        if both is None:
            return self.predict(inputs), self.predict_proba(inputs)
        labels, probs = both(self._as_inputs(inputs))
        return np.asarray(labels, dtype=np.int64), np.asarray(probs, dtype=np.float64)

    def predict_with_proba_each(
        self, inputs: ArrayLike
    ) -> tuple[NDArray[np.int64], NDArray[np.float64] | None]:
        """:meth:`predict_with_proba` of every row as if called with that row alone.

        One estimator call when it offers ``predict_with_proba_each`` (the UU-dagger rule:
        all rows' circuits in one simulation, each row's shots from a generator seeded
        afresh), else one call per row: a batch of video frames gets the decisions the
        frames get one by one, whatever the batch.
        """
        x = self._as_inputs(inputs)
        each = getattr(self.estimator, "predict_with_proba_each", None)
        if each is not None:
            labels, probs = each(x)
            return np.asarray(labels, dtype=np.int64), np.asarray(probs, dtype=np.float64)
        rows = [self.predict_with_proba(x[i : i + 1]) for i in range(len(x))]
        labels = np.concatenate([r[0] for r in rows]) if rows else np.empty(0, np.int64)
        if not rows or rows[0][1] is None:
            return labels, None
        return labels, np.concatenate([r[1] for r in rows if r[1] is not None])

    # ------------------------------------------------------------ persistence

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the model (atomically) in the data-only format; returns the path."""
        state_meta, arrays = _estimator_state(self.estimator)
        meta = {
            "method": self.method,
            "config": self.config.to_dict(),
            "trained_on": self.trained_on,
            "classes": list(DIRECTIONS),
            "params": _params_to_json(self.estimator.get_params()),
            "state": state_meta,
            "summary": self.summary,
        }
        return save_model(path, KIND, FORMAT_VERSION, meta, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> DirectionModel:
        """Read a model written by :meth:`save`.

        Raises
        ------
        InputError
            Missing, corrupt, pickle-based or foreign file, classes other than left,
            straight, right, an unknown method, or settings and arrays that do not fit the
            method's estimator (one line naming the file).
        """
        header, arrays = load_model(path, KIND, {FORMAT_VERSION})
        meta = header.meta
        _check_classes(meta.get("classes", list(DIRECTIONS)), path)
        try:
            method = get_method(str(meta["method"]))
            config = PipelineConfig.from_dict(meta["config"])
            estimator, _ = method.estimator(config)
            estimator.set_params(**_params_from_json(meta["params"]))
            check_estimator_params(estimator)
        except KeyError as exc:
            raise InputError(path, f"model header lacks {exc}") from None
        except (QdcnnError, TypeError, ValueError) as exc:
            raise InputError(path, f"model settings are invalid: {_one_line(exc)}") from None
        _restore_estimator(estimator, meta.get("state", {}), arrays, path)
        return cls(
            method.name,
            config,
            estimator,
            str(meta.get("trained_on", "")),
            dict(meta.get("summary", {})),
        )


def _check_classes(classes: Any, path: str | os.PathLike[str]) -> None:
    """The file's classes are qdcnn's left, straight, right, in that order."""
    if classes != list(DIRECTIONS):
        raise InputError(
            path,
            f"the model's classes {classes!r} are not {list(DIRECTIONS)!r}: it was trained "
            "for other labels than qdcnn's directions",
        )


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def _estimator_state(estimator: Any) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """The estimator's own state functions, or its declared ``fitted_attributes``."""
    if hasattr(estimator, "fitted_state"):
        meta, arrays = estimator.fitted_state()
        return {"custom": meta}, arrays
    attributes = getattr(estimator, "fitted_attributes", None)
    if attributes is None:
        raise ParameterError(
            "estimator",
            type(estimator).__name__,
            "an estimator with fitted_attributes or fitted_state() to be saved",
        )
    return estimator_state(estimator, attributes)


def _restore_estimator(
    estimator: Any, meta: Any, arrays: dict[str, NDArray[Any]], source: str | os.PathLike[str]
) -> None:
    if not isinstance(meta, dict):
        raise InputError(source, "model header field 'state' is not an object")
    if hasattr(estimator, "load_fitted_state"):
        estimator.load_fitted_state(meta.get("custom", {}), arrays, source)
        return
    restore_estimator_state(estimator, estimator.fitted_attributes, meta, arrays, source)
    check_fitted_attributes(estimator, source)


def _params_to_json(params: dict[str, Any]) -> dict[str, Any]:
    """Estimator parameters as JSON: noise models by their label, tuples as lists."""
    out: dict[str, Any] = {}
    for key, value in params.items():
        if hasattr(value, "label") and callable(value.label):
            out[key] = {"noise": value.label()}
        elif isinstance(value, Path):
            out[key] = str(value)
        elif isinstance(value, tuple):
            out[key] = list(value)
        elif isinstance(value, float) and not math.isfinite(value):
            out[key] = {"float": repr(value)}
        else:
            out[key] = value
    return out


def _params_from_json(params: Any) -> dict[str, Any]:
    from qdcnn.quantum.noise_text import parse_noise

    if not isinstance(params, dict):
        raise TypeError("params is not an object")
    out: dict[str, Any] = {}
    for key, value in params.items():
        if isinstance(value, dict) and set(value) == {"noise"}:
            text = str(value["noise"])
            out[key] = None if text == "ideal" else parse_noise(text)
        elif isinstance(value, dict) and set(value) == {"float"}:
            out[key] = float(value["float"])
        elif isinstance(value, list):
            out[key] = tuple(value)
        else:
            out[key] = value
    return out


# ---------------------------------------------------------------- training


def train_direction_model(
    method: str | DirectionMethod,
    inputs: ArrayLike,
    labels: NDArray[np.int64],
    config: PipelineConfig,
    trained_on: str,
    *,
    inner_folds: int = 3,
    gap: int = 5,
    options: TrainingOptions | None = None,
) -> DirectionModel:
    """Fit ``method`` on ``inputs`` (lane features or frames), hyperparameters by inner CV.

    The grid values are chosen by the contiguous inner cross-validation that
    ``qdcnn evaluate`` runs in each fold (:func:`~qdcnn.direction.protocol.fit_with_search`),
    then the estimator is refitted on all of ``inputs``.
    """
    m = get_method(method) if isinstance(method, str) else method
    y = np.asarray(labels, dtype=np.int64)
    estimator, grid = m.estimator(config, options)
    fitted, chosen = fit_with_search(estimator, grid, inputs, y, inner_folds=inner_folds, gap=gap)
    predictions = np.asarray(fitted.predict(inputs), dtype=np.int64)
    summary = {
        "n": int(y.size),
        "class_balance": class_balance(y),
        "training_accuracy": float(np.mean(predictions == y)),
        "chosen_hyperparameters": chosen,
    }
    for key, attribute in (("history", "history_"), ("restarts", "restarts_"), ("seed", "seed_")):
        if hasattr(fitted, attribute):  # CNNs and hybrids: per-epoch diagnostics
            summary[key] = getattr(fitted, attribute)
    return DirectionModel(m.name, config, fitted, trained_on, summary)
