"""Tampered model files: exit 2, one line naming the file and the field, before any input.

A direction model (safetensors: a JSON header plus tensors) is edited at the byte level:
header fields of the wrong type or out of range, a fitted attribute of the wrong kind,
NaN and infinite tensors, a tensor whose shape does not cover its bytes, a file cut short.
A shadow model (JSON) gets fields of the wrong type, out of range or NaN, an unknown
feature, another kind, and a file cut short. Every command that loads one (detect-lanes,
run and score; detect-shadows) answers exit 2 with exactly one ``error:`` line naming the
file and, where a field is at fault, the field, no traceback, nothing on stdout, and no
output folder: no input was read and nothing was written.
"""

from __future__ import annotations

import json
import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fault_support import Inputs, assert_one_error, build_inputs, invoke
from tests.direction.test_model_checks import tampered

Edit = Callable[[dict[str, Any], dict[str, Any], bytearray], None]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    return build_inputs(tmp_path_factory)


def _split(data: bytes) -> tuple[dict[str, Any], dict[str, Any], bytearray]:
    """A safetensors file's tensor table, its qdcnn header and its tensor bytes."""
    (n,) = struct.unpack("<Q", data[:8])
    table = json.loads(data[8 : 8 + n])
    header = json.loads(table["__metadata__"]["qdcnn"])
    return table, header, bytearray(data[8 + n :])


def _join(table: dict[str, Any], header: dict[str, Any], tensors: bytes) -> bytes:
    table = {**table, "__metadata__": {"qdcnn": json.dumps(header)}}
    text = json.dumps(table).encode()
    text += b" " * (-len(text) % 8)
    return struct.pack("<Q", len(text)) + text + bytes(tensors)


def _set_tensor(name: str, values: list[float]) -> Edit:
    def edit(table: dict[str, Any], header: dict[str, Any], tensors: bytearray) -> None:
        start, end = table[name]["data_offsets"]
        tensors[start:end] = np.asarray(values, dtype=np.float64).tobytes()

    return edit


def _set(path: str, value: Any) -> Edit:
    def edit(table: dict[str, Any], header: dict[str, Any], tensors: bytearray) -> None:
        *parents, last = path.split(".")
        node = header
        for key in parents:
            node = node[key]
        node[last] = value

    return edit


def _reshape(table: dict[str, Any], header: dict[str, Any], tensors: bytearray) -> None:
    table["class_prior_"]["shape"] = [4]  # 32 bytes claimed, 24 there


#: (what is edited, the edit, what the error line must say: the field, or its words)
DIRECTION_CASES: list[tuple[str, Edit, str]] = [
    ("kind", _set("kind", 7), "not a 'qdcnn-direction-model'"),
    ("format_version", _set("format_version", "2"), "format version"),
    ("format_version 99", _set("format_version", 99), "format version 99"),
    ("shots", _set("meta.params.shots", "many"), "shots"),
    ("shots < 0", _set("meta.params.shots", -5), "shots"),
    ("straight_margin", _set("meta.params.straight_margin", 7.0), "straight_margin"),
    ("class_prior_ NaN", _set_tensor("class_prior_", [np.nan, 0.5, 0.5]), "class_prior_"),
    ("centroid_ inf", _set_tensor("centroid_", [np.inf]), "centroid_"),
    ("shape", _reshape, "class_prior_"),
]
#: Fitted attributes stored as JSON values of the wrong kind (tests/direction has more).
ATTRIBUTE_CASES = [("majority_class_", "left"), ("centroid_", "abc"), ("classes_", [0, 1, 7])]


def _direction_command(name: str, inputs: Inputs, model: Path, out: Path) -> list[str]:
    if name == "score":
        return ["score", "--data", f"udacity:{inputs.recording}", "--model", str(model)]
    extra = ["--no-video"] if name == "run" else []
    return [name, str(inputs.images), "--out", str(out), "--model", str(model), *extra]


def _assert_refused_before_input(args: list[str], out: Path, *names: str) -> None:
    res = invoke(args)
    assert_one_error(res, 2, *names)
    assert res.stdout == ""
    assert not out.exists()


@pytest.mark.parametrize("command", ["detect-lanes", "run", "score"])
@pytest.mark.parametrize(
    ("case", "edit", "field"), DIRECTION_CASES, ids=[c[0] for c in DIRECTION_CASES]
)
def test_a_tampered_direction_model_is_refused_naming_file_and_field(
    command: str, case: str, edit: Edit, field: str, inputs: Inputs, tmp_path: Path
) -> None:
    table, header, tensors = _split(inputs.direction_model.read_bytes())
    edit(table, header, tensors)
    model = tmp_path / "tampered.safetensors"
    model.write_bytes(_join(table, header, tensors))
    out = tmp_path / "out"
    _assert_refused_before_input(_direction_command(command, inputs, model, out), out, model, field)


@pytest.mark.parametrize("command", ["detect-lanes", "run", "score"])
@pytest.mark.parametrize(("field", "value"), ATTRIBUTE_CASES)
def test_a_fitted_attribute_of_the_wrong_kind_is_refused(
    command: str, field: str, value: Any, inputs: Inputs, tmp_path: Path
) -> None:
    model = tampered(inputs.direction_model, tmp_path / "tampered.safetensors", field, value)
    out = tmp_path / "out"
    _assert_refused_before_input(_direction_command(command, inputs, model, out), out, model, field)


@pytest.mark.parametrize("keep", [0.3, 0.9999])
@pytest.mark.parametrize("command", ["detect-lanes", "run", "score"])
def test_a_truncated_direction_model_is_refused(
    command: str, keep: float, inputs: Inputs, tmp_path: Path
) -> None:
    data = inputs.direction_model.read_bytes()
    model = tmp_path / "cut.safetensors"
    model.write_bytes(data[: int(len(data) * keep)])
    out = tmp_path / "out"
    _assert_refused_before_input(_direction_command(command, inputs, model, out), out, model)


SHADOW_CASES: list[tuple[str, Any, str]] = [
    ("meta.centroid", "abc", "centroid"),
    ("meta.centroid", float("nan"), "NaN"),  # not JSON: the parser stops before the field
    ("meta.centroid", 300.0, "centroid"),
    ("meta.threshold", 2.0, "threshold"),
    ("meta.threshold", [0.9], "threshold"),
    ("meta.feature", "hue", "feature"),
    ("kind", "qdcnn-direction-model", "not a 'qdcnn-shadow-model'"),
    ("format_version", "2", "format version"),
]


@pytest.mark.parametrize(("path", "value", "field"), SHADOW_CASES)
def test_a_tampered_shadow_model_is_refused_naming_file_and_field(
    path: str, value: Any, field: str, inputs: Inputs, tmp_path: Path
) -> None:
    header = json.loads(inputs.shadow_model.read_text())
    _set(path, value)({}, header, bytearray())
    model = tmp_path / "tampered.json"
    model.write_text(json.dumps(header))
    out = tmp_path / "out"
    args = ["detect-shadows", str(inputs.images), "--out", str(out), "--model", str(model)]
    _assert_refused_before_input(args, out, model, field)


def test_a_truncated_shadow_model_is_refused(inputs: Inputs, tmp_path: Path) -> None:
    text = inputs.shadow_model.read_text()
    model = tmp_path / "cut.json"
    model.write_text(text[: len(text) // 2])
    out = tmp_path / "out"
    args = ["detect-shadows", str(inputs.images), "--out", str(out), "--model", str(model)]
    _assert_refused_before_input(args, out, model)
