"""One data-only file format for every saved model: a JSON header plus named arrays.

A model file is a `safetensors <https://huggingface.co/docs/safetensors>`_ file: the
arrays (weights, fitted parameters) as raw tensors, and under the metadata key
``"qdcnn"`` one JSON header::

    {"kind": "qdcnn-direction-model", "format_version": 1, "qdcnn_version": "0.1.0",
     "meta": {...}}

``meta`` holds the model's settings (config, class names, method, training data).
Loading never runs code: safetensors checks that the header's offsets and shapes
cover the file exactly, and the JSON header is plain data. Shadow models, which have
no arrays, are JSON files with the same header fields (:func:`save_json_model`).

Files written by older qdcnn versions with pickle are recognised by their first bytes
and refused with a message saying how to retrain; they are never unpickled.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn import __version__
from qdcnn._fileio import atomic_write_bytes, atomic_write_text
from qdcnn.errors import InputError

_METADATA_KEY = "qdcnn"
#: Kind and format version of a trained direction model (:mod:`qdcnn.direction.model`).
DIRECTION_MODEL_KIND = "qdcnn-direction-model"
DIRECTION_MODEL_VERSION = 2
#: JSON model files larger than this are refused before parsing.
MAX_JSON_BYTES = 16 * 2**20
#: Deepest nesting accepted in a JSON header (the parser recurses per level).
MAX_JSON_DEPTH = 64
_PICKLE_MAGIC = (b"\x80", b"PK\x03\x04")


@dataclass(frozen=True)
class ModelHeader:
    """What every saved model says about itself.

    Attributes
    ----------
    kind : str
        What the file holds, for example ``"qdcnn-direction-model"``.
    format_version : int
        Version of that kind's layout; loaders list the versions they read.
    qdcnn_version : str
        The qdcnn version that wrote the file.
    meta : dict
        Settings of the model (plain JSON values).
    """

    kind: str
    format_version: int
    qdcnn_version: str = __version__
    meta: dict[str, Any] = field(default_factory=dict)

    def to_json(self) -> str:
        return json.dumps(
            {
                "kind": self.kind,
                "format_version": self.format_version,
                "qdcnn_version": self.qdcnn_version,
                "meta": self.meta,
            },
            allow_nan=False,
            default=_plain,
        )


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, tuple | set | frozenset):
        return list(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def save_model(
    path: str | os.PathLike[str],
    kind: str,
    format_version: int,
    meta: Mapping[str, Any],
    arrays: Mapping[str, NDArray[Any]],
) -> Path:
    """Write a model as safetensors with its JSON header; atomic (never half-written).

    Parameters
    ----------
    path : path-like
        Target file (conventionally ``*.safetensors``).
    kind, format_version : str, int
        The header's identity (:class:`ModelHeader`).
    meta : mapping
        Plain JSON settings.
    arrays : mapping of str to ndarray
        Named arrays; they are stored contiguous, in their dtype.
    """
    from safetensors.numpy import save

    header = ModelHeader(kind, int(format_version), __version__, dict(meta))
    tensors = {name: np.ascontiguousarray(a).reshape(np.shape(a)) for name, a in arrays.items()}
    data = save(tensors, metadata={_METADATA_KEY: header.to_json()})
    return atomic_write_bytes(path, data)


def load_model(
    path: str | os.PathLike[str], kind: str, versions: Collection[int]
) -> tuple[ModelHeader, dict[str, NDArray[Any]]]:
    """Read a file written by :func:`save_model`, checking its kind and format version.

    Raises
    ------
    InputError
        Missing, empty, pickle-based, corrupt or truncated file, a header that is not
        qdcnn's, another kind, or an unsupported format version; the message names the file.
    """
    from safetensors import SafetensorError, safe_open

    p = _readable_file(path)
    try:
        with safe_open(str(p), "np") as fh:
            metadata = fh.metadata() or {}
            arrays = {name: fh.get_tensor(name) for name in fh.keys()}
    except (SafetensorError, OSError, ValueError, TypeError) as exc:
        culprit = _tensor_at_fault(p)
        named = f"tensor {culprit!r} does not match its bytes: " if culprit else ""
        reason = named + _first_line(exc)
        raise InputError(p, f"not a readable qdcnn model file ({reason})") from None
    if _METADATA_KEY not in metadata:
        raise InputError(p, "a safetensors file without a qdcnn header (not a qdcnn model)")
    header = _parse_header(p, metadata[_METADATA_KEY], kind, versions)
    return header, arrays


_DTYPE_BYTES = {"BOOL": 1, "U8": 1, "I8": 1, "I16": 2, "U16": 2, "F16": 2, "BF16": 2}
_DTYPE_BYTES |= {"I32": 4, "U32": 4, "F32": 4, "I64": 8, "U64": 8, "F64": 8}


def _tensor_at_fault(path: Path) -> str | None:
    """The first tensor whose shape, type or offsets do not match the bytes of the safetensors
    file ``path`` (for the error line; safetensors' own message does not name it)."""
    try:
        with open(path, "rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            n = int.from_bytes(fh.read(8), "little")
            if n > min(size - 8, MAX_JSON_BYTES):
                return None
            table = json.loads(fh.read(n))
    except (OSError, ValueError):
        return None
    if not isinstance(table, dict):
        return None
    for name, spec in table.items():
        if name != "__metadata__" and not _tensor_fits(spec, size - 8 - n):
            return str(name)
    return None


def _tensor_fits(spec: Any, data_bytes: int) -> bool:
    try:
        start, end = (int(v) for v in spec["data_offsets"])
        count = math.prod(int(d) for d in spec["shape"])
        item = _DTYPE_BYTES[spec["dtype"]]
    except (KeyError, TypeError, ValueError):
        return False
    return 0 <= start <= end <= data_bytes and end - start == count * item


def save_json_model(
    path: str | os.PathLike[str], kind: str, format_version: int, meta: Mapping[str, Any]
) -> Path:
    """Write a model that has no arrays as a JSON file with the same header fields."""
    header = ModelHeader(kind, int(format_version), __version__, dict(meta))
    text = json.dumps(json.loads(header.to_json()), indent=2) + "\n"
    return atomic_write_text(path, text)


def load_json_model(
    path: str | os.PathLike[str], kind: str, versions: Collection[int]
) -> ModelHeader:
    """Read a file written by :func:`save_json_model` (see :func:`load_model`)."""
    p = _readable_file(path)
    if p.stat().st_size > MAX_JSON_BYTES:
        raise InputError(p, f"larger than {MAX_JSON_BYTES // 2**20} MiB: not a qdcnn model file")
    try:
        text = p.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(p, "not a qdcnn model file (not UTF-8 text)") from None
    return _parse_header(p, text, kind, versions)


def _readable_file(path: str | os.PathLike[str]) -> Path:
    p = Path(path)
    if not p.exists():
        raise InputError(p, "model file not found")
    if not p.is_file():
        raise InputError(p, "not a regular file (a model file is expected)")
    try:
        with open(p, "rb") as fh:
            start = fh.read(9)
    except OSError as exc:
        raise InputError(p, f"cannot read: {exc.strerror or exc}") from None
    if not start:
        raise InputError(p, "empty file (0 bytes)")
    # a safetensors file opens with its 8-byte header length, then the JSON header's "{"
    safetensors = len(start) == 9 and start[8:9] == b"{"
    if not safetensors and start.startswith(_PICKLE_MAGIC):
        raise InputError(
            p,
            "a pickle-based file (an older qdcnn model or a torch file); it is never loaded "
            "because unpickling can run code: retrain the model with this qdcnn version",
        )
    return p


def parse_json(text: str, source: str | os.PathLike[str]) -> Any:
    """``json.loads`` with limits: no NaN/Infinity, bounded depth and number length.

    Raises
    ------
    InputError
        Invalid JSON, nesting deeper than :data:`MAX_JSON_DEPTH`, or a number too long.
    """
    depth = _max_depth(text)
    if depth > MAX_JSON_DEPTH:
        raise InputError(source, f"JSON nested {depth} levels deep (at most {MAX_JSON_DEPTH})")

    def constant(name: str) -> Any:
        raise ValueError(f"{name} is not allowed")

    def number(text: str) -> float:
        if len(text) > 40:
            raise ValueError(f"a number of {len(text)} characters")
        value = float(text)
        if not math.isfinite(value):
            raise ValueError(f"{text} is out of range")
        return value

    def integer(text: str) -> int:
        if len(text) > 40:
            raise ValueError(f"an integer of {len(text)} digits")
        return int(text)

    try:
        return json.loads(text, parse_constant=constant, parse_float=number, parse_int=integer)
    except (ValueError, RecursionError) as exc:
        raise InputError(source, f"not valid JSON ({_first_line(exc)})") from None


def _max_depth(text: str) -> int:
    """Deepest bracket nesting outside strings (a cheap scan before parsing)."""
    depth = best = 0
    in_string = escaped = False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            best = max(best, depth)
        elif ch in "]}":
            depth -= 1
    return best


def _parse_header(path: Path, text: str, kind: str, versions: Collection[int]) -> ModelHeader:
    data = parse_json(text, path)
    if not isinstance(data, dict) or "kind" not in data:
        raise InputError(path, f"not a qdcnn model file (no header with kind '{kind}')")
    if data["kind"] != kind:
        raise InputError(path, f"holds a {data['kind']!r}, not a {kind!r}")
    version = data.get("format_version")
    if isinstance(version, bool) or not isinstance(version, int) or version not in versions:
        allowed = ", ".join(str(v) for v in sorted(versions))
        raise InputError(
            path, f"format version {version!r} of {kind!r} is not supported (reads {allowed})"
        )
    meta = data.get("meta", {})
    if not isinstance(meta, dict):
        raise InputError(path, "header field 'meta' is not an object")
    return ModelHeader(kind, version, str(data.get("qdcnn_version", "unknown")), meta)


def _first_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text[:200] or type(exc).__name__


def expect_arrays(
    path: str | os.PathLike[str],
    arrays: Mapping[str, NDArray[Any]],
    shapes: Mapping[str, tuple[int, ...]],
) -> None:
    """Check that ``arrays`` has exactly the names and shapes the header promises.

    Raises
    ------
    InputError
        A missing or unexpected array, or one of another shape (naming it).
    """
    missing = sorted(set(shapes) - set(arrays))
    extra = sorted(set(arrays) - set(shapes))
    if missing or extra:
        raise InputError(path, f"arrays do not match the header (missing {missing}, extra {extra})")
    for name, shape in shapes.items():
        if tuple(arrays[name].shape) != tuple(shape):
            raise InputError(
                path, f"array {name!r} has shape {arrays[name].shape}, the header says {shape}"
            )


# ---------------------------------------------------------------- fitted estimators


def estimator_state(
    estimator: Any, attributes: Collection[str]
) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
    """A fitted estimator's ``attributes`` as (JSON meta, arrays) for :func:`save_model`.

    Numbers, tuples and arrays become arrays (so NaN survives); lists of equal-shape
    arrays are stacked; ``None``, strings and booleans stay in the meta. The meta records
    each attribute's form so :func:`restore_estimator_state` gives back the same types.
    """
    forms: dict[str, Any] = {}
    arrays: dict[str, NDArray[Any]] = {}
    for name in attributes:
        value = getattr(estimator, name)
        if value is None or isinstance(value, bool | str):
            forms[name] = {"value": value}
        elif isinstance(value, np.ndarray):
            forms[name], arrays[name] = "array", value
        elif isinstance(value, int | np.integer):
            forms[name], arrays[name] = "int", np.asarray([value], dtype=np.int64)
        elif isinstance(value, float | np.floating):
            forms[name], arrays[name] = "float", np.asarray([value], dtype=np.float64)
        elif isinstance(value, tuple):
            forms[name], arrays[name] = "tuple", np.asarray(value, dtype=np.float64)
        elif isinstance(value, list) and all(isinstance(v, np.ndarray) for v in value):
            forms[name] = "array-list"
            arrays[name] = np.stack(value) if value else np.zeros((0,))
        elif isinstance(value, list):
            forms[name], arrays[name] = "list", np.asarray(value, dtype=np.float64)
        else:
            raise TypeError(f"cannot store attribute {name!r} of type {type(value).__name__}")
    return {"attributes": forms}, arrays


def restore_estimator_state(
    estimator: Any,
    attributes: Collection[str],
    meta: Mapping[str, Any],
    arrays: Mapping[str, NDArray[Any]],
    source: str | os.PathLike[str],
) -> Any:
    """Set the ``attributes`` that :func:`estimator_state` stored on ``estimator``; returns it.

    Exactly the named attributes must be present: a file can neither leave one out nor
    set any other attribute of the estimator.

    Raises
    ------
    InputError
        A missing, unexpected or unknown-form attribute, or a missing array (a damaged file).
    """
    forms = meta.get("attributes")
    if not isinstance(forms, dict) or set(forms) != set(attributes):
        raise InputError(
            source, f"the model's fitted attributes are not {sorted(attributes)} (a damaged file)"
        )
    for name, form in forms.items():
        if isinstance(form, dict) and set(form) == {"value"}:
            setattr(estimator, name, form["value"])
            continue
        if name not in arrays:
            raise InputError(source, f"fitted attribute {name!r} has no array in the file")
        a = arrays[name]
        converters: dict[str, Any] = {
            "array": lambda x: x,
            "int": lambda x: int(x.reshape(-1)[0]) if x.size == 1 else _bad_scalar(x),
            "float": lambda x: float(x.reshape(-1)[0]) if x.size == 1 else _bad_scalar(x),
            "tuple": lambda x: tuple(float(v) for v in x),
            "list": lambda x: [float(v) for v in x],
            "array-list": lambda x: [row.copy() for row in x],
        }
        if form not in converters:
            raise InputError(source, f"fitted attribute {name!r} has an unknown form {form!r}")
        try:
            setattr(estimator, name, converters[form](a))
        except (TypeError, ValueError) as exc:
            raise InputError(source, f"fitted attribute {name!r} is damaged ({exc})") from None
    return estimator


def _bad_scalar(a: NDArray[Any]) -> Any:
    raise ValueError(f"a scalar is stored as shape {a.shape}")
