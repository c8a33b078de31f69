"""The per-frame pipeline of the paper (Alg. 2), stage by stage, joined by :class:`PipelineConfig`.

load image -> UU-dagger shadow detection -> replace shadow pixels inside the road
ROI with road values -> smoothing, Canny, ROI, HoughLinesP -> grouping into two
lines -> two slopes -> direction decision (a fitted UU-dagger rule or VQC).

For a recording (not the paper's): :func:`auto_lanes` estimates the camera (horizon,
vanishing point, hood) from a few of its frames and puts the ROI built from it into the
lane settings (``--lanes auto``), and :func:`process_recording` runs :func:`process_frame`
over the frames in order, with the lines tracked across frames when
``config.grouping.track`` asks for it, and the preset's settings for frames whose size
differs from the one the camera was estimated on.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import replace
from functools import lru_cache, partial

import numpy as np
from numpy.typing import NDArray

from qdcnn.config import LaneConfig, PipelineConfig
from qdcnn.vision.camera import CameraGeometry, apply_camera, estimate_camera, sample_indices
from qdcnn.vision.grouping import LaneFeatures, group_segments
from qdcnn.vision.lane_stage import lane_segments
from qdcnn.vision.removal import remove_shadows
from qdcnn.vision.roi import polygon_mask, roi_rows
from qdcnn.vision.shadows import detect_shadows_uu


class FrameResult:
    """Everything the pipeline produced for one frame.

    Attributes
    ----------
    shadow_mask : ndarray of bool or None
        UU-dagger shadow mask (``None`` when shadow removal is off).
    corrected : ndarray of uint8
        The frame after shadow removal (the input itself when off); built on first use
        (:func:`process_frame` finds the segments without it).
    segments : ndarray, shape (N, 4)
        HoughLinesP segments ``x1, y1, x2, y2``.
    lanes : dict of str to LaneFeatures
        Two-line features per grouping method (tracked ones from
        :func:`process_recording` when tracking is on).
    notes : list of str
        One line per problem met with this frame (:func:`process_recording`).
    """

    def __init__(
        self,
        shadow_mask: NDArray[np.bool_] | None,
        corrected: NDArray[np.uint8] | Callable[[], NDArray[np.uint8]],
        segments: NDArray[np.float64],
        lanes: dict[str, LaneFeatures],
        notes: list[str] | None = None,
    ) -> None:
        self.shadow_mask = shadow_mask
        self._corrected = corrected
        self.segments = segments
        self.lanes = lanes
        self.notes = [] if notes is None else notes

    @property
    def corrected(self) -> NDArray[np.uint8]:
        if callable(self._corrected):
            self._corrected = self._corrected()
        return self._corrected


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
    corrected: NDArray[np.uint8] | Callable[[], NDArray[np.uint8]] = image
    if cfg.lanes.remove_shadows:
        mask = detect_shadows_uu(image, cfg.shadow, rng=rng).mask
    if mask is None:
        segments = lane_segments(image, cfg.lanes)
    else:
        # the segments of detect_segments(corrected); ``corrected`` is built on first use
        segments = lane_segments(image, cfg.lanes, mask)
        corrected = partial(remove_shadows, image, mask, road_region(image.shape, cfg.lanes.roi))
    lanes = {
        g: group_segments(
            segments,
            image.shape,
            g,
            seed=cfg.grouping.seed,
            extra_features=cfg.grouping.extra_features,
            merge_tolerance=cfg.grouping.merge_tolerance,
            inner_lines=cfg.grouping.inner_lines,
            roi_rows=roi_rows(cfg.lanes.roi),
        )
        for g in groupings
    }
    return FrameResult(mask, corrected, segments, lanes)


@lru_cache(maxsize=16)
def _road_region(shape: tuple[int, int], roi: tuple[tuple[float, float], ...]) -> NDArray[np.bool_]:
    mask = polygon_mask(shape, roi)
    mask.setflags(write=False)
    return mask


def road_region(shape: tuple[int, ...], roi: Sequence[tuple[float, float]]) -> NDArray[np.bool_]:
    """The lane ROI's mask on a frame of ``shape`` (read-only; built once per shape and ROI,
    not once per frame)."""
    polygon = tuple((float(x), float(y)) for x, y in roi)
    return _road_region((int(shape[0]), int(shape[1])), polygon)


def auto_lanes(
    frames: Sequence[NDArray[np.uint8]],
    config: PipelineConfig | None = None,
    preset: LaneConfig | None = None,
) -> tuple[PipelineConfig, CameraGeometry]:
    """``config`` with the lane ROI and vanishing point estimated from ``frames``.

    Parameters
    ----------
    frames : sequence of uint8 arrays
        Frames of one recording, e.g. ``[frames[i] for i in sample_indices(n)]``
        (:func:`qdcnn.vision.camera.sample_indices`).
    config : PipelineConfig, optional
        Settings to start from (their lane settings keep everything but ``roi`` and
        ``vanishing_point``); default ``PipelineConfig`` with :meth:`LaneConfig.dashcam`.
    preset : LaneConfig, optional
        What :func:`~qdcnn.vision.camera.estimate_camera` falls back on when no horizon is
        found; default ``config.lanes``.

    Returns
    -------
    (PipelineConfig, CameraGeometry)
        The settings to run with, and what was estimated (``geometry.describe()`` and
        ``geometry.notes`` say what was chosen and why).
    """
    cfg = config or replace(PipelineConfig(), lanes=LaneConfig.dashcam())
    geometry = estimate_camera(frames, preset or cfg.lanes)
    return replace(cfg, lanes=apply_camera(cfg.lanes, geometry)), geometry


def process_recording(
    frames: Iterable[NDArray[np.uint8]],
    config: PipelineConfig | None = None,
    groupings: Sequence[str] = ("image-split",),
    *,
    camera: CameraGeometry | None = None,
    fallback: LaneConfig | None = None,
    rng: int | np.random.Generator | None = None,
    on_note: Callable[[str], None] | None = None,
) -> Iterator[FrameResult]:
    """:func:`process_frame` over the frames of one recording, in order.

    Parameters
    ----------
    frames : iterable of uint8 arrays
        The recording's frames, in recording order.
    config : PipelineConfig, optional
        Settings, e.g. from :func:`auto_lanes`. With ``config.grouping.track`` other than
        "none" the lines of each grouping are tracked across frames
        (:class:`qdcnn.vision.tracking.LaneTracker`).
    groupings : sequence of str
        Grouping methods, as for :func:`process_frame`.
    camera : CameraGeometry, optional
        The geometry ``config`` was built for; frames of another size than
        ``camera.shape`` are processed with ``fallback`` (default: ``config.lanes`` with
        the :meth:`LaneConfig.dashcam` ROI and vanishing point) and get a note, and the
        tracks restart.
    fallback : LaneConfig, optional
        Lane settings for frames of another size.
    rng : int or Generator, optional
        Seed of the shadow detector's shot sampling.
    on_note : callable, optional
        Called once with each distinct note (e.g. to print it).

    Yields
    ------
    FrameResult
        One per frame, with ``notes`` for frames processed with the fallback.
    """
    from qdcnn.quantum.sampling import as_generator
    from qdcnn.vision.tracking import LaneTracker

    cfg = config or PipelineConfig()
    generator = as_generator(rng)
    preset = LaneConfig.dashcam()
    other = fallback or replace(cfg.lanes, roi=preset.roi, vanishing_point=preset.vanishing_point)
    other_cfg = replace(cfg, lanes=other)
    trackers = {g: LaneTracker(cfg.grouping) for g in groupings}
    told: set[str] = set()
    for image in frames:
        notes: list[str] = []
        frame_cfg = cfg
        if camera is not None and tuple(image.shape[:2]) != camera.shape:
            h, w = camera.shape
            notes.append(
                f"frame of {image.shape[1]}x{image.shape[0]} in a recording of {w}x{h}: "
                "lanes found with the preset's ROI"
            )
            frame_cfg = other_cfg
        result = process_frame(image, frame_cfg, groupings, rng=generator)
        result.lanes = {g: trackers[g].update(lanes) for g, lanes in result.lanes.items()}
        result.notes = notes
        for note in notes:
            if on_note is not None and note not in told:
                on_note(note)
            told.add(note)
        yield result


def recording_sample(n_frames: int) -> list[int]:
    """Indices of the frames :func:`auto_lanes` should see (:func:`sample_indices`)."""
    return [int(i) for i in sample_indices(n_frames)]
