"""The ``qdcnn`` command line: thin commands over the library.

With ``--json`` stdout carries only JSON (one object per line); progress bars
and error lines go to stderr. Exit status: 0 when everything worked, 1 when
some items failed (the others are still processed and reported), 2 for bad
options or unusable input.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.table import Table

from qdcnn.cli_common import (
    JsonOpt,
    ProgressBar,
    emit,
    err,
    fail_on_error,
    out,
    progress,
    report_error,
    report_note,
)
from qdcnn.cli_noise import circuit_cmd, noise_sweep_cmd
from qdcnn.config import PipelineConfig, ShadowConfig
from qdcnn.data.labels import DIRECTIONS
from qdcnn.errors import QdcnnError

app = typer.Typer(
    name="qdcnn",
    help="QDCNN: UU-dagger shadow detection, quantum lane-direction classifiers, noise studies.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
bench_app = typer.Typer(
    help="Benchmarks: measured times and ratios against reference implementations.",
    no_args_is_help=True,
)
app.add_typer(bench_app, name="bench")
app.command("noise-sweep")(noise_sweep_cmd)
app.command("circuit")(circuit_cmd)


@app.command("detect-shadows")
def detect_shadows_cmd(
    paths: Annotated[list[Path], typer.Argument(help="Image files and/or folders of images.")],
    out_dir: Annotated[Path, typer.Option("--out", help="Folder for <stem>_mask.png files.")],
    method: Annotated[str, typer.Option(help="uu | uu-chroma | ibt | cbs | lbp")] = "uu",
    exact: Annotated[
        bool, typer.Option("--exact", help="Exact probabilities instead of shots.")
    ] = False,
    shots: Annotated[int, typer.Option(help="Shots per block circuit (paper: 1024).")] = 1024,
    backend: Annotated[str, typer.Option(help="numpy | aer")] = "numpy",
    threshold: Annotated[
        float | None, typer.Option(help="Fidelity threshold (default 0.97).")
    ] = None,
    centroid: Annotated[float | None, typer.Option(help="Shadow centroid in [0, 255].")] = None,
    model: Annotated[Path | None, typer.Option(help="Model file from train-shadows.")] = None,
    calibration_classes: Annotated[
        int, typer.Option(help="Clusters of the per-image calibration start (paper: 2).")
    ] = 2,
    seed: Annotated[int, typer.Option(help="Seed of shot sampling.")] = 0,
    as_json: JsonOpt = False,
) -> None:
    """Detect shadows; write a 0/255 mask per image at input size."""
    from qdcnn.experiments.shadow_batch import (
        MaskRecord,
        detect_files,
        median_seconds,
        plan_detection,
    )
    from qdcnn.quantum.execute import check_backend
    from qdcnn.vision.detectors import check_method
    from qdcnn.vision.shadows import ShadowModel

    try:
        check_method(method)
        check_backend(backend)
        cfg = ShadowConfig(shots=None if exact else shots, calibration_classes=calibration_classes)
        if threshold is not None:
            cfg = replace(cfg, threshold=threshold)
        if centroid is not None:
            cfg = replace(cfg, centroid=centroid)
        trained = ShadowModel.load(model) if model else None
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    plan = plan_detection(paths)
    failures = list(plan.failures)
    for f in failures:
        report_error(f.error)
        if as_json:
            emit(f.to_dict())
    records: list[MaskRecord] = []
    results = detect_files(
        plan.images, method, out_dir, cfg, model=trained, backend=backend, seed=seed
    )
    table = Table("file", "shadow %", "ms", title=f"shadow detection: {method}")
    for item in progress(results, len(plan.images), f"detect-shadows {method}"):
        if isinstance(item, MaskRecord):
            records.append(item)
            if as_json:
                emit(item.to_dict())
            else:
                table.add_row(
                    Path(item.file).name,
                    f"{100 * item.shadow_fraction:.1f}",
                    f"{1e3 * item.seconds:.2f}",
                )
        else:
            failures.append(item)
            report_error(item.error)
            if as_json:
                emit(item.to_dict())
    med = median_seconds(records)
    summary = {
        "summary": True,
        "method": method,
        "n_images": len(records),
        "n_failed": len(failures),
        "failures": [f.to_dict() for f in failures],
        "skipped": [str(p) for p in plan.skipped],
        "median_seconds": med,
        "shots": cfg.shots if method in ("uu", "uu-chroma") else None,
        "out": str(out_dir),
    }
    if as_json:
        emit(summary)
    else:
        out.print(table)
        out.print(
            f"{len(records)} masks in {out_dir}, {len(failures)} failed, "
            f"{len(plan.skipped)} skipped"
            + (f"; median {1e3 * med:.2f} ms per image (measured)" if med is not None else "")
        )
    raise typer.Exit(1 if failures or not records else 0)


@app.command("score-shadows")
def score_shadows_cmd(
    pred: Annotated[Path, typer.Option(help="Folder of <stem>_mask.png predictions.")],
    gt: Annotated[Path, typer.Option(help="Folder of <stem>.png ground-truth masks.")],
    as_json: JsonOpt = False,
) -> None:
    """Balanced error rate of predicted masks against ground truth (counts summed over the set)."""
    from qdcnn.experiments.shadow_batch import score_folders

    try:
        report = score_folders(pred, gt)
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    for f in report.failures:
        report_error(f.error)
    if as_json:
        emit(report.to_dict())
    elif report.scores:
        s = report.scores
        out.print(
            f"BER {s.ber:.2f}  shadow error {s.shadow_error:.2f}  non-shadow error "
            f"{s.nonshadow_error:.2f}  IoU {s.iou:.2f}  n {s.n}"
        )
    raise typer.Exit(1 if report.failures or report.scores is None else 0)


@app.command("synth")
def synth_cmd(
    out_dir: Annotated[Path, typer.Option("--out", help="Output folder.")],
    preset: Annotated[str, typer.Option(help="track1 | track2 | rain")] = "track1",
    n: Annotated[int, typer.Option("--n", help="Number of frames.")] = 100,
    seed: Annotated[int, typer.Option(help="Seed of the generator.")] = 0,
    width: Annotated[int, typer.Option(help="Frame width in pixels.")] = 320,
    height: Annotated[int, typer.Option(help="Frame height in pixels.")] = 160,
    layout: Annotated[str, typer.Option(help="udacity | shadows | carla | all")] = "all",
    as_json: JsonOpt = False,
) -> None:
    """Render a synthetic drive with exact ground truth in the layouts real data use."""
    from qdcnn.data.synthetic import generate_drive
    from qdcnn.data.writers import write_carla, write_shadow_set, write_udacity
    from qdcnn.errors import ParameterError

    layouts = ("udacity", "shadows", "carla") if layout == "all" else (layout,)
    try:
        if any(lay not in ("udacity", "shadows", "carla") for lay in layouts):
            raise ParameterError("layout", layout, "udacity, shadows, carla or all")
        if not 1 <= n <= 1_000_000:
            raise ParameterError("n", n, "an integer in [1, 1000000]")
        scenes = generate_drive(preset, n, seed=seed, width=width, height=height)
        written = {}
        for lay in layouts:
            target = out_dir / lay if len(layouts) > 1 else out_dir
            if lay == "udacity":
                written[lay] = str(write_udacity(scenes, target))
            elif lay == "shadows":
                written[lay] = str(write_shadow_set(scenes, target))
            else:
                written[lay] = str(write_carla(scenes, target))
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    counts = [int(sum(s.direction == d for s in scenes)) for d in range(3)]
    result = {
        "preset": preset,
        "n": n,
        "seed": seed,
        "size": [width, height],
        "written": written,
        "directions": dict(zip(("left", "straight", "right"), counts, strict=True)),
        "mean_shadow_fraction": float(sum(s.shadow_mask.mean() for s in scenes) / n),
    }
    if as_json:
        emit(result)
    else:
        for lay, where in written.items():
            out.print(f"{lay}: {where}")
        out.print(
            f"{n} frames, directions {result['directions']}, "
            f"mean shadow fraction {result['mean_shadow_fraction']:.3f}"
        )


@app.command("train-shadows")
def train_shadows_cmd(
    data: Annotated[Path, typer.Option(help="Shadow set: DIR/images/* and DIR/masks/<stem>.png.")],
    out_file: Annotated[Path, typer.Option("--out", help="Model file to write (JSON).")],
    features: Annotated[
        str, typer.Option(help="intensity | chromaticity | intensity,chromaticity")
    ] = "intensity",
    centroids: Annotated[
        int, typer.Option(help="Components (1: the paper's single centroid).")
    ] = 1,
    search_threshold: Annotated[
        bool, typer.Option(help="Pick the threshold with the lowest training BER.")
    ] = True,
    seed: Annotated[int, typer.Option(help="Seed of the k-means start.")] = 0,
    as_json: JsonOpt = False,
) -> None:
    """Train a UU-dagger shadow model on images with masks.

    One feature and one centroid is the paper's model (centroid by the propagation
    algorithm, threshold from the paper's candidates). Several features or centroids
    train the multi-centroid model: one centroid and threshold per feature and component.
    """
    from qdcnn.data.shadow_set import load_shadow_set
    from qdcnn.errors import ParameterError
    from qdcnn.vision.shadow_training import train_multi_shadow_model, train_shadow_model
    from qdcnn.vision.shadows import FEATURES

    try:
        names = tuple(f.strip() for f in features.split(",") if f.strip())
        if not names or any(f not in FEATURES for f in names) or len(set(names)) != len(names):
            raise ParameterError("features", features, "intensity and/or chromaticity")
        if not 1 <= centroids <= 8:
            raise ParameterError("centroids", centroids, "an integer in [1, 8]")
        images, masks, failures = load_shadow_set(data)
        for f in failures:
            report_error(f.error)
        cfg = ShadowConfig(feature=names[0], shots=None)  # type: ignore[arg-type]
        if len(names) == 1 and centroids == 1:
            grid = (0.75, 0.9, 0.95, 0.97, 0.98, 0.99, 0.995, 0.998, 0.999)
            model = train_shadow_model(
                images, masks, cfg, thresholds=grid if search_threshold else None
            )
        else:
            model = train_multi_shadow_model(
                images, masks, cfg, features=names, n_centroids=centroids, seed=seed
            )
        model.save(out_file)
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    result = {
        "model": str(out_file),
        **model.to_dict(),
        "failures": [f.to_dict() for f in failures],
    }
    if as_json:
        emit(result)
    else:
        out.print(f"{model.describe()}; written to {out_file}")
    raise typer.Exit(1 if failures else 0)


def _evaluation_config(
    lanes: str,
    seed: int,
    features: str = "slopes",
    edges: str = "grey",
    shadow_removal: bool = True,
) -> PipelineConfig:
    from qdcnn.config import LaneConfig
    from qdcnn.errors import ParameterError
    from qdcnn.experiments.direction_model import with_lane_options

    if lanes not in ("udacity", "paper"):
        raise ParameterError("lanes", lanes, "'udacity' (1 smoothing pass) or 'paper' (30 passes)")
    lane_cfg = LaneConfig.udacity() if lanes == "udacity" else LaneConfig()
    return with_lane_options(
        replace(PipelineConfig(seed=seed), lanes=lane_cfg),
        features=features,
        edges=edges,
        shadow_removal=shadow_removal,
    )


FeaturesOpt = Annotated[
    str,
    typer.Option(
        help="Two classifier inputs: slopes (the paper) | far-offsets | road-centre"
        " | vanishing-points."
    ),
]
EdgesOpt = Annotated[
    str, typer.Option(help="What Canny sees: grey (the paper) | rgb (colour Canny).")
]
ShadowRemovalOpt = Annotated[
    bool, typer.Option(help="UU-dagger shadow removal before the lane stage (the paper: on).")
]


@app.command("evaluate")
def evaluate_cmd(
    data: Annotated[str, typer.Option(help="udacity:PATH | carla:PATH | synthetic:PRESET[:N]")],
    method: Annotated[
        str, typer.Option(help="A method name or 'all' (the paper's table).")
    ] = "all",
    folds: Annotated[int, typer.Option(help="Contiguous cross-validation folds.")] = 5,
    gap: Annotated[
        int, typer.Option(help="Frames left out of training on each side of a test block.")
    ] = 5,
    lanes: Annotated[
        str, typer.Option(help="Lane settings: udacity (1 smoothing pass) | paper (30).")
    ] = "udacity",
    epochs: Annotated[int, typer.Option(help="CNN epochs (dnn-* methods; paper: 25).")] = 25,
    weights: Annotated[
        Path | None, typer.Option(help="ImageNet weights for dnn-resnet50 (state_dict).")
    ] = None,
    seed: Annotated[int, typer.Option(help="Seed of every random choice.")] = 0,
    cache: Annotated[bool, typer.Option(help="Reuse cached lane features.")] = True,
    features: FeaturesOpt = "slopes",
    edges: EdgesOpt = "grey",
    shadow_removal: ShadowRemovalOpt = True,
    threads: Annotated[
        int | None, typer.Option(help="torch CPU threads for dnn-* (default: the usable CPUs).")
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Cross-validated direction accuracy with contiguous folds (the paper's accuracy table)."""
    from qdcnn.data.frames import load_frameset
    from qdcnn.data.labels import check_labels_usable
    from qdcnn.errors import ParameterError
    from qdcnn.experiments.evaluate import (
        ALL_METHODS,
        DNN_METHODS,
        QUANTUM_METHODS,
        check_method,
        contiguous_folds,
        evaluate_features,
    )
    from qdcnn.experiments.features import compute_features

    try:
        check_method(method)
        if threads is not None and threads < 1:
            raise ParameterError("threads", threads, "a positive integer")
        cfg = _evaluation_config(lanes, seed, features, edges, shadow_removal)
        frames = load_frameset(data, seed=seed)
        methods = list(ALL_METHODS if method == "all" else [method])
        if method == "all" and not _has_torch():
            methods = [m for m in methods if m not in DNN_METHODS]
            report_note("skipping dnn-* methods: torch is not installed (pip install 'qdcnn[dnn]')")
        elif method == "all" and not _has_gpu():
            methods.remove("dnn-resnet50")
            report_note(
                "skipping dnn-resnet50: no GPU, and its 25 epochs x folds take tens of "
                "core-hours on a CPU (ask for it alone: --method dnn-resnet50)"
            )
        labels = frames.labels(cfg.labels)
        check_labels_usable(labels, source=data)
        contiguous_folds(len(frames), folds, gap)  # validates folds and gap before any work
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    for problem in frames.problems:
        report_error(str(problem))
    quantum = [m for m in methods if m in QUANTUM_METHODS]
    failures: list[Any] = []
    results = []
    try:
        if quantum:
            groupings = sorted({QUANTUM_METHODS[m][0] for m in quantum})
            with ProgressBar(len(frames), f"lane features ({frames.name})") as bar:
                table = compute_features(
                    frames, cfg, groupings, use_cache=cache, on_frame=bar.advance
                )
            failures = list(table.failures)
            keep = table.readable
            for m in quantum:
                grouping = QUANTUM_METHODS[m][0]
                res = evaluate_features(
                    m,
                    frames.name,
                    table.features[grouping][keep],
                    labels[keep],
                    config=cfg,
                    folds=folds,
                    gap=gap,
                    frames_without_lines=table.frames_without_lines(grouping),
                )
                res.extra["pipeline_ms_per_frame"] = 1e3 * table.seconds_per_frame
                results.append(res)
                if as_json:
                    emit(res.to_dict())
        for m in (m for m in methods if m in DNN_METHODS):
            from qdcnn.experiments.evaluate_dnn import evaluate_cnn

            res = evaluate_cnn(
                m,
                frames,
                labels,
                folds=folds,
                gap=gap,
                epochs=epochs,
                weights=weights,
                seed=seed,
                progress=not as_json,
                num_threads=threads,
            )
            failures.extend(res.extra.pop("failures", []))
            results.append(res)
            if as_json:
                emit(res.to_dict())
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    for f in failures:
        report_error(f.error)
    if as_json:
        if failures:
            emit({"summary": True, "failures": [f.to_dict() for f in failures]})
    else:
        shown = Table(
            "method",
            "accuracy",
            "± std",
            "majority",
            "no lines",
            "seconds",
            title=f"{frames.name}: {len(frames)} frames, {folds} contiguous folds (gap {gap})",
        )
        for r in results:
            shown.add_row(
                r.method,
                f"{r.accuracy:.3f}",
                f"{r.accuracy_std:.3f}",
                f"{r.majority_baseline:.3f}",
                str(r.frames_without_lines),
                f"{r.seconds:.1f}",
            )
        out.print(shown)
    raise typer.Exit(1 if failures else 0)


def _has_torch() -> bool:
    from qdcnn._optional import HAS_TORCH

    return HAS_TORCH


def _has_gpu() -> bool:
    """Whether torch sees a CUDA or Apple MPS device (torch must be installed)."""
    import torch

    mps = getattr(torch.backends, "mps", None)
    return bool(torch.cuda.is_available() or (mps is not None and mps.is_available()))


def _train_default_direction_model(method: str, seed: int) -> Any:
    """A direction model trained on a synthetic track1 drive, for use without a model file."""
    from qdcnn.data.frames import load_frameset
    from qdcnn.experiments.direction_model import default_config, train_direction_model
    from qdcnn.experiments.evaluate import QUANTUM_METHODS
    from qdcnn.experiments.features import compute_features

    cfg = replace(default_config(), seed=seed)
    frames = load_frameset("synthetic:track1:300", seed=seed)
    grouping = QUANTUM_METHODS[method][0]
    table = compute_features(frames, cfg, (grouping,))
    return train_direction_model(
        method, table.features[grouping], frames.labels(cfg.labels), cfg, "synthetic:track1:300"
    )


@app.command("train-direction")
def train_direction_cmd(
    data: Annotated[str, typer.Option(help="udacity:PATH | carla:PATH | synthetic:PRESET[:N]")],
    out_file: Annotated[Path, typer.Option("--out", help="Model file to write.")],
    method: Annotated[str, typer.Option(help="One of the six quantum methods.")] = "image-split-uu",
    lanes: Annotated[str, typer.Option(help="udacity (1 smoothing pass) | paper (30)")] = "udacity",
    seed: Annotated[int, typer.Option(help="Seed.")] = 0,
    features: FeaturesOpt = "slopes",
    edges: EdgesOpt = "grey",
    shadow_removal: ShadowRemovalOpt = True,
    as_json: JsonOpt = False,
) -> None:
    """Train a direction classifier on all frames of a dataset and save it."""
    from qdcnn.data.frames import load_frameset
    from qdcnn.errors import ParameterError
    from qdcnn.experiments.direction_model import train_direction_model
    from qdcnn.experiments.evaluate import QUANTUM_METHODS
    from qdcnn.experiments.features import compute_features

    try:
        if method not in QUANTUM_METHODS:
            raise ParameterError("method", method, "one of " + ", ".join(QUANTUM_METHODS))
        cfg = _evaluation_config(lanes, seed, features, edges, shadow_removal)
        frames = load_frameset(data, seed=seed)
        labels = frames.labels(cfg.labels)
        grouping = QUANTUM_METHODS[method][0]
        with ProgressBar(len(frames), f"lane features ({frames.name})") as bar:
            table = compute_features(frames, cfg, (grouping,), on_frame=bar.advance)
        keep = table.readable
        model = train_direction_model(
            method, table.features[grouping][keep], labels[keep], cfg, data
        )
        model.save(out_file)
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    for f in table.failures:
        report_error(f.error)
    train_acc = float(np.mean(model.predict(table.features[grouping][keep]) == labels[keep]))
    result = {
        "model": str(out_file),
        "method": method,
        "data": data,
        "n": int(keep.sum()),
        "training_accuracy": train_acc,
        "failures": [f.to_dict() for f in table.failures],
    }
    if as_json:
        emit(result)
    else:
        out.print(
            f"{method} trained on {int(keep.sum())} frames of {frames.name} "
            f"(training accuracy {train_acc:.3f}); written to {out_file}"
        )
    raise typer.Exit(1 if table.failures else 0)


@app.command("detect-lanes")
def detect_lanes_cmd(
    paths: Annotated[list[Path], typer.Argument(help="Image files and/or folders of images.")],
    out_dir: Annotated[Path, typer.Option("--out", help="Folder for overlays and predictions.")],
    model: Annotated[Path | None, typer.Option(help="Model from train-direction.")] = None,
    method: Annotated[str, typer.Option(help="Method when no model is given.")] = "image-split-uu",
    seed: Annotated[int, typer.Option(help="Seed.")] = 0,
    as_json: JsonOpt = False,
) -> None:
    """Lane overlays and a left/straight/right decision per frame.

    Without --model, a model of --method is trained first on a synthetic track1
    drive (300 frames) and the output says so.
    """
    from qdcnn.batch import run_batch
    from qdcnn.data.images import read_image, write_image
    from qdcnn.experiments.direction_model import DirectionModel
    from qdcnn.experiments.shadow_batch import plan_detection
    from qdcnn.pipeline import process_frame
    from qdcnn.quantum.sampling import as_generator
    from qdcnn.vision.grouping import mode_columns
    from qdcnn.vision.overlays import draw_lane_overlay

    try:
        if model is not None:
            direction_model = DirectionModel.load(model)
        else:
            from qdcnn.errors import ParameterError
            from qdcnn.experiments.evaluate import QUANTUM_METHODS

            if method not in QUANTUM_METHODS:
                raise ParameterError("method", method, "one of " + ", ".join(QUANTUM_METHODS))
            err.print(f"[dim]no --model: training {method} on a synthetic track1 drive[/dim]")
            direction_model = _train_default_direction_model(method, seed)
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    plan = plan_detection(paths)
    failures = list(plan.failures)
    out_dir.mkdir(parents=True, exist_ok=True)
    rng = as_generator(seed)
    cfg, grouping = direction_model.config, direction_model.grouping
    columns = mode_columns(cfg.grouping.features, cfg.grouping.extra_features)

    def work(path: Path) -> dict[str, Any]:
        image = read_image(path)
        t0 = time.perf_counter()
        frame = process_frame(image, cfg, (grouping,), rng=rng)
        lanes = frame.lanes[grouping]
        direction = DIRECTIONS[int(direction_model.predict(lanes.features)[0])]
        seconds = time.perf_counter() - t0
        overlay = write_image(
            out_dir / f"{path.stem}_lanes.png",
            draw_lane_overlay(
                image, frame.segments, lanes, direction, roi=cfg.lanes.roi, columns=columns
            ),
        )
        return {
            "file": str(path),
            "direction": direction,
            "status": lanes.status,
            "features": [None if np.isnan(v) else float(v) for v in lanes.features],
            "seconds": seconds,
            "overlay": str(overlay),
        }

    rows = []
    table = Table("file", "direction", "lines", "ms", title=f"lanes: {direction_model.method}")
    for outcome in progress(run_batch(plan.images, work), len(plan.images), "detect-lanes"):
        if outcome.result is not None:
            rows.append(outcome.result)
            if as_json:
                emit(outcome.result)
            else:
                r = outcome.result
                table.add_row(
                    Path(r["file"]).name, r["direction"], r["status"], f"{1e3 * r['seconds']:.2f}"
                )
        elif outcome.failure is not None:
            failures.append(outcome.failure)
            report_error(outcome.failure.error)
            if as_json:
                emit(outcome.failure.to_dict())
    with open(out_dir / "predictions.csv", "w", encoding="utf-8") as fh:
        fh.write("file,direction,status\n")
        for r in rows:
            fh.write(f"{r['file']},{r['direction']},{r['status']}\n")
    summary = {
        "summary": True,
        "method": direction_model.method,
        "trained_on": direction_model.trained_on,
        "n_images": len(rows),
        "n_failed": len(failures),
        "failures": [f.to_dict() for f in failures],
        "out": str(out_dir),
    }
    if as_json:
        emit(summary)
    else:
        out.print(table)
        out.print(
            f"{len(rows)} overlays and predictions.csv in {out_dir}; {len(failures)} failed; "
            f"model {direction_model.method} trained on {direction_model.trained_on}"
        )
    raise typer.Exit(1 if failures or not rows else 0)


@app.command("demo")
def demo_cmd(
    out_dir: Annotated[
        Path, typer.Option("--out", help="Folder for index.html and figures.")
    ] = Path("demo-output"),
    quick: Annotated[bool, typer.Option(help="Fewer scenes and repeats.")] = False,
    seed: Annotated[int, typer.Option(help="Seed.")] = 0,
    as_json: JsonOpt = False,
) -> None:
    """Run every stage on built-in synthetic scenes and write an HTML report."""
    from qdcnn.experiments.report import run_demo

    try:
        result = run_demo(
            out_dir, quick=quick, seed=seed, say=lambda m: err.print(f"[dim]{m}[/dim]")
        )
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    if as_json:
        emit(result)
    else:
        out.print(f"report: {result['html']} (numbers in {result['json']})")


@bench_app.command("shadows")
def bench_shadows_cmd(
    frames: Annotated[int, typer.Option(help="Synthetic track2 frames per size.")] = 5,
    repeats: Annotated[int, typer.Option(help="Timed passes; the median is reported.")] = 5,
    aer_blocks: Annotated[
        int, typer.Option(help="Blocks timed one by one on Aer (0: skip).")
    ] = 200,
    lbp: Annotated[bool, typer.Option(help="Include the (slow) LBP baseline.")] = True,
    as_json: JsonOpt = False,
) -> None:
    """Per-frame time of UU-dagger (exact, 1024 shots), per-block Aer, IBT, CBS and LBP."""
    from qdcnn.experiments.shadow_bench import bench_shadows

    try:
        result = bench_shadows(
            frames=frames,
            repeats=repeats,
            aer_blocks=aer_blocks,
            include_lbp=lbp,
            progress=None if as_json else lambda msg: err.print(f"[dim]timing {msg}[/dim]"),
        )
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    if as_json:
        emit(result)
        return
    for row in result["results"]:
        table = Table(
            "detector",
            "ms / frame (measured)",
            "x IBT",
            title=f"{row['size']}, {row['blocks']} blocks",
        )
        ibt = row["seconds"]["ibt"]
        for name, sec in row["seconds"].items():
            table.add_row(name, f"{1e3 * sec:.3f}", f"{sec / ibt:.2f}")
        if "aer_per_block" in row:
            aer = row["aer_per_block"]
            table.add_row(
                f"aer per block (scaled from {aer['blocks_timed']} blocks)",
                f"{1e3 * aer['seconds_per_frame']:.1f}",
                f"{aer['seconds_per_frame'] / ibt:.0f}",
            )
        out.print(table)
        if "ratio_aer_per_block_to_uu_shots" in row:
            out.print(
                "per-block Aer / UU-dagger 1024 shots: "
                f"{row['ratio_aer_per_block_to_uu_shots']:,.0f}x"
            )
    est = Table(
        "profile",
        "seconds (estimate)",
        "source",
        title="hardware-time model (estimates, not measured)",
    )
    for e in result["hardware_estimates"]:
        est.add_row(e["profile"], f"{e['seconds']:.6g}", e["source"])
    out.print(est)


@bench_app.command("pipeline")
def bench_pipeline_cmd(
    data: Annotated[
        str, typer.Option(help="Frames to time (a dataset spec).")
    ] = "synthetic:track1:200",
    frames: Annotated[int, typer.Option(help="Frames timed per pass.")] = 100,
    one_core: Annotated[bool, typer.Option(help="Pin the process to one CPU core.")] = True,
    cnn: Annotated[bool, typer.Option(help="Also time CNN inference (needs torch).")] = True,
    as_json: JsonOpt = False,
) -> None:
    """Frames/s of the whole per-frame pipeline (shadow, lanes, decision) per method."""
    from qdcnn.experiments.pipeline_bench import bench_pipeline

    try:
        result = bench_pipeline(
            data=data,
            frames=frames,
            one_core=one_core,
            cnn=cnn,
            say=None if as_json else lambda m: err.print(f"[dim]{m}[/dim]"),
        )
    except QdcnnError as exc:
        raise fail_on_error(exc) from None
    if as_json:
        emit(result)
        return
    table = Table(
        "pipeline",
        "ms / frame",
        "frames / s",
        title=(
            f"{result['frames']} frames of {result['data']} at "
            f"{result['size'][0]}x{result['size'][1]}, "
            f"{'one core' if result['one_core'] else 'all cores'} (measured)"
        ),
    )
    for row in result["pipeline"]:
        table.add_row(
            row["method"], f"{row['ms_per_frame']:.2f}", f"{row['frames_per_second']:.0f}"
        )
    for row in result.get("cnn_inference", []):
        table.add_row(
            f"CNN {row['arch']} (inference only)",
            f"{1e3 / row['frames_per_second']:.2f}",
            f"{row['frames_per_second']:.0f}",
        )
    out.print(table)


def main() -> None:
    """Entry point of the ``qdcnn`` script."""
    try:
        app()
    except QdcnnError as exc:
        report_error(" ".join(str(exc).split()))
        sys.exit(2)
