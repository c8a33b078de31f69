"""One configuration object for the whole pipeline; every default is the paper's setting.

Each stage reads its own section. Sections are frozen dataclasses, so a changed
setting is a new object (``dataclasses.replace``) and results can record exactly
what produced them (:meth:`PipelineConfig.to_dict`).

References to the paper are to ``shared/paper/qdcnn-paper.tex``; "NOTES" is
``shared/paper/NOTES.md``, which records the readings taken where the paper is
ambiguous.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

from qdcnn.errors import ParameterError


@dataclass(frozen=True)
class ShadowConfig:
    """Block-wise UU-dagger shadow detection (paper Sec. II-A-2 and III-A; NOTES 2-4).

    Attributes
    ----------
    feature : {"intensity", "chromaticity"}
        Block input: greyscale intensity or a chromaticity value computed from RGB.
    downsample : int
        Integer downsampling factor applied before the block grid (paper: 4).
    grid : int
        Blocks per side (paper: 79). When the downsampled image has fewer pixels
        than this along an axis, each block is one downsampled pixel on that axis.
    threshold : float
        Fidelity at or above which a block is shadow (paper: 0.75 or 0.97).
    shots : int or None
        Shots per block circuit (paper: 1024); ``None`` uses exact probabilities.
    median_ksize : int
        Aperture of the median filter applied to the full-size mask (odd).
    centroid : float or None
        Shadow centroid as an 8-bit value in [0, 255]; ``None`` calibrates it per
        image (a clustering start refined by the propagation algorithm).
    propagation_iterations : int
        Maximum iterations of the centroid propagation algorithm.
    propagation_tol : float
        Stop when the centroid angle moves less than this (radians).
    """

    feature: Literal["intensity", "chromaticity"] = "intensity"
    downsample: int = 4
    grid: int = 79
    threshold: float = 0.75
    shots: int | None = 1024
    median_ksize: int = 5
    centroid: float | None = None
    propagation_iterations: int = 50
    propagation_tol: float = 1e-9

    def __post_init__(self) -> None:
        _check_int("shadow.downsample", self.downsample, 1, 64)
        _check_int("shadow.grid", self.grid, 1, 4096)
        _check_range("shadow.threshold", self.threshold, 0.0, 1.0)
        if self.shots is not None:
            _check_int("shadow.shots", self.shots, 1, 10**9)
        if self.median_ksize < 1 or self.median_ksize % 2 == 0:
            raise ParameterError("shadow.median_ksize", self.median_ksize, "a positive odd integer")
        if self.centroid is not None:
            _check_range("shadow.centroid", self.centroid, 0.0, 255.0)
        _check_int("shadow.propagation_iterations", self.propagation_iterations, 1, 10**6)
        if self.feature not in ("intensity", "chromaticity"):
            raise ParameterError("shadow.feature", self.feature, "'intensity' or 'chromaticity'")


@dataclass(frozen=True)
class LaneConfig:
    """Lane preprocessing and line detection (paper Sec. III-A; NOTES 5).

    The ROI is a polygon in coordinates relative to the frame (x / width,
    y / height), so one setting serves 320x160 Udacity frames and larger ones.
    """

    remove_shadows: bool = True
    median_ksize: int = 5
    blur_ksize: int = 5
    blur_sigma: float = 0.0
    smoothing_iterations: int = 30
    canny_low: int = 50
    canny_high: int = 175
    roi: tuple[tuple[float, float], ...] = ((0.0, 1.0), (0.25, 0.45), (0.75, 0.45), (1.0, 1.0))
    hough_rho: float = 1.0
    hough_theta: float = math.pi / 180
    hough_threshold: int = 8
    hough_min_line_length: int = 2
    hough_max_line_gap: int = 25


@dataclass(frozen=True)
class GroupingConfig:
    """Grouping of Hough segments into two lines (paper Sec. II-A-3; NOTES 5)."""

    method: Literal["image-split", "kmeans", "spectral"] = "image-split"
    features: Literal["slopes"] = "slopes"
    seed: int = 0


@dataclass(frozen=True)
class DirectionConfig:
    """UU-dagger direction rule (paper Sec. III-A; NOTES 6).

    ``|P1 - P2| < straight_margin`` gives straight, ``P1 > P2`` right, else left.
    """

    straight_margin: float = 0.2
    shots: int | None = 1024


@dataclass(frozen=True)
class VQCConfig:
    """Two-qubit variational quantum classifier (paper Sec. II-C; NOTES 6)."""

    feature_map_reps: int = 2  # ZZFeatureMap(2) uses Qiskit's default of two repetitions
    ansatz_reps: int = 1  # RealAmplitudes(2, reps=1): four trainable angles
    maxiter: int = 30
    loss: Literal["mse", "cross_entropy"] = "mse"
    shots: int | None = None
    seed: int = 0


@dataclass(frozen=True)
class LabelConfig:
    """Direction labels from recorded steering (NOTES 6 and 9)."""

    window: int = 5
    max_gap_s: float = 1.0
    threshold: float = 0.05


@dataclass(frozen=True)
class PipelineConfig:
    """Every stage's settings; the defaults are the paper's.

    Examples
    --------
    >>> from dataclasses import replace
    >>> cfg = PipelineConfig()
    >>> cfg.shadow.grid, cfg.shadow.downsample, cfg.lanes.canny_high
    (79, 4, 175)
    >>> replace(cfg, shadow=replace(cfg.shadow, threshold=0.97)).shadow.threshold
    0.97
    """

    shadow: ShadowConfig = field(default_factory=ShadowConfig)
    lanes: LaneConfig = field(default_factory=LaneConfig)
    grouping: GroupingConfig = field(default_factory=GroupingConfig)
    direction: DirectionConfig = field(default_factory=DirectionConfig)
    vqc: VQCConfig = field(default_factory=VQCConfig)
    labels: LabelConfig = field(default_factory=LabelConfig)
    seed: int = 0

    def to_dict(self) -> dict[str, Any]:
        """Return the settings as plain JSON-serialisable values."""
        return asdict(self)


def _check_int(name: str, value: object, lo: int, hi: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ParameterError(name, value, f"an integer in [{lo}, {hi}]")


def _check_range(name: str, value: float, lo: float, hi: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
        raise ParameterError(name, value, f"a number in [{lo}, {hi}]")
