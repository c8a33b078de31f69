"""What a noise sweep produced: one row per (method, channel, p), and how to show it.

:class:`NoiseSweepResult` holds the rows and the sweep's settings, gives the JSON objects
(:meth:`~NoiseSweepResult.to_dicts`), the series a figure draws
(:meth:`~NoiseSweepResult.series`) and the tables and summary lines a command prints
(:meth:`~NoiseSweepResult.tables`, :meth:`~NoiseSweepResult.summary_lines`), so that a
front end only formats.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn.experiments.noise.options import DIRECTION_METHODS, SHADOW_METHOD, phase_damping_form

__all__ = ["CHANNEL_SHORT_NAMES", "NoiseSweepResult", "SweepRow", "SweepTable"]

#: Column heads of the printed tables (short enough for six columns).
CHANNEL_SHORT_NAMES: dict[str, str] = {
    "bit-flip": "bit flip",
    "phase-flip": "phase flip",
    "bit-phase-flip": "bit-phase",
    "depolarizing": "depolar.",
    "amplitude-damping": "amp. damp.",
    "phase-damping": "phase damp.",
    "phase-damping-paper": "ph. damp. (paper)",
}


def _finite_or_none(value: Any) -> Any:
    """NaN (an undefined shadow error rate) becomes ``None``, which JSON can carry."""
    return None if isinstance(value, float) and math.isnan(value) else value


@dataclass
class SweepRow:
    """One point of a sweep: a method under one channel at one strength.

    Attributes
    ----------
    method : str
        The classifier kind of a lane method (``"uu"``, ``"vqc"``), the registered name of
        another direction method, or ``"uu-shadow"``.
    grouping : str or None
        Lane grouping of the features (lane methods).
    channel : str
        Noise channel.
    p : float
        Channel strength.
    accuracy : float
        Direction accuracy over the test frames; pixel accuracy for ``uu-shadow``.
    n_test : int
        Test frames (test images for ``uu-shadow``).
    majority_baseline : float or None
        Accuracy of always predicting the training folds' majority class.
    ber, shadow_error, nonshadow_error : float or None
        Shadow scores in percent (``uu-shadow`` only).
    threshold : float or None
        Fidelity threshold of the shadow detector (``uu-shadow`` only).
    """

    method: str
    grouping: str | None
    channel: str
    p: float
    accuracy: float
    n_test: int
    majority_baseline: float | None = None
    ber: float | None = None
    shadow_error: float | None = None
    nonshadow_error: float | None = None
    threshold: float | None = None

    @property
    def label(self) -> str:
        """Legend name: ``image-split-uu`` (the registered method name), or ``uu-shadow``."""
        return self.method if self.grouping is None else f"{self.grouping}-{self.method}"


@dataclass(frozen=True)
class SweepTable:
    """One printed table: a row per strength, a column per channel.

    Attributes
    ----------
    label : str
        The series (``image-split-uu``, ``uu-shadow``).
    title : str
        The line above the table.
    value : {"accuracy", "ber"}
        What the cells hold.
    decimals : int
        Decimals to print (3 for accuracy, 1 for BER in percent).
    channels : tuple of str
        The columns' channels; :attr:`headers` are their short names.
    rows : list of (p, values)
        ``values[i]`` is the cell of ``channels[i]`` (``None`` where nothing was swept).
    """

    label: str
    title: str
    value: str
    decimals: int
    channels: tuple[str, ...]
    rows: list[tuple[float, list[float | None]]]

    @property
    def headers(self) -> tuple[str, ...]:
        """``"p"`` and the channels' short names."""
        return ("p", *(CHANNEL_SHORT_NAMES.get(ch, ch) for ch in self.channels))

    def cells(self) -> list[list[str]]:
        """The rows as text: ``p`` as ``%g``, values with :attr:`decimals`, ``-`` for none."""
        return [
            [f"{p:g}", *("-" if v is None else f"{v:.{self.decimals}f}" for v in values)]
            for p, values in self.rows
        ]


@dataclass
class NoiseSweepResult:
    """All points of a sweep and what produced them.

    Attributes
    ----------
    dataset : str or None
        Name of the direction data (``None`` when only shadows were swept).
    rows : list of SweepRow
    channels, strengths : tuple
        The grid.
    trained_under_noise : bool
        Whether models were retrained under each noise setting.
    shots : int or None
        Shots per circuit; ``None`` for exact probabilities.
    readout : float
        Readout error added at every point.
    seed : int
    shadow_set : str or None
        Name of the shadow images (``uu-shadow`` rows).
    protocol : dict
        Folds, gap, inner folds, shadow train/test sizes.
    """

    dataset: str | None
    rows: list[SweepRow]
    channels: tuple[str, ...]
    strengths: tuple[float, ...]
    trained_under_noise: bool = False
    shots: int | None = None
    readout: float = 0.0
    seed: int = 0
    shadow_set: str | None = None
    protocol: dict[str, Any] = field(default_factory=dict)

    @property
    def phase_damping_form(self) -> str | None:
        return phase_damping_form(self.channels)

    @property
    def evaluation(self) -> str:
        """``"exact probabilities"`` or ``"N shots"``."""
        return "exact probabilities" if self.shots is None else f"{self.shots} shots"

    @property
    def majority_baseline(self) -> float | None:
        """The direction rows' majority-class baseline (``None`` without direction rows)."""
        return next((r.majority_baseline for r in self.rows if r.majority_baseline), None)

    def to_dicts(self) -> list[dict[str, Any]]:
        """One JSON object per row, with the sweep's settings repeated in each."""
        out = []
        for row in self.rows:
            d = {
                k: _finite_or_none(v)
                for k, v in asdict(row).items()
                if v is not None or k == "grouping"
            }
            d.update(
                dataset=self.shadow_set if row.method == SHADOW_METHOD else self.dataset,
                trained_under_noise=self.trained_under_noise,
                phase_damping_form=self.phase_damping_form,
                shots=self.shots,
                readout=self.readout,
                seed=self.seed,
            )
            out.append(d)
        return out

    def labels(self, method: str | None = None) -> list[str]:
        """Legend names of the series, in order of first appearance."""
        seen: dict[str, None] = {}
        for r in self.rows:
            if method is None or r.method == method:
                seen.setdefault(r.label, None)
        return list(seen)

    def direction_labels(self) -> list[str]:
        """Series of the direction methods: the UU-dagger rule's, the VQC's, then others."""
        kinds = {k: i for i, k in enumerate(DIRECTION_METHODS)}
        rows = [r for r in self.rows if r.method != SHADOW_METHOD]
        order = {r.label: kinds.get(r.method, len(kinds)) for r in reversed(rows)}
        return sorted(dict.fromkeys(r.label for r in rows), key=lambda lab: order[lab])

    def series(
        self, label: str, channel: str, key: str = "accuracy"
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(p, value)`` of one series under one channel, sorted by ``p``."""
        pts = sorted(
            (r.p, getattr(r, key)) for r in self.rows if r.label == label and r.channel == channel
        )
        return np.array([p for p, _ in pts]), np.array([v for _, v in pts], dtype=np.float64)

    # ------------------------------------------------------------ printed form

    def table_rows(self, label: str) -> list[tuple[float, list[float | None]]]:
        """``(p, values per channel)`` of one series: accuracy, or BER for ``uu-shadow``."""
        key = "ber" if label == SHADOW_METHOD else "accuracy"
        values = {(r.channel, r.p): getattr(r, key) for r in self.rows if r.label == label}
        return [(p, [values.get((ch, p)) for ch in self.channels]) for p in self.strengths]

    def table(self, label: str) -> SweepTable:
        """The printed table of one series, titled with its data and test size."""
        shadow = label == SHADOW_METHOD
        rows = [r for r in self.rows if r.label == label]
        what = "BER (%)" if shadow else "accuracy"
        data = self.shadow_set if shadow else self.dataset
        unit = "images" if shadow else "frames"
        n_test = rows[0].n_test if rows else 0
        title = f"{label} {what}, {data} ({n_test} test {unit})"
        return SweepTable(
            label,
            title,
            "ber" if shadow else "accuracy",
            1 if shadow else 3,
            self.channels,
            self.table_rows(label),
        )

    def tables(self) -> list[SweepTable]:
        """One table per series, in order of first appearance."""
        return [self.table(label) for label in self.labels()]

    def summary_lines(self) -> list[str]:
        """The lines printed under the tables: training and evaluation, phase damping,
        majority baseline, protocol."""
        trained = "trained under noise" if self.trained_under_noise else "trained without noise"
        readout = f"; readout error {self.readout:g}" if self.readout else ""
        lines = [f"{trained}; {self.evaluation}{readout}"]
        form = self.phase_damping_form
        if form:
            lines.append(f"phase damping: {form}")
        baseline = self.majority_baseline
        if baseline is not None:
            lines.append(f"majority-class baseline: {baseline:.3f}")
        proto = self.protocol
        if "folds" in proto:
            lines.append(
                f"{proto['folds']} contiguous folds (gap {proto['gap']}, "
                f"inner CV {proto['inner_folds']})"
            )
        if "shadow_thresholds" in proto:
            shown = "/".join(f"{t:g}" for t in proto["shadow_thresholds"])
            lines.append(f"shadow threshold chosen among {shown} by training BER")
        return lines
