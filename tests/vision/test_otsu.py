"""Otsu's threshold of float values equals scikit-image's, bin for bin."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.vision.otsu import otsu_threshold, uniform_histogram


def _samples(rng: np.random.Generator) -> list[np.ndarray]:
    """Uniform, bimodal and block-mean-like (sums over 16 to 240 pixels) values."""
    out = []
    for i in range(400):
        n = int(rng.integers(2, 4000))
        kind = i % 4
        if kind == 0:
            out.append(rng.random(n) * 255)
        elif kind == 1:
            out.append(rng.integers(0, 255 * 16, n) / 16.0)
        elif kind == 2:
            area = rng.choice([16.0, 20.0, 24.0, 32.0, 128.0, 160.0, 192.0, 240.0], n)
            out.append(np.floor(rng.random(n) * 255 * area) / area)
        else:
            low, high = rng.normal(60, 10, n // 2), rng.normal(180, 20, n - n // 2)
            out.append(np.clip(np.concatenate([low, high]), 0, 255))
    return out


def test_uniform_histogram_equals_numpy(rng: np.random.Generator) -> None:
    for v in _samples(rng):
        if v.min() == v.max():
            continue
        counts, edges = uniform_histogram(v, 256, float(v.min()), float(v.max()))
        ref_counts, ref_edges = np.histogram(v, 256)
        np.testing.assert_array_equal(counts, ref_counts)
        np.testing.assert_array_equal(edges, ref_edges)


def test_otsu_threshold_equals_scikit_image(rng: np.random.Generator) -> None:
    from skimage.filters import threshold_otsu

    for v in _samples(rng):
        assert otsu_threshold(v) == threshold_otsu(v, nbins=256)


def test_values_on_bin_edges_land_in_numpy_bins() -> None:
    """Values exactly on (or an ulp from) the edges: numpy's correction step is kept."""
    edges = np.linspace(0.0, 255.0, 257)
    v = np.concatenate([edges, np.nextafter(edges, -1.0)[1:], np.nextafter(edges, 300.0)[:-1]])
    counts, _ = uniform_histogram(v, 256, 0.0, 255.0)
    np.testing.assert_array_equal(counts, np.histogram(v, 256)[0])


def test_constant_values() -> None:
    assert otsu_threshold(np.full(7, 3.5)) == pytest.approx(3.5)
