"""What a noise sweep may be asked for: strengths, channels, methods, groupings, thresholds.

Every parser takes the text a command line gives (or a sequence) and returns a tuple of
checked names or numbers, raising :class:`~qdcnn.errors.ParameterError` with a one-line
message otherwise.

Methods. ``uu`` and ``vqc`` are the paper's two direction classifiers, run on the lane
features of every grouping asked for (``image-split`` by default); a registered method name
of :mod:`qdcnn.direction.methods` (``image-split-uu``, ``kmeans-vqc``, or any later
method with ``quantum=True``) names one classifier on its own inputs; ``uu-shadow`` is the
UU-dagger shadow detector; ``all`` is ``uu``, ``vqc`` and ``uu-shadow``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from qdcnn._validation import check_probability
from qdcnn.config import PAPER_SHADOW_THRESHOLDS, SHADOW_THRESHOLD_GRID
from qdcnn.direction.methods import GROUPINGS, get_method, method_names
from qdcnn.errors import ParameterError
from qdcnn.quantum.noise import PAPER_CHANNELS, check_channel

__all__ = [
    "DIRECTION_METHODS",
    "MAX_STRENGTHS",
    "METHODS",
    "PAPER_STRENGTHS",
    "PHASE_DAMPING_FORMS",
    "SHADOW_METHOD",
    "SHADOW_THRESHOLD_CHOICES",
    "check_grid",
    "check_phase_damping_form",
    "direction_methods",
    "parse_channels",
    "parse_groupings",
    "parse_methods",
    "parse_shadow_thresholds",
    "parse_strengths",
    "phase_damping_form",
]

#: Shorthand direction methods: the classifier kinds, run on every grouping asked for.
DIRECTION_METHODS: tuple[str, ...] = ("uu", "vqc")
SHADOW_METHOD = "uu-shadow"
METHODS: tuple[str, ...] = (*DIRECTION_METHODS, SHADOW_METHOD)
PHASE_DAMPING_FORMS: tuple[str, ...] = ("textbook", "paper")
MAX_STRENGTHS = 1000
#: Named candidate sets of the shadow threshold: the fine grid ``train-shadows`` uses, or
#: the paper's two values.
SHADOW_THRESHOLD_CHOICES: dict[str, tuple[float, ...]] = {
    "grid": SHADOW_THRESHOLD_GRID,
    "paper": PAPER_SHADOW_THRESHOLDS,
}
_RANGE_HELP = "START:STOP:STEP (e.g. 0:0.99:0.11) or a comma list (e.g. 0,0.1,0.5)"


def _items(text: str | Sequence[str]) -> list[str]:
    parts = text.split(",") if isinstance(text, str) else [str(t) for t in text]
    return [t.strip() for t in parts if t.strip()]


def parse_strengths(text: str) -> tuple[float, ...]:
    """Noise strengths from ``START:STOP:STEP`` or a comma list, sorted, each in [0, 1].

    A range includes ``STOP`` when it lies on the grid (to 1e-9 of a step); values are
    rounded to 12 decimals so that ``0:0.99:0.11`` gives exactly 0, 0.11, ..., 0.99.

    Examples
    --------
    >>> parse_strengths("0:0.99:0.11")[:4], len(parse_strengths("0:0.99:0.11"))
    ((0.0, 0.11, 0.22, 0.33), 10)
    >>> parse_strengths("0.5, 0, 0.1")
    (0.0, 0.1, 0.5)
    """
    s = str(text).strip()
    if not s:
        raise ParameterError("p", text, _RANGE_HELP)
    if ":" in s:
        parts = s.split(":")
        if len(parts) != 3:
            raise ParameterError("p", text, _RANGE_HELP)
        try:
            start, stop, step = (float(v) for v in parts)
        except ValueError:
            raise ParameterError("p", text, _RANGE_HELP) from None
        if not all(math.isfinite(v) for v in (start, stop, step)) or step <= 0 or stop < start:
            raise ParameterError("p", text, f"{_RANGE_HELP}, with STEP > 0 and START <= STOP")
        count = math.floor((stop - start) / step + 1e-9) + 1
        if count > MAX_STRENGTHS:
            raise ParameterError("p", text, f"at most {MAX_STRENGTHS} strengths")
        values = [start + i * step for i in range(count)]
    else:
        try:
            values = [float(v) for v in s.split(",")]
        except ValueError:
            raise ParameterError("p", text, _RANGE_HELP) from None
        if len(values) > MAX_STRENGTHS:
            raise ParameterError("p", f"<{len(values)} values>", f"at most {MAX_STRENGTHS}")
    rounded = [round(v, 12) + 0.0 for v in values]  # + 0.0 turns -0.0 into 0.0
    for v in rounded:
        check_probability("p", v)
    return tuple(sorted(set(rounded)))


#: 0, 0.11, ..., 0.99: the strengths of the paper's Fig. 7.
PAPER_STRENGTHS: tuple[float, ...] = parse_strengths("0:0.99:0.11")


def check_phase_damping_form(form: str) -> str:
    """Return ``form`` if it is ``"textbook"`` or ``"paper"``, else raise."""
    if form not in PHASE_DAMPING_FORMS:
        raise ParameterError("phase_damping", form, "'textbook' or 'paper'")
    return form


def parse_channels(text: str | Sequence[str], phase_damping: str = "textbook") -> tuple[str, ...]:
    """Channel names from a comma list; ``all`` is the six of the paper's Fig. 7.

    ``phase_damping`` says which form the name ``phase-damping`` (and ``all``) means:
    ``"textbook"`` (Qiskit's ``phase_damping_error``) or ``"paper"`` (the printed
    operators, channel ``phase-damping-paper``). Duplicates are dropped, order kept.

    Examples
    --------
    >>> parse_channels("bit-flip,phase-damping", phase_damping="paper")
    ('bit-flip', 'phase-damping-paper')
    """
    check_phase_damping_form(phase_damping)
    names = _items(text)
    if not names:
        raise ParameterError("channels", text, "'all' or a comma list of channel names")
    out: list[str] = []
    for name in names:
        expanded = PAPER_CHANNELS if name == "all" else (check_channel(name),)
        for ch in expanded:
            ch = "phase-damping-paper" if ch == "phase-damping" and phase_damping == "paper" else ch
            if ch not in out:
                out.append(ch)
    return tuple(out)


def phase_damping_form(channels: Sequence[str]) -> str | None:
    """Which phase damping the channels use: "textbook", "paper", "textbook+paper" or None."""
    forms = [
        f
        for f, ch in zip(PHASE_DAMPING_FORMS, ("phase-damping", "phase-damping-paper"), strict=True)
        if ch in channels
    ]
    return "+".join(forms) or None


def check_grid(channels: Sequence[str], strengths: Sequence[float], readout: float = 0.0) -> None:
    """Refuse an empty grid, an unknown channel, or a strength or ``readout`` (the readout
    error added at every point) outside [0, 1]."""
    if not channels:
        raise ParameterError("channels", list(channels), "at least one channel")
    if not strengths:
        raise ParameterError("p", list(strengths), "at least one strength")
    if len(strengths) > MAX_STRENGTHS:
        raise ParameterError("p", f"<{len(strengths)} values>", f"at most {MAX_STRENGTHS}")
    for ch in channels:
        check_channel(ch)
    for p in strengths:
        check_probability("p", p)
    check_probability("readout", readout)


def _quantum_method_names() -> list[str]:
    return [n for n in method_names() if get_method(n).quantum]


def _methods_help() -> str:
    return (
        "a comma list of uu, vqc, uu-shadow or all, or registered quantum methods ("
        + ", ".join(_quantum_method_names())
        + ")"
    )


def parse_methods(text: str | Sequence[str]) -> tuple[str, ...]:
    """Methods from a comma list (module docstring); ``all`` is uu, vqc and uu-shadow.

    Registered names must be quantum methods (``quantum=True``): the others have no
    circuit that noise could act on.

    Examples
    --------
    >>> parse_methods("vqc,kmeans-uu,uu-shadow")
    ('vqc', 'kmeans-uu', 'uu-shadow')
    """
    out: list[str] = []
    for name in _items(text):
        for m in METHODS if name == "all" else (name,):
            if m not in METHODS:
                if m not in method_names():
                    raise ParameterError("methods", m, _methods_help())
                if not get_method(m).quantum:
                    raise ParameterError(
                        "methods",
                        m,
                        "a quantum method (it has no simulated circuit to add noise to)",
                    )
            if m not in out:
                out.append(m)
    if not out:
        raise ParameterError("methods", text, _methods_help())
    return tuple(out)


def direction_methods(methods: Sequence[str]) -> tuple[str, ...]:
    """The direction methods among ``methods`` (all but ``uu-shadow``)."""
    return tuple(m for m in methods if m != SHADOW_METHOD)


def parse_groupings(text: str | Sequence[str]) -> tuple[str, ...]:
    """Lane groupings from a comma list of image-split, kmeans, spectral (duplicates dropped).

    Examples
    --------
    >>> parse_groupings("kmeans, image-split,kmeans")
    ('kmeans', 'image-split')
    """
    names = tuple(dict.fromkeys(_items(text)))
    if not names or any(g not in GROUPINGS for g in names):
        raise ParameterError("grouping", text, "a comma list of " + ", ".join(GROUPINGS))
    return names


def parse_shadow_thresholds(value: str | Sequence[float]) -> tuple[float, ...]:
    """Candidate shadow thresholds: ``"grid"`` (:data:`~qdcnn.config.SHADOW_THRESHOLD_GRID`,
    what ``train-shadows`` uses), ``"paper"`` (0.75 and 0.97) or numbers in [0, 1].

    Examples
    --------
    >>> parse_shadow_thresholds("paper")
    (0.75, 0.97)
    """
    if isinstance(value, str):
        if value not in SHADOW_THRESHOLD_CHOICES:
            raise ParameterError(
                "thresholds", value, "'grid', 'paper' or a sequence of numbers in [0, 1]"
            )
        return SHADOW_THRESHOLD_CHOICES[value]
    values = tuple(check_probability("thresholds", v) for v in value)
    if not values:
        raise ParameterError("thresholds", value, "at least one threshold")
    return values
