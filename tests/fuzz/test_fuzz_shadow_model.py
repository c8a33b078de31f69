"""Fuzzing ShadowModel.load: any JSON, and damaged model files, give a model or one InputError."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from fuzz_support import fuzz_settings, hang_guard

from qdcnn.errors import InputError
from qdcnn.vision.shadow_model_file import MAX_COMPONENTS
from qdcnn.vision.shadows import FEATURES, ShadowModel

hypothesis = pytest.importorskip("hypothesis")
st = hypothesis.strategies
given = hypothesis.given
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")  # numpy overflow and the like

FIELDS = ["kind", "format_version", "qdcnn_version", "meta", "feature", "centroid", "threshold"]
FIELDS += ["features", "centroids", "thresholds", "provenance"]
KIND = "qdcnn-shadow-model"

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**50), 10**50),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([KIND, "intensity", "chromaticity", "", "hue"]),
    st.text(max_size=8),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(
        st.lists(inner, max_size=4),
        st.dictionaries(st.one_of(st.sampled_from(FIELDS), st.text(max_size=6)), inner, max_size=5),
    ),
    max_leaves=25,
)
good_number = st.one_of(st.floats(0, 1), st.integers(0, 1))  # valid in every number field
odd_number = st.one_of(
    st.floats(-10, 300), st.integers(-5, 300), st.booleans(), st.none(), st.just(float("nan"))
)


def mostly(
    good: st.SearchStrategy[object], odd: st.SearchStrategy[object]
) -> st.SearchStrategy[object]:
    """``good`` four times in five, else ``odd``: most files get far into the checks."""
    return st.integers(0, 4).flatmap(lambda i: odd if i == 0 else good)


numbers = mostly(good_number, odd_number)


@st.composite
def model_like(draw: st.DrawFn) -> dict[str, object]:
    """Dictionaries shaped like a model file (version 1 or 2) with odd values in some fields."""
    fields: dict[str, object] = {
        "feature": draw(mostly(st.sampled_from(FEATURES), scalars)),
        "centroid": draw(numbers),
        "threshold": draw(numbers),
    }
    if draw(st.booleans()):
        k = draw(mostly(st.integers(1, 3), st.integers(0, MAX_COMPONENTS + 2)))
        names = draw(mostly(st.lists(st.sampled_from(FEATURES), min_size=1, max_size=2), values))
        width = len(names) if isinstance(names, list) else 1
        row_width = mostly(st.just(width), st.integers(0, width + 1))
        rows = row_width.flatmap(lambda n: st.lists(numbers, min_size=n, max_size=n))
        fields["features"] = names
        fields["centroids"] = draw(st.lists(rows, min_size=k, max_size=k))
        fields["thresholds"] = draw(mostly(st.lists(rows, min_size=k, max_size=k), values))
    if draw(st.integers(0, 4)) == 0:
        for name in draw(st.lists(st.sampled_from(list(fields)), max_size=2)):
            fields.pop(name, None)
    if draw(st.booleans()):
        fields["provenance" if draw(st.integers(0, 4)) else "extra"] = draw(values)
    if draw(st.booleans()):  # version 1: fields at the top, provenance under "meta"
        if "provenance" in fields:
            fields["meta"] = fields.pop("provenance")
        return {"kind": KIND, **fields}
    version = draw(mostly(st.just(2), scalars))
    return {"kind": KIND, "format_version": version, "qdcnn_version": "0.1.0", "meta": fields}


def check_load(path: Path, text: str) -> None:
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    with hang_guard():
        try:
            model = ShadowModel.load(path)
        except InputError as exc:
            assert str(exc).startswith(f"{path}: ") and "\n" not in str(exc)
            hypothesis.event("InputError: " + exc.reason.split(" (")[0].split(":")[0][:30])
            return
    hypothesis.event("model")
    assert model.feature in FEATURES and isinstance(model.meta, dict)
    assert 0 <= model.centroid <= 255 and 0 <= model.threshold <= 1
    for value in (model.centroid, model.threshold):
        assert type(value) is float and math.isfinite(value)
    assert len(model.centroids) <= MAX_COMPONENTS
    for row in (*model.centroids, *model.thresholds):
        assert all(type(v) is float and math.isfinite(v) for v in row)
    assert ShadowModel.load(model.save(path)) == model  # what loads, saves and loads again


@pytest.fixture(scope="module")
def target(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz-shadow") / "model.json"


@fuzz_settings(150)
@given(data=values)
def test_any_json_value(target: Path, data: object) -> None:
    check_load(target, json.dumps(data))


@fuzz_settings(250)
@given(data=model_like())
def test_model_shaped_json(target: Path, data: dict[str, object]) -> None:
    check_load(target, json.dumps(data))


VALID = [
    json.dumps({"kind": KIND, "feature": "intensity", "centroid": 61.5, "threshold": 0.97}),
    json.dumps(
        {
            "kind": KIND,
            "format_version": 2,
            "qdcnn_version": "0.1.0",
            "meta": {
                "feature": "intensity",
                "centroid": 50.0,
                "threshold": 0.95,
                "provenance": {"trained_on": "x"},
                "features": ["intensity", "chromaticity"],
                "centroids": [[50.0, 140.0]],
                "thresholds": [[0.95, 0.9]],
            },
        }
    ),
]


@st.composite
def damaged(draw: st.DrawFn) -> str:
    text = list(draw(st.sampled_from(VALID)))
    for _ in range(draw(st.integers(1, 5))):
        pos = draw(st.integers(0, len(text)))
        kind = draw(st.sampled_from(["set", "insert", "truncate", "nest"]))
        if kind == "set" and pos < len(text):
            text[pos] = draw(st.sampled_from(list('{}[]",:0123456789.-eE tfnaNI')))
        elif kind == "insert":
            text[pos:pos] = list(draw(st.text(max_size=6)))
        elif kind == "truncate":
            del text[pos:]
        else:
            depth = draw(st.integers(1, 200))
            text[pos:pos] = list("[" * depth + "]" * depth)
    return "".join(text)


@fuzz_settings(200)
@given(text=damaged())
def test_damaged_model_files(target: Path, text: str) -> None:
    check_load(target, text)
