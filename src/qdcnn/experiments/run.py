"""``qdcnn run``: dashcam videos, image folders and recordings to per-frame decisions.

One runner over :func:`qdcnn.runtime.engine.run_inputs`: the inputs are video
files, image folders or dataset specs (``udacity:PATH``, ``carla:PATH``,
``synthetic:PRESET[:N]``); the per-frame work is the pipeline and a direction model
(a model file of any registered method, or the default model of ``--method``), through
:class:`~qdcnn.direction.processor.LaneDirectionProcessor`; the chunks run in this
process or on a Dask cluster (:class:`~qdcnn.runtime.scheduler.Executor`).
"""

from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from qdcnn._validation import check_seed
from qdcnn.config import PipelineConfig
from qdcnn.data.frames import load_frameset, parse_data_spec
from qdcnn.direction.builtin import direction_model
from qdcnn.direction.methods import get_method
from qdcnn.errors import ParameterError
from qdcnn.outputs import refuse_output_in_inputs
from qdcnn.runtime.engine import (
    InputResult,
    Progress,
    RunOptions,
    RunResult,
    resolve_inputs,
    run_inputs,
)
from qdcnn.runtime.reporting import Failure, Reporter

__all__ = ["RunSpec", "run", "run_with_model"]

_SPEC_KINDS = ("udacity:", "carla:", "synthetic:")


@dataclass(frozen=True)
class RunSpec:
    """What ``qdcnn run`` processes, with which model, and where.

    Attributes
    ----------
    inputs : tuple of str
        Video files, image folders or dataset specs.
    out : Path
        Output folder (``<name>/frames.csv``, ``timings.csv``, ``overlay.mp4``, ``summary.json``).
    model : Path or None
        A direction model file (``train-direction``); ``None``: the built-in model
        (:func:`~qdcnn.direction.builtin.builtin_model`).
    method : str or None
        A registered lane method whose built-in lane model decides when no model is
        given; ``None``: the built-in QDCNN model (the lane model of ``image-split-uu``
        without torch or with lane settings other than the defaults).
    options : RunOptions
        Chunking, ``smooth`` majority vote, overlay, ``force``, lock wait.
    scheduler : str or None
        ``None`` (this process), ``local:N`` or ``tcp://HOST:PORT`` (the ``dask`` extra).
    seed : int
        Seed of the shot sampling and of the default model.
    config : PipelineConfig or None
        The pipeline the built-in model is trained with when no ``model`` is given
        (``None``: ``PipelineConfig(seed=seed)``); a model file carries its own.
    """

    inputs: tuple[str, ...]
    out: Path
    model: Path | None = None
    method: str | None = None
    options: RunOptions = field(default_factory=RunOptions)
    scheduler: str | None = None
    seed: int = 0
    config: PipelineConfig | None = None

    def __post_init__(self) -> None:
        if self.method is not None:
            get_method(self.method)
        check_seed("seed", self.seed)
        if self.config is not None and not isinstance(self.config, PipelineConfig):
            raise ParameterError("config", type(self.config).__name__, "a PipelineConfig")

    @property
    def pipeline(self) -> PipelineConfig:
        """The config of the built-in model (``config``, or the default one)."""
        return self.config or PipelineConfig(seed=self.seed)


def run(spec: RunSpec, reporter: Reporter | None = None) -> RunResult:
    """Process every input of ``spec``; each input's result is reported as it finishes."""
    return run_with_model(spec, reporter)[0]


def run_with_model(spec: RunSpec, reporter: Reporter | None = None) -> tuple[RunResult, str]:
    """:func:`run`, and one line naming the model that decided."""
    from qdcnn.direction.processor import LaneDirectionProcessor
    from qdcnn.runtime.scheduler import Executor

    report = reporter or Reporter()
    inputs = [_input(item, spec) for item in spec.inputs]
    resolve_inputs(inputs)  # a mistyped path stops the run before the model is loaded
    refuse_output_in_inputs(spec.out, [_folder_of(item) for item in spec.inputs])
    model, name = direction_model(
        spec.model, spec.method, spec.seed, spec.pipeline, report.note, reporter=report
    )
    processor = LaneDirectionProcessor(model, seed=spec.seed)
    with ExitStack() as stack:
        executor = stack.enter_context(Executor(spec.scheduler)) if spec.scheduler else None
        bars: dict[str, Any] = {}
        result = run_inputs(
            inputs,
            processor,
            spec.out,
            options=spec.options,
            executor=executor,
            progress=lambda p: _advance(p, bars, stack, report),
        )
    for item in result.inputs:
        report.result(item.to_dict())
        for failure in _failures(item):
            report.failure(failure)
    return result, name


#: Bad frames of one input told one line each; the rest in one line (all are in frames.csv).
MAX_FRAME_LINES = 50


def _failures(item: InputResult) -> list[Failure]:
    """The input's error, or one line per bad frame naming it and the file or row."""
    if item.error is not None:
        return [Failure(item.source, item.error)]
    lines = [
        Failure(item.source, f"{item.source}: frame {index}: {reason}")
        for index, reason in item.bad_frames[:MAX_FRAME_LINES]
    ]
    more = len(item.bad_frames) - MAX_FRAME_LINES
    if more > 0:
        where = item.outputs.get("frames.csv", "frames.csv")
        lines.append(
            Failure(item.source, f"{item.source}: {more} more bad frames (status, note: {where})")
        )
    return lines


def _input(item: str, spec: RunSpec) -> Any:
    """A path as it is; a dataset spec loaded as a frame source."""
    if item.startswith(_SPEC_KINDS):
        parse_data_spec(item)
        # numbered as the recording's rows: a skipped row stays a frame, with its reason
        return load_frameset(item, seed=spec.seed).in_recording_order()
    return item


def _folder_of(item: str) -> Path:
    """The folder an input reads: a recording spec's folder, or the path itself."""
    if item.startswith(("udacity:", "carla:")):
        path = Path(parse_data_spec(item).value)
        return path if path.is_dir() else path.parent
    return Path(item)


def _advance(progress: Progress, bars: dict[str, Any], stack: ExitStack, report: Reporter) -> None:
    """One progress bar per input, opened at its first report."""
    entry = bars.get(progress.input)
    if entry is None:
        advance = stack.enter_context(report.progress(progress.total, f"run {progress.input}"))
        entry = bars[progress.input] = [advance, 0]
    advance, done = entry
    for _ in range(progress.done - done):
        advance()
    entry[1] = progress.done
