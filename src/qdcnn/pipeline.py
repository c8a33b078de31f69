"""The per-frame pipeline of the paper (Alg. 2), stage by stage, joined by :class:`PipelineConfig`.

load image -> UU-dagger shadow detection -> replace shadow pixels inside the road
ROI with road values -> smoothing, Canny, ROI, HoughLinesP -> grouping into two
lines -> two slopes -> direction decision (a fitted UU-dagger rule or VQC).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from qdcnn.config import PipelineConfig
from qdcnn.vision.grouping import LaneFeatures, group_segments
from qdcnn.vision.lanes import detect_segments
from qdcnn.vision.removal import remove_shadows
from qdcnn.vision.roi import polygon_mask
from qdcnn.vision.shadows import detect_shadows_uu

GROUPINGS: tuple[str, ...] = ("image-split", "kmeans", "spectral")


@dataclass
class FrameResult:
    """Everything the pipeline produced for one frame.

    Attributes
    ----------
    shadow_mask : ndarray of bool or None
        UU-dagger shadow mask (``None`` when shadow removal is off).
    corrected : ndarray of uint8
        The frame after shadow removal (the input itself when off).
    segments : ndarray, shape (N, 4)
        HoughLinesP segments ``x1, y1, x2, y2``.
    lanes : dict of str to LaneFeatures
        Two-line features per grouping method.
    """

    shadow_mask: NDArray[np.bool_] | None
    corrected: NDArray[np.uint8]
    segments: NDArray[np.float64]
    lanes: dict[str, LaneFeatures]


def process_frame(
    image: NDArray[np.uint8],
    config: PipelineConfig | None = None,
    groupings: Sequence[str] = ("image-split",),
    *,
    rng: int | np.random.Generator | None = None,
) -> FrameResult:
    """Run shadow removal and lane extraction on one RGB frame.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3)
        RGB frame.
    config : PipelineConfig, optional
        Settings of every stage (paper defaults).
    groupings : sequence of str
        Grouping methods whose features to compute; they share the segments.
    rng : int or Generator, optional
        Seed of the shadow detector's shot sampling.
    """
    cfg = config or PipelineConfig()
    mask = None
    corrected = image
    if cfg.lanes.remove_shadows:
        mask = detect_shadows_uu(image, cfg.shadow, rng=rng).mask
        corrected = remove_shadows(image, mask, polygon_mask(image.shape, cfg.lanes.roi))
    segments = detect_segments(corrected, cfg.lanes)
    lanes = {
        g: group_segments(
            segments,
            image.shape,
            g,
            seed=cfg.grouping.seed,
            extra_features=cfg.grouping.extra_features,
            merge_tolerance=cfg.grouping.merge_tolerance,
        )
        for g in groupings
    }
    return FrameResult(mask, corrected, segments, lanes)
