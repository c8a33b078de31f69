"""``qdcnn reproduce``: every table and figure of the paper, measured, in one report.

:func:`run_reproduce` computes the sections in dependency order (Table II reads Table I,
Fig. 5 the CNN histories of Tables I and III, Fig. 2 the VQC weights of Fig. 6), each
inside its own error boundary: a section that raises, or a dataset that fails to load, is
reported in its place and the rest still renders. After every section its JSON goes to
``sections/<id>.json`` and the page and ``report.json`` are rewritten, so an interrupted
run leaves a readable report and ``resume`` continues it.
"""

from __future__ import annotations

import json
import os
import platform
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from qdcnn import __version__
from qdcnn._fileio import atomic_write_text, make_folder, os_reason
from qdcnn._optional import has_gpu
from qdcnn.batch import Failure
from qdcnn.errors import InputError, ParameterError, QdcnnError
from qdcnn.experiments.reproduce import paper_values
from qdcnn.experiments.reproduce.accuracy import accuracy_section, comparison_section
from qdcnn.experiments.reproduce.context import RunContext, StageReporter
from qdcnn.experiments.reproduce.figures import (
    circuit_section,
    groupings_section,
    samples_section,
)
from qdcnn.experiments.reproduce.html import render_page
from qdcnn.experiments.reproduce.model import Section
from qdcnn.experiments.reproduce.noise import noise_section
from qdcnn.experiments.reproduce.shadows import shadow_section
from qdcnn.experiments.reproduce.spec import ReproduceSpec
from qdcnn.experiments.reproduce.timing import timing_section
from qdcnn.experiments.reproduce.training import cnn_section, vqc_section
from qdcnn.outputs import LOCK_NAME, OutputFolder
from qdcnn.runtime.reporting import Reporter

__all__ = ["PAGE_ORDER", "SECTIONS", "ReproduceResult", "run_reproduce"]

SectionRun = Callable[[RunContext, Section], None]


@dataclass(frozen=True)
class SectionDef:
    """A section of the report: its id, title (the paper's number first) and how to compute it."""

    id: str
    title: str
    run: SectionRun


#: In computing order (a section may read the data of the ones before it).
SECTIONS: tuple[SectionDef, ...] = (
    SectionDef(
        "table-i",
        "Table I: direction accuracy, Track 1 and Track 2",
        lambda ctx, s: accuracy_section(ctx, s, ("track1", "track2")),
    ),
    SectionDef(
        "table-iii",
        "Table III: direction accuracy, CARLA",
        lambda ctx, s: accuracy_section(ctx, s, ("carla",)),
    ),
    SectionDef("table-ii", "Table II: comparison with other approaches", comparison_section),
    SectionDef("table-iv", "Table IV: shadow-detection time per frame", timing_section),
    SectionDef("fig-6", "Fig. 6: VQC objective per iteration", vqc_section),
    SectionDef("fig-2", "Fig. 2: the VQC circuit (and the UU† circuit)", circuit_section),
    SectionDef("fig-3", "Fig. 3: sample frames per class", samples_section),
    SectionDef(
        "fig-4", "Fig. 4: lane groupings, Hough segments and fitted lines", groupings_section
    ),
    SectionDef("fig-5", "Fig. 5: CNN loss and accuracy per epoch", cnn_section),
    SectionDef(
        "fig-7", "Fig. 7: accuracy against noise strength, and the shadow BER", noise_section
    ),
    SectionDef(
        "shadows", "Shadow detection quality: BER and overlays (not in the paper)", shadow_section
    ),
)
#: The page's order: the paper's.
PAGE_ORDER: tuple[str, ...] = (
    "table-i",
    "table-ii",
    "table-iii",
    "table-iv",
    "fig-2",
    "fig-3",
    "fig-4",
    "fig-5",
    "fig-6",
    "fig-7",
    "shadows",
)
STATE_FILE = "sections/run.json"
#: Sections a resumed run keeps (the others are computed again).
REUSED_STATUSES = ("ok", "skipped")


@dataclass
class ReproduceResult:
    """What a reproduce run wrote and how each section went."""

    out: Path
    sections: list[Section]
    failures: list[Failure] = field(default_factory=list)
    reused: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def html(self) -> Path:
        return self.out / "index.html"

    @property
    def json(self) -> Path:
        return self.out / "report.json"

    @property
    def exit_code(self) -> int:
        """0 when every section and dataset worked, 1 when some failed (the report is complete)."""
        return 1 if self.failures else 0

    def to_dict(self) -> dict[str, Any]:
        return {
            "html": str(self.html),
            "json": str(self.json),
            "sections": {s.id: s.status for s in self.sections},
            "reused": self.reused,
            "failures": [f.to_dict() for f in self.failures],
            "seconds": self.seconds,
        }


# ---------------------------------------------------------------- output folder


def prepare_output(spec: ReproduceSpec) -> dict[str, Section]:
    """Check and set up the output folder; the finished sections a resumed run keeps.

    An existing, non-empty folder is reused only with ``force`` (the report's own files
    are removed first) or ``resume`` (same settings only).
    """
    out = spec.out
    if out.exists() and not out.is_dir():
        raise InputError(out, "exists and is not a folder")
    kept: dict[str, Section] = {}
    if out.is_dir() and any(p.name != LOCK_NAME for p in out.iterdir()):
        if spec.resume:
            kept = _finished_sections(spec)
        elif spec.force:
            _remove_report_files(out)
        else:
            raise InputError(
                out,
                "folder exists and is not empty: use --force to overwrite it or --resume to "
                "continue the run in it",
            )
    make_folder(out / "figures")
    make_folder(out / "sections")
    state = {"fingerprint": spec.fingerprint(), "spec": spec.to_dict()}
    atomic_write_text(out / STATE_FILE, json.dumps(state, indent=2))
    return kept


def _remove_report_files(out: Path) -> None:
    """Remove the report of an earlier run; a link in the way is removed, never followed."""
    try:
        for name in ("index.html", "report.json"):
            (out / name).unlink(missing_ok=True)
        for folder in ("figures", "sections"):
            if (out / folder).is_symlink():
                (out / folder).unlink()
            elif (out / folder).is_dir():
                shutil.rmtree(out / folder)
    except OSError as exc:
        raise InputError(out, f"cannot remove the old report: {os_reason(exc)}") from None


def _finished_sections(spec: ReproduceSpec) -> dict[str, Section]:
    state_path = spec.out / STATE_FILE
    try:
        state = json.loads(state_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        raise InputError(
            spec.out, "holds no reproduce run to resume (sections/run.json): use --force"
        ) from None
    if state.get("fingerprint") != spec.fingerprint():
        raise ParameterError(
            "resume",
            str(spec.out),
            "a folder written with the same data and settings (this one holds another run: "
            "use --force to overwrite it)",
        )
    kept = {}
    for d in SECTIONS:
        path = spec.out / "sections" / f"{d.id}.json"
        try:
            section = Section.from_dict(json.loads(path.read_text(encoding="utf-8")))
        except (OSError, ValueError, KeyError, TypeError):
            continue
        figures_there = all((spec.out / f).is_file() for f in section.figures)
        if section.status in REUSED_STATUSES and figures_there:
            kept[d.id] = section
    return kept


# ---------------------------------------------------------------- the run


def run_reproduce(spec: ReproduceSpec, reporter: Reporter | None = None) -> ReproduceResult:
    """Compute every section, write ``index.html``, ``report.json`` and the figures.

    Raises
    ------
    InputError, ParameterError
        The output folder cannot be used (exists without ``force`` or ``resume``, holds
        a run of other settings, or another run is writing to it). Everything that goes
        wrong later is reported inside the report and in :attr:`ReproduceResult.failures`.
    """
    if spec.out.exists() and not spec.out.is_dir():
        raise InputError(spec.out, "exists and is not a folder")
    with OutputFolder(spec.out):  # one run at a time; a killed run's temporaries go
        return _run_sections(spec, reporter or Reporter())


def _run_sections(spec: ReproduceSpec, report: Reporter) -> ReproduceResult:
    """:func:`run_reproduce` in its locked output folder."""
    t0 = time.perf_counter()
    kept = prepare_output(spec)
    ctx = RunContext.create(spec, report)
    result = ReproduceResult(spec.out, [], reused=sorted(kept))
    seen_errors: set[str] = set()
    with report.progress(len(SECTIONS), "reproduce sections") as section_done:
        for i, d in enumerate(SECTIONS, 1):
            if isinstance(report, StageReporter):
                report.stage(i, len(SECTIONS), d.title + (" (reused)" if d.id in kept else ""))
            section = kept.get(d.id) or _compute(d, ctx)
            ctx.sections[d.id] = section
            if d.id not in kept:
                atomic_write_text(
                    spec.out / "sections" / f"{d.id}.json",
                    json.dumps(section.to_dict(), indent=1, default=_jsonable),
                )
            for message in section.errors:
                failure = Failure(d.id, message)
                result.failures.append(failure)
                if message not in seen_errors:
                    seen_errors.add(message)
                    report.failure(failure)
            report.result(
                {
                    "section": d.id,
                    "title": d.title,
                    "status": section.status,
                    "seconds": section.seconds,
                    "reused": d.id in kept,
                }
            )
            result.seconds = time.perf_counter() - t0
            _write(ctx, result)
            section_done()
    result.sections = [ctx.sections[i] for i in PAGE_ORDER]
    return result


def _compute(d: SectionDef, ctx: RunContext) -> Section:
    section = Section(d.id, d.title)
    t0 = time.perf_counter()
    try:
        d.run(ctx, section)
    except QdcnnError as exc:
        section.error(str(exc))
        section.status = "failed"
    except Exception as exc:  # a bug must not cost the rest of the report
        section.error(f"{type(exc).__name__}: {exc}")
        section.status = "failed"
    section.seconds = time.perf_counter() - t0
    return section


# ---------------------------------------------------------------- writing


def _jsonable(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, float | int | str | bool) or value is None:
        return value
    return str(value)


def versions() -> dict[str, str | None]:
    """Installed versions of qdcnn and the libraries behind the numbers (None: absent)."""
    out: dict[str, str | None] = {"qdcnn": __version__, "python": platform.python_version()}
    for dist in (
        "numpy",
        "scipy",
        "scikit-learn",
        "scikit-image",
        "opencv-python-headless",
        "opencv-python",
        "matplotlib",
        "qiskit",
        "qiskit-aer",
        "qiskit-machine-learning",
        "torch",
    ):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = None
    return out


def machine() -> dict[str, Any]:
    """The machine the measurements ran on."""
    try:
        usable: int | None = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        usable = os.cpu_count()
    load = os.getloadavg() if hasattr(os, "getloadavg") else None
    return {
        "cpus": os.cpu_count(),
        "cpus_usable": usable,
        "processor": platform.processor() or platform.machine(),
        "platform": platform.platform(),
        "load_average": None if load is None else [round(v, 2) for v in load],
        "gpu": has_gpu(),
    }


def _paper_values() -> dict[str, Any]:
    return {
        "accuracy": paper_values.ACCURACY,
        "text_disagrees": [
            {"dataset": k[0], "method": k[1], "text": v}
            for k, v in paper_values.TEXT_DISAGREES.items()
        ],
        "comparison": list(paper_values.COMPARISON),
        "timing_seconds": paper_values.TIMING_SECONDS,
        "cnn_training": paper_values.CNN_TRAINING,
        "noise_points": [
            dict(zip(("dataset", "kind", "channel", "p", "accuracy"), p, strict=True))
            for p in paper_values.NOISE_POINTS
        ],
    }


def _report_json(ctx: RunContext, result: ReproduceResult) -> dict[str, Any]:
    spec = ctx.spec
    return {
        "kind": "qdcnn reproduce report",
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "spec": spec.to_dict() | {"out": str(spec.out), "use_cache": spec.use_cache},
        "fingerprint": spec.fingerprint(),
        "config": {mode: cfg.to_dict() for mode, cfg in ctx.configs.items()},
        "versions": versions(),
        "machine": machine(),
        "times": {
            "kind": "measured",
            "total_seconds": result.seconds,
            "sections": {
                sid: {"seconds": s.seconds, "reused": sid in result.reused}
                for sid, s in ctx.sections.items()
            },
            "hardware_estimates": "not here: sections.table-iv.data.estimates (kind 'estimate')",
        },
        "datasets": ctx.dataset_info(),
        "paper_values": _paper_values(),
        "sections": {
            sid: {k: v for k, v in s.to_dict().items() if k != "blocks"}
            for sid, s in ctx.sections.items()
        },
        "failures": [f.to_dict() for f in result.failures],
    }


def _write(ctx: RunContext, result: ReproduceResult) -> None:
    out = ctx.spec.out
    atomic_write_text(
        out / "report.json", json.dumps(_report_json(ctx, result), indent=1, default=_jsonable)
    )
    titles = {d.id: d.title for d in SECTIONS}
    sections = [ctx.sections.get(i) or Section(i, titles[i], "pending") for i in PAGE_ORDER]
    atomic_write_text(out / "index.html", _page(ctx, result, sections))


def _page(ctx: RunContext, result: ReproduceResult, sections: list[Section]) -> str:
    spec = ctx.spec
    profile = spec.profile
    source = (
        "the built-in synthetic presets `track1`, `track2` and `rain` standing in for the "
        "paper's Track 1, Track 2 and CARLA (rain)"
        if spec.synthetic
        else "the recordings listed below"
    )
    intro = [
        f"Generated {time.strftime('%Y-%m-%d %H:%M')} by `qdcnn reproduce` "
        f"({profile.name} profile) on {source}. Nothing was downloaded.",
        "Each section is titled with the paper's table or figure number and shows the paper's "
        "printed values (blue cells) next to the values measured here. Times are measured on "
        "this machine; hardware-time estimates are labelled as such and kept in their own "
        "table. Every number is also in `report.json`, with the full configuration and the "
        "versions that produced it.",
    ]
    settings = [("profile", profile.name), ("seed", str(spec.seed))]
    for d in ctx.dataset_info():
        frames = (
            f"{d['n_frames']} frames"
            + (
                f" (first of {d['n_frames_recorded']})"
                if d.get("n_frames_recorded", d["n_frames"]) != d["n_frames"]
                else ""
            )
            if "n_frames" in d
            else d.get("error", "not loaded")
        )
        settings.append((f"{d['title']} ({d['key']})", f"`{d['spec']}`: {frames}"))
    settings.append(("shadow set", str(spec.shadow_set or "synthetic track2 scenes")))
    cpus = machine()
    settings.append(
        (
            "machine",
            f"{cpus['cpus']} CPUs ({cpus['processor']}), load "
            f"{cpus['load_average']}, GPU: {'yes' if cpus['gpu'] else 'no'}",
        )
    )
    settings.append(
        (
            "time",
            f"{result.seconds:.0f} s so far (measured)"
            + (f"; reused sections: {', '.join(result.reused)}" if result.reused else ""),
        )
    )
    ver = versions()
    settings.append(("versions", ", ".join(f"{k} {v}" for k, v in ver.items() if v)))
    notes = ["Fig. 1 (the system model) is a diagram, not a result: it is not reproduced."]
    if profile.name == "quick":
        notes.append(
            f"--quick: {profile.synthetic_frames}-frame synthetic drives, at most "
            f"{profile.max_frames} frames of each recording, named options for the UU† methods "
            "only, noise sweeps on the image-split grouping, Table IV at 320x160 only, no CNNs "
            "unless --cnn."
        )
    details = [
        (
            f"full configuration: {mode} pipeline (`PipelineConfig.to_dict()`)",
            json.dumps(cfg.to_dict(), indent=1, default=_jsonable),
        )
        for mode, cfg in ctx.configs.items()
    ]
    return render_page(
        sections,
        title="QDCNN paper, reproduced",
        intro=intro,
        settings=settings,
        notes=notes,
        details=details,
    )
