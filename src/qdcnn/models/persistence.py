"""CNN model files and training checkpoints in qdcnn's one model format (JSON header + safetensors).

A direction-classifier file (kind :data:`MODEL_KIND`, format version
:data:`MODEL_FORMAT_VERSION`) holds the network's ``state_dict`` as arrays under
their ``state_dict`` names, and the header ``meta`` the caller gives (for
:class:`~qdcnn.models.training.CNNDirectionClassifier`: architecture, estimator
params, class names, input spec, history, best epoch). A training checkpoint
(kind :data:`_CHECKPOINT_KIND`) adds the optimiser's state: its tensors as arrays
``optimizer.state.<param index>.<name>``, its parameter groups and the
learning-rate scheduler's state as JSON. Nothing is ever unpickled
(:func:`qdcnn.persistence.load_model` refuses pickle and torch files).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import require
from qdcnn.errors import InputError
from qdcnn.models.specs import COLOURS, InputSpec
from qdcnn.persistence import load_model, save_model

require("torch", "saving and loading CNN models")
import torch  # noqa: E402
from torch import nn  # noqa: E402

MODEL_KIND = "qdcnn-cnn-direction-classifier"
MODEL_FORMAT_VERSION = 2
_CHECKPOINT_KIND = "qdcnn-cnn-training-checkpoint"
_CHECKPOINT_FORMAT_VERSION = 1
_MODEL_PREFIX = "model."
_OPTIMIZER_PREFIX = "optimizer.state."
# Header field listing the 0-d arrays (BatchNorm's num_batches_tracked, AdamW's step): they
# are stored with shape (1,), as qdcnn.persistence.save_model's np.ascontiguousarray makes them.
_SCALARS = "scalar_arrays"


def json_safe(value: Any) -> Any:
    """``value`` with tuples as lists and NaN / infinite floats as ``None`` (JSON has neither)."""
    if isinstance(value, Mapping):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def state_arrays(network: nn.Module) -> dict[str, NDArray[Any]]:
    """The network's ``state_dict`` as NumPy arrays on the CPU (copies)."""
    return {k: v.detach().cpu().numpy().copy() for k, v in network.state_dict().items()}


def _save(
    path: str | os.PathLike[str],
    kind: str,
    version: int,
    meta: Mapping[str, Any],
    arrays: Mapping[str, NDArray[Any]],
) -> Path:
    scalars = sorted(k for k, v in arrays.items() if v.ndim == 0)
    stored = {k: (v.reshape(1) if v.ndim == 0 else v) for k, v in arrays.items()}
    return save_model(path, kind, version, {**json_safe(meta), _SCALARS: scalars}, stored)


def _load(
    path: str | os.PathLike[str], kind: str, version: int
) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    header, arrays = load_model(path, kind, {version})
    meta = dict(header.meta)
    scalars = meta.pop(_SCALARS, [])
    if not isinstance(scalars, list) or not all(isinstance(k, str) for k in scalars):
        raise InputError(path, f"header field {_SCALARS!r} is not a list of array names")
    for name in scalars:
        if name not in arrays or arrays[name].shape != (1,):
            raise InputError(
                path, f"header lists {name!r} as a scalar, the file holds no such array"
            )
        arrays[name] = arrays[name].reshape(())
    return meta, arrays


def save_network(path: str | os.PathLike[str], network: nn.Module, meta: Mapping[str, Any]) -> Path:
    """Write ``network``'s weights and ``meta`` as a :data:`MODEL_KIND` file (atomic)."""
    return _save(path, MODEL_KIND, MODEL_FORMAT_VERSION, meta, state_arrays(network))


def read_network_file(
    path: str | os.PathLike[str],
) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """Header ``meta`` and weight arrays of a :data:`MODEL_KIND` file.

    Raises
    ------
    InputError
        Missing, empty, pickle or torch, corrupt or truncated file, another kind or version.
    """
    return _load(path, MODEL_KIND, MODEL_FORMAT_VERSION)


def read_saved_network(
    path: str | os.PathLike[str],
) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """Header ``meta`` and weight arrays of a CNN or hybrid network saved by qdcnn: a
    :data:`MODEL_KIND` file, or a direction model (``train-direction``) holding one.

    Raises
    ------
    InputError
        Neither, or a direction model of a method that is not a CNN (one line).
    """
    from qdcnn.persistence import DIRECTION_MODEL_KIND, DIRECTION_MODEL_VERSION

    try:
        return read_network_file(path)
    except InputError as first:
        try:
            header, arrays = load_model(path, DIRECTION_MODEL_KIND, {DIRECTION_MODEL_VERSION})
        except InputError:
            raise first from None
    state = header.meta.get("state")
    custom = state.get("custom") if isinstance(state, dict) else None
    if not isinstance(custom, dict) or "architecture" not in custom:
        method = header.meta.get("method")
        raise InputError(path, f"the model's method {method!r} has no trained network")
    return dict(custom), arrays


def load_state_arrays(
    network: nn.Module, arrays: Mapping[str, NDArray[Any]], path: str | os.PathLike[str], name: str
) -> None:
    """Copy ``arrays`` into ``network`` after checking every name and shape against it.

    Raises
    ------
    InputError
        Missing or unexpected arrays, wrong shapes or non-finite values (one line,
        :func:`qdcnn.models.weights.check_state_dict`).
    """
    from qdcnn.models.weights import check_state_dict

    state = {k: torch.from_numpy(np.array(v)) for k, v in arrays.items()}
    checked = check_state_dict(state, network, path, name=name)
    expected = network.state_dict()
    for key, value in checked.items():
        if value.dtype != expected[key].dtype:
            raise InputError(
                path, f"array {key} is {value.dtype}, the network expects {expected[key].dtype}"
            )
    network.load_state_dict(checked, strict=False)


def spec_to_meta(spec: InputSpec) -> dict[str, Any]:
    """An :class:`InputSpec` as plain JSON values."""
    return {
        "crop": list(spec.crop),
        "height": spec.height,
        "width": spec.width,
        "colour": spec.colour,
    }


def spec_from_meta(value: object, path: str | os.PathLike[str]) -> InputSpec:
    """The :class:`InputSpec` a header stores, checked field by field.

    Raises
    ------
    InputError
        A missing or malformed field (naming it).
    """
    if not isinstance(value, Mapping):
        raise InputError(path, "header field 'input_spec' is missing or not an object")
    crop = value.get("crop")
    ok_crop = (
        isinstance(crop, list)
        and len(crop) == 2
        and all(isinstance(c, int | float) and not isinstance(c, bool) for c in crop)
        and 0.0 <= crop[0] < crop[1] <= 1.0
    )
    if not ok_crop:
        raise InputError(path, f"header input_spec crop {crop!r} is not [top, bottom] in [0, 1]")
    size = [value.get("height"), value.get("width")]
    if not all(isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 8192 for v in size):
        raise InputError(path, f"header input_spec size {size!r} is not two integers in [1, 8192]")
    colour = value.get("colour")
    if colour not in COLOURS:
        raise InputError(path, f"header input_spec colour {colour!r} is not one of {COLOURS}")
    return InputSpec((float(crop[0]), float(crop[1])), size[0], size[1], colour)  # type: ignore[index, arg-type]


def history_from_meta(
    meta: Mapping[str, Any], path: str | os.PathLike[str]
) -> tuple[list[dict[str, Any]], int]:
    """The training history and best epoch a header stores, checked.

    Raises
    ------
    InputError
        ``history`` is not a list of epoch records, or ``best_epoch`` not one of its epochs.
    """
    history = meta.get("history", [])
    if not isinstance(history, list) or not all(isinstance(h, dict) for h in history):
        raise InputError(path, "header field 'history' is not a list of epoch records")
    best = meta.get("best_epoch", 0)
    if isinstance(best, bool) or not isinstance(best, int) or not 0 <= best <= len(history):
        raise InputError(path, f"header best_epoch {best!r} is not an epoch of its history")
    return history, best


# ---------------------------------------------------------------- checkpoints
def save_checkpoint(
    path: str | os.PathLike[str],
    network: nn.Module,
    optimiser: torch.optim.Optimizer,
    meta: Mapping[str, Any],
    scheduler: torch.optim.lr_scheduler.LRScheduler | None = None,
) -> Path:
    """Write network, optimiser (and scheduler) state as a :data:`_CHECKPOINT_KIND` file.

    The optimiser's per-parameter tensors (AdamW's ``step``, ``exp_avg``,
    ``exp_avg_sq``) become arrays; its parameter groups (learning rate, betas, ...),
    any non-tensor per-parameter values and the scheduler's state go to the header.
    Random-number-generator states are not stored.
    """
    arrays = {_MODEL_PREFIX + k: v for k, v in state_arrays(network).items()}
    opt = optimiser.state_dict()
    scalars: dict[str, dict[str, Any]] = {}
    for index, entries in opt["state"].items():
        for name, value in entries.items():
            if isinstance(value, torch.Tensor):
                arrays[f"{_OPTIMIZER_PREFIX}{index}.{name}"] = value.detach().cpu().numpy().copy()
            else:
                scalars.setdefault(str(index), {})[name] = value
    header = {
        **meta,
        "optimizer": {
            "class": type(optimiser).__name__,
            "param_groups": opt["param_groups"],
            "scalars": scalars,
        },
        "scheduler": None if scheduler is None else scheduler.state_dict(),
    }
    return _save(path, _CHECKPOINT_KIND, _CHECKPOINT_FORMAT_VERSION, header, arrays)


def load_checkpoint(
    path: str | os.PathLike[str],
    network: nn.Module,
    optimiser: torch.optim.Optimizer | None = None,
    scheduler: torch.optim.lr_scheduler.LRScheduler | None = None,
    *,
    name: str = "checkpoint",
) -> dict[str, Any]:
    """Restore a :func:`save_checkpoint` file into ``network`` (and optimiser, scheduler).

    Returns
    -------
    dict
        The header ``meta`` (history, epoch, ... as the trainer wrote them).

    Raises
    ------
    InputError
        Not a checkpoint, weights that do not fit ``network``, or optimiser state
        of another optimiser class or parameter count.
    """
    meta, arrays = _load(path, _CHECKPOINT_KIND, _CHECKPOINT_FORMAT_VERSION)
    model = {
        k.removeprefix(_MODEL_PREFIX): v for k, v in arrays.items() if k.startswith(_MODEL_PREFIX)
    }
    load_state_arrays(network, model, path, name)
    if optimiser is not None:
        state = _optimizer_state(path, meta.get("optimizer"), arrays, optimiser)
        try:
            optimiser.load_state_dict(state)
        except (ValueError, KeyError, TypeError, RuntimeError) as exc:
            raise InputError(path, f"optimiser state does not fit: {exc}") from None
    if scheduler is not None:
        if not isinstance(meta.get("scheduler"), dict):
            raise InputError(path, "checkpoint holds no learning-rate scheduler state")
        scheduler.load_state_dict(meta["scheduler"])
    return meta


def _optimizer_state(
    path: str | os.PathLike[str],
    saved: object,
    arrays: Mapping[str, NDArray[Any]],
    optimiser: torch.optim.Optimizer,
) -> dict[str, Any]:
    if not isinstance(saved, dict) or not isinstance(saved.get("param_groups"), list):
        raise InputError(path, "checkpoint holds no optimiser state")
    if saved.get("class") != type(optimiser).__name__:
        raise InputError(
            path, f"optimiser state of {saved.get('class')!r}, not {type(optimiser).__name__!r}"
        )
    groups = [
        {k: (tuple(v) if isinstance(v, list) and k != "params" else v) for k, v in group.items()}
        for group in saved["param_groups"]
    ]
    n_saved = sum(len(g.get("params", [])) for g in groups)
    n_here = sum(len(g["params"]) for g in optimiser.param_groups)
    if n_saved != n_here:
        raise InputError(
            path, f"optimiser state for {n_saved} parameters, the network has {n_here}"
        )
    state: dict[int, dict[str, Any]] = {}
    for key, value in arrays.items():
        if key.startswith(_OPTIMIZER_PREFIX):
            index, _, name = key.removeprefix(_OPTIMIZER_PREFIX).partition(".")
            entry = state.setdefault(_param_index(path, index, n_here), {})
            entry[name] = torch.from_numpy(np.array(value))
    scalars = saved.get("scalars") or {}
    if not isinstance(scalars, dict):
        raise InputError(path, "checkpoint optimiser scalars are not an object")
    for index, entries in scalars.items():
        if not isinstance(entries, dict):
            raise InputError(path, f"checkpoint optimiser scalars of parameter {index!r} malformed")
        state.setdefault(_param_index(path, index, n_here), {}).update(entries)
    return {"state": state, "param_groups": groups}


def _param_index(path: str | os.PathLike[str], text: str, n: int) -> int:
    if not text.isdigit() or int(text) >= n:
        raise InputError(path, f"optimiser state for parameter {text!r} of {n}")
    return int(text)
