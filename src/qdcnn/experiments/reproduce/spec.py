"""What ``qdcnn reproduce`` runs: the datasets under the paper's labels, the profile, the output.

Datasets are given as ``LABEL=SPEC`` (``track1=udacity:PATH``, ``track2=udacity:PATH``,
``carla=carla:PATH``); a label may be given more than once (each dataset becomes its own
column under the paper's label, e.g. two Track 2 recordings). Without datasets the three
synthetic presets stand in for the paper's three: ``track1``, ``track2`` and ``rain``
(CARLA, rain).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from qdcnn._validation import check_int, check_seed
from qdcnn.data.frames import load_frameset, parse_data_spec
from qdcnn.data.images import require_file_or_folder
from qdcnn.data.shadow_set import require_shadow_set
from qdcnn.errors import ParameterError
from qdcnn.experiments.noise import PAPER_STRENGTHS
from qdcnn.experiments.reproduce.paper_values import DATASET_LABELS, DATASET_TITLES
from qdcnn.vision.grouping import GROUPINGS

__all__ = [
    "FULL",
    "QUICK",
    "SYNTHETIC_PRESET_OF",
    "TINY",
    "DatasetEntry",
    "Profile",
    "ReproduceSpec",
    "parse_data_option",
]

#: The synthetic preset that stands in for each of the paper's datasets.
SYNTHETIC_PRESET_OF: dict[str, str] = {"track1": "track1", "track2": "track2", "carla": "rain"}


def check_label(label: str) -> str:
    """Return ``label`` if it is one of the paper's dataset labels, else raise."""
    if label not in DATASET_LABELS:
        raise ParameterError("data label", label, "one of " + ", ".join(DATASET_LABELS))
    return label


@dataclass(frozen=True)
class DatasetEntry:
    """One dataset of the report: the paper's label it stands for and its spec."""

    label: str
    spec: str
    index: int = 0

    @property
    def key(self) -> str:
        """A unique id for file names and JSON keys: ``track2``, then ``track2-2``, ..."""
        return self.label if self.index == 0 else f"{self.label}-{self.index + 1}"

    @property
    def title(self) -> str:
        """The paper's name of the label (``Track 1``)."""
        return DATASET_TITLES[self.label]

    def to_dict(self) -> dict[str, str]:
        return {"key": self.key, "label": self.label, "spec": self.spec}


def parse_data_option(text: str) -> DatasetEntry:
    """``LABEL=SPEC`` from the command line as a :class:`DatasetEntry`.

    Examples
    --------
    >>> parse_data_option("track1=udacity:../shared/data/udacity-lake-track")
    DatasetEntry(label='track1', spec='udacity:../shared/data/udacity-lake-track', index=0)
    """
    label, sep, spec = str(text).partition("=")
    if not sep or not spec.strip():
        raise ParameterError("data", text, "LABEL=SPEC, e.g. track1=udacity:PATH")
    entry = DatasetEntry(check_label(label.strip()), spec.strip())
    parse_data_spec(entry.spec)  # a bad kind or suffix is an error before any work
    return entry


@dataclass(frozen=True)
class Profile:
    """Sizes of a run: ``quick`` (a few minutes on 2 cores) or the full one.

    Attributes
    ----------
    synthetic_frames : int
        Frames of each synthetic drive.
    max_frames : int or None
        Frames taken from the start of each recording (``None``: all).
    named_kinds : tuple of str or None
        Classifier kinds also evaluated with the named options (``None``: every lane method).
    noise_groupings : tuple of str
        Lane groupings of the noise sweep.
    noise_strengths : tuple of float
        Noise strengths of the sweep (the paper's 0, 0.11, ..., 0.99).
    shadow_scenes : int
        Synthetic shadow scenes when no shadow set is given (half train, half test).
    bench_sizes, bench_frames, bench_repeats, aer_blocks
        The shadow-timing benchmark (Table IV).
    """

    name: str
    synthetic_frames: int
    max_frames: int | None
    named_kinds: tuple[str, ...] | None
    noise_groupings: tuple[str, ...]
    noise_strengths: tuple[float, ...]
    shadow_scenes: int
    bench_sizes: tuple[tuple[int, int], ...]
    bench_frames: int
    bench_repeats: int
    aer_blocks: int

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "synthetic_frames": self.synthetic_frames,
            "max_frames": self.max_frames,
            "named_kinds": self.named_kinds,
            "noise_groupings": list(self.noise_groupings),
            "noise_strengths": list(self.noise_strengths),
            "shadow_scenes": self.shadow_scenes,
            "bench_sizes": [list(s) for s in self.bench_sizes],
            "bench_frames": self.bench_frames,
            "bench_repeats": self.bench_repeats,
            "aer_blocks": self.aer_blocks,
        }


QUICK = Profile(
    "quick",
    synthetic_frames=300,
    max_frames=1000,
    # the named options' VQC grid (angle span x repetitions x 3 restarts) takes ~10x longer
    named_kinds=("uu",),
    noise_groupings=("image-split",),
    noise_strengths=PAPER_STRENGTHS,
    shadow_scenes=16,
    bench_sizes=((320, 160), (1280, 720)),
    # as `qdcnn bench shadows` (shadow_bench.BENCH_FRAMES, BENCH_REPEATS): fewer frames
    # and passes gave ratios to IBT off by 2x, and 5 passes by up to 30 % on a busy machine
    bench_frames=5,
    bench_repeats=15,
    aer_blocks=20,
)
FULL = Profile(
    "full",
    synthetic_frames=600,
    max_frames=None,
    named_kinds=None,
    noise_groupings=GROUPINGS,
    noise_strengths=PAPER_STRENGTHS,
    shadow_scenes=48,
    bench_sizes=((320, 160), (1280, 720)),
    bench_frames=5,
    bench_repeats=21,
    aer_blocks=200,
)
#: Seconds, for tests and smoke checks: every section runs, the numbers mean nothing.
TINY = Profile(
    "tiny",
    synthetic_frames=80,
    max_frames=120,
    named_kinds=("uu",),
    noise_groupings=("image-split",),
    noise_strengths=(0.0, 0.5, 0.99),
    shadow_scenes=4,
    bench_sizes=((160, 80),),
    bench_frames=1,
    bench_repeats=1,
    aer_blocks=2,
)


def _entries(
    data: Mapping[str, str | Sequence[str]] | Iterable[DatasetEntry],
) -> tuple[DatasetEntry, ...]:
    if isinstance(data, Mapping):
        out = []
        for label, specs in data.items():
            for spec in [specs] if isinstance(specs, str) else list(specs):
                out.append(DatasetEntry(check_label(label), spec))
    else:
        out = [DatasetEntry(check_label(e.label), e.spec) for e in data]
    for e in out:
        parse_data_spec(e.spec)
    return tuple(out)


#: The frame methods of the paper (``--cnn-methods paper``).
PAPER_CNNS = ("dnn-pilotnet", "dnn-resnet50")


def check_cnn_methods(value: str) -> None:
    """``paper``, ``all`` or a comma list of registered frame methods."""
    from qdcnn.direction.methods import get_method

    if value in ("paper", "all"):
        return
    for name in value.split(","):
        if get_method(name.strip()).inputs != "frames":
            raise ParameterError(
                "cnn_methods", value, f"'paper', 'all' or frame methods ({name} reads lanes)"
            )


@dataclass(frozen=True)
class ReproduceSpec:
    """What :func:`~qdcnn.experiments.reproduce.run_reproduce` runs.

    Attributes
    ----------
    out : Path
        Folder of ``index.html``, ``report.json``, ``figures/`` and ``sections/``.
    data : mapping or sequence of DatasetEntry
        ``label -> spec`` (or a list of specs) or entries; empty: the synthetic presets.
    quick : bool
        The quick profile (:data:`QUICK`) instead of the full one.
    force : bool
        Reuse an existing output folder, recomputing everything.
    resume : bool
        Reuse an existing output folder of the same settings, keeping finished sections.
    seed : int
        Seed of every random choice.
    cnn : bool or None
        Run the frame methods (CNNs); ``None``: when torch is installed and not quick.
    cnn_methods : str
        Which frame methods run: ``"paper"`` (PilotNet, and ResNet-50 with a GPU),
        ``"all"`` (also every hybrid and its classical twin) or a comma list of names.
    epochs : int
        CNN training epochs (the paper: 25).
    threads : int or None
        torch CPU threads.
    shadow_set : Path or None
        Images + masks for the shadow sections (default: synthetic track2 scenes).
    max_frames, synthetic_frames : int or None
        Override the profile's sizes.
    use_cache : bool
        Reuse cached lane features.
    custom_profile : Profile or None
        A profile instead of quick or full (e.g. :data:`TINY` for tests).
    """

    out: Path
    data: Any = field(default_factory=tuple)
    quick: bool = False
    force: bool = False
    resume: bool = False
    seed: int = 0
    cnn: bool | None = None
    cnn_methods: str = "paper"
    epochs: int = 25
    threads: int | None = None
    shadow_set: Path | None = None
    max_frames: int | None = None
    synthetic_frames: int | None = None
    use_cache: bool = True
    custom_profile: Profile | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "out", Path(self.out))
        object.__setattr__(self, "data", _entries(self.data))
        check_seed("seed", self.seed)
        check_cnn_methods(self.cnn_methods)
        check_int("epochs", self.epochs, 1, 10_000)
        if self.threads is not None:
            check_int("threads", self.threads, 1, 1024)
        if self.max_frames is not None:
            check_int("max_frames", self.max_frames, 10, 10_000_000)
        if self.synthetic_frames is not None:
            check_int("synthetic_frames", self.synthetic_frames, 10, 100_000)
        if self.force and self.resume:
            raise ParameterError("force/resume", "both", "at most one of --force and --resume")

    def check_paths(self) -> None:
        """Raise :class:`~qdcnn.errors.InputError` for a recording that does not load or a
        shadow set that is not there, before any work (the command line's check; without it
        a recording that fails to load is reported in each section it belongs to).

        Recordings are read as far as their label tables (images are read lazily later).
        """
        for entry in self.data:
            parsed = parse_data_spec(entry.spec)  # without its @label suffix
            if parsed.kind != "synthetic":
                require_file_or_folder(parsed.value, f"{parsed.kind} recording")
                load_frameset(entry.spec)
        if self.shadow_set is not None:
            require_shadow_set(Path(self.shadow_set))

    @property
    def profile(self) -> Profile:
        """The profile with this spec's size overrides."""
        base = self.custom_profile or (QUICK if self.quick else FULL)
        return replace(
            base,
            synthetic_frames=self.synthetic_frames or base.synthetic_frames,
            max_frames=self.max_frames if self.max_frames is not None else base.max_frames,
        )

    @property
    def synthetic(self) -> bool:
        """Whether the synthetic presets stand in for the paper's datasets."""
        return not self.data

    def datasets(self) -> tuple[DatasetEntry, ...]:
        """The datasets of the report, in the paper's label order."""
        if self.data:
            order = {label: i for i, label in enumerate(DATASET_LABELS)}
            ordered = sorted(self.data, key=lambda e: order[e.label])
            seen: dict[str, int] = {}
            out = []
            for e in ordered:
                out.append(DatasetEntry(e.label, e.spec, seen.get(e.label, 0)))
                seen[e.label] = seen.get(e.label, 0) + 1
            return tuple(out)
        n = self.profile.synthetic_frames
        return tuple(
            DatasetEntry(label, f"synthetic:{SYNTHETIC_PRESET_OF[label]}:{n}")
            for label in DATASET_LABELS
        )

    def to_dict(self) -> dict[str, Any]:
        """The settings that decide the numbers (what a resumed run must match)."""
        return {
            "data": [e.to_dict() for e in self.datasets()],
            "quick": self.quick,
            "seed": self.seed,
            "cnn": self.cnn,
            "cnn_methods": self.cnn_methods,
            "epochs": self.epochs,
            "shadow_set": None if self.shadow_set is None else str(self.shadow_set.resolve()),
            "profile": self.profile.to_dict(),
        }

    def fingerprint(self) -> str:
        """Hash of :meth:`to_dict`: a resumed run reuses sections of the same fingerprint."""
        text = json.dumps(self.to_dict(), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]
