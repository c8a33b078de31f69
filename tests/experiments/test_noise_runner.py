"""run_noise_sweep: what ``qdcnn noise-sweep`` does, from Python (the CLI tests, one level down)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sklearn.base import BaseEstimator, ClassifierMixin

from qdcnn.config import SHADOW_THRESHOLD_GRID, PipelineConfig, ShadowConfig
from qdcnn.data.frames import load_frameset
from qdcnn.data.images import write_image, write_mask
from qdcnn.data.labels import STRAIGHT
from qdcnn.direction.methods import DirectionMethod, register, unregister
from qdcnn.direction.protocol import ContiguousKFold, majority_baseline
from qdcnn.errors import ParameterError
from qdcnn.experiments.noise import (
    PAPER_STRENGTHS,
    NoiseSweepSpec,
    predict_folds,
    run_noise_sweep,
    shadow_sweep,
    split_train_test,
    synthetic_shadow_set,
)
from qdcnn.quantum.circuits import uu_dagger_circuit
from qdcnn.quantum.execute import run_probabilities
from qdcnn.quantum.noise import PAPER_CHANNELS
from qdcnn.runtime.reporting import Collector
from qdcnn.vision.shadow_training import train_shadow_model


@pytest.fixture(autouse=True)
def _cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))


class Recorder(Collector):
    """Keeps failures and notes, and the (description, total, steps) of every progress."""

    def __init__(self) -> None:
        super().__init__()
        self.progresses: list[list[Any]] = []

    @contextmanager
    def progress(self, total: int, description: str) -> Iterator[Any]:
        entry = [description, total, 0]
        self.progresses.append(entry)

        def advance(*_: object) -> None:
            entry[2] += 1

        yield advance


# ---------------------------------------------------------------- the spec


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"strengths": "0:1"}, "strengths='0:1' is invalid: a tuple (parse text with"),
        ({"strengths": (0.0, 1.5)}, "p=1.5 is invalid: a probability in [0, 1]"),
        ({"strengths": (0.0, "x")}, "p='x' is invalid"),
        ({"strengths": (True,)}, "p=True is invalid"),
        ({"strengths": ()}, "p=[] is invalid: at least one strength"),
        ({"strengths": tuple(i / 2000 for i in range(1001))}, "p='<1001 values>' is invalid"),
        ({"channels": ("bit-flip", "bitflip")}, "channel='bitflip' is invalid"),
        ({"channels": "all"}, "channels='all' is invalid: a tuple"),
        ({"methods": ("uu", "dnn")}, "methods='dnn' is invalid"),
        ({"methods": ("dnn-pilotnet",)}, "methods='dnn-pilotnet' is invalid: a quantum method"),
        ({"methods": "uu,vqc"}, "methods='uu,vqc' is invalid: a tuple"),
        ({"groupings": ("halves",)}, "grouping=('halves',) is invalid"),
        ({"readout": 2.0}, "readout=2.0 is invalid"),
        ({"shots": -3}, "shots=-3 is invalid"),
        (
            {"methods": ("uu", "qdcnn-head"), "shots": 100},
            "shots=100 is invalid: not used by qdcnn-head",
        ),
        ({"inner_folds": 1}, "inner_folds=1 is invalid: 0 (none) or 2 to 100"),
        ({"folds": 1}, "folds=1 is invalid"),
        ({"gap": -1}, "gap=-1 is invalid"),
        ({"shadow_frames": 2001}, "shadow_frames=2001 is invalid: an integer in [2, 2000]"),
        ({"seed": -1}, "seed=-1 is invalid"),
        ({"train_under_noise": 1}, "train_under_noise=1 is invalid: True or False"),
        ({"shadow_thresholds": "grid"}, "shadow_thresholds='grid' is invalid: a tuple"),
        ({"shadow_thresholds": (0.5, 2.0)}, "thresholds=2.0 is invalid"),
        ({"config": {}}, "config='dict' is invalid: a PipelineConfig"),
    ],
)
def test_spec_refuses_bad_values(kwargs: dict, message: str) -> None:
    with pytest.raises(ParameterError) as err:
        NoiseSweepSpec(data="synthetic:track1:30", **kwargs)
    assert message in str(err.value)
    assert "\n" not in str(err.value)


def test_direction_methods_need_data() -> None:
    with pytest.raises(ParameterError, match="^data=None is invalid: a dataset"):
        NoiseSweepSpec(methods=("vqc",))
    spec = NoiseSweepSpec(methods=("uu-shadow",))  # shadows alone need none
    assert spec.method_list == ("uu-shadow",)
    with_set = NoiseSweepSpec(data="synthetic:track1:30", methods=("uu",), shadow_set=Path("x"))
    assert with_set.method_list == ("uu", "uu-shadow")


def test_spec_holds_checked_tuples() -> None:
    spec = NoiseSweepSpec(
        methods=["uu-shadow", "uu-shadow"],  # type: ignore[arg-type]
        channels=["bit-flip", "bit-flip"],  # type: ignore[arg-type]
        strengths=[0, 0.5, 0.5],  # type: ignore[arg-type]
        groupings=["kmeans"],  # type: ignore[arg-type]
        shadow_thresholds=[0.9],  # type: ignore[arg-type]
    )
    assert spec.methods == ("uu-shadow",) and spec.channels == ("bit-flip",)
    assert spec.strengths == (0.0, 0.5) and isinstance(spec.strengths[0], float)
    assert spec.groupings == ("kmeans",) and spec.shadow_thresholds == (0.9,)
    default = NoiseSweepSpec(methods=("uu-shadow",))
    assert default.channels == PAPER_CHANNELS and default.strengths == PAPER_STRENGTHS
    assert default.shadow_thresholds == SHADOW_THRESHOLD_GRID


# ---------------------------------------------------------------- direction methods


SMALL = {
    "data": "synthetic:track1:60",
    "seed": 3,  # a drive of 17 left and 43 straight frames
    "channels": ("bit-flip", "phase-damping-paper"),
    "strengths": (0.0, 0.5, 1.0),
    "folds": 2,
    "gap": 0,
    "inner_folds": 0,
}


def test_direction_rows_json_progress_and_figure(tmp_path: Path) -> None:
    plot = tmp_path / "fig.png"
    report = Recorder()
    run = run_noise_sweep(NoiseSweepSpec(methods=("uu", "vqc"), plot=plot, **SMALL), report)
    assert run.exit_code == 0 and run.failures == [] and report.failures == []
    rows = run.to_dicts()
    assert len(rows) == 2 * 2 * 3  # no summary object without failures
    assert {(r["method"], r["channel"], r["p"]) for r in rows} == {
        (m, c, p)
        for m in ("uu", "vqc")
        for c in ("bit-flip", "phase-damping-paper")
        for p in (0.0, 0.5, 1.0)
    }
    for r in rows:
        assert r["dataset"] == "synthetic-track1" and r["n_test"] == 60
        assert r["trained_under_noise"] is False and r["phase_damping_form"] == "paper"
        assert 0.0 <= r["accuracy"] <= 1.0 and r["seed"] == 3 and r["shots"] is None
    y = load_frameset("synthetic:track1:60", seed=3).labels(PipelineConfig().labels)
    baseline = majority_baseline(y, list(ContiguousKFold(2, 0).split(y)))
    assert all(r["majority_baseline"] == baseline for r in rows)
    assert run.figures == [plot] and plot.read_bytes()[:4] == b"\x89PNG"
    assert not (tmp_path / "fig_shadow.png").exists()
    assert report.progresses == [
        ["lane features (synthetic-track1)", 60, 60],
        ["noise sweep", 12, 12],
    ]
    # the same seed gives the same rows (features now come from the cache)
    assert run_noise_sweep(NoiseSweepSpec(methods=("uu", "vqc"), **SMALL)).to_dicts() == rows


def test_registry_names_give_the_shorthand_rows() -> None:
    shorthand = run_noise_sweep(
        NoiseSweepSpec(methods=("uu",), groupings=("image-split", "kmeans"), **SMALL)
    ).to_dicts()
    named = run_noise_sweep(
        NoiseSweepSpec(
            methods=("image-split-uu", "kmeans-uu"), groupings=("spectral",), **SMALL
        )
    ).to_dicts()
    assert named == shorthand
    assert [r["grouping"] for r in named[::3]] == ["image-split", "image-split", "kmeans", "kmeans"]


def test_tables_and_summary_lines() -> None:
    spec = NoiseSweepSpec(
        data="synthetic:track1:60",
        seed=3,
        methods=("uu",),
        channels=("depolarizing",),
        strengths=(0.0, 0.5),
        folds=2,
        inner_folds=0,
        train_under_noise=True,
        shots=128,
        readout=0.01,
    )
    result = run_noise_sweep(spec).result
    (table,) = result.tables()
    assert table.title == "image-split-uu accuracy, synthetic-track1 (60 test frames)"
    assert table.headers == ("p", "depolar.")
    cells = table.cells()
    assert [c[0] for c in cells] == ["0", "0.5"]
    assert cells[1][1] == f"{result.rows[1].accuracy:.3f}"
    assert result.summary_lines() == [
        "trained under noise; 128 shots; readout error 0.01",
        f"majority-class baseline: {result.rows[0].majority_baseline:.3f}",
        "2 contiguous folds (gap 5, inner CV 0)",
    ]


# ---------------------------------------------------------------- a frames-input method


class BrightnessRule(ClassifierMixin, BaseEstimator):
    """A toy quantum method on frames: one UU-dagger circuit per frame on the brightness
    difference of its halves; straight within the margin, else left or right."""

    def __init__(self, margin: float = 0.05, train_noise: Any = None) -> None:
        self.margin = margin
        self.train_noise = train_noise

    def fit(self, X: Any, y: Any) -> BrightnessRule:
        self.classes_ = np.arange(3)
        self.majority_ = int(np.bincount(np.asarray(y), minlength=3).argmax())
        return self

    def predict(self, X: Any, noise: Any = None) -> np.ndarray:
        frames = np.asarray(X, dtype=np.float64)
        half = frames.shape[2] // 2
        d = frames[:, :, :half].mean(axis=(1, 2, 3)) - frames[:, :, half:].mean(axis=(1, 2, 3))
        theta = np.pi / 2 + np.arctan(d / 10.0)
        circuit = uu_dagger_circuit(np.full(d.size, np.pi), theta)
        p0 = run_probabilities(circuit, noise=noise)[:, 0]
        out = np.where(p0 > 0.5, 2, 0)
        out[np.abs(p0 - 0.5) < self.margin] = STRAIGHT
        return out


@pytest.fixture
def brightness_method() -> Iterator[str]:
    name = "toy-brightness-uu"
    register(
        DirectionMethod(
            name,
            "frames",
            lambda config, options: (BrightnessRule(), {}),
            "toy",
            quantum=True,
        )
    )
    yield name
    unregister(name)


def test_a_frames_input_quantum_method_is_swept(brightness_method: str) -> None:
    spec = NoiseSweepSpec(
        data="synthetic:track1:60",
        seed=3,
        methods=(brightness_method,),
        channels=("depolarizing",),
        strengths=(0.0, 1.0),
        folds=2,
        gap=0,
        inner_folds=0,
        train_under_noise=True,
    )
    report = Recorder()
    run = run_noise_sweep(spec, report)
    rows = run.result.rows
    assert [(r.method, r.grouping, r.p) for r in rows] == [
        (brightness_method, None, 0.0),
        (brightness_method, None, 1.0),
    ]
    assert run.result.labels() == [brightness_method]
    # depolarizing at p=1 leaves P0 = 1/2 everywhere: every frame is called straight
    y = load_frameset("synthetic:track1:60", seed=3).labels(PipelineConfig().labels)
    assert rows[1].accuracy == pytest.approx(np.mean(y == STRAIGHT))
    assert [p[0] for p in report.progresses] == ["noise sweep"]  # no lane features computed
    with pytest.raises(ParameterError, match="^shots=8 is invalid: not used by toy-brightness"):
        replace(spec, shots=8)
    frames = np.stack(load_frameset("synthetic:track1:10", seed=3).images or [])[:6]
    models = [(np.arange(6), BrightnessRule())]
    with pytest.raises(ParameterError, match="^shots=8 is invalid: BrightnessRule models run"):
        predict_folds(models, frames, None, shots=8)
    assert predict_folds(models, frames, None).shape == (6,)


# ---------------------------------------------------------------- shadows


def test_shadow_set_with_a_bad_file(tmp_path: Path) -> None:
    images, masks = synthetic_shadow_set(4, seed=2)
    root = tmp_path / "set"
    for i, (im, m) in enumerate(zip(images, masks, strict=True)):
        write_image(root / "images" / f"s{i}.png", im)
        write_mask(root / "masks" / f"s{i}.png", m)
    (root / "images" / "zz_broken.png").write_bytes(b"not a png")
    plot = tmp_path / "ber.png"
    report = Recorder()
    spec = NoiseSweepSpec(
        methods=("uu-shadow",),
        shadow_set=root,
        channels=("depolarizing",),
        strengths=(0.0, 1.0),
        plot=plot,
    )
    run = run_noise_sweep(spec, report)
    assert run.exit_code == 1
    *rows, summary = run.to_dicts()
    assert [r["p"] for r in rows] == [0.0, 1.0]
    assert all(r["method"] == "uu-shadow" and r["dataset"] == "set" for r in rows)
    assert rows[0]["ber"] < 30 and rows[1]["ber"] == 50.0
    assert summary["summary"] is True and "zz_broken.png" in summary["failures"][0]["error"]
    assert report.failures == run.failures and len(run.failures) == 1
    assert run.figures == [plot] and plot.read_bytes()[:4] == b"\x89PNG"
    assert run.result.protocol == {
        "shadow_train": 2,
        "shadow_test": 2,
        "shadow_thresholds": list(SHADOW_THRESHOLD_GRID),
    }
    assert report.progresses == [["shadow noise sweep", 2, 2]]


def test_shadow_model_is_the_one_train_shadows_trains() -> None:
    images, masks = synthetic_shadow_set(6, seed=4)
    tr, te = split_train_test(len(images))
    kwargs = {"channels": ("bit-flip",), "strengths": (0.0,)}
    _, model = shadow_sweep(images[tr], masks[tr], images[te], masks[te], **kwargs)
    reference = train_shadow_model(
        images[tr], masks[tr], ShadowConfig(shots=None), SHADOW_THRESHOLD_GRID
    )
    assert model.threshold == reference.threshold and model.centroid == reference.centroid
    rows, paper = shadow_sweep(
        images[tr], masks[tr], images[te], masks[te], thresholds="paper", **kwargs
    )
    assert paper.threshold in (0.75, 0.97) and rows[0].threshold == paper.threshold
    with pytest.raises(ParameterError, match="thresholds=1.5 is invalid"):
        shadow_sweep(images[tr], masks[tr], images[te], masks[te], thresholds=(0.9, 1.5))
