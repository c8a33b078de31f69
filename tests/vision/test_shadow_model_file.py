"""Shadow model files: the versioned header, version-1 files, hostile JSON as one-line errors."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from qdcnn import __version__
from qdcnn.errors import InputError
from qdcnn.vision.shadow_model_file import MAX_COMPONENTS, read_shadow_model
from qdcnn.vision.shadows import ShadowModel

MULTI = ShadowModel(
    "intensity",
    50.0,
    0.95,
    {"trained_on": "test", "n_images": 3},
    ("intensity", "chromaticity"),
    ((50.0, 140.0), (60.0, 100.0)),
    ((0.95, 0.9), (0.98, 0.97)),
)


def v1_text(**fields: object) -> str:
    """A file as qdcnn wrote it before format versions: ``kind`` beside the fields."""
    data = {"kind": "qdcnn-shadow-model", "feature": "intensity", "centroid": 61.5}
    data.update({"threshold": 0.97, "meta": {"trained_on": "old"}}, **fields)
    return json.dumps(data, indent=2)


def v2_text(**meta: object) -> str:
    fields: dict[str, object] = {"feature": "intensity", "centroid": 61.5, "threshold": 0.97}
    fields.update(meta)
    header = {"kind": "qdcnn-shadow-model", "format_version": 2, "qdcnn_version": "0.1.0"}
    return json.dumps({**header, "meta": fields})


def load_text(tmp_path: Path, text: str) -> ShadowModel:
    path = tmp_path / "model.json"
    path.write_text(text)
    return ShadowModel.load(path)


def message(tmp_path: Path, text: str) -> str:
    with pytest.raises(InputError) as info:
        load_text(tmp_path, text)
    out = str(info.value)
    assert "\n" not in out and out.startswith(f"{tmp_path / 'model.json'}: ")
    return out.removeprefix(f"{tmp_path / 'model.json'}: ")


def test_saved_file_has_the_versioned_header(tmp_path: Path) -> None:
    path = MULTI.save(tmp_path / "sub" / "multi.json")
    data = json.loads(path.read_text())
    assert data["kind"] == "qdcnn-shadow-model"
    assert data["format_version"] == 2 and data["qdcnn_version"] == __version__
    assert data["meta"]["provenance"] == {"trained_on": "test", "n_images": 3}
    assert data["meta"]["centroids"] == [[50.0, 140.0], [60.0, 100.0]]
    assert ShadowModel.load(path) == MULTI
    assert [p.name for p in path.parent.iterdir()] == ["multi.json"]  # no temporary left


def test_version_one_files_are_still_read(tmp_path: Path) -> None:
    model = load_text(tmp_path, v1_text())
    assert model == ShadowModel("intensity", 61.5, 0.97, {"trained_on": "old"})
    multi = v1_text(
        features=["intensity", "chromaticity"],
        centroids=[[50.0, 140.0], [60.0, 100.0]],
        thresholds=[[0.95, 0.9], [0.98, 0.97]],
        meta={"trained_on": "test", "n_images": 3},
        centroid=50.0,
        threshold=0.95,
    )
    assert load_text(tmp_path, multi) == MULTI
    assert load_text(tmp_path, v1_text(meta={})).meta == {}


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("[" * 100_000 + "]" * 100_000, "JSON nested 100000 levels deep (at most 64)"),
        ('{"a": ' * 70 + "1" + "}" * 70, "JSON nested 70 levels deep (at most 64)"),
        (v2_text().replace("61.5", "9" * 5000), "not valid JSON (an integer of 5000 digits)"),
        (
            v2_text().replace("61.5", "6" * 3000 + ".5"),
            "not valid JSON (a number of 3002 characters)",
        ),
        (v2_text().replace("61.5", "NaN"), "not valid JSON (NaN is not allowed)"),
        (v2_text().replace("61.5", "1e999"), "not valid JSON (1e999 is out of range)"),
        ("", "empty file (0 bytes)"),
        ("\ufeff{}", "not a qdcnn shadow model (not valid JSON (Unexpected UTF-8 BOM"),
    ],
)
def test_hostile_json_is_one_line(tmp_path: Path, text: str, expected: str) -> None:
    got = message(tmp_path, text)
    assert expected in got


def test_version_one_hostile_values(tmp_path: Path) -> None:
    assert message(tmp_path, v1_text(centroid=True)) == (
        "bad field: centroid=True is invalid: a finite number in [0, 255]"
    )
    assert message(tmp_path, v1_text(threshold="0.9")) == (
        "bad field: threshold='0.9' is invalid: a finite number in [0, 1]"
    )
    assert message(tmp_path, v1_text(feature="hue")) == (
        "bad field: feature='hue' is invalid: one of 'intensity', 'chromaticity'"
    )
    assert message(tmp_path, v1_text(meta=[1])) == "field 'provenance' is not an object"
    assert message(tmp_path, v1_text(colour="red")) == "unknown field 'colour' in a shadow model"


@pytest.mark.parametrize(
    ("meta", "expected"),
    [
        ({"centroid": False}, "centroid=False is invalid: a finite number in [0, 255]"),
        ({"centroid": -1}, "centroid=-1 is invalid: a finite number in [0, 255]"),
        ({"threshold": 1.5}, "threshold=1.5 is invalid: a finite number in [0, 1]"),
        ({"threshold": None}, "threshold=None is invalid: a finite number in [0, 1]"),
        ({"centroid": "x" * 100}, f"centroid='{'x' * 37}...' is invalid"),
        ({"feature": ["intensity"]}, "feature='<list>' is invalid"),
        ({"features": ["intensity"]}, "features='<given>' is invalid: with all of"),
        (
            {"features": [], "centroids": [[1.0]], "thresholds": [[0.5]]},
            "features='<list of 0>' is invalid: a list of 1 to 8 entries",
        ),
        (
            {"features": ["intensity"], "centroids": [[1.0]], "thresholds": [[True]]},
            "thresholds[0]=True is invalid: a finite number in [0, 1]",
        ),
        (
            {"features": ["intensity"], "centroids": [[1.0, 2.0]], "thresholds": [[0.5]]},
            "centroids[0]='<list of 2>' is invalid: a list of 1 to 1 entries",
        ),
        (
            {"features": ["intensity"], "centroids": [[1.0]], "thresholds": [[0.5], [0.5]]},
            "thresholds='<2 rows>' is invalid: one row per centroid",
        ),
        (
            {
                "features": ["intensity"],
                "centroids": [[1.0]] * (MAX_COMPONENTS + 1),
                "thresholds": [[0.5]] * (MAX_COMPONENTS + 1),
            },
            f"centroids='<list of {MAX_COMPONENTS + 1}>' is invalid: a list of 1 to 64 entries",
        ),
    ],
)
def test_every_field_is_checked(tmp_path: Path, meta: dict[str, object], expected: str) -> None:
    got = message(tmp_path, v2_text(**meta))
    assert got.startswith("bad field: ") and expected in got


def test_components_up_to_the_limit_load(tmp_path: Path) -> None:
    k = MAX_COMPONENTS
    text = v2_text(features=["chromaticity"], centroids=[[100.0]] * k, thresholds=[[0.9]] * k)
    assert len(load_text(tmp_path, text).centroids) == k


def test_header_problems(tmp_path: Path) -> None:
    assert message(tmp_path, "[]") == (
        "not a qdcnn shadow model (no header with kind 'qdcnn-shadow-model')"
    )
    assert message(tmp_path, json.dumps({"kind": ["x"] * 1000})) == (
        "holds a '<list>', not a 'qdcnn-shadow-model'"
    )
    future = v2_text().replace('"format_version": 2', '"format_version": 3')
    assert message(tmp_path, future) == (
        "format version 3 of 'qdcnn-shadow-model' is not supported (reads 2)"
    )
    bool_version = v2_text().replace('"format_version": 2', '"format_version": true')
    assert "format version True" in message(tmp_path, bool_version)
    assert message(tmp_path, v2_text().replace('"meta": {', '"meta": [{').replace("}}", "}]}")) == (
        "header field 'meta' is not an object"
    )
    assert message(tmp_path, json.dumps({"kind": "qdcnn-shadow-model", "format_version": 2})) == (
        "shadow model has no field 'feature'"
    )


def test_odd_files(tmp_path: Path) -> None:
    fifo = tmp_path / "model.fifo"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match="not a regular file"):
        read_shadow_model(fifo)  # returns at once: a FIFO is never opened
    (tmp_path / "latin1.json").write_bytes(b'{"kind": "caf\xe9"}')
    with pytest.raises(InputError, match="latin1.json: not a qdcnn shadow model \\(not UTF-8"):
        read_shadow_model(tmp_path / "latin1.json")
    (tmp_path / "pickle.json").write_bytes(b"\x80\x04K\x01.")
    with pytest.raises(InputError, match="pickle.json: not a qdcnn shadow model"):
        read_shadow_model(tmp_path / "pickle.json")
