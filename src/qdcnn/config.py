"""One configuration object for the whole pipeline, with named presets.

Each stage reads its own section. Sections are frozen dataclasses, so a changed
setting is a new object (``dataclasses.replace``) and results can record exactly
what produced them (:meth:`PipelineConfig.to_dict`, :meth:`PipelineConfig.from_dict`).

Presets (:meth:`PipelineConfig.preset`): ``"udacity"`` is the no-argument default, the
paper's settings with the one change that makes them work on recordings (one smoothing
pass before Canny instead of 30, see :class:`LaneConfig`); ``"paper"`` is the paper's
literal settings. Every section's own defaults are the paper's values unless its
docstring says otherwise.

References to the paper are to ``shared/paper/qdcnn-paper.tex``; "NOTES" is
``shared/paper/NOTES.md``, which records the readings taken where the paper is
ambiguous.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from typing import Any, ClassVar, Literal

from qdcnn._validation import (
    check_choice,
    check_float,
    check_int,
    check_odd,
    check_optional_shots,
    check_probability,
    check_seed,
)
from qdcnn.errors import ParameterError

#: The paper's two shadow thresholds on the UU-dagger fidelity, one per dataset (NOTES 2).
PAPER_SHADOW_THRESHOLDS: tuple[float, ...] = (0.75, 0.97)
#: Candidate thresholds a trained shadow model chooses from (the paper's two among them).
SHADOW_THRESHOLD_GRID: tuple[float, ...] = (0.75, 0.9, 0.95, 0.97, 0.98, 0.99, 0.995, 0.998, 0.999)


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
        Fidelity at or above which a block is shadow. The paper uses 0.75 and
        0.97, one per dataset; qdcnn defaults to 0.97 because with 8-bit values
        the test is a band of +-28 grey levels around the centroid at 0.97 but
        +-85 levels at 0.75, wide enough to take in lit road near a shadow.
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
    calibration_classes : int
        Clusters of the per-image calibration start (used when no centroid or
        model is given): 2 is the two-means split of the paper's clustering start;
        3 or 4 take the darkest (for chromaticity: highest) class of a multi-Otsu
        split, so that a dark non-shadow cluster (canopies, tar) can sit apart.
    """

    feature: Literal["intensity", "chromaticity"] = "intensity"
    downsample: int = 4
    grid: int = 79
    threshold: float = 0.97
    shots: int | None = 1024
    median_ksize: int = 5
    centroid: float | None = None
    propagation_iterations: int = 50
    propagation_tol: float = 1e-9
    calibration_classes: int = 2

    def __post_init__(self) -> None:
        check_int("shadow.downsample", self.downsample, 1, 64)
        check_int("shadow.calibration_classes", self.calibration_classes, 2, 4)
        check_int("shadow.grid", self.grid, 1, 4096)
        check_float("shadow.threshold", self.threshold, 0.0, 1.0)
        check_optional_shots(self.shots, "shadow.shots")
        check_odd("shadow.median_ksize", self.median_ksize)
        if self.centroid is not None:
            check_float("shadow.centroid", self.centroid, 0.0, 255.0)
        check_int("shadow.propagation_iterations", self.propagation_iterations, 1, 10**6)
        check_choice("shadow.feature", self.feature, ("intensity", "chromaticity"))


@dataclass(frozen=True)
class LaneConfig:
    """Lane preprocessing and line detection (paper Sec. III-A; NOTES 5).

    The ROI is a polygon in coordinates relative to the frame (x / (W - 1),
    y / (H - 1), see :func:`qdcnn.vision.roi.polygon_pixels`), so one setting serves
    320x160 Udacity frames and larger ones. Named polygons are in :attr:`ROI_PRESETS`:

    - ``"udacity"`` (the default): drawn for 320x160 Udacity simulator frames. Top edge
      just below the horizon (vanishing point near (0.5, 0.39)), sides from y = 0.5 down,
      and a notch that leaves out the car's hood (its top is at y = 0.85 in the middle).
    - ``"paper-640x480"``: the paper's literal ``[(0, h), (80, 380), (380, 380), (w, h)]``
      in pixels, assuming the paper's frames were 640x480 (the paper does not give the
      size; :func:`qdcnn.vision.lanes.paper_roi` converts it for any other assumed size).
      On 320x160 Udacity frames it covers little more than the hood (rows 126-159).

    Attributes
    ----------
    remove_shadows : bool
        Whether :func:`qdcnn.pipeline.process_frame` replaces the UU-dagger shadow pixels
        inside the ROI by road pixels before this stage (the paper: yes).
    median_ksize, blur_ksize : int
        Odd apertures of the median filter and of the Gaussian blur (paper: 5 and 5).
    blur_sigma : float
        Gaussian sigma; 0 lets OpenCV derive it from the kernel size (paper: 0).
    smoothing_iterations : int
        Times median filter + blur are applied (paper: 30). Thirty passes act like a
        Gaussian of sigma ~6 px and leave no gradient above Canny's 175 unless an edge
        has nearly full contrast, at any frame size: on the Udacity recordings no edge
        survives. :meth:`udacity` uses 1.
    smoothing_margin : int or None
        Smooth only the ROI's bounding box grown by this many pixels (faster); ``None``
        smooths the whole frame, the paper's literal order. Edges inside the ROI differ
        only where the iterated filters' support reaches past the margin.
    canny_low, canny_high : int
        Canny hysteresis thresholds (paper: 50 and 175).
    roi : tuple of (x, y) pairs
        Relative ROI polygon applied to the edge map.
    hough_rho, hough_theta, hough_threshold, hough_min_line_length, hough_max_line_gap
        ``cv2.HoughLinesP`` settings (paper: 1, pi/180, 8, 2, 25).
    edge_channels : {"grey", "rgb"}
        What Canny sees. ``"grey"`` (the paper): the greyscale frame. ``"rgb"`` (not the
        paper's): the three colour channels, smoothed alike, with OpenCV's colour Canny,
        which keeps at each pixel the channel of largest gradient, so a yellow line on
        grey asphalt (nearly equal in grey) still gives edges.
    min_segment_angle : float
        Hough segments less steep than this many degrees from the horizontal are dropped
        (0, the paper: keep all). Near-horizontal segments come from kerb tops, shadows
        and the horizon rather than from the lane borders.
    max_segment_angle : float
        Hough segments steeper than this many degrees from the horizontal are dropped
        (90, the paper: keep all; not the paper's). Near-vertical segments come from poles,
        tree trunks and car sides; lane borders seen from a car are rarely steeper than 80.
    work_width : int or None
        Frame width, in pixels, at which smoothing, Canny and Hough run (not the paper's).
        ``None`` (the paper) works on the frame as given, so the pixel settings (apertures,
        Hough lengths and gaps, smoothing margin) mean different things at 320x160 and at
        1280x720. With a width set, every frame is resized to it first (aspect kept; OpenCV
        area interpolation when shrinking) and the segments are scaled back to the frame's
        pixels, so the pixel settings are relative to the frame size and one setting serves
        every size; the blur of the smoothing passes scales with them.
    marks : {"none", "hls", "lab"}
        Lane-mark evidence (not the paper's). ``"none"`` (the paper): Canny of the grey (or
        colour) frame. ``"hls"`` / ``"lab"``: Canny of a mask of white and yellow markings
        selected in that OpenCV colour space, so markings give edges and vegetation, kerbs
        and shadows mostly do not (:func:`qdcnn.vision.marks.marking_mask`).
    marks_contrast : float
        How much lighter than the road beside it a white marking must be, as a ratio: its
        lightness above the horizontal opening (a top-hat) by this fraction of the
        opening's value (and by 4 grey levels at least); 0.4 is above the grain of
        asphalt (10 % of its pixels are 12 % lighter than their surroundings on the real
        sample at 320 px, 35 % on the synthetic asphalt) and below paint (about 100 %).
    marks_width : float
        Widest marking, as a fraction of the working width: the top-hat's window is this
        wide, and brighter structures wider than it (sky, walls) are not markings.
    vanishing_point : (x, y) or None
        Where the lane lines of a straight road meet, relative to the frame (as the ROI);
        set by :func:`qdcnn.vision.camera.apply_camera` or a preset. Used only by
        ``vp_tolerance``.
    vp_tolerance : float or None
        Position filter (not the paper's): a segment is kept only when it lies below the
        vanishing point's row and its line crosses that row within this fraction of the
        width of the vanishing point (a lane border points at it; tree and car outlines
        mostly do not). ``None`` (the paper) keeps every segment.
    camera : {"fixed", "auto"}
        ``"fixed"`` uses ``roi`` as it is; ``"auto"`` (``--lanes auto``) replaces ``roi``
        and ``vanishing_point`` per recording by those estimated from its frames
        (:func:`qdcnn.pipeline.auto_lanes`).
    """

    ROI_PRESETS: ClassVar[dict[str, tuple[tuple[float, float], ...]]] = {
        # clockwise from the bottom-left corner; (0.08, 1.0)..(0.92, 1.0) cut out the hood
        "udacity": (
            (0.0, 1.0),
            (0.0, 0.5),
            (0.3, 0.42),
            (0.7, 0.42),
            (1.0, 0.5),
            (1.0, 1.0),
            (0.92, 1.0),
            (0.7, 0.87),
            (0.5, 0.82),
            (0.3, 0.87),
            (0.08, 1.0),
        ),
        "paper-640x480": (
            (0.0, 1.0),
            (80 / 639, 380 / 479),
            (380 / 639, 380 / 479),
            (1.0, 1.0),
        ),
        # qdcnn.vision.camera.camera_roi(horizon 0.40, vanishing point x 0.5, no hood) at
        # 640x480: a trapezoid narrowing towards the vanishing point, no hood notch
        "dashcam": (
            (0.0, 1.0),
            (0.0, 0.586764),
            (0.275039, 0.44),
            (0.724961, 0.44),
            (1.0, 0.586764),
            (1.0, 1.0),
        ),
    }
    #: ``marks`` choices: no colour evidence (the paper), or markings selected in HLS / Lab
    MARKS: ClassVar[tuple[str, ...]] = ("none", "hls", "lab")

    remove_shadows: bool = True
    median_ksize: int = 5
    blur_ksize: int = 5
    blur_sigma: float = 0.0
    smoothing_iterations: int = 30
    smoothing_margin: int | None = 8
    canny_low: int = 50
    canny_high: int = 175
    roi: tuple[tuple[float, float], ...] = ROI_PRESETS["udacity"]
    hough_rho: float = 1.0
    hough_theta: float = math.pi / 180
    hough_threshold: int = 8
    hough_min_line_length: int = 2
    hough_max_line_gap: int = 25
    edge_channels: Literal["grey", "rgb"] = "grey"
    min_segment_angle: float = 0.0
    max_segment_angle: float = 90.0
    work_width: int | None = None
    marks: Literal["none", "hls", "lab"] = "none"
    marks_contrast: float = 0.4
    marks_width: float = 0.05
    vanishing_point: tuple[float, float] | None = None
    vp_tolerance: float | None = None
    camera: Literal["fixed", "auto"] = "fixed"

    def __post_init__(self) -> None:
        check_odd("lanes.median_ksize", self.median_ksize)
        check_odd("lanes.blur_ksize", self.blur_ksize)
        check_float("lanes.blur_sigma", self.blur_sigma, 0.0, 1000.0)
        check_int("lanes.smoothing_iterations", self.smoothing_iterations, 0, 1000)
        if self.smoothing_margin is not None:
            check_int("lanes.smoothing_margin", self.smoothing_margin, 0, 10**5)
        check_int("lanes.canny_low", self.canny_low, 0, 10**4)
        check_int("lanes.canny_high", self.canny_high, 0, 10**4)
        if self.canny_low > self.canny_high:
            raise ParameterError(
                "lanes.canny_low", self.canny_low, f"at most canny_high={self.canny_high}"
            )
        roi = self.roi
        if not (isinstance(roi, tuple | list) and len(roi) >= 3 and all(map(_is_frame_point, roi))):
            raise ParameterError(
                "lanes.roi", roi, "at least 3 (x, y) pairs relative to the frame size"
            )
        check_float("lanes.hough_rho", self.hough_rho, 1e-3, 1e4)
        check_float("lanes.hough_theta", self.hough_theta, 1e-6, math.pi)
        check_int("lanes.hough_threshold", self.hough_threshold, 1, 10**6)
        check_int("lanes.hough_min_line_length", self.hough_min_line_length, 0, 10**6)
        check_int("lanes.hough_max_line_gap", self.hough_max_line_gap, 0, 10**6)
        check_choice("lanes.edge_channels", self.edge_channels, ("grey", "rgb"))
        check_float("lanes.min_segment_angle", self.min_segment_angle, 0.0, 90.0)
        check_float("lanes.max_segment_angle", self.max_segment_angle, 0.0, 90.0)
        if self.max_segment_angle <= self.min_segment_angle:
            raise ParameterError(
                "lanes.max_segment_angle",
                self.max_segment_angle,
                f"greater than min_segment_angle={self.min_segment_angle} (an empty range "
                "keeps no Hough segment, so no lane line is found)",
            )
        if self.work_width is not None:
            check_int("lanes.work_width", self.work_width, 16, 8192)
        check_choice("lanes.marks", self.marks, self.MARKS)
        check_float("lanes.marks_contrast", self.marks_contrast, 0.0, 10.0)
        check_float("lanes.marks_width", self.marks_width, 0.002, 0.5)
        vp = self.vanishing_point
        if vp is not None and not (isinstance(vp, tuple | list) and _is_frame_point(vp)):
            raise ParameterError(
                "lanes.vanishing_point", vp, "None or (x, y) relative to the frame size"
            )
        check_choice("lanes.camera", self.camera, ("fixed", "auto"))
        if self.vp_tolerance is not None:
            check_float("lanes.vp_tolerance", self.vp_tolerance, 0.0, 10.0)
            if self.vanishing_point is None:
                raise ParameterError(
                    "lanes.vp_tolerance",
                    self.vp_tolerance,
                    "None unless vanishing_point is set (a preset or apply_camera sets it)",
                )

    @classmethod
    def udacity(cls, **changes: Any) -> LaneConfig:
        """Settings for 320x160 Udacity frames: the paper's, but 1 smoothing iteration.

        On the lake and mountain recordings 1 iteration gives two lines in 88-93 % of the
        frames (2 iterations: 71-74 %, 30: none); ``changes`` override any field.
        """
        return cls(**{"smoothing_iterations": 1, **changes})

    @classmethod
    def paper(cls, **changes: Any) -> LaneConfig:
        """The paper's literal settings (Sec. III-A; NOTES 5).

        Thirty smoothing passes over the whole frame, Canny 50/175, the paper's ROI in the
        pixels of an assumed 640x480 frame (``"paper-640x480"``), HoughLinesP 1, pi/180, 8,
        2, 25 in the frame's own pixels; ``changes`` override any field.
        """
        base: dict[str, Any] = {
            "roi": cls.ROI_PRESETS["paper-640x480"],
            "smoothing_iterations": 30,
            "smoothing_margin": None,
        }
        return cls(**{**base, **changes})

    @classmethod
    def dashcam(cls, **changes: Any) -> LaneConfig:
        """Settings for a windscreen camera with no hood in view (not the paper's).

        The ``"dashcam"`` ROI (horizon near 40 % of the height, a trapezoid narrowing
        towards the vanishing point at the middle column), the paper's Canny and Hough
        values at a working width of 320 pixels (``work_width``; so they mean at 640x480 or
        1280x720 what they mean on 320x160 frames), 1 smoothing pass as
        :meth:`udacity`, and the vanishing point the ROI was drawn for. Colour evidence,
        segment filters and tracking stay off (named options). :func:`qdcnn.vision.camera.
        apply_camera` replaces the ROI and vanishing point by those estimated for a
        recording (``--lanes auto``).
        """
        base: dict[str, Any] = {
            "roi": cls.ROI_PRESETS["dashcam"],
            "smoothing_iterations": 1,
            "work_width": 320,
            "vanishing_point": (0.5, 0.40),
        }
        return cls(**{**base, **changes})

    @classmethod
    def auto(cls, **changes: Any) -> LaneConfig:
        """:meth:`dashcam` whose ROI and vanishing point are estimated per recording.

        ``camera="auto"``: before a recording's features are computed, its horizon,
        vanishing point and static hood are estimated from a sample of its frames
        (:func:`qdcnn.pipeline.auto_lanes`); without a usable horizon the dashcam preset
        stays, with a note.
        """
        return cls.dashcam(**{"camera": "auto", **changes})

    #: named lane presets (``--lanes``)
    PRESETS: ClassVar[tuple[str, ...]] = ("udacity", "paper", "dashcam", "auto")

    @classmethod
    def preset(cls, name: str, **changes: Any) -> LaneConfig:
        """The lane preset called ``name`` (one of :attr:`PRESETS`), with ``changes``."""
        if name not in cls.PRESETS:
            raise ParameterError("lanes", name, "one of " + ", ".join(map(repr, cls.PRESETS)))
        factory = {
            "udacity": cls.udacity,
            "paper": cls.paper,
            "dashcam": cls.dashcam,
            "auto": cls.auto,
        }[name]
        return factory(**changes)


@dataclass(frozen=True)
class GroupingConfig:
    """Grouping of Hough segments into two lines (paper Sec. II-A-3; NOTES 5).

    The grouping itself (image-split, k-means or spectral) is not a setting: every
    direction method names its own (:mod:`qdcnn.direction.methods`), and one pass of the
    pipeline computes the features of several groupings from the same segments.

    Attributes
    ----------
    features : str
        Feature mode: the two columns a 2-input classifier uses (:attr:`FEATURE_MODES`).
        ``"slopes"`` (the paper): the two fitted slopes dx/dy, left line first. The
        others (not the paper's) need their extras in ``extra_features``
        (:meth:`for_features` adds them): ``"far-offsets"`` (x of each line at a far
        row), ``"road-centre"`` (x of the centre line at a far and a near row) and
        ``"vanishing-points"`` (x of the vanishing point of the whole lines and of lines
        fitted to the near segments). The feature vector always starts with the two slopes.
    extra_features : tuple of str
        Named additions appended after the two slopes (not the paper's): any of
        ``"intercepts"``, ``"angles"``, ``"vanishing-point-offset"``, ``"far-offsets"``,
        ``"road-centre"``, ``"near-vanishing-point-offset"``
        (:mod:`qdcnn.vision.grouping`).
    merge_tolerance : float or None
        Two groups that one line fits within this fraction of the width (weighted RMS)
        are one line, status "one-line"; ``None`` keeps two slopes whenever there are
        two groups (:func:`qdcnn.vision.grouping.group_segments`).
    seed : int
        Seed of k-means and spectral clustering.
    track : {"none", "ema", "kalman"}
        Temporal tracking of the two fitted lines across the frames of a recording (not the
        paper's; :mod:`qdcnn.vision.tracking`). ``"none"`` (the paper): every frame alone.
        ``"ema"``: each line's x at two rows is an exponential moving average;
        ``"kalman"``: a constant-velocity Kalman filter on the same two numbers. Either
        way a line missing in a frame is carried from the last frames for up to
        ``track_hold`` frames, and the features are computed from the tracked lines.
    track_alpha : float
        Weight of the new frame in the moving average (1 = no smoothing).
    track_hold : int
        Frames a missing or rejected (too far from the track) line is carried for.
    inner_lines : bool
        Fit each side's innermost line only (not the paper's): segments of the other
        lane's far border, kerbs or parked cars on that side are left out of the fit
        (:func:`qdcnn.vision.grouping.group_segments`).
    """

    #: mode -> (its two column names, the extras that compute them)
    FEATURE_MODES: ClassVar[dict[str, tuple[tuple[str, str], tuple[str, ...]]]] = {
        "slopes": (("slope_left", "slope_right"), ()),
        "far-offsets": (("far_left", "far_right"), ("far-offsets",)),
        "road-centre": (("centre_far", "centre_near"), ("road-centre",)),
        "vanishing-points": (
            ("vanishing_point_offset", "near_vanishing_point_offset"),
            ("vanishing-point-offset", "near-vanishing-point-offset"),
        ),
    }
    EXTRAS: ClassVar[tuple[str, ...]] = (
        "intercepts",
        "angles",
        "vanishing-point-offset",
        "far-offsets",
        "road-centre",
        "near-vanishing-point-offset",
    )

    features: str = "slopes"
    extra_features: tuple[str, ...] = ()
    merge_tolerance: float | None = 0.03
    seed: int = 0
    track: Literal["none", "ema", "kalman"] = "none"
    track_alpha: float = 0.5
    track_hold: int = 5
    inner_lines: bool = False

    @classmethod
    def for_features(cls, features: str, **changes: Any) -> GroupingConfig:
        """A config for feature mode ``features`` with the extras it needs appended.

        Examples
        --------
        >>> GroupingConfig.for_features("far-offsets").extra_features
        ('far-offsets',)
        """
        if features not in cls.FEATURE_MODES:
            allowed = ", ".join(map(repr, cls.FEATURE_MODES))
            raise ParameterError("grouping.features", features, f"one of {allowed}")
        extras = tuple(changes.pop("extra_features", ()))
        extras += tuple(e for e in cls.FEATURE_MODES[features][1] if e not in extras)
        return cls(features=features, extra_features=extras, **changes)

    def __post_init__(self) -> None:
        if self.features not in self.FEATURE_MODES:
            allowed = ", ".join(map(repr, self.FEATURE_MODES))
            raise ParameterError("grouping.features", self.features, f"one of {allowed}")
        for extra in self.extra_features:
            if extra not in self.EXTRAS:
                raise ParameterError(
                    "grouping.extra_features",
                    extra,
                    "one of " + ", ".join(map(repr, self.EXTRAS)),
                )
        needed = self.FEATURE_MODES[self.features][1]
        if any(e not in self.extra_features for e in needed):
            raise ParameterError(
                "grouping.extra_features",
                self.extra_features,
                f"to include {needed} for features={self.features!r}"
                " (GroupingConfig.for_features adds them)",
            )
        if self.merge_tolerance is not None:
            check_float("grouping.merge_tolerance", self.merge_tolerance, 0.0, 1.0)
        check_choice("grouping.track", self.track, ("none", "ema", "kalman"))
        check_float("grouping.track_alpha", self.track_alpha, 0.01, 1.0)
        check_int("grouping.track_hold", self.track_hold, 0, 10**4)


@dataclass(frozen=True)
class DirectionConfig:
    """UU-dagger direction rule (paper Sec. III-A; NOTES 6).

    ``|P1 - P2| < straight_margin`` gives straight, ``P1 > P2`` right, else left.
    """

    straight_margin: float = 0.2
    shots: int | None = 1024

    def __post_init__(self) -> None:
        check_probability("direction.straight_margin", self.straight_margin)
        check_optional_shots(self.shots, "direction.shots")


@dataclass(frozen=True)
class VQCConfig:
    """Two-qubit variational quantum classifier (paper Sec. II-C; NOTES 6)."""

    feature_map_reps: int = 2  # ZZFeatureMap(2) uses Qiskit's default of two repetitions
    ansatz_reps: int = 1  # RealAmplitudes(2, reps=1): four trainable angles
    maxiter: int = 30
    loss: Literal["mse", "cross_entropy"] = "mse"
    shots: int | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        check_int("vqc.feature_map_reps", self.feature_map_reps, 1, 8)
        check_int("vqc.ansatz_reps", self.ansatz_reps, 0, 16)
        check_int("vqc.maxiter", self.maxiter, 1, 100_000)
        check_choice("vqc.loss", self.loss, ("mse", "cross_entropy"))
        check_optional_shots(self.shots, "vqc.shots")
        check_seed("vqc.seed", self.seed)


@dataclass(frozen=True)
class LabelConfig:
    """Direction labels from recorded steering (NOTES 6 and 9).

    Attributes
    ----------
    window : int
        Steering is smoothed over +-``window`` frames (never across a time gap).
    max_gap_s : float
        A timestamp gap longer than this splits the smoothing.
    threshold : float or None
        ``|smoothed steering|`` below this is straight, in the recording's steering unit;
        ``None`` takes the unit's default (0.05 for the simulator's [-1, 1]; the same
        road-wheel angle in radians or degrees: :data:`qdcnn.data.labels.DEFAULT_THRESHOLDS`).
    steering_unit : {"auto", "norm", "rad", "deg"}
        Unit of the recorded steering; ``"auto"`` decides from the recording
        (:func:`qdcnn.data.labels.infer_steering_unit`).
    threshold_quantile : float or None
        A percentile in [1, 99] instead of ``threshold`` (``--label-threshold p33``):
        the threshold is that percentile of ``|smoothed steering|`` over the TRAINING
        frames, pooled across units and applied unchanged to test frames
        (:func:`qdcnn.data.frames.resolve_quantile_threshold`). At most one of
        ``threshold`` and ``threshold_quantile`` is set. A dataset spec's own
        ``@threshold=`` overrides both for that recording.
    """

    window: int = 5
    max_gap_s: float = 1.0
    threshold: float | None = None
    steering_unit: str = "auto"
    threshold_quantile: float | None = None

    def __post_init__(self) -> None:
        check_int("labels.window", self.window, 0, 10_000)
        check_float("labels.max_gap_s", self.max_gap_s, 0.0, 1e6, open_lo=True)
        if self.threshold is not None:
            check_float("labels.threshold", self.threshold, 0.0, 1e6)
        check_choice("steering_unit", self.steering_unit, ("auto", "norm", "rad", "deg"))
        if self.threshold_quantile is not None:
            check_float("labels.threshold_quantile", self.threshold_quantile, 1.0, 99.0)
            if self.threshold is not None:
                raise ParameterError(
                    "labels.threshold_quantile",
                    self.threshold_quantile,
                    f"not together with labels.threshold={self.threshold!r}",
                )


@dataclass(frozen=True)
class PipelineConfig:
    """Every stage's settings. The default is the ``"udacity"`` preset (:meth:`preset`).

    Examples
    --------
    >>> from dataclasses import replace
    >>> cfg = PipelineConfig()
    >>> cfg.shadow.grid, cfg.shadow.downsample, cfg.lanes.canny_high
    (79, 4, 175)
    >>> cfg.lanes.smoothing_iterations, PipelineConfig.paper().lanes.smoothing_iterations
    (1, 30)
    >>> replace(cfg, shadow=replace(cfg.shadow, threshold=0.75)).shadow.threshold
    0.75
    >>> PipelineConfig.from_dict(cfg.to_dict()) == cfg
    True
    """

    shadow: ShadowConfig = field(default_factory=ShadowConfig)
    lanes: LaneConfig = field(default_factory=LaneConfig.udacity)
    grouping: GroupingConfig = field(default_factory=GroupingConfig)
    direction: DirectionConfig = field(default_factory=DirectionConfig)
    vqc: VQCConfig = field(default_factory=VQCConfig)
    labels: LabelConfig = field(default_factory=LabelConfig)
    seed: int = 0

    #: preset name -> what it is; :meth:`preset` builds them.
    PRESETS: ClassVar[dict[str, str]] = {
        "udacity": "the paper's settings with 1 smoothing pass (works on 320x160 recordings)",
        "paper": "the paper's literal settings (30 smoothing passes)",
        "dashcam": "a windscreen camera without a hood: trapezoid ROI, settings scaled to 320 px",
        "auto": "dashcam, with the ROI estimated per recording (horizon, vanishing point, hood)",
    }

    def __post_init__(self) -> None:
        check_seed("seed", self.seed)

    @classmethod
    def paper(cls, **changes: Any) -> PipelineConfig:
        """The paper's literal settings, including its 30 median + blur passes before Canny."""
        return cls(lanes=LaneConfig(), **changes)

    @classmethod
    def udacity(cls, **changes: Any) -> PipelineConfig:
        """The default: the paper's settings, one smoothing pass (:meth:`LaneConfig.udacity`)."""
        return cls(lanes=LaneConfig.udacity(), **changes)

    @classmethod
    def preset(cls, name: str, **changes: Any) -> PipelineConfig:
        """The named preset ``name`` (one of :attr:`PRESETS`)."""
        if name not in cls.PRESETS:
            raise ParameterError("lanes", name, "one of " + ", ".join(map(repr, cls.PRESETS)))
        return cls(lanes=LaneConfig.preset(name), **changes)

    def with_lane_options(
        self, *, features: str = "slopes", edges: str = "grey", shadow_removal: bool = True
    ) -> PipelineConfig:
        """This config with a feature mode, Canny's input and shadow removal set.

        The named options of ``qdcnn evaluate`` and ``train-direction`` (``--features``,
        ``--edges``, ``--[no-]shadow-removal``); the defaults are the paper's.
        """
        if edges not in ("grey", "rgb"):
            raise ParameterError("edges", edges, "'grey' (the paper) or 'rgb' (colour Canny)")
        channels: Literal["grey", "rgb"] = "rgb" if edges == "rgb" else "grey"
        lanes = replace(self.lanes, edge_channels=channels, remove_shadows=bool(shadow_removal))
        return replace(self, lanes=lanes, grouping=GroupingConfig.for_features(features))

    def with_lane_evidence(
        self,
        *,
        marks: str = "none",
        segment_angles: tuple[float, float] | None = None,
        vp_tolerance: float | None = None,
        inner_lines: bool = False,
        track: str = "none",
    ) -> PipelineConfig:
        """This config with the lane-evidence options (not the paper's; the defaults keep it).

        ``marks`` picks white and yellow markings before Canny (``"lab"``, ``"hls"``),
        ``segment_angles`` keeps Hough segments between two angles from the horizontal,
        ``vp_tolerance`` keeps segments that point at the vanishing point, ``inner_lines``
        keeps each side's innermost line, ``track`` smooths lines across frames
        (``"ema"``, ``"kalman"``).
        """
        lo, hi = (self.lanes.min_segment_angle, self.lanes.max_segment_angle)
        if segment_angles is not None:
            lo, hi = segment_angles
            if not lo < hi:
                raise ParameterError(
                    "segment_angles",
                    f"{lo:g},{hi:g}",
                    "LO,HI degrees from the horizontal with LO < HI (equal angles keep no "
                    "Hough segment, so no lane line is found)",
                )
        lanes = replace(
            self.lanes,
            marks=marks,  # type: ignore[arg-type]
            min_segment_angle=lo,
            max_segment_angle=hi,
            vp_tolerance=vp_tolerance,
        )
        grouping = replace(self.grouping, inner_lines=bool(inner_lines), track=track)  # type: ignore[arg-type]
        return replace(self, lanes=lanes, grouping=grouping)

    def with_labels(
        self,
        *,
        steering_unit: str = "auto",
        threshold: float | None = None,
        threshold_quantile: float | None = None,
    ) -> PipelineConfig:
        """This config with the recording's steering unit and the label threshold set.

        The options ``--steering-unit`` and ``--label-threshold`` (``None``: the unit's
        default threshold; ``pNN`` is ``threshold_quantile=NN``, see :class:`LabelConfig`).
        """
        labels = replace(
            self.labels,
            steering_unit=steering_unit,
            threshold=threshold,
            threshold_quantile=threshold_quantile,
        )
        return replace(self, labels=labels)

    def to_dict(self) -> dict[str, Any]:
        """Return the settings as plain JSON-serialisable values."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PipelineConfig:
        """The config :meth:`to_dict` wrote (lists become tuples; every value is re-checked).

        Raises
        ------
        ParameterError
            An unknown section or field, or a value its section refuses.
        """
        if not isinstance(data, Mapping):
            raise ParameterError("config", type(data).__name__, "a mapping of sections")
        sections = {f.name: f for f in fields(cls)}
        unknown = sorted(set(data) - set(sections))
        if unknown:
            raise ParameterError("config", unknown, f"sections among {sorted(sections)}")
        values: dict[str, Any] = {}
        for name, value in data.items():
            section_type = _SECTION_TYPES.get(name)
            values[name] = value if section_type is None else _section(section_type, name, value)
        return cls(**values)


_SECTION_TYPES: dict[str, type] = {
    "shadow": ShadowConfig,
    "lanes": LaneConfig,
    "grouping": GroupingConfig,
    "direction": DirectionConfig,
    "vqc": VQCConfig,
    "labels": LabelConfig,
}


def _is_frame_point(point: Any) -> bool:
    """Whether ``point`` is an ``(x, y)`` pair of finite numbers in [-1, 2], relative to the
    frame size (a little outside the frame is allowed)."""
    try:
        x, y = point
        return all(math.isfinite(float(v)) and -1.0 <= float(v) <= 2.0 for v in (x, y))
    except (TypeError, ValueError):
        return False


def _section(section_type: type, name: str, value: object) -> Any:
    if not isinstance(value, Mapping):
        raise ParameterError(f"config.{name}", type(value).__name__, "a mapping of fields")
    known = {f.name for f in fields(section_type)}
    unknown = sorted(set(value) - known)
    if unknown:
        raise ParameterError(f"config.{name}", unknown, f"fields among {sorted(known)}")
    return section_type(**{k: _as_tuples(v) for k, v in value.items()})


def _as_tuples(value: Any) -> Any:
    """JSON lists back to the tuples the frozen sections hold."""
    if isinstance(value, list):
        return tuple(_as_tuples(v) for v in value)
    return value

