"""The UU-dagger fidelity test: exact, shot-sampled, on NumPy and Aer, and its band form."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.errors import ParameterError
from qdcnn.quantum.uu_dagger import (
    angle_to_value,
    band_halfwidth,
    classify,
    fidelity,
    overlap_fidelity,
    ry_state_table,
    value_to_angle,
)


def test_exact_fidelity_is_cos_squared_of_half_difference(rng: np.random.Generator) -> None:
    tc, tx = rng.uniform(0, np.pi), rng.uniform(0, np.pi, 500)
    np.testing.assert_allclose(fidelity(tc, tx, shots=None), np.cos((tc - tx) / 2) ** 2, atol=1e-12)


def test_identical_states_have_fidelity_one_and_orthogonal_zero() -> None:
    np.testing.assert_allclose(
        fidelity(0.7, [0.7, 0.7 + np.pi], shots=None), [1.0, 0.0], atol=1e-12
    )


def test_value_angle_mapping() -> None:
    np.testing.assert_allclose(value_to_angle([0, 127.5, 255]), [0, np.pi / 2, np.pi])
    np.testing.assert_allclose(angle_to_value(value_to_angle([3.0, 200.0])), [3.0, 200.0])


def test_default_is_1024_shots(rng: np.random.Generator) -> None:
    tx = rng.uniform(0, np.pi, 2000)
    est = fidelity(1.0, tx, rng=4)
    # 1024-shot estimates are multiples of 1/1024 and unbiased
    np.testing.assert_allclose(est * 1024, np.round(est * 1024), atol=1e-9)
    exact = fidelity(1.0, tx, shots=None)
    assert abs((est - exact).mean()) < 4 * np.sqrt((exact * (1 - exact)).mean() / 1024 / tx.size)


@pytest.mark.parametrize("threshold", [0.75, 0.97, 0.5, 0.99])
def test_band_threshold_equivalence(threshold: float) -> None:
    values = np.arange(256.0)
    centroid = 60.0
    members, _ = classify(values, centroid, threshold, shots=None)
    halfwidth = angle_to_value(band_halfwidth(threshold))
    inside = np.abs(values - centroid) <= halfwidth
    # identical away from the boundary value, where float rounding can decide either way
    away = np.abs(np.abs(values - centroid) - halfwidth) > 1e-6
    np.testing.assert_array_equal(members[away], inside[away])
    assert members.sum() == pytest.approx(inside.sum(), abs=1)


def test_band_halfwidths_of_paper_thresholds() -> None:
    # 0.75 -> +-85 grey levels, 0.97 -> +-28.26 grey levels around the centroid
    assert float(angle_to_value(band_halfwidth(0.75))) == pytest.approx(85.0)
    assert float(angle_to_value(band_halfwidth(0.97))) == pytest.approx(28.26, abs=0.01)
    with pytest.raises(ParameterError, match="threshold=1.5 is invalid"):
        band_halfwidth(1.5)


def test_classify_keeps_input_shape() -> None:
    members, scores = classify(np.full((3, 4), 50.0), 50.0, 0.9, shots=None)
    assert members.shape == scores.shape == (3, 4)
    assert members.all()


def test_aer_backend_agrees_with_numpy(rng: np.random.Generator) -> None:
    pytest.importorskip("qiskit_aer")
    tx = rng.uniform(0, np.pi, 25)
    np.testing.assert_allclose(
        fidelity(0.9, tx, shots=None, backend="aer"), fidelity(0.9, tx, shots=None), atol=1e-10
    )
    exact = fidelity(0.9, tx, shots=None)
    est = fidelity(0.9, tx, shots=1024, backend="aer", rng=0)
    assert (np.abs(est - exact) <= 4 * np.sqrt(exact * (1 - exact) / 1024) + 1e-9).all()


def test_unknown_backend() -> None:
    with pytest.raises(ParameterError, match="backend='gpu' is invalid"):
        fidelity(0.1, 0.2, backend="gpu")


@pytest.mark.parametrize("denominator", [1, 7, 16, 32])
def test_state_table_overlap_equals_the_circuit_simulation(denominator: int) -> None:
    cos_half, sin_half = ry_state_table(denominator)
    values = np.arange(cos_half.size) / denominator
    assert values[-1] == 255.0
    for centroid in (0.0, 61.3, 200.0):
        tc = float(value_to_angle(centroid))
        np.testing.assert_allclose(
            overlap_fidelity(tc, cos_half, sin_half),
            fidelity(tc, value_to_angle(values), shots=None),
            rtol=0,
            atol=1e-12,
        )


def test_state_table_overlap_agrees_with_aer(rng: np.random.Generator) -> None:
    pytest.importorskip("qiskit_aer")
    cos_half, sin_half = ry_state_table(16)
    k = rng.integers(0, cos_half.size, 25)
    tc = float(value_to_angle(87.0))
    np.testing.assert_allclose(
        overlap_fidelity(tc, cos_half[k], sin_half[k]),
        fidelity(tc, value_to_angle(k / 16), shots=None, backend="aer"),
        atol=1e-10,
    )


@pytest.mark.parametrize(("denominator", "scale"), [(0, 255.0), (4, 255.5), (3, 0.0)])
def test_state_table_checks_its_arguments(denominator: int, scale: float) -> None:
    with pytest.raises(ParameterError, match="denominator/scale"):
        ry_state_table(denominator, scale)
