"""Scores of direction predictions and their block-bootstrap intervals (issue 19)."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.signal import lfilter
from scipy.special import ndtr
from sklearn.metrics import balanced_accuracy_score, f1_score

from qdcnn.direction.scores import (
    Interval,
    block_bootstrap,
    block_length,
    collapsed,
    format_with_interval,
    one_answer_share,
    paired_difference,
    score,
)
from qdcnn.errors import InputError, ParameterError

Labels = NDArray[np.int64]
Draw = Callable[[np.random.Generator], tuple[Labels, Labels]]


# --- metrics: known answers -------------------------------------------------------------


@pytest.mark.parametrize(
    ("truth", "pred", "share", "mixed", "collapse"),
    [
        ([0] * 50 + [1] * 50, [1] * 96 + [0] * 4, 0.96, True, True),
        ([0] * 50 + [1] * 50, [1] * 95 + [0] * 5, 0.95, True, False),  # the rule says "more than"
        ([1] * 91 + [2] * 9, [1] * 100, 1.0, False, False),  # right is under 10 % of the block
        ([1] * 90 + [2] * 10, [1] * 100, 1.0, True, True),
        ([0] * 40 + [1] * 20 + [2] * 40, [0, 1, 2] * 33 + [0], 0.34, True, False),
    ],
)
def test_collapse_rule_known_answers(
    truth: list[int], pred: list[int], share: float, mixed: bool, collapse: bool
) -> None:
    assert one_answer_share(truth, pred) == (pytest.approx(share), mixed)
    assert collapsed(truth, pred) is collapse


def test_collapse_rule_refuses_mismatched_lengths() -> None:
    with pytest.raises(ParameterError, match=r"y_pred='shape \(1,\)' is invalid: shape \(2,\)"):
        one_answer_share([0, 1], [1])


def test_score_hand_computed_case() -> None:
    y_true = [0, 0, 0, 0, 1, 1, 2, 2, 2, 2]
    y_pred = [0, 0, 1, 2, 1, 0, 2, 2, 2, 1]
    s = score(y_true, y_pred)
    assert s.n == 10
    assert s.accuracy == pytest.approx(6 / 10)
    # recalls: left 2/4, straight 1/2, right 3/4
    assert s.per_class == pytest.approx({"left": 0.5, "straight": 0.5, "right": 0.75})
    assert s.balanced_accuracy == pytest.approx((0.5 + 0.5 + 0.75) / 3)
    # F1 = 2 tp / (2 tp + fp + fn): left 4/7, straight 2/5, right 6/8
    assert s.macro_f1 == pytest.approx((4 / 7 + 2 / 5 + 6 / 8) / 3)
    assert s.confusion == ((2, 1, 1), (1, 1, 0), (0, 1, 3))
    assert s.undefined is None


def test_score_absent_class_has_no_recall_and_is_left_out_of_balanced_accuracy() -> None:
    s = score([0, 0, 1, 1], [0, 2, 1, 1])
    assert s.per_class == {"left": 0.5, "straight": 1.0, "right": None}
    assert s.balanced_accuracy == pytest.approx(0.75)
    assert s.confusion[2] == (0, 0, 0)


def test_balanced_accuracy_is_undefined_for_one_class() -> None:
    s = score(np.ones(120, dtype=int), np.r_[np.ones(100, dtype=int), np.zeros(20, dtype=int)])
    assert s.balanced_accuracy is None
    assert s.undefined == "all 120 test labels are 'straight'"
    d = s.to_dict()
    assert d["balanced_accuracy"] is None and d["undefined"] == s.undefined
    with pytest.raises(InputError, match="undefined: all 120 test labels are 'straight'"):
        block_bootstrap(np.ones(120, dtype=int), np.ones(120, dtype=int), "balanced_accuracy")


def test_to_dict_is_plain_json() -> None:
    import json

    d = score([0, 1, 2, 2], [0, 1, 1, 2]).to_dict()
    assert set(d) == {"n", "accuracy", "balanced_accuracy", "macro_f1", "per_class", "confusion"}
    assert json.loads(json.dumps(d)) == d


def test_bad_labels_are_named() -> None:
    with pytest.raises(ParameterError, match="y_pred"):
        score([0, 1, 2], [0, 1, 3])
    with pytest.raises(ParameterError, match="y_pred"):
        score([0, 1, 2], [0, 1])
    with pytest.raises(InputError, match="no test frames"):
        score([], [])


def test_resampled_metrics_match_sklearn_on_the_original_frames() -> None:
    """With one resample that is the identity, the vectorised metrics are sklearn's."""
    from qdcnn.direction.scores import _metric_values

    rng = np.random.default_rng(3)
    for _ in range(20):
        y = rng.integers(0, 3, 50)
        p = np.where(rng.random(50) < 0.6, y, rng.integers(0, 3, 50))
        ident = np.arange(50)[None, :]
        assert _metric_values(y, p, "balanced_accuracy", ident)[0] == pytest.approx(
            balanced_accuracy_score(y, p)
        )
        assert _metric_values(y, p, "macro_f1", ident)[0] == pytest.approx(
            f1_score(y, p, average="macro", zero_division=0)
        )


def test_format_with_interval() -> None:
    iv = Interval(0.6621, 0.7602, 1000, 25, "x")
    assert format_with_interval(0.7134, iv) == "0.71 [0.66, 0.76]"
    assert format_with_interval(0.7134, iv, digits=3) == "0.713 [0.662, 0.760]"


# --- data with runs: a known population value -----------------------------------------


def labels_with_runs(rng: np.random.Generator, n: int, mean_run: float) -> Labels:
    """Classes 0/1/2 (1/4, 1/2, 1/4) in runs of geometric length (bends and straights)."""
    classes = rng.choice(3, size=n, p=[0.25, 0.5, 0.25])
    return np.repeat(classes, rng.geometric(1 / mean_run, n))[:n]


def markov_correct(rng: np.random.Generator, n: int, accuracy: float, wrong_run: float) -> Labels:
    """Correct/wrong as a two-state Markov chain started in its stationary law.

    Wrong runs have mean length ``wrong_run``, correct runs ``wrong_run * a / (1 - a)``,
    so the stationary probability of correct is exactly ``accuracy``.
    """
    leave_wrong = 1 / wrong_run
    leave_correct = leave_wrong * (1 - accuracy) / accuracy
    first = bool(rng.random() < accuracy)
    lengths = np.empty(2 * n, dtype=np.int64)
    lengths[0::2] = rng.geometric(leave_correct if first else leave_wrong, n)
    lengths[1::2] = rng.geometric(leave_wrong if first else leave_correct, n)
    states = np.tile([first, not first], n)
    return np.repeat(states, lengths)[:n].astype(np.int64)


def wrong_class(rng: np.random.Generator, y: Labels) -> Labels:
    return (y + rng.integers(1, 3, y.size)) % 3


def accuracy_draw(rng: np.random.Generator, n: int = 600) -> tuple[Labels, Labels]:
    """Accuracy 0.7 exactly in the population; wrong runs of 5 frames on average."""
    y = labels_with_runs(rng, n, 20)
    correct = markov_correct(rng, n, 0.7, 5).astype(bool)
    return y, np.where(correct, y, wrong_class(rng, y))


RECALLS = np.array([0.6, 0.8, 0.7])  # population balanced accuracy 0.7, accuracy 0.725


def balanced_draw(rng: np.random.Generator, n: int = 600) -> tuple[Labels, Labels]:
    """Recall per class exactly ``RECALLS``; errors correlated along frames.

    A frame is correct when ``Phi(g_t) < RECALLS[class]``, with ``g`` a stationary
    Gaussian AR(1) (phi 0.8), so errors come in runs but P(correct | class) is exact.
    """
    y = labels_with_runs(rng, n, 20)
    phi = 0.8
    shocks = rng.standard_normal(n) * np.sqrt(1 - phi**2)
    shocks[0] = rng.standard_normal()
    g = lfilter([1.0], [1.0, -phi], shocks)
    correct = ndtr(g) < RECALLS[y]
    return y, np.where(correct, y, wrong_class(rng, y))


def coverage(draw: Draw, metric: str, truth: float, draws: int, **kw: int) -> float:
    rng = np.random.default_rng(2024)
    hits = 0
    for i in range(draws):
        y, p = draw(rng)
        iv = block_bootstrap(y, p, metric, resamples=500, seed=i, **kw)
        hits += iv.low <= truth <= iv.high
    return hits / draws


# --- coverage -------------------------------------------------------------------------


def test_block_bootstrap_covers_the_population_accuracy() -> None:
    """800 draws of n=600 with correlated errors: the 95 % interval covers 0.7 in 93-97 %."""
    assert 0.93 <= coverage(accuracy_draw, "accuracy", 0.7, 800) <= 0.97


def test_iid_bootstrap_under_covers_correlated_errors() -> None:
    """Resampling single frames treats runs of errors as independent evidence."""
    assert coverage(accuracy_draw, "accuracy", 0.7, 200, block=1, min_block=1) < 0.75


def test_block_bootstrap_covers_the_population_balanced_accuracy() -> None:
    """Balanced accuracy: a little below nominal at n=600 (0.92 over 1000 draws; see
    docs/uncertainty.md), far above the i.i.d. bootstrap."""
    blocks = coverage(balanced_draw, "balanced_accuracy", 0.7, 300)
    single = coverage(balanced_draw, "balanced_accuracy", 0.7, 100, block=1, min_block=1)
    assert blocks >= 0.89
    assert single < 0.8


# --- block length, paired difference, determinism, speed -------------------------------


def test_automatic_block_grows_with_run_length_and_respects_min_block() -> None:
    rng = np.random.default_rng(5)
    y = labels_with_runs(rng, 2000, 20)
    short = np.where(markov_correct(rng, 2000, 0.7, 2).astype(bool), y, wrong_class(rng, y))
    long = np.where(markov_correct(rng, 2000, 0.7, 20).astype(bool), y, wrong_class(rng, y))
    assert block_length(y, long, "accuracy") > block_length(y, short, "accuracy")
    assert block_length(y, short, "accuracy", min_block=40) == 40
    iid = np.where(rng.random(2000) < 0.7, y, wrong_class(rng, y))
    assert block_length(y, iid, "accuracy") == 11  # the label smoothing span


def test_block_limits() -> None:
    y = np.tile([0, 1, 2], 10)
    with pytest.raises(ParameterError, match="block"):
        block_bootstrap(y, y, "accuracy", block=5)  # shorter than min_block 11
    with pytest.raises(InputError, match="too few"):
        block_bootstrap(y[:20], y[:20], "accuracy")
    with pytest.raises(ParameterError, match="metric"):
        block_bootstrap(y, y, "precision")


def test_identical_predictors_differ_by_exactly_zero() -> None:
    y, p = accuracy_draw(np.random.default_rng(1))
    for metric in ("accuracy", "balanced_accuracy", "macro_f1"):
        d = paired_difference(y, p, p, metric)
        assert d.value == 0.0
        assert d.interval.low == 0.0 and d.interval.high == 0.0


def test_better_predictor_on_a_known_subset_has_a_positive_interval() -> None:
    """b is a made wrong on 5 frames in every 30 where a is right: a's lead is certain."""
    rng = np.random.default_rng(2)
    y, a = accuracy_draw(rng)
    b = a.copy()
    hurt = (np.arange(y.size) % 30 < 5) & (a == y)
    b[hurt] = wrong_class(rng, y[hurt])
    d = paired_difference(y, a, b, "accuracy")
    assert d.value == pytest.approx(hurt.sum() / y.size)
    assert 0 < d.interval.low <= d.value <= d.interval.high
    assert paired_difference(y, a, b, "balanced_accuracy").interval.low > 0


def test_same_seed_same_interval_other_seed_other_interval() -> None:
    y, p = balanced_draw(np.random.default_rng(4))
    first = block_bootstrap(y, p, seed=7)
    assert block_bootstrap(y, p, seed=7) == first
    assert block_bootstrap(y, p, seed=8) != first
    assert first.low < score(y, p).balanced_accuracy < first.high  # type: ignore[operator]


def test_five_thousand_frames_thousand_resamples_is_fast() -> None:
    """Best of three, so a busy machine's pause does not count."""
    y, p = accuracy_draw(np.random.default_rng(6), n=5000)
    seconds = []
    for _ in range(3):
        start = time.perf_counter()
        block_bootstrap(y, p, "accuracy", resamples=1000)
        seconds.append(time.perf_counter() - start)
    assert min(seconds) < 1.0


def test_runs_of_several_seeds_average_on_the_same_resampled_frames() -> None:
    rng = np.random.default_rng(3)
    y = np.repeat(rng.integers(0, 3, 30), 10)
    p = np.where(rng.random(300) < 0.7, y, (y + 1) % 3)
    one = block_bootstrap(y, p, "balanced_accuracy", seed=2)
    assert block_bootstrap(y, np.stack([p, p]), "balanced_accuracy", seed=2) == one
    q = np.where(rng.random(300) < 0.5, y, (y + 2) % 3)
    both = block_bootstrap(y, np.stack([p, q]), "accuracy", seed=2)
    mean = (score(y, p).accuracy + score(y, q).accuracy) / 2
    assert both.low <= mean <= both.high
    d = paired_difference(y, np.stack([p, q]), p, "accuracy", seed=2)
    assert d.value == pytest.approx(mean - score(y, p).accuracy)
