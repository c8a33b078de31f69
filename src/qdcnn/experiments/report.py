"""The ``qdcnn demo`` report: every stage on synthetic scenes, written as an HTML page.

Sections: shadow detection (BER of UU-dagger and the classical baselines on a
synthetic track2 shadow set, with overlays), timing (measured, next to the
labelled hardware-time estimates), and lane direction (cross-validated accuracy
of the six quantum methods on synthetic drives, with overlays). Numbers also go
to ``report.json``. Sections whose optional extras are missing say so.
"""

from __future__ import annotations

import html
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import has_module
from qdcnn.config import PipelineConfig, ShadowConfig
from qdcnn.data.images import write_image
from qdcnn.vision.metrics import confusion_counts, shadow_scores

Say = Callable[[str], None]


@dataclass
class Section:
    """One part of the report: a title, HTML body and the numbers behind it."""

    title: str
    body: str
    data: dict[str, Any] = field(default_factory=dict)


def _table(header: list[str], rows: list[list[Any]]) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _detector(
    method: str, config: ShadowConfig
) -> Callable[[NDArray[np.uint8]], NDArray[np.bool_]]:
    from qdcnn.vision.detectors import detect_shadows

    return lambda image: detect_shadows(image, method, config)


def shadow_section(out_dir: Path, *, n_test: int, n_train: int, seed: int, say: Say) -> Section:
    """BER of every detector on synthetic track2 scenes, and overlay panels."""
    from qdcnn.data.synthetic import generate_scenes
    from qdcnn.vision.detectors import SHADOW_METHODS, detect_shadows
    from qdcnn.vision.overlays import draw_shadow_overlay
    from qdcnn.vision.shadow_training import train_multi_shadow_model, train_shadow_model
    from qdcnn.vision.shadows import detect_shadows_uu

    say("shadows: rendering synthetic track2 scenes")
    test = generate_scenes("track2", n_test, seed=seed + 1000)
    train = generate_scenes("track2", n_train, seed=seed)
    exact = ShadowConfig(shots=None)
    say("shadows: training UU-dagger models on the training scenes")
    grid = (0.9, 0.95, 0.97, 0.98, 0.99, 0.995)
    images, masks = [s.image for s in train], [s.shadow_mask for s in train]
    model = train_shadow_model(images, masks, exact, grid)
    multi = train_multi_shadow_model(images, masks, exact, n_centroids=3, seed=seed)
    shots = replace(exact, shots=1024)
    detectors: dict[str, Callable[[NDArray[np.uint8]], NDArray[np.bool_]]] = {
        "uu multi-centroid, intensity + chromaticity (trained, 1024 shots)": lambda im: (
            detect_shadows_uu(im, shots, model=multi, rng=seed).mask
        ),
        "uu paper model (trained, 1024 shots)": lambda im: (
            detect_shadows_uu(im, shots, model=model, rng=seed).mask
        ),
        "uu paper, per-image calibration (1024 shots)": lambda im: detect_shadows(
            im, "uu", shots, rng=seed
        ),
    }
    for method in SHADOW_METHODS[1:]:
        detectors[method] = _detector(method, exact)
    rows, scores, panels = [], {}, []
    for name, fn in detectors.items():
        say(f"shadows: {name}")
        t0 = time.perf_counter()
        masks = [fn(s.image) for s in test]
        seconds = (time.perf_counter() - t0) / len(test)
        sc = shadow_scores(
            [confusion_counts(m, s.shadow_mask) for m, s in zip(masks, test, strict=True)]
        )
        scores[name] = {**sc.to_dict(), "ms_per_frame": 1e3 * seconds}
        rows.append(
            [
                name,
                f"{sc.ber:.2f}",
                f"{sc.shadow_error:.2f}",
                f"{sc.nonshadow_error:.2f}",
                f"{sc.iou:.1f}",
                f"{1e3 * seconds:.2f}",
            ]
        )
        panels.append(
            [draw_shadow_overlay(s.image, m) for s, m in zip(test[:3], masks[:3], strict=True)]
        )
    truth = [draw_shadow_overlay(s.image, s.shadow_mask) for s in test[:3]]
    sheet = np.vstack([np.hstack([t, *(p[i] for p in panels)]) for i, t in enumerate(truth)])
    write_image(out_dir / "shadows.png", sheet)
    legend = "ground truth | " + " | ".join(detectors)
    body = (
        f"<p>{n_test} synthetic <code>track2</code> test scenes (seed {seed + 1000}); the trained "
        f"models were trained on {n_train} other scenes: the paper's model learned centroid "
        f"{model.centroid:.1f} and threshold {model.threshold}; the multi-centroid model "
        f"{html.escape(multi.describe())}. "
        "BER and errors in percent, counts summed over the set; times measured per frame.</p>"
        + _table(["detector", "BER", "shadow err.", "non-shadow err.", "IoU", "ms / frame"], rows)
        + f"<p><img src='shadows.png' width='100%'><br><small>{html.escape(legend)}</small></p>"
    )
    return Section(
        "Shadow detection",
        body,
        {"scores": scores, "model": model.to_dict(), "multi_model": multi.to_dict()},
    )


def timing_section(*, quick: bool, say: Say) -> Section:
    """Measured per-frame times and the labelled hardware-time estimates."""
    from qdcnn.experiments.shadow_bench import bench_shadows

    aer = 20 if has_module("qiskit_aer") else 0
    result = bench_shadows(
        frames=2 if quick else 4,
        repeats=2 if quick else 3,
        aer_blocks=aer,
        include_lbp=True,
        progress=lambda m: say(f"timing: {m}"),
    )
    parts = []
    for row in result["results"]:
        rows = [[k, f"{1e3 * v:.3f}"] for k, v in row["seconds"].items()]
        if "aer_per_block" in row:
            a = row["aer_per_block"]
            rows.append(
                [
                    f"Aer, one run call per block (scaled from {a['blocks_timed']} blocks)",
                    f"{1e3 * a['seconds_per_frame']:.1f}",
                ]
            )
        parts.append(
            f"<h3>{row['size']} ({row['blocks']} blocks), measured</h3>"
            + _table(["detector", "ms / frame"], rows)
        )
    if not has_module("qiskit_aer"):
        parts.append(
            "<p>Aer timing skipped: qiskit-aer is not installed (pip install 'qdcnn[quantum]').</p>"
        )
    est = [[e["profile"], f"{e['seconds']:.6g}", e["source"]] for e in result["hardware_estimates"]]
    parts.append(
        "<h3>Hardware-time model (estimates, not measurements)</h3>"
        "<p>224,676 blocks x 1000 runs x 2 gates, as the paper assumes.</p>"
        + _table(["profile", "seconds (estimate)", "source"], est)
    )
    return Section("Timing", "".join(parts), result)


def named_options_config(config: PipelineConfig) -> PipelineConfig:
    """The direction study's best named options (not the paper's) on top of ``config``.

    Road-centre features, colour Canny and no shadow removal
    (``qdcnn evaluate --features road-centre --edges rgb --no-shadow-removal``).
    """
    return config.with_lane_options(features="road-centre", edges="rgb", shadow_removal=False)


def direction_section(out_dir: Path, *, n_frames: int, seed: int, say: Say) -> Section:
    """Cross-validated accuracy of the six quantum methods on synthetic drives.

    Each method runs with the paper's settings; the UU-dagger methods also with the
    named options of :func:`named_options_config`, on the same frames and folds.
    """
    from qdcnn.data.frames import load_frameset
    from qdcnn.experiments.direction_model import default_config
    from qdcnn.experiments.evaluate import evaluate_features
    from qdcnn.experiments.features import compute_features
    from qdcnn.experiments.methods import get_method, method_names
    from qdcnn.pipeline import process_frame
    from qdcnn.vision.overlays import draw_lane_overlay

    cfg = replace(default_config(), seed=seed)
    configs = {"paper": cfg, "named": named_options_config(cfg)}
    rows, data = [], {}
    overlays = []
    for preset in ("track1", "track2", "rain"):
        say(f"direction: synthetic {preset} drive ({n_frames} frames)")
        frames = load_frameset(f"synthetic:{preset}:{n_frames}", seed=seed)
        y = frames.labels(cfg.labels)
        tables = {mode: compute_features(frames, c) for mode, c in configs.items()}
        for method in method_names(inputs="lanes"):
            grouping, kind = get_method(method).grouping, get_method(method).kind
            assert grouping is not None
            # the named options' VQC grid (angle span x repetitions, 3 restarts) takes ~10x
            # longer, too slow for a demo; `qdcnn evaluate` runs it
            modes = ("paper", "named") if kind == "uu" else ("paper",)
            results = {
                mode: evaluate_features(
                    method,
                    frames.name,
                    tables[mode].features[grouping],
                    y,
                    config=configs[mode],
                    frames_without_lines=tables[mode].frames_without_lines(grouping),
                )
                for mode in modes
            }
            data[f"{preset}/{method}"] = results["paper"].to_dict()
            if "named" in results:
                data[f"{preset}/{method}/named-options"] = results["named"].to_dict()
            shown = [results.get(mode) for mode in configs]
            rows.append(
                [
                    preset,
                    method,
                    *(f"{r.accuracy:.3f} ± {r.accuracy_std:.3f}" if r else "—" for r in shown),
                    f"{results['paper'].majority_baseline:.3f}",
                    " / ".join(str(r.frames_without_lines) if r else "—" for r in shown),
                ]
            )
        frame = process_frame(frames.image(n_frames // 2), cfg, ("image-split",), rng=seed)
        overlays.append(
            draw_lane_overlay(
                frames.image(n_frames // 2),
                frame.segments,
                frame.lanes["image-split"],
                roi=cfg.lanes.roi,
            )
        )
    write_image(out_dir / "lanes.png", np.hstack(overlays))
    body = (
        f"<p>Synthetic drives of {n_frames} frames; labels from steering smoothed over +-5 "
        "frames; 5 contiguous folds with a 5-frame gap; hyperparameters chosen inside the "
        "training folds. <b>paper</b>: the paper's pipeline (shadow removal, grey Canny, the "
        "two slopes). <b>named options</b> (not the paper's): <code>--features road-centre "
        "--edges rgb --no-shadow-removal</code>, shown for the UU-dagger methods; "
        "<code>qdcnn evaluate</code> with the same options also runs the VQC methods (their "
        "wider grid takes about ten times longer).</p>"
        + _table(
            [
                "preset",
                "method",
                "accuracy (paper)",
                "accuracy (named options)",
                "majority baseline",
                "frames without two lines (paper / named)",
            ],
            rows,
        )
        + "<p><img src='lanes.png' width='100%'><br><small>track1 | track2 | rain: Hough segments, "
        "fitted lines and ROI (paper settings)</small></p>"
    )
    return Section("Lane direction", body, data)


PAGE = """<!doctype html><html><head><meta charset="utf-8"><title>qdcnn demo</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:auto}}
table{{border-collapse:collapse;margin:8px 0}}
td,th{{border:1px solid #bbb;padding:3px 8px;text-align:left}}th{{background:#eee}}</style></head>
<body><h1>qdcnn demo</h1><p>Generated {when} by <code>qdcnn demo</code> on synthetic data
(no data downloaded). Measured times are from this machine; estimated hardware times are
labelled.</p>
{sections}</body></html>"""


def run_demo(
    out_dir: Path, *, quick: bool = False, seed: int = 0, say: Say | None = None
) -> dict[str, Any]:
    """Run every stage on synthetic data and write ``index.html`` and ``report.json``."""
    log = say or (lambda _m: None)
    out_dir.mkdir(parents=True, exist_ok=True)
    sections = [
        shadow_section(
            out_dir, n_test=8 if quick else 24, n_train=8 if quick else 24, seed=seed, say=log
        ),
        timing_section(quick=quick, say=log),
        direction_section(out_dir, n_frames=150 if quick else 300, seed=seed, say=log),
    ]
    page = PAGE.format(
        when=time.strftime("%Y-%m-%d %H:%M"),
        sections="".join(f"<h2>{html.escape(s.title)}</h2>{s.body}" for s in sections),
    )
    (out_dir / "index.html").write_text(page, encoding="utf-8")
    report = {s.title: s.data for s in sections}
    (out_dir / "report.json").write_text(
        json.dumps(report, indent=2, default=float), encoding="utf-8"
    )
    return {"html": str(out_dir / "index.html"), "json": str(out_dir / "report.json")}
