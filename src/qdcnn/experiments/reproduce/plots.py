"""The report's matplotlib figures (Agg canvas, no pyplot): titles, units, legends, paper marks."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn.experiments.reproduce.paper_values import NOISE_POINTS, paper_accuracy

__all__ = [
    "accuracy_bars",
    "cnn_curves",
    "image_grid",
    "mark_paper_noise_points",
    "objective_curves",
]

Panels = Sequence[tuple[str, Sequence[tuple[str, NDArray[np.uint8] | None]]]]


def _figure(width: float, height: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def image_grid(rows: Panels, title: str) -> Any:
    """Images in rows (one per dataset) with a title per panel; ``None`` panels say so."""
    ncols = max(len(panels) for _, panels in rows)
    fig = _figure(3.6 * ncols, 2.3 * len(rows) + 0.6)
    axes = fig.subplots(len(rows), ncols, squeeze=False)
    for r, (row_title, panels) in enumerate(rows):
        for c in range(ncols):
            ax = axes[r][c]
            ax.set_xticks([])
            ax.set_yticks([])
            if c >= len(panels):
                ax.set_visible(False)
                continue
            name, image = panels[c]
            if image is None:
                ax.text(0.5, 0.5, "not available", ha="center", va="center", color="0.4")
            else:
                ax.imshow(image)
            ax.set_title(name, fontsize=9)
            if c == 0:
                ax.set_ylabel(row_title, fontsize=9)
    fig.suptitle(title)
    return fig


def accuracy_bars(entries: Sequence[Any], results: dict[str, Any], methods: list[str]) -> Any:
    """One panel per dataset: measured accuracy per method, the paper's value, the majority."""
    shown = [e for e in entries if "error" not in results[e.key]]
    fig = _figure(max(6.0, 0.75 * len(methods) + 2.5), 3.1 * max(len(shown), 1) + 0.4)
    axes = fig.subplots(max(len(shown), 1), 1, squeeze=False).ravel()
    x = np.arange(len(methods))
    for ax, e in zip(axes, shown, strict=False):
        r = results[e.key]
        for j, (mode, colour) in enumerate((("paper", "C0"), ("named", "C1"))):
            acc = [r["results"][mode].get(m, {}).get("accuracy", np.nan) for m in methods]
            std = [r["results"][mode].get(m, {}).get("accuracy_std", 0.0) for m in methods]
            label = "measured, paper pipeline" if mode == "paper" else "measured, named options"
            ax.bar(x + (j - 0.5) * 0.38, acc, 0.38, yerr=std, color=colour, label=label, capsize=2)
        paper = [paper_accuracy(e.label, m) for m in methods]
        px = [i for i, v in enumerate(paper) if v is not None]
        ax.scatter(
            px,
            [paper[i] for i in px],
            marker="D",
            color="black",
            zorder=3,
            label=f"paper, {e.title}",
        )
        if r.get("majority_baseline") is not None:
            ax.axhline(
                r["majority_baseline"],
                color="0.4",
                linestyle="--",
                linewidth=1,
                label="majority class",
            )
        ax.set_title(f"{e.title}: {r['name']} ({r['n']} frames)", fontsize=10)
        ax.set_ylabel("direction accuracy")
        ax.set_ylim(0, 1)
        ax.set_xticks(x, methods, rotation=20, ha="right", fontsize=8)
        ax.grid(axis="y", alpha=0.3)
        ax.legend(fontsize=7, ncols=2, loc="upper right")
    return fig


def cnn_curves(curves: Sequence[tuple[str, list[list[dict[str, Any]]], float | None]]) -> Any:
    """Per (title, fold histories, paper's final validation accuracy): loss and accuracy."""
    fig = _figure(11.0, 3.2 * len(curves) + 0.4)
    axes = fig.subplots(len(curves), 2, squeeze=False)
    for (title, folds, paper), (ax_loss, ax_acc) in zip(curves, axes, strict=True):
        for i, history in enumerate(folds):
            epochs = [h["epoch"] for h in history]
            ax_loss.plot(
                epochs,
                [h["train_loss"] for h in history],
                color=f"C{i}",
                label=f"fold {i + 1} train",
            )
            val = [h.get("val_loss") for h in history]
            if any(v is not None for v in val):
                ax_loss.plot(
                    epochs,
                    [np.nan if v is None else v for v in val],
                    color=f"C{i}",
                    linestyle="--",
                    label=f"fold {i + 1} validation",
                )
            acc = [h.get("val_accuracy") for h in history]
            ax_acc.plot(
                epochs,
                [np.nan if v is None else v for v in acc],
                color=f"C{i}",
                marker="o",
                markersize=3,
                label=f"fold {i + 1}",
            )
        if paper is not None:
            ax_acc.axhline(paper, color="black", linestyle=":", label="paper (ResNet-50, final)")
        ax_loss.set_title(f"{title}: loss", fontsize=10)
        ax_loss.set_xlabel("epoch")
        ax_loss.set_ylabel("cross-entropy loss")
        ax_acc.set_title(f"{title}: validation accuracy", fontsize=10)
        ax_acc.set_xlabel("epoch")
        ax_acc.set_ylabel("accuracy")
        ax_acc.set_ylim(0, 1)
        for ax in (ax_loss, ax_acc):
            ax.grid(alpha=0.3)
            ax.legend(fontsize=6, ncols=2)
    return fig


def objective_curves(panels: Sequence[tuple[str, dict[str, list[float]]]], loss: str) -> Any:
    """One panel per dataset: the VQC objective per COBYLA evaluation, a line per grouping."""
    ncols = min(3, len(panels))
    nrows = -(-len(panels) // ncols)
    fig = _figure(4.6 * ncols, 3.3 * nrows + 0.5)
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax in axes[len(panels) :]:
        ax.set_visible(False)
    for ax, (title, series) in zip(axes, panels, strict=False):
        for name, values in series.items():
            ax.plot(np.arange(1, len(values) + 1), values, marker="o", markersize=2.5, label=name)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("objective evaluation (COBYLA)")
        ax.set_ylabel("MSE (Eq. 10)" if loss == "mse" else loss)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle("VQC training objective per iteration (Fig. 6)")
    return fig


def mark_paper_noise_points(fig: Any, channels: Sequence[str], label: str) -> int:
    """Add the paper's stated Fig. 7 points of dataset ``label`` to an accuracy figure.

    Returns the number of points drawn.
    """
    axes = [ax for ax in fig.axes if ax.get_visible()][: len(channels)]
    drawn = 0
    styles = {"uu": ("*", "black"), "vqc": ("P", "black")}
    for dataset, kind, channel, p, acc in NOISE_POINTS:
        if dataset != label or channel not in channels:
            continue
        marker, colour = styles.get(kind, ("x", "black"))
        ax = axes[list(channels).index(channel)]
        ax.scatter(
            [p],
            [acc],
            marker=marker,
            s=90,
            color=colour,
            zorder=4,
            label=f"paper ({'UU†' if kind == 'uu' else 'VQC'})",
        )
        drawn += 1
    if drawn:
        handles, names = [], []
        for ax in axes:
            for h, n in zip(*ax.get_legend_handles_labels(), strict=True):
                if n.startswith("paper") and n not in names:
                    handles.append(h)
                    names.append(n)
        fig.legend(handles, names, loc="outside upper right", fontsize=8)
    return drawn
