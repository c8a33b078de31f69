"""``qdcnn score``: a direction model's scores on labelled data, with block-bootstrap intervals.

The runner is imported when the command runs, so ``qdcnn --help`` loads none of it.
The options ``--resamples``, ``--block``, ``--steering-unit`` and ``--label-threshold``
are defined here: the last two default to the model's own label settings, unlike those
of ``evaluate``.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.table import Column, Table

from qdcnn.cli._common import CacheOpt, CliReporter, JsonOpt, SeedOpt, emit, fail, out
from qdcnn.errors import QdcnnError

if TYPE_CHECKING:
    from qdcnn.direction.scores import Interval
    from qdcnn.experiments.score import DatasetScore, ScoreResult

DatasetsOpt = Annotated[
    list[str],
    typer.Option(
        "--data", help="udacity:PATH | carla:PATH | synthetic:PRESET[:N]; repeat for more."
    ),
]
ModelOpt = Annotated[
    Path | None,
    typer.Option(help="Model from train-direction (default: the built-in lane model of run)."),
]
ResamplesOpt = Annotated[int, typer.Option(help="Bootstrap resamples per interval.")]
BlockOpt = Annotated[
    int | None,
    typer.Option(help="Frames per bootstrap block (default: chosen per dataset, at least 11)."),
]
ScoreUnitOpt = Annotated[
    str | None,
    typer.Option(
        help="Unit of the recorded steering: auto | norm | rad | deg (default: the model's)."
    ),
]
ScoreThresholdOpt = Annotated[
    float | None,
    typer.Option(help="Label threshold in the steering unit (default: the model's)."),
]


def score_cmd(
    data: DatasetsOpt,
    model: ModelOpt = None,
    seed: SeedOpt = 0,
    resamples: ResamplesOpt = 1000,
    block: BlockOpt = None,
    steering_unit: ScoreUnitOpt = None,
    label_threshold: ScoreThresholdOpt = None,
    cache: CacheOpt = True,
    as_json: JsonOpt = False,
) -> None:
    """Score a direction model on labelled data, with 95 % block-bootstrap intervals.

    Balanced accuracy (the main figure), accuracy, macro-F1 and recall per class.
    Labels come from the steering with the model's label settings.
    A dataset whose labels are all one class has no balanced accuracy (its row says why).
    Rows that give no label (steering not a number, image missing) and frames that cannot
    be read are left out of the score, each named in a note: line (counted as skipped).
    Exit status 1 when a dataset could not be loaded (the others are still scored).
    """
    from qdcnn.experiments.score import ScoreSpec, run_score

    try:
        spec = ScoreSpec(
            tuple(data), model, seed, resamples, block, steering_unit, label_threshold, cache
        )
        result = run_score(spec, CliReporter(as_json))
    except QdcnnError as exc:
        raise fail(exc) from None
    if as_json:
        emit(result.summary())
    else:
        out.print(_score_table(result))
        for line in _notes(result):
            out.print(line, markup=False, soft_wrap=True)
    raise typer.Exit(result.exit_code)


def _score_table(result: ScoreResult) -> Table:
    table = Table(
        *(
            Column(name, overflow="fold")
            for name in ("dataset", "balanced accuracy", "accuracy", "macro-F1", "recall L/S/R")
        ),
        Column("frames", justify="right"),
        title=f"{result.model.method}: direction scores [95 % interval]",
    )
    for row in result.rows:
        s = row.scores
        table.add_row(
            row.dataset,
            _with_interval(s.balanced_accuracy, row.intervals["balanced_accuracy"]),
            _with_interval(s.accuracy, row.intervals["accuracy"]),
            _number(s.macro_f1),
            " ".join(_number(v) for v in s.per_class.values()),
            str(s.n),
        )
    return table


def _with_interval(value: float | None, interval: Interval | None) -> str:
    from qdcnn.direction.scores import format_with_interval

    if value is None:
        return "undefined"
    return _number(value) if interval is None else format_with_interval(value, interval)


def _number(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def _notes(result: ScoreResult) -> list[str]:
    """How the numbers were obtained, then why any of them is missing."""
    source = "built-in" if result.model_name.startswith("built-in") else result.model_name
    datasets = ", ".join(row.dataset for row in result.rows) or "nothing"
    lines = [
        f"{result.model.method} model {source} trained on {result.model.trained_on}; "
        f"scored on {datasets}; {_interval_method(result.rows)}"
    ]
    for row in result.rows:
        if row.scores.undefined is not None:
            lines.append(f"{row.dataset}: balanced accuracy undefined: {row.scores.undefined}")
        if row.interval_note is not None:
            lines.append(f"{row.dataset}: no interval: {row.interval_note}")
    return lines


def _interval_method(rows: list[DatasetScore]) -> str:
    """``95 % block-bootstrap interval, 1000 resamples of 25-frame blocks`` (blocks per
    dataset when they differ)."""
    shown = [(row, iv) for row in rows for iv in row.intervals.values() if iv is not None]
    if not shown:
        return "no intervals"
    first = shown[0][1]
    blocks = sorted({iv.block for _, iv in shown})
    if len(blocks) == 1:
        size = f"{blocks[0]}-frame blocks"
    else:
        size = "blocks of " + ", ".join(f"{r.block} frames ({r.dataset})" for r in rows if r.block)
    return (
        f"{100 * first.level:g} % block-bootstrap interval, {first.resamples} resamples of {size}"
    )
