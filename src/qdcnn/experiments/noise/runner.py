"""``qdcnn noise-sweep`` as a library call: :class:`NoiseSweepSpec` in, :class:`NoiseSweepRun` out.

:func:`run_noise_sweep` does everything the command does: it loads the direction data
(:func:`~qdcnn.direction.lane_data.load_lane_data`: frames, labels and lane features of
the readable frames), sweeps the direction methods (:func:`~.direction.direction_sweep`),
renders or loads the shadow images and sweeps the shadow detector
(:func:`~.shadow.shadow_sweep`), and writes the figures. Long loops report progress and bad
files are reported as failures through a :class:`~qdcnn.runtime.reporting.Reporter`;
the result carries everything a front end prints (:meth:`NoiseSweepResult.tables`,
:meth:`NoiseSweepResult.summary_lines`, :meth:`NoiseSweepRun.to_dicts`).

"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._validation import (
    check_bool,
    check_int,
    check_optional_shots,
    check_probability,
    check_seed,
)
from qdcnn.batch import Failure
from qdcnn.config import SHADOW_THRESHOLD_GRID, PipelineConfig
from qdcnn.data.frames import FrameSet
from qdcnn.direction.methods import TrainingOptions, get_method, method_names
from qdcnn.direction.protocol import ContiguousKFold
from qdcnn.errors import ParameterError
from qdcnn.experiments.evaluate import executor_for
from qdcnn.experiments.noise.direction import FRAMES, SweepTarget, direction_sweep, sweep_targets
from qdcnn.experiments.noise.options import (
    DIRECTION_METHODS,
    PAPER_STRENGTHS,
    SHADOW_METHOD,
    check_grid,
    direction_methods,
    parse_groupings,
    parse_methods,
    parse_shadow_thresholds,
)
from qdcnn.experiments.noise.results import NoiseSweepResult, SweepRow
from qdcnn.experiments.noise.shadow import (
    MAX_SHADOW_FRAMES,
    shadow_sweep,
    split_train_test,
    synthetic_shadow_set,
)
from qdcnn.quantum.noise import PAPER_CHANNELS
from qdcnn.runtime.reporting import Reporter

__all__ = ["NoiseSweepRun", "NoiseSweepSpec", "run_noise_sweep"]

SYNTHETIC_SHADOW_SET = "synthetic-track2-scenes"


@dataclass(frozen=True)
class NoiseSweepSpec:
    """What ``qdcnn noise-sweep`` runs; every value is checked on construction.

    Attributes
    ----------
    The sequences hold checked names and numbers (kept as tuples, duplicates dropped); the
    command line's text forms (``"uu,vqc"``, ``"0:0.99:0.11"``) are parsed by the ``parse_*``
    functions of :mod:`qdcnn.experiments.noise.options` first.

    data : str or None
        Direction data (``udacity:PATH``, ``carla:PATH``, ``synthetic:PRESET[:N]``); needed
        when a direction method is swept.
    methods : tuple of str
        ``uu``, ``vqc``, ``uu-shadow`` or registered quantum methods
        (:func:`~.options.parse_methods`).
    channels : tuple of str
        Channel names (:data:`~qdcnn.quantum.noise.CHANNELS`; default: the six of Fig. 7).
    strengths : tuple of float
        Noise strengths in [0, 1], at most 1000 (default: 0, 0.11, ..., 0.99).
    groupings : tuple of str
        Lane groupings the shorthands ``uu`` and ``vqc`` run on.
    train_under_noise : bool
        Retrain under each noise setting (default: train once without noise).
    shots : int or None
        Shots per circuit at evaluation (default: exact probabilities).
    readout : float
        Readout error added at every point, in [0, 1].
    folds, gap, inner_folds : int
        The protocol of :mod:`qdcnn.direction.protocol` (``inner_folds=0``: no search).
    config : PipelineConfig
        Pipeline and classifier settings (its ``seed`` is replaced by :attr:`seed`).
    shadow_set : path or None
        Shadow set ``DIR/images/*`` + ``DIR/masks/<stem>.png`` for ``uu-shadow`` (implies
        ``uu-shadow``; default: synthetic track2 scenes).
    shadow_frames : int
        Synthetic track2 scenes for ``uu-shadow`` (half train, half test), 2 to 2000.
    plot : path or None
        Where the accuracy figure goes (shadow BER: ``NAME_shadow.EXT``, or ``plot`` itself
        when no direction method is swept).
    seed : int
        Seed of every random choice.
    use_cache : bool
        Reuse cached lane features.
    shadow_thresholds : tuple of float
        Candidates of the shadow threshold (default: the fine grid ``train-shadows`` uses;
        ``parse_shadow_thresholds("paper")`` gives the paper's 0.75 and 0.97).
    training : TrainingOptions
        Settings of frame methods (the hybrids): epochs, threads, context.
    scheduler : str or None
        Where folds and (channel, p) points run: ``None`` (this process), ``local:N`` or
        ``tcp://HOST:PORT`` (the ``dask`` extra); the rows are the same.
    """

    data: str | None = None
    methods: tuple[str, ...] = DIRECTION_METHODS
    channels: tuple[str, ...] = PAPER_CHANNELS
    strengths: tuple[float, ...] = PAPER_STRENGTHS
    groupings: tuple[str, ...] = ("image-split",)
    train_under_noise: bool = False
    shots: int | None = None
    readout: float = 0.0
    folds: int = 5
    gap: int = 5
    inner_folds: int = 3
    config: PipelineConfig = field(default_factory=PipelineConfig)
    shadow_set: Path | None = None
    shadow_frames: int = 24
    plot: Path | None = None
    seed: int = 0
    use_cache: bool = True
    shadow_thresholds: tuple[float, ...] = SHADOW_THRESHOLD_GRID
    training: TrainingOptions = field(default_factory=TrainingOptions)
    scheduler: str | None = None

    def __post_init__(self) -> None:
        if self.data is not None and not isinstance(self.data, str):
            raise ParameterError("data", self.data, "a dataset spec such as synthetic:track1:60")
        self._normalise("methods", parse_methods)
        self._normalise("channels", lambda names: tuple(dict.fromkeys(names)))
        self._normalise("strengths", lambda ps: tuple(dict.fromkeys(_probabilities(ps))))
        check_grid(self.channels, self.strengths)
        self._normalise("groupings", parse_groupings)
        self._normalise("shadow_thresholds", parse_shadow_thresholds)
        methods = self.method_list
        check_bool("train_under_noise", self.train_under_noise)
        check_optional_shots(self.shots)
        _check_shots_apply(self.shots, methods)
        check_probability("readout", self.readout)
        check_int("folds", self.folds, 2, 10_000)
        check_int("gap", self.gap, 0, 10_000)
        if isinstance(self.inner_folds, bool) or self.inner_folds not in (0, *range(2, 101)):
            raise ParameterError("inner_folds", self.inner_folds, "0 (none) or 2 to 100")
        if not isinstance(self.config, PipelineConfig):
            raise ParameterError("config", type(self.config).__name__, "a PipelineConfig")
        for name in ("shadow_set", "plot"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, str | os.PathLike):
                raise ParameterError(name, value, "a path or None")
        check_int("shadow_frames", self.shadow_frames, 2, MAX_SHADOW_FRAMES)
        check_seed("seed", self.seed)
        check_bool("use_cache", self.use_cache)
        if direction_methods(methods) and self.data is None:
            raise ParameterError("data", None, "a dataset (--data) for the uu and vqc methods")

    def _normalise(self, name: str, checked: Callable[[Sequence[Any]], tuple[Any, ...]]) -> None:
        """Store field ``name`` as ``checked`` returns it; text is refused (parse it first)."""
        value = getattr(self, name)
        if isinstance(value, str) or not isinstance(value, Sequence):
            raise ParameterError(
                name, value, "a tuple (parse text with qdcnn.experiments.noise.options)"
            )
        object.__setattr__(self, name, checked(value))

    @property
    def method_list(self) -> tuple[str, ...]:
        """The methods, with ``uu-shadow`` added when a shadow set is given."""
        if self.shadow_set is not None and SHADOW_METHOD not in self.methods:
            return (*self.methods, SHADOW_METHOD)
        return self.methods


@dataclass
class NoiseSweepRun:
    """What :func:`run_noise_sweep` produced: the rows, the figures and the bad items."""

    result: NoiseSweepResult
    figures: list[Path] = field(default_factory=list)
    failures: list[Failure] = field(default_factory=list)

    @property
    def exit_code(self) -> int:
        """0 when every item worked, 1 when some input files failed."""
        return 1 if self.failures else 0

    def to_dicts(self) -> list[dict[str, Any]]:
        """The JSON lines of ``--json``: one object per row, then a summary when items failed."""
        out = self.result.to_dicts()
        if self.failures:
            out.append({"summary": True, "failures": [f.to_dict() for f in self.failures]})
        return out


def run_noise_sweep(spec: NoiseSweepSpec, reporter: Reporter | None = None) -> NoiseSweepRun:
    """Sweep every method of ``spec`` over its noise grid (module docstring)."""
    report = reporter or Reporter()
    methods = spec.method_list
    cfg = replace(spec.config, seed=spec.seed)
    failures: list[Failure] = []

    def fail(items: list[Failure]) -> None:
        for f in items:
            failures.append(f)
            report.failure(f)

    rows: list[SweepRow] = []
    dataset = shadow_name = None
    protocol: dict[str, Any] = {}
    if direction_methods(methods):
        dataset, direction_rows = _sweep_direction(spec, cfg, report, fail)
        rows += direction_rows
        protocol.update(folds=spec.folds, gap=spec.gap, inner_folds=spec.inner_folds)
    if SHADOW_METHOD in methods:
        shadow_name, shadow_rows, shadow_protocol = _sweep_shadows(spec, cfg, report, fail)
        rows += shadow_rows
        protocol.update(shadow_protocol)
    result = NoiseSweepResult(
        dataset,
        rows,
        spec.channels,
        spec.strengths,
        trained_under_noise=spec.train_under_noise,
        shots=spec.shots,
        readout=spec.readout,
        seed=spec.seed,
        shadow_set=shadow_name,
        protocol=protocol,
    )
    figures: list[Path] = []
    if spec.plot is not None:
        from qdcnn.experiments.noise.plot import write_figures

        figures = write_figures(result, spec.plot)
    return NoiseSweepRun(result, figures, failures)


def _sweep_direction(
    spec: NoiseSweepSpec,
    cfg: PipelineConfig,
    report: Reporter,
    fail: Callable[[list[Failure]], None],
) -> tuple[str, list[SweepRow]]:
    """The direction methods' rows, on the spec's data (named by the returned dataset name)."""
    assert spec.data is not None
    from qdcnn.data.frames import load_frameset

    unit = spec.config.labels.steering_unit
    frames = load_frameset(spec.data, seed=spec.seed, steering_unit=unit)
    ContiguousKFold(spec.folds, spec.gap).check(len(frames))  # before any work
    direction = direction_methods(spec.method_list)
    targets = sweep_targets(direction, spec.groupings)
    inputs, y, bad = _direction_inputs(spec, cfg, frames, targets, report)
    fail(bad)
    n_points = len(spec.channels) * len(spec.strengths)
    with (
        report.progress(len(targets) * n_points, "noise sweep") as advance,
        executor_for(spec.scheduler) as executor,
    ):
        rows = direction_sweep(
            inputs,
            y,
            methods=direction,
            groupings=spec.groupings,
            channels=spec.channels,
            strengths=spec.strengths,
            config=cfg,
            folds=spec.folds,
            gap=spec.gap,
            inner_folds=spec.inner_folds,
            train_under_noise=spec.train_under_noise,
            shots=spec.shots,
            readout=spec.readout,
            seed=spec.seed,
            on_step=advance,
            training=spec.training,
            executor=executor,
        )
    return frames.name, rows


def _sweep_shadows(
    spec: NoiseSweepSpec,
    cfg: PipelineConfig,
    report: Reporter,
    fail: Callable[[list[Failure]], None],
) -> tuple[str, list[SweepRow], dict[str, Any]]:
    """The shadow detector's rows on the spec's shadow set (or synthetic scenes): the set's
    name, the rows, and the train/test split and thresholds for the protocol."""
    if spec.shadow_set is not None:
        from qdcnn.data.shadow_set import load_shadow_set

        images, masks, bad = load_shadow_set(Path(spec.shadow_set))
        fail(bad)
        shadow_name = Path(spec.shadow_set).resolve().name
    else:
        images, masks = synthetic_shadow_set(spec.shadow_frames, seed=spec.seed)
        shadow_name = SYNTHETIC_SHADOW_SET
    tr, te = split_train_test(len(images))
    protocol = {
        "shadow_train": tr.stop - tr.start,
        "shadow_test": te.stop - te.start,
        "shadow_thresholds": list(spec.shadow_thresholds),
    }
    with report.progress(len(spec.channels) * len(spec.strengths), "shadow noise sweep") as step:
        rows, _ = shadow_sweep(
            images[tr],
            masks[tr],
            images[te],
            masks[te],
            channels=spec.channels,
            strengths=spec.strengths,
            config=cfg.shadow,
            thresholds=spec.shadow_thresholds,
            train_under_noise=spec.train_under_noise,
            shots=spec.shots,
            readout=spec.readout,
            seed=spec.seed,
            on_step=step,
        )
    return shadow_name, rows, protocol


def _direction_inputs(
    spec: NoiseSweepSpec,
    cfg: PipelineConfig,
    frames: FrameSet,
    targets: list[SweepTarget],
    report: Reporter,
) -> tuple[dict[str, Any], NDArray[np.int64], list[Failure]]:
    """What the targets read, restricted to the frames all of them can use, and the labels.

    Lane methods read the lane features of their grouping (readable frames,
    :func:`~qdcnn.direction.lane_data.load_lane_data`); frame methods read the stacked
    frames (frames of the first frame's size).
    """
    from qdcnn.data.frames import stack_images
    from qdcnn.data.labels import check_labels_usable
    from qdcnn.direction.lane_data import load_lane_data

    groupings = sorted({t.grouping for t in targets if t.grouping is not None})
    keep = np.ones(len(frames), dtype=bool)
    failures = [Failure(p.source, str(p)) for p in frames.problems]
    lanes = None
    if groupings:
        with report.progress(len(frames), f"lane features ({frames.name})") as advance:
            lanes = load_lane_data(
                frames, cfg, groupings, use_cache=spec.use_cache, on_frame=advance
            )
        keep &= lanes.keep
        failures = lanes.failures
        for note in lanes.camera_notes():
            report.note(note)
    images = None
    if any(t.grouping is None for t in targets):
        images, readable, unreadable = stack_images(frames)
        keep &= readable
        seen = {f.file for f in failures}
        failures += [f for f in unreadable if f.file not in seen]
    labels = frames.labels(cfg.labels)[keep]
    check_labels_usable(labels, source=frames.spec)
    inputs: dict[str, Any] = {}
    if lanes is not None:
        inputs.update({g: lanes.table.features[g][keep] for g in groupings})
    if images is not None:
        inputs[FRAMES] = images[keep]
    return inputs, labels, failures


def _probabilities(values: Sequence[Any]) -> list[float]:
    return [check_probability("p", v) for v in values]


def _check_shots_apply(shots: int | None, methods: Sequence[str]) -> None:
    """Image methods (the hybrid CNNs) run on exact probabilities: refuse shots up front,
    before any training, instead of after it."""
    registered = [m for m in direction_methods(methods) if m in method_names()]
    hybrids = [m for m in registered if get_method(m).inputs == "frames"]
    if shots is not None and hybrids:
        raise ParameterError(
            "shots",
            shots,
            f"not used by {', '.join(hybrids)} (image methods run on exact probabilities); "
            "leave it unset or sweep them separately",
        )
