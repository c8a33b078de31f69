"""Noise sweeps: option parsing, batched noisy prediction, known answers, figures."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from qdcnn.config import PipelineConfig, ShadowConfig
from qdcnn.data.labels import LEFT, RIGHT, STRAIGHT
from qdcnn.errors import ParameterError
from qdcnn.experiments.evaluate import evaluate_features
from qdcnn.experiments.noise import (
    PAPER_STRENGTHS,
    NoiseSweepResult,
    SweepRow,
    direction_sweep,
    parse_channels,
    parse_methods,
    parse_strengths,
    phase_damping_form,
    predict_folds,
    shadow_sweep,
    split_train_test,
    synthetic_shadow_set,
)
from qdcnn.experiments.noise.plot import (
    accuracy_figure,
    save_figure,
    shadow_figure,
    shadow_plot_path,
)
from qdcnn.quantum.direction import UUDirectionClassifier
from qdcnn.quantum.noise import CHANNELS, PAPER_CHANNELS, NoiseSpec
from qdcnn.quantum.vqc import VQCClassifier
from qdcnn.vision.metrics import confusion_counts, shadow_scores
from qdcnn.vision.shadows import detect_shadows_uu


def road_slopes(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``[slope_left, slope_right]``: straight symmetric, bends shift both slopes; some NaN."""
    rng = np.random.default_rng(seed)
    y = np.repeat(rng.integers(0, 3, n // 10 + 1), 10)[:n]  # runs of 10 frames, like a drive
    spread = rng.uniform(0.8, 1.2, n)
    shift = np.select([y == 0, y == 2], [1.0, -1.0], 0.0) * rng.uniform(0.3, 0.9, n)
    X = np.stack([-spread + shift, spread + shift], axis=1) + rng.normal(0, 0.3, (n, 2))
    X[rng.choice(n, n // 20, replace=False), rng.integers(0, 2)] = np.nan
    return X, y


# ---------------------------------------------------------------- options


def test_paper_strengths_are_exact() -> None:
    assert len(PAPER_STRENGTHS) == 10
    assert PAPER_STRENGTHS == tuple(round(0.11 * i, 2) for i in range(10))
    assert parse_strengths("0:0.3:0.1") == (0.0, 0.1, 0.2, 0.3)
    assert parse_strengths("0:1:0.25") == (0.0, 0.25, 0.5, 0.75, 1.0)
    assert parse_strengths("0:0.5:0.3") == (0.0, 0.3)  # STOP off the grid is left out
    assert parse_strengths("0.5, 0,0.1,0.5") == (0.0, 0.1, 0.5)
    assert parse_strengths("1") == (1.0,)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0:1", "p='0:1' is invalid: START:STOP:STEP"),
        ("a:b:c", "p='a:b:c' is invalid: START:STOP:STEP"),
        ("0:1:0", "with STEP > 0 and START <= STOP"),
        ("1:0:0.1", "with STEP > 0 and START <= STOP"),
        ("0:1.5:0.5", "p=1.5 is invalid: a probability in [0, 1]"),
        ("-0.1,0.2", "p=-0.1 is invalid: a probability in [0, 1]"),
        ("0.1,,x", "p='0.1,,x' is invalid"),
        ("", "p='' is invalid"),
        ("0:1:0.0001", "at most 1000 strengths"),
    ],
)
def test_bad_strengths(text: str, message: str) -> None:
    with pytest.raises(ParameterError) as err:
        parse_strengths(text)
    assert message in str(err.value)


def test_channels_and_phase_damping_forms() -> None:
    assert parse_channels("all") == PAPER_CHANNELS
    paper = parse_channels("all", phase_damping="paper")
    assert paper[-1] == "phase-damping-paper" and "phase-damping" not in paper
    assert phase_damping_form(paper) == "paper"
    both = parse_channels("phase-damping, phase-damping-paper,bit-flip,bit-flip")
    assert both == ("phase-damping", "phase-damping-paper", "bit-flip")
    assert phase_damping_form(both) == "textbook+paper"
    assert phase_damping_form(("bit-flip",)) is None
    with pytest.raises(ParameterError, match="channel='bitflip' is invalid: one of bit-flip"):
        parse_channels("bit-flip,bitflip")
    with pytest.raises(ParameterError, match="phase_damping='both' is invalid"):
        parse_channels("all", phase_damping="both")
    with pytest.raises(ParameterError, match="channels=' , ' is invalid"):
        parse_channels(" , ")
    assert parse_methods("all") == ("uu", "vqc", "uu-shadow")
    with pytest.raises(ParameterError, match="methods='dnn' is invalid"):
        parse_methods("uu,dnn")


# ---------------------------------------------------------------- batched prediction


@pytest.fixture(scope="module")
def fitted() -> dict:
    X, y = road_slopes(120, 3)
    halves = [np.arange(0, 60), np.arange(60, 120)]
    uu = [
        UUDirectionClassifier(shots=None, angle_map=m, n_centroids=90, n_margins=26).fit(
            X[rows], y[rows]
        )
        for rows, m in zip(halves, ("arctan", "minmax"), strict=True)
    ]
    vqc = [
        VQCClassifier(maxiter=15, interpret=i, seed=s).fit(X[rows], y[rows])
        for rows, i, s in zip(halves, ("min2", "mod3"), (0, 1), strict=True)
    ]
    # each model predicts the other half
    return {"X": X, "y": y, "tests": halves[::-1], "uu": uu, "vqc": vqc}


@pytest.mark.parametrize("kind", ["uu", "vqc"])
def test_batched_prediction_equals_each_estimator(fitted: dict, kind: str) -> None:
    X = fitted["X"]
    models = list(zip(fitted["tests"], fitted[kind], strict=True))
    for channel in CHANNELS:
        for p in (0.0, 0.3, 0.8):
            noise = NoiseSpec(channel, p, readout=0.05 if p == 0.3 else 0.0)
            expected = np.concatenate([est.predict(X[rows], noise=noise) for rows, est in models])
            np.testing.assert_array_equal(predict_folds(models, X, noise), expected)


def test_known_answers_at_full_strength(fitted: dict) -> None:
    X = fitted["X"]
    rows = fitted["tests"][0]
    missing = ~np.all(np.isfinite(X[rows]), axis=1)
    assert missing.any()
    # amplitude damping at p=1 resets the qubit after every gate: P1 = P2 = 1, straight
    uu = UUDirectionClassifier(centroid=1.0, train_margin=False, shots=None)
    uu.fit(X[fitted["tests"][1]], fitted["y"][fitted["tests"][1]])
    pred = predict_folds([(rows, uu)], X, NoiseSpec("amplitude-damping", 1.0))
    assert (pred[~missing] == STRAIGHT).all()
    assert (pred[missing] == uu.majority_class_).all()
    # depolarizing at p=1 leaves I/4: classes get 1/4, 1/4, 1/2 through "min2" -> right,
    # and 1/2, 1/4, 1/4 through "mod3" -> left
    vqc_min2, vqc_mod3 = fitted["vqc"]
    full = NoiseSpec("depolarizing", 1.0)
    assert (predict_folds([(rows, vqc_min2)], X, full)[~missing] == RIGHT).all()
    assert (predict_folds([(rows, vqc_mod3)], X, full)[~missing] == LEFT).all()


def test_shots_are_seeded(fitted: dict) -> None:
    X = fitted["X"]
    models = list(zip(fitted["tests"], fitted["uu"], strict=True))
    noise = NoiseSpec("bit-flip", 0.2)
    a = predict_folds(models, X, noise, shots=32, rng=5)
    assert np.array_equal(a, predict_folds(models, X, noise, shots=32, rng=5))
    exact = predict_folds(models, X, noise)
    assert not np.array_equal(a, exact)  # 32 shots move some frames across the rule's bands
    assert np.mean(a == exact) > 0.5


# ---------------------------------------------------------------- direction sweep


def test_sweep_agrees_with_evaluate_and_is_reproducible() -> None:
    X, y = road_slopes(100, 7)
    cfg = PipelineConfig()
    kwargs = {
        "methods": ("vqc",),
        "channels": ("depolarizing", "phase-damping", "phase-damping-paper"),
        "strengths": (0.0, 0.5),
        "config": cfg,
        "folds": 5,
        "gap": 3,
    }
    rows = direction_sweep({"image-split": X}, y, **kwargs)
    assert [(r.channel, r.p) for r in rows] == [
        (c, p) for c in kwargs["channels"] for p in kwargs["strengths"]
    ]
    assert all(r.n_test == 100 and r.grouping == "image-split" for r in rows)
    # noiseless points equal the cross-validated accuracy of `evaluate` (5 equal folds)
    ref = evaluate_features("image-split-vqc", "slopes", X, y, config=cfg, folds=5, gap=3)
    at_zero = {r.channel: r.accuracy for r in rows if r.p == 0.0}
    assert at_zero["depolarizing"] == pytest.approx(ref.accuracy, abs=1e-12)
    assert at_zero["phase-damping"] == pytest.approx(ref.accuracy, abs=1e-12)
    assert rows[0].majority_baseline == pytest.approx(ref.majority_baseline, abs=1e-12)
    # the same seed gives the same rows, with shots too
    shot_kw = {**kwargs, "methods": ("uu",), "shots": 64, "inner_folds": 0}
    first = direction_sweep({"image-split": X}, y, seed=3, **shot_kw)
    assert first == direction_sweep({"image-split": X}, y, seed=3, **shot_kw)


def test_sweep_rejects_bad_grids() -> None:
    X, y = road_slopes(60, 1)
    with pytest.raises(ParameterError, match="p=1.2 is invalid"):
        direction_sweep({"image-split": X}, y, strengths=(0.1, 1.2))
    with pytest.raises(ParameterError, match="channel='nope' is invalid"):
        direction_sweep({"image-split": X}, y, channels=("nope",))
    with pytest.raises(ParameterError, match="methods='uu-shadow' is invalid"):
        direction_sweep({"image-split": X}, y, methods=("uu-shadow",))


def test_train_under_noise_runs_per_point() -> None:
    X, y = road_slopes(80, 2)
    rows = direction_sweep(
        {"image-split": X},
        y,
        methods=("uu",),
        channels=("bit-flip",),
        strengths=(0.0, 0.45),
        folds=2,
        gap=0,
        inner_folds=0,
        train_under_noise=True,
    )
    plain = direction_sweep(
        {"image-split": X},
        y,
        methods=("uu",),
        channels=("bit-flip",),
        strengths=(0.45,),
        folds=2,
        gap=0,
        inner_folds=0,
    )
    # near p = 1/2 the noiseless margin leaves everything straight; retraining adapts it
    assert rows[1].accuracy > plain[0].accuracy


# ---------------------------------------------------------------- shadow sweep


@pytest.fixture(scope="module")
def shadow_rows() -> tuple[list[SweepRow], object, list, list]:
    images, masks = synthetic_shadow_set(4, seed=1)
    tr, te = split_train_test(len(images))
    rows, model = shadow_sweep(
        images[tr],
        masks[tr],
        images[te],
        masks[te],
        channels=("depolarizing", "amplitude-damping"),
        strengths=(0.0, 1.0),
    )
    return rows, model, images[te], masks[te]


def test_shadow_sweep_known_answers(shadow_rows: tuple) -> None:
    rows, model, images, masks = shadow_rows
    by = {(r.channel, r.p): r for r in rows}
    assert all(r.method == "uu-shadow" and r.n_test == 2 for r in rows)
    # p = 0: the noiseless detector's BER over the test set
    counts = [
        confusion_counts(detect_shadows_uu(im, ShadowConfig(shots=None), model=model).mask, m)
        for im, m in zip(images, masks, strict=True)
    ]
    ref = shadow_scores(counts)
    assert by[("depolarizing", 0.0)].ber == pytest.approx(ref.ber, abs=1e-12)
    assert by[("amplitude-damping", 0.0)].ber == pytest.approx(ref.ber, abs=1e-12)
    assert ref.ber < 30
    # depolarizing p=1: every score is 1/2, below the threshold: nothing is shadow
    assert by[("depolarizing", 1.0)].ber == 50.0
    assert by[("depolarizing", 1.0)].shadow_error == 100.0
    # amplitude damping p=1: every score is 1: everything is shadow
    assert by[("amplitude-damping", 1.0)].nonshadow_error == 100.0


def test_shadow_threshold_under_noise() -> None:
    images, masks = synthetic_shadow_set(4, seed=1)
    tr, te = split_train_test(len(images))
    kwargs = {"channels": ("depolarizing",), "thresholds": (0.6, 0.97)}
    plain, model = shadow_sweep(
        images[tr], masks[tr], images[te], masks[te], strengths=(0.0, 0.2), **kwargs
    )
    tuned, _ = shadow_sweep(
        images[tr],
        masks[tr],
        images[te],
        masks[te],
        strengths=(0.0, 0.2),
        train_under_noise=True,
        **kwargs,
    )
    assert model.threshold == 0.97
    # p = 0: the same choice as the noiseless training
    assert tuned[0].threshold == 0.97 and tuned[0].ber == plain[0].ber
    # depolarizing 0.2 after both gates caps every score at 0.5 + 0.5 * 0.8**2 = 0.82 < 0.97:
    # the noiseless threshold finds no shadow, the re-chosen 0.6 does
    assert plain[1].ber == 50.0
    assert tuned[1].threshold == 0.6 and tuned[1].ber < 50.0


def test_split_train_test() -> None:
    assert split_train_test(5) == (slice(0, 3), slice(3, 5))
    assert split_train_test(2, 0.9) == (slice(0, 1), slice(1, 2))
    with pytest.raises(ParameterError, match="images=1 is invalid"):
        split_train_test(1)


# ---------------------------------------------------------------- results and figures


def _result(shadow: list[SweepRow], trained: bool = False) -> NoiseSweepResult:
    rows = [
        SweepRow(m, "image-split", ch, p, acc, 30, 0.2)
        for m, base in (("uu", 0.7), ("vqc", 0.5))
        for ch in PAPER_CHANNELS
        for p, acc in zip((0.0, 0.5, 1.0), (base, base - 0.1, 1 / 3), strict=True)
    ]
    return NoiseSweepResult(
        "synthetic-track1",
        rows + shadow,
        PAPER_CHANNELS,
        (0.0, 0.5, 1.0),
        trained_under_noise=trained,
        shadow_set="scenes",
    )


def test_json_rows(shadow_rows: tuple) -> None:
    rows = [*shadow_rows[0], SweepRow("uu-shadow", None, "bit-flip", 0.1, 0.9, 2, ber=math.nan)]
    dicts = _result(rows).to_dicts()
    text = "\n".join(json.dumps(d, allow_nan=False) for d in dicts)  # no NaN in the JSON
    first = json.loads(text.splitlines()[0])
    assert first == {
        "method": "uu",
        "grouping": "image-split",
        "channel": "bit-flip",
        "p": 0.0,
        "accuracy": 0.7,
        "n_test": 30,
        "majority_baseline": 0.2,
        "dataset": "synthetic-track1",
        "trained_under_noise": False,
        "phase_damping_form": "textbook",
        "shots": None,
        "readout": 0.0,
        "seed": 0,
    }
    shadow = dicts[-2]
    assert shadow["method"] == "uu-shadow" and shadow["dataset"] == "scenes"
    assert {"ber", "accuracy", "threshold", "shadow_error"} <= set(shadow)
    assert dicts[-1]["ber"] is None


def test_figures(shadow_rows: tuple, tmp_path: Path) -> None:
    result = _result(shadow_rows[0], trained=True)
    fig = accuracy_figure(result)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 6
    assert [ax.get_title() for ax in axes][-1] == "Phase damping (textbook)"
    lines = axes[0].get_lines()
    assert [ln.get_label() for ln in lines] == [
        "image-split UU\u2020",
        "image-split VQC",
        "majority class",
    ]
    np.testing.assert_allclose(lines[0].get_ydata(), [0.7, 0.6, 1 / 3])
    title = fig._suptitle.get_text()
    assert "synthetic-track1 (30 frames)" in title
    assert "trained under noise" in title and "phase damping: textbook" in title
    png = save_figure(fig, tmp_path / "a" / "fig.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    sfig = shadow_figure(result)
    sax = [ax for ax in sfig.axes if ax.get_visible()]
    assert len(sax) == 6  # all six panels, the two swept channels drawn
    p, ber = result.series("uu-shadow", "depolarizing", "ber")
    np.testing.assert_allclose(sax[3].get_lines()[0].get_xdata(), p)
    np.testing.assert_allclose(sax[3].get_lines()[0].get_ydata(), ber)
    assert "2 test images" in sfig._suptitle.get_text()
    assert shadow_plot_path("out/noise.png") == Path("out/noise_shadow.png")
    with pytest.raises(ParameterError, match="no uu-shadow rows"):
        shadow_figure(_result([]))
