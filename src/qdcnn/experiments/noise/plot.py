"""Figures of a noise sweep: the paper's Fig. 7 as one panel per channel.

:func:`accuracy_figure` draws direction accuracy against noise strength ``p``, one panel
per channel (2 x 3 for the paper's six), one line per method and grouping, and the
majority-class baseline dashed. :func:`shadow_figure` draws the UU-dagger shadow
detector's balanced error rate the same way. Titles name the data, how models were
trained ("trained without noise" or "trained under noise"), how probabilities were
evaluated (exact or shots) and which phase damping the panels use.

Figures are built on a matplotlib ``Figure`` without pyplot (Agg canvas), so no display
is involved.
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import Any

from qdcnn._fileio import atomic_write_bytes
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.noise.options import SHADOW_METHOD
from qdcnn.experiments.noise.results import NoiseSweepResult

__all__ = [
    "CHANNEL_TITLES",
    "accuracy_figure",
    "save_figure",
    "shadow_figure",
    "shadow_plot_path",
    "sweep_title",
    "write_figures",
]

CHANNEL_TITLES: dict[str, str] = {
    "bit-flip": "Bit flip",
    "phase-flip": "Phase flip",
    "bit-phase-flip": "Bit-phase flip",
    "depolarizing": "Depolarizing",
    "amplitude-damping": "Amplitude damping",
    "phase-damping": "Phase damping (textbook)",
    "phase-damping-paper": "Phase damping (paper's form)",
}
_METHOD_NAMES = {"uu": "UU\u2020", "vqc": "VQC"}


def _legend_name(result: NoiseSweepResult, label: str) -> str:
    row = next(r for r in result.rows if r.label == label)
    name = _METHOD_NAMES.get(row.method, row.method)
    return f"{row.grouping} {name}" if row.grouping else name


def sweep_title(result: NoiseSweepResult, what: str, data: str | None) -> str:
    """Two-line title: what against p on which data; training, evaluation, phase damping."""
    trained = "trained under noise" if result.trained_under_noise else "trained without noise"
    parts = [trained, result.evaluation]
    if result.readout:
        parts.append(f"readout error {result.readout:g}")
    form = result.phase_damping_form
    if form is not None:
        parts.append(f"phase damping: {form}")
    return f"{what} vs noise strength p on {data}\n" + ", ".join(parts)


def _figure(n_panels: int) -> tuple[Any, list[Any]]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    ncols = min(3, n_panels)
    nrows = math.ceil(n_panels / ncols)
    fig = Figure(figsize=(4.2 * ncols, 3.3 * nrows + 0.9), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, sharex=True, sharey=True, squeeze=False).ravel().tolist()
    for ax in axes[n_panels:]:
        ax.set_visible(False)
    return fig, axes[:n_panels]


def _check_rows(result: NoiseSweepResult, shadow: bool) -> None:
    if not any((r.method == SHADOW_METHOD) == shadow for r in result.rows):
        what = SHADOW_METHOD if shadow else "direction"
        raise ParameterError("result", f"<no {what} rows>", "a sweep of those methods")


def accuracy_figure(result: NoiseSweepResult) -> Any:
    """Direction accuracy against ``p``: one panel per channel, one line per method.

    Returns
    -------
    matplotlib.figure.Figure
    """
    _check_rows(result, shadow=False)
    fig, axes = _figure(len(result.channels))
    labels = result.direction_labels()
    baseline = next(
        (r.majority_baseline for r in result.rows if r.majority_baseline is not None), None
    )
    for ax, channel in zip(axes, result.channels, strict=True):
        for label in labels:
            p, acc = result.series(label, channel)
            ax.plot(p, acc, marker="o", markersize=3.5, label=_legend_name(result, label))
        if baseline is not None:
            ax.axhline(baseline, color="0.5", linestyle="--", linewidth=1, label="majority class")
        ax.set_title(CHANNEL_TITLES.get(channel, channel))
        ax.set_ylim(0.0, 1.0)
        ax.set_xlim(-0.02, 1.02)
        ax.grid(alpha=0.3)
    for ax in axes:
        if ax.get_subplotspec().is_last_row():
            ax.set_xlabel("noise strength p")
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel("accuracy")
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncols=min(len(names), 6))
    n_test = next(r.n_test for r in result.rows if r.method != SHADOW_METHOD)
    fig.suptitle(sweep_title(result, "Direction accuracy", f"{result.dataset} ({n_test} frames)"))
    return fig


def shadow_figure(result: NoiseSweepResult) -> Any:
    """UU-dagger shadow detection BER (percent) against ``p``, one panel per channel.

    Returns
    -------
    matplotlib.figure.Figure
    """
    _check_rows(result, shadow=True)
    fig, axes = _figure(len(result.channels))
    rows = [r for r in result.rows if r.method == SHADOW_METHOD]
    top = max(55.0, max(r.ber or 0.0 for r in rows) + 5)
    for ax, channel in zip(axes, result.channels, strict=True):
        p, ber = result.series(SHADOW_METHOD, channel, "ber")
        ax.plot(p, ber, marker="o", markersize=3.5, color="C3", label="UU\u2020 shadow BER")
        ax.axhline(50.0, color="0.5", linestyle="--", linewidth=1, label="all one class (50)")
        ax.set_title(CHANNEL_TITLES.get(channel, channel))
        ax.set_ylim(0.0, top)
        ax.set_xlim(-0.02, 1.02)
        ax.grid(alpha=0.3)
        if ax.get_subplotspec().is_last_row():
            ax.set_xlabel("noise strength p")
        if ax.get_subplotspec().is_first_col():
            ax.set_ylabel("BER (%)")
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncols=2)
    thresholds = sorted({r.threshold for r in rows if r.threshold is not None})
    shown = "/".join(f"{t:g}" for t in thresholds)
    data = f"{result.shadow_set} ({rows[0].n_test} test images, threshold {shown})"
    fig.suptitle(sweep_title(result, "UU\u2020 shadow detection BER", data))
    return fig


def shadow_plot_path(path: str | os.PathLike[str]) -> Path:
    """Where the shadow figure goes next to the accuracy figure: ``NAME_shadow.EXT``."""
    p = Path(path)
    return p.with_name(f"{p.stem}_shadow{p.suffix or '.png'}")


def save_figure(fig: Any, path: str | os.PathLike[str], *, dpi: int = 120) -> Path:
    """Save ``fig`` (format from the suffix, PNG by default) and return the path.

    The figure is rendered to bytes, then written atomically (a link at ``path`` is refused).
    """
    p = Path(path)
    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, dpi=dpi, format=p.suffix[1:] or "png")
    except ValueError as exc:
        raise InputError(p, f"cannot write the figure ({exc})") from None
    return atomic_write_bytes(p, buffer.getvalue())


def write_figures(result: NoiseSweepResult, path: str | os.PathLike[str]) -> list[Path]:
    """Write the accuracy figure to ``path`` and the shadow BER figure next to it
    (:func:`shadow_plot_path`), or the shadow figure to ``path`` when the sweep has no
    direction rows; returns the files written."""
    direction = any(r.method != SHADOW_METHOD for r in result.rows)
    shadow = any(r.method == SHADOW_METHOD for r in result.rows)
    written = []
    if direction:
        written.append(save_figure(accuracy_figure(result), path))
    if shadow:
        target = shadow_plot_path(path) if direction else path
        written.append(save_figure(shadow_figure(result), target))
    return written
