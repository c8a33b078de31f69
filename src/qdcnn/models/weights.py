"""Reading and checking local ``state_dict`` weight files, with one-line errors.

Nothing is ever downloaded: weights come from a file the user names, for example
torchvision's ImageNet ResNet-50 file saved elsewhere. A file is either a
safetensors file (recognised by its header, whatever its name) or a PyTorch file
read with ``torch.load(weights_only=True)``; neither can run code when loaded.
"""

from __future__ import annotations

import json
import os
import struct
from collections.abc import Mapping
from pathlib import Path

from qdcnn._optional import require
from qdcnn.errors import InputError

require("torch", "loading CNN weights")
import torch  # noqa: E402
from torch import nn  # noqa: E402

# safetensors itself refuses headers over 100 MB
_MAX_SAFETENSORS_HEADER = 100_000_000
# BatchNorm's step counter: absent from older torchvision files and irrelevant to inference.
_OPTIONAL_SUFFIXES: tuple[str, ...] = (".num_batches_tracked",)


def _read_weights_file(path: str | os.PathLike[str]) -> object:
    """Unpickle a PyTorch file safely (tensors, dicts, lists and numbers only).

    Raises
    ------
    InputError
        The file is missing, a directory, corrupt, or holds pickled Python objects.
    """
    p = Path(path)
    _check_exists(p)
    try:
        return torch.load(p, map_location="cpu", weights_only=True)
    except PermissionError:
        raise InputError(p, "cannot read: permission denied") from None
    except Exception as exc:  # torch raises UnpicklingError, RuntimeError, EOFError, ...
        if "global" in str(exc).lower():
            raise InputError(
                p,
                "holds pickled Python objects, not a plain state_dict "
                "(save model.state_dict() instead)",
            ) from None
        raise InputError(
            p, "not a readable PyTorch weights file (corrupt, truncated or another format)"
        ) from None


def _is_safetensors_file(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` starts like a safetensors file: a little-endian header length, then ``{``.

    A truncated safetensors file still counts (it then fails to read with a safetensors
    message); a missing or unreadable path does not.
    """
    try:
        with open(path, "rb") as fh:
            start = fh.read(9)
    except OSError:
        return False
    if len(start) < 9:
        return False
    (header_len,) = struct.unpack("<Q", start[:8])
    return start[8:9] == b"{" and header_len < _MAX_SAFETENSORS_HEADER


def _read_safetensors_file(path: str | os.PathLike[str]) -> dict[str, torch.Tensor]:
    """All tensors of a safetensors file, on the CPU.

    Raises
    ------
    InputError
        The file is missing, a directory, empty, or not a readable safetensors file.
    """
    from safetensors import SafetensorError
    from safetensors.torch import load_file

    p = Path(path)
    _check_exists(p)
    try:
        return dict(load_file(p, device="cpu"))
    except (SafetensorError, OSError, ValueError, json.JSONDecodeError) as exc:
        reason = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise InputError(p, f"not a readable safetensors file ({reason})") from None


def _read_state_dict(path: str | os.PathLike[str]) -> dict[str, torch.Tensor]:
    """The ``state_dict`` in a safetensors or PyTorch weights file (see :func:`_as_state_dict`)."""
    if _is_safetensors_file(path):
        return _as_state_dict(_read_safetensors_file(path), path)
    return _as_state_dict(_read_weights_file(path), path)


def _check_exists(p: Path) -> None:
    if not p.exists():
        raise InputError(p, "file not found")
    if p.is_dir():
        raise InputError(p, "is a directory, not a weights file")
    if p.stat().st_size == 0:
        raise InputError(p, "empty file (0 bytes)")


def _as_state_dict(obj: object, path: str | os.PathLike[str]) -> dict[str, torch.Tensor]:
    """Extract a ``state_dict`` from what a weights file held.

    Accepts a plain ``state_dict``, a training checkpoint holding one under
    ``"state_dict"``, ``"model_state_dict"`` or ``"model"``, and strips the
    ``"module."`` prefix ``DataParallel`` adds.
    """
    if isinstance(obj, Mapping):
        for key in ("state_dict", "model_state_dict", "model"):
            if isinstance(obj.get(key), Mapping):
                obj = obj[key]
                break
    if not isinstance(obj, Mapping):
        raise InputError(path, f"holds a {type(obj).__name__}, not a state_dict")
    if not obj:
        raise InputError(path, "holds an empty state_dict")
    state: dict[str, torch.Tensor] = {}
    for key, value in obj.items():
        if not isinstance(key, str) or not isinstance(value, torch.Tensor):
            raise InputError(
                path, f"not a state_dict: entry {key!r} is a {type(value).__name__}, not a tensor"
            )
        state[key] = value
    if all(k.startswith("module.") for k in state):
        state = {k.removeprefix("module."): v for k, v in state.items()}
    return state


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def check_state_dict(
    state: Mapping[str, torch.Tensor],
    model: nn.Module,
    path: str | os.PathLike[str],
    *,
    name: str,
    skip_prefixes: tuple[str, ...] = (),
) -> dict[str, torch.Tensor]:
    """Check that ``state`` fits ``model`` key by key and shape by shape.

    Parameters
    ----------
    state : mapping of str to Tensor
        Weights read from ``path``.
    model : nn.Module
        The model they are meant for.
    path : str or path-like
        The file, for error messages.
    name : str
        What the file should hold, for error messages (``"torchvision ResNet-50"``).
    skip_prefixes : tuple of str
        Keys ignored on both sides, such as ``("fc.",)`` when the head is replaced.

    Returns
    -------
    dict of str to Tensor
        The entries of ``state`` to load (skipped keys removed).

    Raises
    ------
    InputError
        Keys are missing or unexpected, shapes differ, or values are not finite.
    """
    expected = {k: v for k, v in model.state_dict().items() if not k.startswith(skip_prefixes)}
    given = {k: v for k, v in state.items() if not k.startswith(skip_prefixes)}
    missing = [k for k in expected if k not in given and not k.endswith(_OPTIONAL_SUFFIXES)]
    unexpected = [k for k in given if k not in expected]
    problems = []
    if missing:
        problems.append(f"missing {_count(len(missing), 'key')} such as {missing[0]}")
    if unexpected:
        problems.append(f"unexpected {_count(len(unexpected), 'key')} such as {unexpected[0]}")
    if problems:
        raise InputError(path, f"not a {name} state_dict: " + "; ".join(problems))
    wrong = [k for k, v in given.items() if tuple(v.shape) != tuple(expected[k].shape)]
    if wrong:
        k = wrong[0]
        raise InputError(
            path,
            f"not a {name} state_dict: {_count(len(wrong), 'tensor')} with the wrong shape, "
            f"such as {k} {tuple(given[k].shape)} instead of {tuple(expected[k].shape)}",
        )
    for k, v in given.items():
        # a sum is NaN or infinite when any element is (a cheap screen); confirm element-wise
        if v.is_floating_point() and not bool(torch.isfinite(v.sum())):
            if not bool(torch.isfinite(v).all()):
                raise InputError(path, f"weights contain NaN or infinite values (in {k})")
    return given


def inflate_input_channels(
    state: Mapping[str, torch.Tensor], model: nn.Module
) -> dict[str, torch.Tensor]:
    """Fit RGB first-layer kernels to a network that takes K stacked RGB frames.

    A 4-d convolution kernel of shape ``(O, 3, kh, kw)`` in ``state`` whose
    counterpart in ``model`` has shape ``(O, 3K, kh, kw)`` is tiled K times along
    its input channels and divided by K, so K identical frames give the pretrained
    layer's output (the usual "inflation" of image weights to frame stacks). Every
    other entry is returned unchanged.
    """
    expected = model.state_dict()
    out = dict(state)
    for key, value in state.items():
        target = expected.get(key)
        if target is None or value.ndim != 4 or target.ndim != 4 or value.shape[1] != 3:
            continue
        k, rest = divmod(int(target.shape[1]), 3)
        same_other = value.shape[0] == target.shape[0] and value.shape[2:] == target.shape[2:]
        if k > 1 and rest == 0 and same_other:
            out[key] = value.repeat(1, k, 1, 1) / k
    return out


def load_weights(
    model: nn.Module,
    path: str | os.PathLike[str],
    *,
    name: str,
    skip_prefixes: tuple[str, ...] = (),
) -> None:
    """Read a local weights file, check it against ``model`` and copy it in place.

    Keys under ``skip_prefixes`` keep the model's own values (for example a new
    3-class ``fc`` head on an ImageNet backbone). RGB first-layer kernels are
    inflated to a model that takes stacked frames (:func:`inflate_input_channels`).

    Examples
    --------
    >>> from qdcnn.models.resnet import resnet50
    >>> model = resnet50(num_classes=3)
    >>> load_weights(model, "missing.pth", name="torchvision ResNet-50", skip_prefixes=("fc.",))
    Traceback (most recent call last):
    ...
    qdcnn.errors.InputError: missing.pth: file not found
    """
    state = inflate_input_channels(_read_state_dict(path), model)
    checked = check_state_dict(state, model, path, name=name, skip_prefixes=skip_prefixes)
    model.load_state_dict(checked, strict=False)
