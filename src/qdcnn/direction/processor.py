"""Today's per-frame pipeline as a :class:`~qdcnn.runtime.chunks.FrameProcessor`.

:class:`LaneDirectionProcessor` runs UU-dagger shadow detection and removal, the lane stage
and a fitted direction model on each frame, and draws the video overlay (shadow tint, lane
segments by group, fitted lines, decision caption). The model is one attribute, so it can
come from a model file, from :meth:`LaneDirectionProcessor.train` or from a method registry.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.errors import QdcnnError
from qdcnn.runtime.chunks import FrameOutcome
from qdcnn.vision.grouping import LaneFeatures
from qdcnn.vision.overlays import (
    GROUP_COLOURS,
    LINE_COLOURS,
    MIDDLE_COLOUR,
    ROI_COLOUR,
    TEXT_COLOUR,
)
from qdcnn.vision.roi import polygon_pixels

if TYPE_CHECKING:
    from qdcnn.direction.model import DirectionModel


class LaneDirectionProcessor:
    """Today's pipeline as a processor: shadows, lanes and a fitted direction model.

    Per frame: :func:`qdcnn.pipeline.process_frame` with the model's pipeline settings
    (UU-dagger shadow detection and removal, Canny, Hough, the model's grouping) and the
    model's decision on the lane features, with its class probabilities
    (``probabilities=False`` leaves them out). The shadow detector's shot sampling is
    seeded by ``(seed, frame index)`` and the classifier sees one frame per call, so a
    frame gets the same result in any chunk and on any worker. The overlay tints the
    shadow mask and draws the lane segments, fitted lines and the decision
    (:func:`draw_video_overlay`).

    The model source is one attribute (``model``, a
    :class:`qdcnn.direction.model.DirectionModel`), so it can come from a file,
    from :meth:`train` or, later, from the method registry.
    """

    classes: tuple[str, ...] | None

    def __init__(
        self,
        model: DirectionModel,
        *,
        seed: int = 0,
        tint: bool = True,
        probabilities: bool = True,
    ) -> None:
        from qdcnn.data.labels import DIRECTIONS

        self.model = model
        self.seed = int(seed)
        self.tint = bool(tint)
        self.config = model.config
        self.grouping = model.grouping or "image-split"
        self.reads_frames = model.grouping is None
        has_proba = probabilities and hasattr(model.estimator, "predict_proba")
        self.classes = tuple(DIRECTIONS) if has_proba else None
        self._names = tuple(DIRECTIONS)

    @classmethod
    def train(
        cls,
        method: str | None = None,
        *,
        data: str | Sequence[str] | None = None,
        seed: int = 0,
    ) -> LaneDirectionProcessor:
        """Fit lane method ``method`` on ``data`` (dataset specs) with the default settings.

        Without arguments this is the built-in default model of ``qdcnn run``
        (:mod:`qdcnn.direction.builtin`), read from the cache when there.
        """
        from qdcnn.direction import builtin as dm

        specs = dm.DEFAULT_TRAINING_DATA if data is None else data
        model = dm.default_direction_model(method or dm.DEFAULT_METHOD, seed, data=specs)
        return cls(model, seed=seed)

    def settings(self) -> dict[str, Any]:
        return {
            "processor": "lane-direction",
            "method": self.model.method,
            "config": self.config.to_dict(),
            "trained_on": self.model.trained_on,
            "estimator": estimator_fingerprint(self.model.estimator),
            "seed": self.seed,
            "tint": self.tint,
            "probabilities": self.classes is not None,
        }

    def process(self, image: NDArray[np.uint8], index: int) -> FrameOutcome:
        """Shadows, lanes and the model's decision (and class probabilities) for one frame.

        The classifier is called for this frame alone: with shots, a quantum classifier
        samples from a generator seeded afresh per call, so a one-row call gives a frame
        the same decision in any chunk or batch (and the same as ``qdcnn detect-lanes``);
        a call on many rows would share one stream of samples between them.
        """
        frame, lanes = self._analyse(image, index)
        labels, probs = self._decide(self._inputs(image, lanes))
        return self._outcome(frame, lanes, int(labels[0]), None if probs is None else probs[0])

    def process_batch(
        self, images: Sequence[NDArray[np.uint8]], indices: Sequence[int]
    ) -> list[FrameOutcome | QdcnnError]:
        """:meth:`process` for many frames, with the same outcome per frame.

        Shadows and lanes are found frame by frame (each with its own seeded sampler);
        the decision is one classifier call on all the frames' lane features that gives
        each frame what a call on it alone gives (the UU-dagger rule's circuits run once
        for the batch, each frame's shots drawn as alone), else one call per frame.
        A frame whose analysis fails gets its :class:`~qdcnn.errors.QdcnnError`.
        """
        found: list[tuple[Any, LaneFeatures] | QdcnnError] = []
        for image, index in zip(images, indices, strict=True):
            try:
                found.append(self._analyse(image, index))
            except QdcnnError as exc:
                found.append(exc)
        good = [i for i, f in enumerate(found) if not isinstance(f, QdcnnError)]
        decisions = self._decide_many([self._inputs(images[i], found[i][1]) for i in good])  # type: ignore[index]
        out: list[FrameOutcome | QdcnnError] = list(found)  # type: ignore[arg-type]
        for i, (label, probs) in zip(good, decisions, strict=True):
            if isinstance(label, QdcnnError):
                out[i] = label
            else:
                frame, lanes = found[i]  # type: ignore[misc]
                out[i] = self._outcome(frame, lanes, label, probs)
        return out

    def _analyse(self, image: NDArray[np.uint8], index: int) -> tuple[Any, LaneFeatures]:
        """The pipeline's result for one frame (sampler seeded by ``(seed, index)``) and its
        lane features under the model's grouping."""
        from qdcnn.pipeline import process_frame

        rng = np.random.default_rng([self.seed, index])
        frame = process_frame(image, self.config, (self.grouping,), rng=rng)
        return frame, frame.lanes[self.grouping]

    def _inputs(self, image: NDArray[np.uint8], lanes: LaneFeatures) -> NDArray[Any]:
        """The classifier's input rows for one frame: the frame itself or its lane features."""
        return image[None] if self.reads_frames else np.atleast_2d(lanes.features)

    def _decide(self, inputs: NDArray[Any]) -> tuple[NDArray[np.int64], NDArray[np.float64] | None]:
        """Labels and (when asked for) class probabilities of input rows, in one call."""
        if self.classes is None:
            return self.model.predict(inputs), None
        return self.model.predict_with_proba(inputs)

    def _decide_many(
        self, rows: list[NDArray[Any]]
    ) -> list[tuple[int, NDArray[np.float64] | None] | tuple[QdcnnError, None]]:
        """Label and probabilities per frame of ``rows`` (one input row each), each as
        :meth:`process` decides it: one call for all lane rows
        (:meth:`DirectionModel.predict_with_proba_each`), one call per frame otherwise or
        when that call fails (so an error lands on its frame)."""
        if rows and not self.reads_frames:
            try:
                labels, probs = self.model.predict_with_proba_each(np.concatenate(rows))
            except QdcnnError:
                pass
            else:
                probs = None if self.classes is None else probs
                return [
                    (int(labels[i]), None if probs is None else probs[i]) for i in range(len(rows))
                ]
        out: list[tuple[int, NDArray[np.float64] | None] | tuple[QdcnnError, None]] = []
        for row in rows:
            try:
                labels, probs = self._decide(row)
            except QdcnnError as exc:
                out.append((exc, None))
                continue
            out.append((int(labels[0]), None if probs is None else probs[0]))
        return out

    def _outcome(
        self, frame: Any, lanes: LaneFeatures, label: int, probs: NDArray[np.float64] | None
    ) -> FrameOutcome:
        mask = frame.shadow_mask
        fraction = None if mask is None else float(np.count_nonzero(mask)) / mask.size
        scores = None if probs is None else tuple(float(p) for p in probs)
        drawing = (frame.segments, lanes, mask)
        return FrameOutcome(self._names[label], scores, fraction, lanes.status, drawing)

    def draw(
        self, image: NDArray[np.uint8], outcome: FrameOutcome, decision: str | None
    ) -> NDArray[np.uint8]:
        """Shadow tint, lane segments by group, fitted lines and the decision caption."""
        segments, lanes, mask = outcome.drawing
        base = tint_mask(image, mask) if self.tint and mask is not None else image.copy()
        return draw_video_overlay(base, segments, lanes, decision, self.config.lanes.roi)


@lru_cache(maxsize=8)
def _half_tint(shape: tuple[int, int, int]) -> NDArray[np.uint8]:
    half = np.zeros(shape, dtype=np.uint8)
    half[..., 0] = half[..., 2] = 127  # half of magenta, draw_shadow_overlay's colour
    half.setflags(write=False)
    return half


def tint_mask(image: NDArray[np.uint8], mask: NDArray[np.bool_]) -> NDArray[np.uint8]:
    """A copy of ``image`` with the mask tinted magenta at opacity 1/2: ``image // 2 +
    127`` per tinted channel, within one grey level of
    :func:`qdcnn.vision.overlays.draw_shadow_overlay` at ``alpha=0.5`` (integer arithmetic
    and OpenCV's masked copy: about 30 us per 320x160 frame instead of 1 ms)."""
    out = image.copy()
    tinted = (image >> 1) + _half_tint(image.shape)
    cv2.copyTo(tinted, mask.view(np.uint8), out)
    return out


@lru_cache(maxsize=8)
def _roi_outline(shape: tuple[int, int], roi: tuple[tuple[float, float], ...]) -> NDArray[np.int32]:
    return np.rint(polygon_pixels(shape, roi)).astype(np.int32).reshape(-1, 1, 2)


def draw_video_overlay(
    canvas: NDArray[np.uint8],
    segments: NDArray[np.float64],
    lanes: LaneFeatures,
    decision: str | None,
    roi: tuple[tuple[float, float], ...] | None = None,
) -> NDArray[np.uint8]:
    """Draw on ``canvas`` (in place, returned): ROI outline, Hough segments coloured by
    group, the fitted lines over the ROI's rows, the centre line, and a caption with the
    decision and the lane status.

    The colours of :func:`qdcnn.vision.overlays.draw_lane_overlay`, drawn with one
    ``cv2.polylines`` call per group and without anti-aliasing, so that an overlay costs
    a fraction of a frame's processing time (the still-image overlay draws each segment
    anti-aliased and prints the classifier's inputs).
    """
    h, w = canvas.shape[:2]
    y_top, y_bottom = 0, h - 1
    if roi is not None:
        outline = _roi_outline((h, w), tuple(roi))
        cv2.polylines(canvas, [outline], True, ROI_COLOUR, 1)
        y_top, y_bottom = int(outline[:, 0, 1].min()), int(outline[:, 0, 1].max())
    seg = np.rint(np.asarray(segments, dtype=np.float64).reshape(-1, 4)).astype(np.int32)
    labels = np.asarray(lanes.labels)
    for group in (0, 1):
        chosen = seg[labels == group] if len(labels) == len(seg) else seg[:0]
        if len(chosen):
            cv2.polylines(canvas, list(chosen.reshape(-1, 2, 2)), False, GROUP_COLOURS[group], 2)
    fits = [*zip(lanes.lines, LINE_COLOURS, strict=False), (lanes.middle_line, MIDDLE_COLOUR)]
    for line, colour in fits:
        if line is not None:
            a, b = line
            p1 = (round(float(a * y_top + b)), y_top)
            p2 = (round(float(a * y_bottom + b)), y_bottom)
            cv2.line(canvas, p1, p2, colour, 1)
    scale = max(h / 160.0, 0.5)
    cv2.putText(
        canvas,
        str(lanes.status),
        (3, int(12 * scale)),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.35 * scale,
        TEXT_COLOUR,
        1,
        cv2.LINE_AA,
    )
    if decision is not None:
        cv2.putText(
            canvas,
            decision,
            (3, int(32 * scale)),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.6 * scale,
            TEXT_COLOUR,
            max(1, int(scale)),
            cv2.LINE_AA,
        )
    return canvas


def estimator_fingerprint(estimator: Any) -> str:
    """Hash of an estimator's parameters and fitted attributes (names ending in ``_``)."""
    h = hashlib.sha256(type(estimator).__qualname__.encode())
    params = estimator.get_params() if hasattr(estimator, "get_params") else {}
    h.update(repr(sorted(params.items())).encode())
    for name, value in sorted(vars(estimator).items()):
        if not name.endswith("_") or name.startswith("_"):
            continue
        h.update(name.encode())
        arr = np.asarray(value) if isinstance(value, np.ndarray | float | int) else None
        h.update(arr.tobytes() if arr is not None else repr(value).encode())
    return h.hexdigest()[:24]
