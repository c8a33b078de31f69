"""The shadow model file: a JSON model header (:mod:`qdcnn.persistence`) with checked fields.

Format version 2 (written now) is :func:`~qdcnn.persistence.save_json_model`'s header::

    {"kind": "qdcnn-shadow-model", "format_version": 2, "qdcnn_version": "0.1.0",
     "meta": {"feature": "intensity", "centroid": 61.5, "threshold": 0.97,
              "provenance": {...},
              "features": [...], "centroids": [[...]], "thresholds": [[...]]}}

(the last three only for multi-centroid models). Version 1, written by qdcnn before
format versions, had the same fields at the top level beside ``"kind"``, with the
provenance under ``"meta"``; it is still read.

Reading is bounded (:data:`~qdcnn.persistence.MAX_JSON_BYTES`, nesting depth, number
length: :func:`~qdcnn.persistence.parse_json`) and every field is checked: booleans
are not numbers, NaN and infinities are refused, centroids lie in [0, 255],
thresholds in [0, 1], and a model has at most :data:`MAX_COMPONENTS` components.
Every problem is one :class:`~qdcnn.errors.InputError` naming the file.
"""

from __future__ import annotations

import os
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from qdcnn._validation import check_float
from qdcnn.errors import InputError, ParameterError
from qdcnn.persistence import MAX_JSON_BYTES, load_json_model, parse_json, save_json_model

_KIND = "qdcnn-shadow-model"
_FORMAT_VERSION = 2
#: Most components (centroids) a multi-centroid model may have.
MAX_COMPONENTS = 64
#: Most features per component.
_MAX_FEATURES = 8
_FEATURE_NAMES = ("intensity", "chromaticity")
_SINGLE = ("feature", "centroid", "threshold")
_MULTI = ("features", "centroids", "thresholds")
_FIELDS = frozenset((*_SINGLE, "provenance", *_MULTI))


def write_shadow_model(path: str | os.PathLike[str], fields: Mapping[str, Any]) -> Path:
    """Write the model ``fields`` (as :func:`read_shadow_model` returns them), atomically."""
    return save_json_model(path, _KIND, _FORMAT_VERSION, dict(fields))


def read_shadow_model(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read and check a shadow model file of format version 1 or 2.

    Returns
    -------
    dict
        ``feature`` (str), ``centroid``, ``threshold`` (float), ``provenance``
        (dict) and, for multi-centroid models, ``features`` (tuple of str),
        ``centroids`` and ``thresholds`` (tuples of tuples of float, ``(k, F)``).

    Raises
    ------
    InputError
        A missing, non-regular, oversized, non-UTF-8 or invalid JSON file, another
        kind of file, an unsupported format version, or a missing, unknown or
        out-of-range field (one line, naming the file).
    """
    p = Path(path)
    data = _read_json(p)
    if not isinstance(data, dict) or "kind" not in data:
        raise InputError(p, f"not a qdcnn shadow model (no header with kind {_KIND!r})")
    if data["kind"] != _KIND:
        raise InputError(p, f"holds a {_short(data['kind'])!r}, not a {_KIND!r}")
    version = data.get("format_version", 1)
    if isinstance(version, bool) or not isinstance(version, int):
        raise InputError(
            p, f"format version {_short(version)!r} of {_KIND!r} is not supported (reads 1, 2)"
        )
    if "format_version" not in data:
        fields = {k: v for k, v in data.items() if k != "kind"}  # version 1
        if "meta" in fields:
            fields["provenance"] = fields.pop("meta")
    else:
        fields = load_json_model(p, _KIND, (_FORMAT_VERSION,)).meta
    return _checked(fields, str(p))


def _read_json(p: Path) -> Any:
    try:
        info = os.stat(p)
    except FileNotFoundError:
        raise InputError(p, "model file not found") from None
    except (OSError, ValueError) as exc:
        raise InputError(p, f"cannot read: {getattr(exc, 'strerror', None) or exc}") from None
    if not stat.S_ISREG(info.st_mode):
        raise InputError(p, "not a regular file (a model file is expected)")
    if info.st_size == 0:
        raise InputError(p, "empty file (0 bytes)")
    if info.st_size > MAX_JSON_BYTES:
        raise InputError(p, f"larger than {MAX_JSON_BYTES // 2**20} MiB: not a qdcnn model file")
    try:
        text = p.read_bytes().decode("utf-8")
    except UnicodeDecodeError:
        raise InputError(p, "not a qdcnn shadow model (not UTF-8 text)") from None
    except OSError as exc:
        raise InputError(p, f"cannot read: {exc.strerror or exc}") from None
    try:
        return parse_json(text, p)
    except InputError as exc:
        raise InputError(p, f"not a qdcnn shadow model ({exc.reason})") from None


def _checked(fields: dict[str, Any], source: str) -> dict[str, Any]:
    unknown = sorted(set(fields) - _FIELDS)
    if unknown:
        raise InputError(source, f"unknown field {_short(unknown[0])!r} in a shadow model")
    missing = [name for name in _SINGLE if name not in fields]
    if missing:
        raise InputError(source, f"shadow model has no field {missing[0]!r}")
    provenance = fields.get("provenance", {})
    if not isinstance(provenance, dict):
        raise InputError(source, "field 'provenance' is not an object")
    try:
        out: dict[str, Any] = {
            "feature": _feature("feature", fields["feature"]),
            "centroid": _number("centroid", fields["centroid"], 255.0),
            "threshold": _number("threshold", fields["threshold"], 1.0),
            "provenance": provenance,
        }
        out.update(_multi(fields))
    except ParameterError as exc:
        raise InputError(source, f"bad field: {exc}") from None
    return out


def _multi(fields: dict[str, Any]) -> dict[str, Any]:
    present = [name for name in _MULTI if name in fields]
    if not present:
        return {}
    if len(present) != len(_MULTI):
        raise ParameterError(present[0], "<given>", "with all of " + ", ".join(_MULTI))
    features = _list("features", fields["features"], 1, _MAX_FEATURES)
    names = tuple(_feature("features", f) for f in features)
    width = len(names)
    centroids = _table("centroids", fields["centroids"], width, 255.0)
    thresholds = _table("thresholds", fields["thresholds"], width, 1.0)
    if len(thresholds) != len(centroids):
        raise ParameterError("thresholds", f"<{len(thresholds)} rows>", "one row per centroid")
    return {"features": names, "centroids": centroids, "thresholds": thresholds}


def _feature(name: str, value: object) -> str:
    if not isinstance(value, str) or value not in _FEATURE_NAMES:
        raise ParameterError(name, _short(value), "one of " + ", ".join(map(repr, _FEATURE_NAMES)))
    return value


def _list(name: str, value: object, lo: int, hi: int) -> list[Any]:
    if not isinstance(value, list) or not lo <= len(value) <= hi:
        size = f"<list of {len(value)}>" if isinstance(value, list) else f"<{type(value).__name__}>"
        raise ParameterError(name, size, f"a list of {lo} to {hi} entries")
    return value


def _table(name: str, value: object, width: int, hi: float) -> tuple[tuple[float, ...], ...]:
    rows = _list(name, value, 1, MAX_COMPONENTS)
    out = []
    for i, row in enumerate(rows):
        entries = _list(f"{name}[{i}]", row, width, width)
        out.append(tuple(_number(f"{name}[{i}]", v, hi) for v in entries))
    return tuple(out)


def _number(name: str, value: object, hi: float) -> float:
    """A finite number in ``[0, hi]``; booleans, strings and containers are refused."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ParameterError(name, _short(value), f"a finite number in [0, {hi:g}]")
    return check_float(name, value, 0.0, hi)


def _short(value: object) -> object:
    """``value`` itself when it prints short, else a placeholder naming its type."""
    if value is None or isinstance(value, bool | int | float):
        return value
    if isinstance(value, str):
        return value if len(value) <= 40 else value[:37] + "..."
    return f"<{type(value).__name__}>"
