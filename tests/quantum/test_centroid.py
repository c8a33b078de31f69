"""The propagation algorithm trains the centroid (paper Eqs. 1-4, NOTES 3)."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.errors import ParameterError
from qdcnn.quantum.centroid import (
    kmeans_start,
    propagate_centroid,
    propagation_fixed_point,
    propagation_step,
)


@pytest.mark.parametrize("start", [0.1, 1.0, 2.9])
def test_converges_to_mean_of_tight_cluster(rng: np.random.Generator, start: float) -> None:
    x = rng.normal(1.7, 0.01, 400)
    res = propagate_centroid(x, start, tol=1e-12)
    assert res.converged
    assert res.theta == pytest.approx(x.mean(), abs=1e-5)
    # D = 2 cos(tau) has a double root at tau = 0, so the Newton step halves the distance
    errors = np.abs(np.array(res.history) - res.theta)[5:15]
    np.testing.assert_allclose(errors[1:] / errors[:-1], 0.5, atol=0.02)


def test_single_value_newton_step_is_exact_identity() -> None:
    # theta + tan((x - theta)/2) moves towards x, and the fixed point is x itself
    res = propagate_centroid([1.2], 0.4, tol=1e-14)
    assert res.theta == pytest.approx(1.2, abs=1e-12)
    steps = np.diff(res.history)
    assert (steps[:-1] > 0).all()


def test_opposite_sign_would_diverge() -> None:
    # the paper's update with the other sign convention moves away from the data
    theta, x = 1.0, np.array([1.3])
    wrong = theta - propagation_step(theta, x)
    right = theta + propagation_step(theta, x)
    assert abs(wrong - 1.3) > abs(theta - 1.3) > abs(right - 1.3)


def test_history_records_every_iteration() -> None:
    res = propagate_centroid([0.5, 0.6, 0.7], 2.0, iterations=3, tol=0.0)
    assert len(res.history) == 4
    assert res.history[0] == 2.0
    assert not res.converged


def test_far_outlier_cannot_throw_centroid_out_of_range(rng: np.random.Generator) -> None:
    x = np.concatenate([rng.normal(0.2, 0.02, 50), [np.pi]])
    res = propagate_centroid(x, 0.0)
    assert 0.0 <= res.theta <= np.pi


def test_kmeans_start_picks_the_dark_cluster(rng: np.random.Generator) -> None:
    values = np.concatenate([rng.normal(50, 3, 300), rng.normal(180, 5, 700)])
    assert kmeans_start(values) == pytest.approx(50, abs=1)
    assert kmeans_start(values, pick="highest") == pytest.approx(180, abs=1)


def test_bad_inputs() -> None:
    with pytest.raises(ParameterError, match="angles='no finite values'"):
        propagate_centroid([np.nan])
    with pytest.raises(ParameterError, match="iterations=0"):
        propagate_centroid([1.0], iterations=0)


def _binned(rng: np.random.Generator, centre: float, spread: float) -> tuple[np.ndarray, ...]:
    values = np.clip(rng.normal(centre, spread, 3000), 0, 255)
    counts = np.bincount(np.round(values * 4).astype(np.intp))
    levels = np.flatnonzero(counts)
    return levels * 0.25 * np.pi / 255, counts[levels].astype(float), values.mean() * np.pi / 255


@pytest.mark.parametrize(("centre", "spread"), [(40, 8), (90, 20), (128, 18), (200, 5)])
def test_fixed_point_is_where_the_propagation_converges(
    rng: np.random.Generator, centre: float, spread: float
) -> None:
    angles, weights, start = _binned(rng, centre, spread)
    fast = propagation_fixed_point(angles, weights, start)
    assert fast is not None
    slow = propagate_centroid(angles, start, weights=weights)
    assert slow.converged
    assert fast == pytest.approx(slow.theta, abs=1e-8)
    assert abs(propagation_step(fast, angles, weights)) < 1e-14  # the root itself


def test_fixed_point_declines_when_the_propagation_may_not_reach_it(
    rng: np.random.Generator,
) -> None:
    angles, weights, start = _binned(rng, 90, 20)
    assert propagation_fixed_point(angles, weights, start, iterations=2) is None
    wide = np.array([0.1, 1.0, 2.5])  # spread beyond 2 pi / 3: not known to contract
    assert propagation_fixed_point(wide, np.ones(3), 1.2) is None
    assert propagation_fixed_point(angles, weights, start + 1.0) is None  # too far a start
