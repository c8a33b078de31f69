"""The one model-file format: JSON header + safetensors arrays, and its refusals."""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest

from qdcnn.errors import InputError
from qdcnn.persistence import (
    MAX_JSON_DEPTH,
    expect_arrays,
    load_json_model,
    load_model,
    parse_json,
    save_json_model,
    save_model,
)


def test_round_trip_keeps_header_and_arrays(tmp_path):
    arrays = {"w": np.arange(6.0).reshape(2, 3), "b": np.array([1, 2], dtype=np.int64)}
    path = save_model(tmp_path / "m.safetensors", "toy", 2, {"lr": 0.1, "classes": ["a"]}, arrays)
    header, got = load_model(path, "toy", {1, 2})
    assert header.kind == "toy" and header.format_version == 2
    assert header.meta == {"lr": 0.1, "classes": ["a"]}
    np.testing.assert_array_equal(got["w"], arrays["w"])
    assert got["b"].dtype == np.int64
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary file left behind


def test_wrong_kind_and_version_are_named(tmp_path):
    path = save_model(tmp_path / "m.safetensors", "toy", 3, {}, {"w": np.zeros(1)})
    with pytest.raises(InputError, match="holds a 'toy', not a 'other'"):
        load_model(path, "other", {3})
    with pytest.raises(InputError, match="format version 3 .* not supported"):
        load_model(path, "toy", {1})


def test_pickle_file_is_refused_without_unpickling(tmp_path):
    marker = tmp_path / "ran"

    class Evil:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    path = tmp_path / "model.pkl"
    path.write_bytes(pickle.dumps(Evil()))
    with pytest.raises(InputError, match="pickle-based file"):
        load_model(path, "toy", {1})
    assert not marker.exists()


@pytest.mark.parametrize("cut", [1, 8, 40])
def test_truncated_file_is_an_input_error(tmp_path, cut):
    path = save_model(tmp_path / "m.safetensors", "toy", 1, {}, {"w": np.zeros(64)})
    data = path.read_bytes()
    path.write_bytes(data[:-cut])
    with pytest.raises(InputError, match="m.safetensors"):
        load_model(path, "toy", {1})


def test_expect_arrays_names_the_lying_shape(tmp_path):
    with pytest.raises(InputError, match="array 'w' has shape \\(2,\\), the header says \\(3,\\)"):
        expect_arrays("f", {"w": np.zeros(2)}, {"w": (3,)})
    with pytest.raises(InputError, match="missing \\['b'\\]"):
        expect_arrays("f", {"w": np.zeros(2)}, {"w": (2,), "b": (1,)})


def test_json_model_round_trip_and_limits(tmp_path):
    path = save_json_model(tmp_path / "s.json", "shadow", 1, {"centroid": 40.0})
    assert load_json_model(path, "shadow", {1}).meta == {"centroid": 40.0}
    deep = "[" * (MAX_JSON_DEPTH + 1) + "]" * (MAX_JSON_DEPTH + 1)
    with pytest.raises(InputError, match="nested"):
        parse_json(deep, "x.json")
    with pytest.raises(InputError, match="5000 digits"):
        parse_json("1" * 5000, "x.json")
    with pytest.raises(InputError, match="NaN is not allowed"):
        parse_json('{"a": NaN}', "x.json")
    (tmp_path / "bad.json").write_text(json.dumps({"kind": "shadow", "format_version": True}))
    with pytest.raises(InputError, match="format version True"):
        load_json_model(tmp_path / "bad.json", "shadow", {1})


@pytest.mark.parametrize("pad", range(0, 300, 7))
def test_a_header_length_that_starts_like_pickle_is_still_read(tmp_path, pad):
    # the first byte of a safetensors file is its header length mod 256: 0x80 must not matter
    path = save_model(tmp_path / "m.safetensors", "toy", 1, {"pad": "x" * pad}, {"w": np.zeros(2)})
    assert load_model(path, "toy", {1})[0].meta["pad"] == "x" * pad
