"""Datasets named on the command line: ``udacity:PATH``, ``carla:PATH``, ``synthetic:PRESET[:N]``.

Any of them may end in ``@key=value[,key=value]`` with the recording's own label
settings (``unit``, ``threshold``): see :func:`parse_data_spec`.

A :class:`FrameSet` gives frames one at a time (read lazily from disk, or held
in memory for synthetic drives), the steering per frame and its timestamps, so
labels, features and CNN inputs all come from the same object.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from qdcnn.batch import Failure, run_batch
from qdcnn.config import LabelConfig
from qdcnn.data.images import read_image
from qdcnn.data.labels import (
    DirectionLabels,
    Quantile,
    SteeringUnit,
    label_directions,
    unit_disagreement,
    unit_free_steering,
)
from qdcnn.data.recording import RowError
from qdcnn.errors import InputError, ParameterError

_DEFAULT_SYNTHETIC_FRAMES = 600
#: Most bytes of frames a synthetic dataset spec renders into memory (10,000 320x160 frames).
_MAX_SYNTHETIC_BYTES = 10_000 * 320 * 160 * 3


@dataclass
class FrameSet:
    """Frames with steering, from a recording or the synthetic generator.

    Attributes
    ----------
    name : str
        Short name for reports (folder name or ``synthetic-<preset>``).
    spec : str
        The specification it was loaded from, ``@`` suffix included.
    steering : ndarray of float64, shape (N,)
        Steering per frame (negative = left).
    timestamps : ndarray of float64 or None
        Seconds per frame.
    sources : list of str
        File path (or synthetic id) of each frame.
    problems : list of InputError
        Rows skipped while loading.
    label_threshold : float, Quantile or None
        The spec's own ``@threshold=`` (in ``unit``), used over the config's; ``None``:
        the config decides.
    notes : list of str
        Warnings for people that runners report (a given unit the values disagree with).
    positions : ndarray of int64 or None
        Each frame's place among the recording's data rows, skipped rows included
        (:attr:`qdcnn.data.recording.Recording.positions`); ``None``: ``0 .. N-1``.
    """

    name: str
    spec: str
    steering: NDArray[np.float64]
    timestamps: NDArray[np.float64] | None
    sources: list[str]
    problems: list[InputError] = field(default_factory=list)
    images: list[NDArray[np.uint8]] | None = None
    paths: list[Path] | None = None
    unit: SteeringUnit = field(default_factory=SteeringUnit)
    label_threshold: float | Quantile | None = None
    notes: list[str] = field(default_factory=list)
    positions: NDArray[np.int64] | None = None

    def __len__(self) -> int:
        return len(self.sources)

    def in_recording_order(self) -> FrameSet | RecordingFrames:
        """The frames numbered as the recording's rows: itself when no row was skipped,
        else a :class:`RecordingFrames` that keeps each skipped row as a frame."""
        skipped = [p for p in self.problems if isinstance(p, RowError)]
        if self.positions is None or not skipped:
            return self
        return RecordingFrames(self, skipped)

    def image(self, i: int) -> NDArray[np.uint8]:
        """Frame ``i`` as RGB uint8 (raises :class:`InputError` for an unreadable file)."""
        if self.images is not None:
            return self.images[i]
        assert self.paths is not None
        return read_image(self.paths[i])

    def labels(
        self, config: LabelConfig | None = None, *, train: Sequence[FrameSet] | None = None
    ) -> NDArray[np.int64]:
        """Direction labels from steering smoothed as ``config`` says (see :meth:`label_info`)."""
        return self.label_info(config, train=train).labels

    def threshold_request(self, config: LabelConfig | None = None) -> float | Quantile | None:
        """The threshold asked for: the spec's ``@threshold=``, else ``config``'s
        (``threshold`` or ``threshold_quantile``), else ``None`` (the unit's default)."""
        cfg = config or LabelConfig()
        if self.label_threshold is not None:
            return self.label_threshold
        if cfg.threshold_quantile is not None:
            return Quantile(cfg.threshold_quantile)
        return cfg.threshold

    def label_info(
        self, config: LabelConfig | None = None, *, train: Sequence[FrameSet] | None = None
    ) -> DirectionLabels:
        """Labels with the unit and threshold that produced them.

        The steering unit is the one decided when the recording was loaded; the threshold
        is :meth:`threshold_request` in that unit, or the unit's default when it is
        ``None``. A percentile (:class:`~qdcnn.data.labels.Quantile`) is resolved on the
        ``train`` frame sets only (:func:`resolve_quantile_threshold`; a training set
        passes all training sets, itself included) and converted into this set's unit,
        so every set, train or test, gets the same road-wheel threshold.
        """
        cfg = config or LabelConfig()
        wanted = self.threshold_request(cfg)
        if not isinstance(wanted, Quantile):
            return self._labels_at(cfg, wanted)
        if train is None:
            raise ParameterError(
                "label_threshold",
                str(wanted),
                f"a percentile of the training frames: label {self.name} with train=",
            )
        scale = resolve_quantile_threshold(train, wanted.percent, cfg)
        info = self._labels_at(cfg, scale * self.unit.default_threshold)
        return replace(info, threshold_source=f"{wanted} of the training frames")

    def _labels_at(self, cfg: LabelConfig, threshold: float | None) -> DirectionLabels:
        return label_directions(
            self.steering,
            self.timestamps,
            unit=self.unit,
            threshold=threshold,
            window=cfg.window,
            max_gap_s=cfg.max_gap_s,
        )

    def fingerprint(self) -> str:
        """Identity of the data for caches: spec, frame names, sizes and modification times.

        The spec's ``@`` suffix (label settings) is left out: it changes no frame.
        """
        h = hashlib.sha256(os.fsencode(_split_suffix(self.spec)[0]))
        h.update(self.steering.tobytes())
        for src in self.sources:
            h.update(os.fsencode(src))
            if self.paths is not None:
                try:
                    st = os.stat(src)
                    h.update(f"{st.st_size}:{st.st_mtime_ns}".encode())
                except OSError:
                    h.update(b"missing")
        return h.hexdigest()[:24]


class RecordingFrames:
    """The frames of a recording in its label file's order, the skipped rows included.

    Frame ``k`` is the ``k``-th data row. :meth:`image` of a row the loader skipped raises
    its :class:`~qdcnn.data.recording.RowError` (``"<file>:row <n>: <reason>"``), so a run
    keeps the row as a frame with a status instead of renumbering the frames after it.
    A frame source for :func:`qdcnn.runtime.engine.run_inputs`.
    """

    def __init__(self, frames: FrameSet, skipped: Sequence[RowError]) -> None:
        assert frames.positions is not None
        self.frames = frames
        self.name, self.spec = frames.name, frames.spec
        self._kept = {int(pos): k for k, pos in enumerate(frames.positions)}
        self._skipped = {e.position: e for e in skipped}
        self._size = len(self._kept) + len(self._skipped)
        if set(self._kept) | set(self._skipped) != set(range(self._size)):
            raise InputError(frames.spec, "frame positions do not cover the recording's rows")
        self.timestamps: NDArray[np.float64] | None = None
        if frames.timestamps is not None:
            self.timestamps = np.full(self._size, np.nan)
            self.timestamps[frames.positions] = frames.timestamps

    def __len__(self) -> int:
        return self._size

    def image(self, i: int) -> NDArray[np.uint8]:
        """Frame ``i``; a skipped row raises its :class:`~qdcnn.data.recording.RowError`."""
        k = self._kept.get(i)
        if k is None:
            raise self._skipped[i]
        return self.frames.image(k)

    def fingerprint(self) -> str:
        """The frames' :meth:`FrameSet.fingerprint` and every skipped row's reason."""
        h = hashlib.sha256(self.frames.fingerprint().encode())
        for pos in sorted(self._skipped):
            h.update(f"{pos}:{self._skipped[pos]}\n".encode())
        return h.hexdigest()[:24]


_SPEC_UNITS = ("norm", "rad", "deg", "auto")


@dataclass(frozen=True)
class DataSpec:
    """A parsed dataset specification (:func:`parse_data_spec`).

    Attributes
    ----------
    kind : {"udacity", "carla", "synthetic"}
    value : str
        The path, or ``PRESET[:N]``.
    unit : str or None
        The spec's ``@unit=`` (``norm``, ``rad``, ``deg`` or ``auto``); ``None``: not given.
    threshold : float, Quantile or None
        The spec's ``@threshold=``; ``None``: not given.
    left : {"negative", "positive"} or None
        The spec's ``@left=``: the sign of a left turn in the recorded steering; ``None``:
        not given (negative, the Udacity simulator's convention).
    """

    kind: str
    value: str
    unit: str | None = None
    threshold: float | Quantile | None = None
    left: str | None = None


def parse_spec(spec: str) -> tuple[str, str]:
    """Split ``KIND:VALUE`` and check the kind (an ``@`` suffix is not split off here)."""
    kind, sep, value = spec.partition(":")
    if not sep or not value or kind not in ("udacity", "carla", "synthetic"):
        raise ParameterError("data", spec, "udacity:PATH, carla:PATH or synthetic:PRESET[:N]")
    return kind, value


def parse_data_spec(text: str) -> DataSpec:
    """Parse ``KIND:VALUE[@key=value[,key=value]]``.

    The suffix after the last ``@`` (taken as one only when it holds ``=``, so a path
    with ``@`` in it still works) carries this recording's own label settings; each
    overrides the global option (``--steering-unit``, ``--label-threshold``) for this
    recording only:

    ``unit=norm|rad|deg|auto``
        The unit of its steering.
    ``threshold=NUMBER``
        The label threshold in that unit (``|smoothed steering|`` at or below it is
        straight).
    ``threshold=pNN``
        The NN-th percentile (1..99) of ``|smoothed steering|`` over the TRAINING frames,
        pooled across units (:func:`resolve_quantile_threshold`).
    ``left=negative|positive``
        The sign of a left turn in its steering. The Udacity simulator and most
        behavioural-cloning sets steer left below zero (the default); ROS vehicle logs,
        such as Udacity's real-car Challenge 2 drives, steer left above zero, so their
        steering is negated on loading.

    Examples
    --------
    >>> spec = parse_data_spec("udacity:../shared/data/real-dashcam-sample@unit=rad,threshold=p33")
    >>> spec.kind, spec.value, spec.unit, spec.threshold
    ('udacity', '../shared/data/real-dashcam-sample', 'rad', Quantile(percent=33.0))
    >>> parse_data_spec("carla:/a/b@left=positive")
    DataSpec(kind='carla', value='/a/b', unit=None, threshold=None, left='positive')

    Raises
    ------
    ParameterError
        ``data=<the spec>`` and the problem: a bad kind, an unknown or repeated key, a
        unit not in the list, a threshold that is neither a number >= 0 nor ``pNN``, a
        left sign that is neither ``negative`` nor ``positive``.
    """
    head, suffix = _split_suffix(text)
    try:
        kind, value = parse_spec(head)
    except ParameterError as e:
        raise ParameterError("data", text, str(e).partition(": ")[2]) from None
    settings = _spec_settings(text, suffix)
    unit = settings.get("unit")
    threshold = _spec_threshold(text, settings["threshold"]) if "threshold" in settings else None
    return DataSpec(kind, value, unit, threshold, settings.get("left"))


def _split_suffix(text: str) -> tuple[str, str]:
    """``KIND:VALUE`` and the ``@`` suffix (``""`` when there is none)."""
    head, at, suffix = text.rpartition("@")
    return (head, suffix) if at and "=" in suffix else (text, "")


def _spec_settings(text: str, suffix: str) -> dict[str, str]:
    settings: dict[str, str] = {}
    for item in suffix.split(",") if suffix else []:
        key, eq, val = item.partition("=")
        if not eq:
            raise ParameterError("data", text, f"{item!r} in the @ suffix is not key=value")
        if key not in ("unit", "threshold", "left"):
            raise ParameterError("data", text, f"unknown key {key!r} (keys: unit, threshold, left)")
        if key in settings:
            raise ParameterError("data", text, f"{key!r} given twice")
        settings[key] = val
    if "unit" in settings and settings["unit"] not in _SPEC_UNITS:
        raise ParameterError(
            "data", text, f"unit {settings['unit']!r} is not one of {', '.join(_SPEC_UNITS)}"
        )
    if settings.get("left", "negative") not in ("negative", "positive"):
        raise ParameterError(
            "data", text, f"left {settings['left']!r} is not 'negative' or 'positive'"
        )
    return settings


def _spec_threshold(text: str, raw: str) -> float | Quantile:
    try:
        quantile = Quantile.parse(raw)
    except ParameterError:
        raise ParameterError(
            "data", text, f"threshold {raw!r} is not pNN with a percentile in 1..99"
        ) from None
    if quantile is not None:
        return quantile
    try:
        number = float(raw)
    except ValueError:
        number = math.nan
    if not math.isfinite(number) or number < 0:
        raise ParameterError(
            "data", text, f"threshold {raw!r} is not a number >= 0 or pNN (a percentile)"
        )
    return number


def load_frameset(spec: str, *, seed: int = 0, steering_unit: str = "auto") -> FrameSet:
    """Load a dataset from its specification (:func:`parse_data_spec`).

    ``synthetic:PRESET[:N]`` renders a recording-like drive of ``N`` frames at the
    preset's natural size (320x160; 640x480 for ``dashcam``; default 600 frames, at most
    :data:`_MAX_SYNTHETIC_BYTES` of them, held in memory) with
    :func:`qdcnn.data.synthetic.generate_drive`; its steering is in [-1, 1]. Recordings
    are read lazily; ``steering_unit`` says the unit of their steering (``"auto"``:
    decided from the recording, :func:`qdcnn.data.labels.infer_steering_unit`).

    A spec suffix ``@unit=...,threshold=...,left=...`` overrides ``steering_unit`` and the
    config's label threshold for this recording only, and says its steering sign, e.g.
    ``udacity:../shared/data/real-dashcam-sample@unit=rad,threshold=p33`` (radians, the
    straight class = the 33 % smallest |smoothed steering| of the training frames).
    A synthetic drive takes ``unit=norm`` or ``auto`` only. A given unit that the values
    exceed (rows beyond its limit skipped) adds a line to ``FrameSet.notes``.
    """
    parsed = parse_data_spec(spec)
    if parsed.kind == "synthetic":
        if parsed.unit not in (None, "auto", "norm"):
            raise ParameterError("data", spec, "a synthetic drive steers in norm ([-1, 1])")
        if parsed.left == "positive":
            raise ParameterError("data", spec, "a synthetic drive steers left below zero")
        frames = _load_synthetic(spec, parsed.value, seed)
    else:
        frames = _load_recording(spec, parsed, parsed.unit or steering_unit)
    if parsed.left == "positive":  # stored as everywhere else in qdcnn: negative = left
        frames.steering = -frames.steering
    frames.label_threshold = parsed.threshold
    return frames


def _load_synthetic(spec: str, value: str, seed: int) -> FrameSet:
    from qdcnn.data.synthetic import PRESETS, generate_drive
    from qdcnn.data.synthetic_world import STYLES

    preset, _, count = value.partition(":")
    if preset not in PRESETS:
        raise ParameterError("data", spec, f"a synthetic preset in {', '.join(PRESETS)}")
    try:
        n = int(count) if count else _DEFAULT_SYNTHETIC_FRAMES
    except ValueError:
        raise ParameterError("data", spec, "synthetic:PRESET[:N] with an integer N") from None
    width, height = STYLES[preset].size  # the preset's natural frame size
    most = _MAX_SYNTHETIC_BYTES // (width * height * 3)
    if not 10 <= n <= most:
        raise ParameterError(
            "data",
            spec,
            f"between 10 and {most} synthetic {preset} frames (they are held in memory; "
            "for longer drives write them with 'qdcnn synth --n N --out DIR' and use "
            "udacity:DIR/udacity)",
        )
    scenes = generate_drive(preset, n, seed=seed, width=width, height=height)
    times = np.arange(n) / 10.0
    return FrameSet(
        f"synthetic-{preset}",
        spec,
        np.array([s.steering for s in scenes]),
        times,
        [f"synthetic:{preset}:seed{seed}:frame{i}" for i in range(n)],
        images=[s.image for s in scenes],
        unit=SteeringUnit("norm", "norm", "the synthetic generator steers in [-1, 1]"),
    )


def _load_recording(spec: str, parsed: DataSpec, steering_unit: str) -> FrameSet:
    from qdcnn.data.carla import load_carla
    from qdcnn.data.udacity import load_udacity

    loader = load_udacity if parsed.kind == "udacity" else load_carla
    rec = loader(parsed.value, steering_unit=steering_unit)
    name = Path(parsed.value).resolve().name
    beyond = sum(1 for p in rec.problems if _is_beyond_unit(p))
    note = unit_disagreement(name, rec.unit, beyond, len(rec) + len(rec.problems))
    return FrameSet(
        name,
        spec,
        np.asarray(rec.steering, dtype=np.float64),
        rec.timestamps,
        [str(p) for p in rec.frames],
        list(rec.problems),
        paths=list(rec.frames),
        unit=rec.unit,
        notes=[] if note is None else [note],
        positions=rec.positions,
    )


def _is_beyond_unit(problem: InputError) -> bool:
    """A row the loader skipped for steering outside its unit's range
    (:meth:`qdcnn.data.recording.LabelRows.finish` words it ``steering X is outside [..]``)."""
    return problem.reason.startswith("steering ") and " is outside [" in problem.reason


def resolve_quantile_threshold(
    train_framesets: Sequence[FrameSet], q: float, config: LabelConfig | None = None
) -> float:
    """The ``q``-th percentile of ``|smoothed steering|`` over the training frames, unit-free.

    Each set's smoothed steering is divided by its unit's default threshold
    (:func:`~qdcnn.data.labels.unit_free_steering`), so a ``norm`` and a ``rad``
    recording of the same drive give the same values and pool; multiply the result by a
    set's ``unit.default_threshold`` for its threshold in its own unit
    (:meth:`FrameSet.label_info` does). Only the sets passed are used: pass the
    training sets, never the test sets.
    """
    cfg = config or LabelConfig()
    Quantile(float(q))  # checks 1 <= q <= 99
    if not train_framesets or not any(len(fs) for fs in train_framesets):
        raise ParameterError("train", "<no frames>", "training frames to take a percentile of")
    scaled = [
        unit_free_steering(
            fs.steering, fs.timestamps, fs.unit, window=cfg.window, max_gap_s=cfg.max_gap_s
        )
        for fs in train_framesets
    ]
    return float(np.percentile(np.concatenate(scaled), q))


def stack_images(frames: FrameSet) -> tuple[NDArray[np.uint8], NDArray[np.bool_], list[Failure]]:
    """All frames as one ``(N, H, W, 3)`` array; unreadable frames are zero and listed."""
    first: NDArray[np.uint8] | None = None
    images: list[NDArray[np.uint8] | None] = []
    failures: list[Failure] = []
    for outcome in run_batch(range(len(frames)), frames.image, name=lambda i: frames.sources[i]):
        if outcome.result is not None and (first is None or outcome.result.shape == first.shape):
            first = outcome.result if first is None else first
            images.append(outcome.result)
        else:
            images.append(None)
            if outcome.failure is not None:
                failures.append(outcome.failure)
            else:
                shape = None if outcome.result is None else outcome.result.shape
                failures.append(
                    Failure(
                        frames.sources[outcome.item],
                        f"{frames.sources[outcome.item]}: frame size {shape} differs from "
                        f"the first frame's {None if first is None else first.shape}",
                    )
                )
    if first is None:
        return np.zeros((0, 1, 1, 3), np.uint8), np.zeros(len(frames), bool), failures
    readable = np.array([im is not None for im in images])
    stack = np.zeros((len(frames), *first.shape), np.uint8)
    for i, im in enumerate(images):
        if im is not None:
            stack[i] = im
    return stack, readable, failures
