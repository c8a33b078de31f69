"""UU-dagger shadow detection's balanced error rate against noise strength (Fig. 7's shadows).

The block-wise UU-dagger detector's centroid is trained on training images with masks
(:func:`qdcnn.vision.shadow_training.train_shadow_model`), its threshold chosen by training
BER among the candidates: by default the fine grid
:data:`~qdcnn.config.SHADOW_THRESHOLD_GRID` that ``train-shadows`` uses, so a sweep scores
the model ``train-shadows`` would train on the same images (``thresholds="paper"``: the
paper's 0.75 and 0.97). Test images are then detected under each (channel, p) and scored
by the balanced error rate of the pixel counts summed over the test set
(:func:`qdcnn.vision.metrics.shadow_scores`). With ``train_under_noise`` the threshold is
re-chosen among the same candidates on the training blocks' noisy scores.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from qdcnn._threads import single_thread
from qdcnn._validation import check_int
from qdcnn.config import ShadowConfig
from qdcnn.errors import ParameterError
from qdcnn.experiments.noise._rng import point_rng
from qdcnn.experiments.noise.options import (
    PAPER_STRENGTHS,
    SHADOW_METHOD,
    check_grid,
    parse_shadow_thresholds,
)
from qdcnn.experiments.noise.results import SweepRow
from qdcnn.quantum.noise import PAPER_CHANNELS, NoiseSpec
from qdcnn.quantum.uu_dagger import fidelity, value_to_angle
from qdcnn.vision.metrics import ConfusionCounts, confusion_counts, shadow_scores
from qdcnn.vision.shadow_training import block_shadow_fraction, train_shadow_model
from qdcnn.vision.shadows import (
    ShadowModel,
    block_grid,
    block_means,
    detect_shadows_uu,
    feature_input,
)

__all__ = ["MAX_SHADOW_FRAMES", "shadow_sweep", "split_train_test", "synthetic_shadow_set"]

#: Most synthetic scenes a sweep renders.
MAX_SHADOW_FRAMES = 2000


def synthetic_shadow_set(
    n: int = 24, *, preset: str = "track2", seed: int = 0
) -> tuple[list[NDArray[np.uint8]], list[NDArray[np.bool_]]]:
    """``n`` independent synthetic road scenes and their exact shadow masks."""
    from qdcnn.data.synthetic import generate_scenes

    check_int("shadow_frames", n, 2, MAX_SHADOW_FRAMES)
    scenes = generate_scenes(preset, n, seed=seed)
    return [s.image for s in scenes], [s.shadow_mask for s in scenes]


def split_train_test(n: int, train_fraction: float = 0.5) -> tuple[slice, slice]:
    """The first ``ceil(n * train_fraction)`` items train (at least 1, leaving at least 1 test)."""
    if not 0.0 < train_fraction < 1.0:
        raise ParameterError("train_fraction", train_fraction, "a number in (0, 1)")
    if n < 2:
        raise ParameterError("images", n, "at least 2 images with masks (train and test)")
    k = min(max(math.ceil(n * train_fraction), 1), n - 1)
    return slice(0, k), slice(k, n)


def _noisy_threshold(
    model: ShadowModel,
    images: Sequence[NDArray[np.uint8]],
    masks: Sequence[NDArray[np.bool_]],
    config: ShadowConfig,
    noise: NoiseSpec,
    thresholds: Sequence[float],
) -> float:
    """The candidate threshold with the lowest block-level training BER under ``noise``."""
    values, truth = [], []
    for image, mask in zip(images, masks, strict=True):
        geometry = block_grid(image.shape[:2], config.downsample, config.grid)
        feats = feature_input(image, model.feature)
        values.append(block_means(feats, geometry, config.downsample).ravel())
        truth.append(block_shadow_fraction(mask, config).ravel() >= 0.5)
    v, gt = np.concatenate(values), np.concatenate(truth)
    scores = fidelity(value_to_angle(model.centroid), value_to_angle(v), shots=None, noise=noise)
    bers = [shadow_scores(confusion_counts((scores >= t)[None], gt[None])).ber for t in thresholds]
    return float(thresholds[int(np.argmin(bers))])


def shadow_sweep(
    train_images: Sequence[NDArray[np.uint8]],
    train_masks: Sequence[NDArray[np.bool_]],
    test_images: Sequence[NDArray[np.uint8]],
    test_masks: Sequence[NDArray[np.bool_]],
    *,
    channels: Sequence[str] = PAPER_CHANNELS,
    strengths: Sequence[float] = PAPER_STRENGTHS,
    config: ShadowConfig | None = None,
    thresholds: str | Sequence[float] = "grid",
    train_under_noise: bool = False,
    shots: int | None = None,
    readout: float = 0.0,
    seed: int = 0,
    on_step: Callable[[], None] | None = None,
) -> tuple[list[SweepRow], ShadowModel]:
    """Balanced error rate of UU-dagger shadow detection under each (channel, p).

    Parameters
    ----------
    train_images, train_masks : sequences
        RGB images and bool shadow masks the centroid (and threshold) is trained on.
    test_images, test_masks : sequences
        The images scored at every noise setting.
    channels, strengths : sequences
        The noise grid.
    config : ShadowConfig, optional
        Detector settings (its ``shots`` is replaced by ``shots``).
    thresholds : "grid", "paper" or sequence of float
        Candidate fidelity thresholds (module docstring).
    train_under_noise : bool
        Re-choose the threshold on the training blocks' scores under each noise setting.
    shots : int or None
        Shots per block circuit; ``None`` for exact probabilities.
    readout : float
        Readout error added at every point.
    seed : int
        Seed of shot sampling.
    on_step : callable, optional
        Called after every (channel, p) point.

    Returns
    -------
    rows : list of SweepRow
        ``method="uu-shadow"``; ``ber``, ``shadow_error`` and ``nonshadow_error`` in percent,
        ``accuracy`` the share of correctly classified pixels.
    model : ShadowModel
        The noiseless model.
    """
    cfg = replace(config or ShadowConfig(), shots=shots)
    check_grid(channels, strengths, readout)
    candidates = parse_shadow_thresholds(thresholds)
    if not test_images or len(test_images) != len(test_masks):
        raise ParameterError(
            "test images/masks", f"{len(test_images)}/{len(test_masks)}", "equal, non-zero counts"
        )
    model = train_shadow_model(list(train_images), list(train_masks), cfg, candidates)
    rows = []
    with single_thread():
        for channel in channels:
            for p in strengths:
                noise = NoiseSpec(channel, float(p), readout)
                used = model
                if train_under_noise:
                    t = _noisy_threshold(model, train_images, train_masks, cfg, noise, candidates)
                    used = replace(model, threshold=t)
                gen = point_rng(seed, SHADOW_METHOD, channel, p)
                rows.append(_shadow_row(used, test_images, test_masks, cfg, noise, gen))
                if on_step:
                    on_step()
    return rows, model


def _shadow_row(
    model: ShadowModel,
    images: Sequence[NDArray[np.uint8]],
    masks: Sequence[NDArray[np.bool_]],
    cfg: ShadowConfig,
    noise: NoiseSpec,
    rng: np.random.Generator,
) -> SweepRow:
    """Detect shadows in every test image under ``noise`` (one (channel, p)); the sweep row
    of the pixel counts summed."""
    assert noise.channel is not None
    counts = ConfusionCounts(0, 0, 0, 0)
    for i, (image, mask) in enumerate(zip(images, masks, strict=True)):
        det = detect_shadows_uu(image, cfg, model=model, noise=noise, rng=rng)
        counts = counts + confusion_counts(det.mask, mask, source=f"test image {i}")
    scores = shadow_scores(counts)
    return SweepRow(
        SHADOW_METHOD,
        None,
        noise.channel,
        noise.p,
        (counts.tp + counts.tn) / counts.total,
        len(images),
        ber=scores.ber,
        shadow_error=scores.shadow_error,
        nonshadow_error=scores.nonshadow_error,
        threshold=model.threshold,
    )
