"""Plot of a VQC's objective per COBYLA evaluation (the paper's callback graph, Alg. 3).

Draws on a matplotlib ``Figure`` created without pyplot, so no display or interactive
backend is involved; save it with ``ax.figure.savefig(path)``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from qdcnn._validation import has_shape
from qdcnn.errors import ParameterError

_LOSS_LABELS = {"mse": "MSE (Eq. 10)", "cross_entropy": "cross-entropy (bits)"}


def plot_objective_history(
    history: Sequence[float], ax: Any = None, *, loss: str = "mse", title: str | None = None
) -> Any:
    """Line plot of objective value against evaluation number, best-so-far dashed.

    Parameters
    ----------
    history : sequence of float
        Objective value per evaluation (``VQCClassifier.objective_history_``).
    ax : matplotlib.axes.Axes or None
        Where to draw; ``None`` makes a new ``Figure`` (6 x 4 in) with one Axes.
    loss : str
        Loss name for the y label.
    title : str or None
        Axes title; ``None`` gives "VQC training objective".

    Returns
    -------
    matplotlib.axes.Axes
    """
    values = np.asarray(history, dtype=np.float64)
    if not has_shape(values, "N") or values.size == 0:
        raise ParameterError("history", f"<{values.size} values>", "a non-empty 1-D sequence")
    if ax is None:
        from matplotlib.figure import Figure

        ax = Figure(figsize=(6, 4)).add_subplot()
    steps = np.arange(1, values.size + 1)
    ax.plot(steps, values, marker="o", markersize=3, label="objective")
    ax.plot(steps, np.minimum.accumulate(values), linestyle="--", label="best so far")
    ax.set_xlabel("objective evaluation (COBYLA)")
    ax.set_ylabel(_LOSS_LABELS.get(loss, loss))
    ax.set_title("VQC training objective" if title is None else title)
    ax.legend()
    return ax
