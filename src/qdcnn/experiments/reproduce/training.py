"""Fig. 5 (CNN loss and accuracy per epoch) and Fig. 6 (the VQC objective per iteration).

Fig. 5 draws the per-epoch histories the CNN rows of Tables I and III recorded, one line
per fold. Fig. 6 fits each VQC method of the registry on all frames of each dataset (the
hyperparameters chosen by the protocol's inner contiguous CV) and draws the objective
its COBYLA callback recorded, one curve per grouping and dataset, as the paper does.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from qdcnn.direction.methods import get_method, method_names
from qdcnn.direction.protocol import fit_with_search
from qdcnn.errors import QdcnnError
from qdcnn.experiments.reproduce.accuracy import PROTOCOL, frame_methods
from qdcnn.experiments.reproduce.context import DatasetUnavailable, RunContext
from qdcnn.experiments.reproduce.model import Cell, Section, cell
from qdcnn.experiments.reproduce.paper_values import CNN_TRAINING, DATASET_TITLES

__all__ = ["cnn_section", "vqc_section"]


def _fmt(value: Any, digits: int = 3) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def cnn_section(ctx: RunContext, section: Section) -> None:
    """Fig. 5 from the CNN histories of Tables I and III."""
    from qdcnn.experiments.reproduce.plots import cnn_curves

    curves: list[tuple[str, list[list[dict[str, Any]]], float | None]] = []
    rows: list[list[Cell]] = []
    for sid in ("table-i", "table-iii"):
        table = ctx.sections.get(sid)
        for d in ({} if table is None else table.data.get("datasets", {})).values():
            paper = CNN_TRAINING.get(d.get("label", ""), {})
            for method, folds in d.get("cnn_history", {}).items():
                if not folds:
                    continue
                title = f"{DATASET_TITLES[d['label']]}: {d['name']}, {method}"
                curves.append((title, folds, paper.get("final_val_accuracy")))
                for i, h in enumerate(folds):
                    last = h[-1] if h else {}
                    rows.append(
                        [
                            title,
                            str(i + 1),
                            str(len(h)),
                            cell(_fmt(last.get("train_loss")), "measured"),
                            cell(_fmt(last.get("val_loss")), "measured"),
                            cell(_fmt(last.get("val_accuracy")), "measured"),
                            cell(_fmt(paper.get("final_val_accuracy"), 2), "paper"),
                        ]
                    )
    section.data = {
        "paper": CNN_TRAINING,
        "curves": [{"title": t, "folds": f} for t, f, _ in curves],
    }
    if not curves:
        section.status = "skipped"
        _, notes = frame_methods(ctx)
        for n in notes or ["no CNN was trained in Tables I and III"]:
            section.note(n)
        return
    section.text(
        "Per-epoch training of each CNN row of Tables I and III, one line per fold: training "
        "loss (solid) and validation loss (dashed) on frames held out of each fold's training "
        "frames, and validation accuracy. The paper's line is its ResNet-50's final validation "
        "accuracy (Sec. III-C, III-D); it trained 25 epochs on 5,280 samples per epoch."
    )
    section.figure(
        ctx.save_figure(cnn_curves(curves), "fig-5-cnn"),
        "CNN loss and validation accuracy per epoch.",
        alt="CNN training curves",
    )
    section.table(
        [
            "dataset, method",
            "fold",
            "epochs run",
            "last train loss",
            "last val. loss",
            "last val. accuracy",
            "paper: final val. accuracy",
        ],
        rows,
    )


def vqc_section(ctx: RunContext, section: Section) -> None:
    """Fig. 6: each VQC method fitted on all frames of each dataset; its objective curve."""
    from qdcnn.experiments.reproduce.plots import objective_curves

    cfg = ctx.configs["paper"]
    methods = [get_method(n) for n in method_names(inputs="lanes")]
    vqc = [m for m in methods if m.kind == "vqc"]
    panels: list[tuple[str, dict[str, list[float]]]] = []
    fits: dict[str, Any] = {}
    rows: list[list[Cell]] = []
    for entry in ctx.datasets:
        try:
            lanes = ctx.lane_data(entry, "paper")
        except DatasetUnavailable as exc:
            section.error(str(exc))
            continue
        series: dict[str, list[float]] = {}
        fits[entry.key] = {}
        for m in vqc:
            assert m.grouping is not None
            X, y = lanes.features(m.grouping), lanes.y
            estimator, grid = m.estimator(cfg)
            try:
                fitted, chosen = fit_with_search(
                    estimator, grid, X, y, inner_folds=PROTOCOL["inner_folds"], gap=PROTOCOL["gap"]
                )
            except QdcnnError as exc:
                section.error(f"{entry.title}, {m.name}: {exc}")
                continue
            history = [float(v) for v in fitted.objective_history_]
            series[m.grouping] = history
            fits[entry.key][m.name] = _fit_record(fitted, X, chosen, history)
            rows.append(
                [
                    entry.title,
                    lanes.frames.name,
                    m.name,
                    str(len(history)),
                    cell(f"{history[0]:.4f}", "measured"),
                    cell(f"{min(history):.4f}", "measured"),
                    str(chosen or ""),
                ]
            )
        if series:
            panels.append((f"{entry.title}: {lanes.frames.name} ({lanes.y.size} frames)", series))
    section.data = {"fits": fits, "maxiter": cfg.vqc.maxiter, "loss": cfg.vqc.loss}
    if not panels:
        section.status = "failed"
        return
    section.text(
        f"Each VQC method trained on all frames of each dataset (COBYLA, maxiter "
        f"{cfg.vqc.maxiter}, {cfg.vqc.loss.upper()} objective as the paper's Eq. 10; the "
        "interpret map chosen by inner contiguous CV), its objective at every evaluation as the "
        "paper's callback records it. The paper prints no values for Fig. 6."
    )
    section.figure(
        ctx.save_figure(objective_curves(panels, cfg.vqc.loss), "fig-6-vqc-objective"),
        "VQC objective per COBYLA evaluation, one curve per grouping.",
        alt="VQC objective curves",
    )
    section.table(
        [
            "dataset",
            "name",
            "method",
            "evaluations",
            "first objective",
            "lowest objective",
            "chosen",
        ],
        rows,
    )


def _fit_record(
    fitted: Any, X: Any, chosen: dict[str, Any], history: list[float]
) -> dict[str, Any]:
    ok = np.flatnonzero(np.all(np.isfinite(X[:, :2]), axis=1))
    example = fitted.scale_features(X[ok[:1]])[0].tolist() if ok.size else None
    return {
        "objective_history": history,
        "weights": np.asarray(fitted.weights_, dtype=float).tolist(),
        "chosen": chosen,
        "example_input": example,
    }
