"""Fig. 2 (the circuits), Fig. 3 (sample frames per class) and Fig. 4 (lane groupings).

Fig. 2 draws the paper's VQC (ZZ feature map + RealAmplitudes, with the weights fitted for
Fig. 6 when that section ran) and the UU-dagger test circuit, by Qiskit's text drawer when
qiskit is installed, else by qdcnn's gate listing. Figs. 3 and 4 are drawn from the
report's own datasets: one frame per class, and one frame per grouping with its Hough
segments and fitted lines (:func:`qdcnn.vision.overlays.draw_lane_overlay`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from qdcnn._optional import has_module
from qdcnn.data.labels import DIRECTIONS
from qdcnn.errors import QdcnnError
from qdcnn.experiments.reproduce.context import DatasetUnavailable, RunContext
from qdcnn.experiments.reproduce.model import Cell, Section, cell
from qdcnn.experiments.reproduce.spec import DatasetEntry

__all__ = ["circuit_section", "groupings_section", "samples_section"]

#: The paper's class order in Fig. 3: (a) left, (b) right, (c) straight.
FIG3_ORDER: tuple[str, ...] = ("left", "right", "straight")
#: The paper's grouping order in Fig. 4: (a) k-means, (b) image-split, (c) spectral.
FIG4_ORDER: tuple[str, ...] = ("kmeans", "image-split", "spectral")

# ---------------------------------------------------------------- Fig. 2


def _vqc_example(ctx: RunContext) -> tuple[list[float], list[float], str]:
    """Inputs and weights of the drawn VQC: Fig. 6's first fitted image-split VQC if any."""
    fig6 = ctx.sections.get("fig-6")
    for key, fits in ({} if fig6 is None else fig6.data.get("fits", {})).items():
        fit = fits.get("image-split-vqc")
        if fit and fit.get("example_input") is not None:
            source = (
                f"weights of image-split-vqc fitted on {key} (Fig. 6), input: the scaled "
                "slopes of that dataset's first frame with two lines"
            )
            return list(fit["example_input"]), list(fit["weights"]), source
    return [0.5, 1.5], [0.1, 0.2, 0.3, 0.4], "illustrative input and weights (Fig. 6 did not run)"


def circuit_section(ctx: RunContext, section: Section) -> None:
    """Fig. 2: the VQC circuit and the UU-dagger circuit, drawn, with outcome probabilities."""
    from qdcnn.quantum.circuits import uu_dagger_circuit, vqc_circuit
    from qdcnn.quantum.execute import run_probabilities
    from qdcnn.quantum.export import draw_text
    from qdcnn.quantum.uu_dagger import value_to_angle

    drawer = "Qiskit's text drawer" if has_module("qiskit") else "qdcnn's gate listing"
    if not has_module("qiskit"):
        section.note("qiskit is not installed: circuits are listed gate by gate, not drawn")
    cfg = ctx.configs["paper"].vqc
    x, weights, source = _vqc_example(ctx)
    vqc = vqc_circuit(
        [x], weights, feature_map_reps=cfg.feature_map_reps, ansatz_reps=cfg.ansatz_reps
    )
    centroid, value = 60.0, 75.0
    tc, tx = value_to_angle(centroid), value_to_angle(value)
    uu = uu_dagger_circuit(tc, tx)
    p_vqc = run_probabilities(vqc)[0]
    p_uu = run_probabilities(uu)[0]
    section.text(
        f"The paper's Fig. 2 is the VQC of Sec. II-C. Drawn by {drawer}; {source}. "
        "Probabilities are exact (statevector), qubit 0 the least significant bit."
    )
    section.pre(draw_text(vqc), caption="VQC: ZZ feature map (reps 2) then RealAmplitudes (reps 1)")
    section.table(
        ["basis state (q1 q0)", "probability"],
        [[format(i, "02b"), cell(f"{p:.4f}", "measured")] for i, p in enumerate(p_vqc)],
        caption="VQC outcome probabilities",
    )
    section.pre(
        draw_text(uu),
        caption=f"UU†: RY(θc) then RY(-θx); θc = π·{centroid:g}/255 (a shadow centroid), "
        f"θx = π·{value:g}/255 (a block)",
    )
    expected = float(np.cos((tc - tx) / 2) ** 2)
    section.text(
        f"UU† P(0) = {p_uu[0]:.4f}, cos²((θc − θx)/2) = {expected:.4f}: the fidelity score the "
        "shadow detector and the direction rule threshold."
    )
    section.table(["", "paper (Sec. II-C, Alg. 1)", "drawn here"], _circuit_rows(vqc, weights))
    section.data = {
        "drawer": drawer,
        "vqc": {
            "x": x,
            "weights": weights,
            "source": source,
            "probabilities": p_vqc.tolist(),
            "gates": [g.name for g in vqc.gates],
            "num_qubits": vqc.num_qubits,
        },
        "uu_dagger": {
            "theta_c": float(tc),
            "theta_x": float(tx),
            "p0": float(p_uu[0]),
            "gates": [g.name for g in uu.gates],
        },
    }


def _circuit_rows(vqc: Any, weights: list[float]) -> list[list[Cell]]:
    return [
        ["VQC qubits", cell("2", "paper"), cell(str(vqc.num_qubits), "measured")],
        ["VQC trainable parameters", cell("4", "paper"), cell(str(len(weights)), "measured")],
        ["VQC feature map", cell("ZZFeatureMap(2)", "paper"), cell("ZZ, reps 2", "measured")],
        ["VQC ansatz", cell("RealAmplitudes", "paper"), cell("RealAmplitudes, reps 1", "measured")],
        ["UU† qubits / gates", cell("1 / 2", "paper"), cell("1 / 2", "measured")],
    ]


# ---------------------------------------------------------------- Fig. 3


def representative(labels: NDArray[np.int64], cls: int) -> int | None:
    """The middle frame of the longest run of ``cls`` in ``labels`` (None if absent).

    Examples
    --------
    >>> representative(np.array([0, 1, 1, 1, 0, 1]), 1)
    2
    """
    best, start, best_len = None, None, 0
    for i, v in enumerate([*labels.tolist(), -1]):
        if v == cls and start is None:
            start = i
        elif v != cls and start is not None:
            if i - start > best_len:
                best, best_len = (start + i - 1) // 2, i - start
            start = None
    return best


def samples_section(ctx: RunContext, section: Section) -> None:
    """Fig. 3: one frame of each class per dataset (the middle of its longest run)."""
    from qdcnn.experiments.reproduce.plots import image_grid

    cfg = ctx.configs["paper"]
    grid: list[tuple[str, list[tuple[str, NDArray[np.uint8] | None]]]] = []
    data: dict[str, Any] = {}
    for entry in ctx.datasets:
        try:
            frames = ctx.frames(entry)
        except DatasetUnavailable as exc:
            section.error(str(exc))
            continue
        labels = frames.labels(cfg.labels)
        panels, picks = [], {}
        for name in FIG3_ORDER:
            i = representative(labels, DIRECTIONS.index(name))
            image = _read(frames, i, section)
            picks[name] = None if i is None else {"frame": i, "source": frames.sources[i]}
            title = f"{name}, frame {i}" if i is not None else f"{name}: no such frame"
            panels.append((title, image))
        grid.append((f"{entry.title}: {frames.name}", panels))
        data[entry.key] = picks
    section.data = {"frames": data}
    if not grid:
        section.status = "failed"
        return
    section.text(
        "One frame per class and dataset: the middle frame of the longest run of that label "
        "(steering smoothed over ±5 frames, threshold 0.05), in the paper's order "
        "(a) left, (b) right, (c) straight."
    )
    section.figure(
        ctx.save_figure(image_grid(grid, "Sample frames per class (Fig. 3)"), "fig-3-samples"),
        "Sample frames per class for each dataset.",
        alt="sample frames per class",
    )


def _read(frames: Any, i: int | None, section: Section) -> NDArray[np.uint8] | None:
    if i is None:
        return None
    try:
        image: NDArray[np.uint8] = frames.image(i)
    except QdcnnError as exc:
        section.error(f"{frames.name}: {exc}")
        return None
    return image


# ---------------------------------------------------------------- Fig. 4


def _grouping_frame(ctx: RunContext, entry: DatasetEntry) -> int:
    """A frame where every grouping finds two lines that can border a road (status "ok"),
    in the longest bend if possible."""
    lanes = ctx.lane_data(entry, "paper")
    ok = np.ones(len(lanes.frames), bool)
    for status in lanes.table.status.values():
        ok &= status == "ok"
    labels = lanes.labels
    for cls in (DIRECTIONS.index("left"), DIRECTIONS.index("right")):
        masked = np.where(ok, labels, -1)
        i = representative(masked, cls)
        if i is not None:
            return i
    good = np.flatnonzero(ok)
    return int(good[len(good) // 2]) if good.size else len(lanes.frames) // 2


def groupings_section(ctx: RunContext, section: Section) -> None:
    """Fig. 4: one frame per dataset under each grouping: segments, groups, fitted lines."""
    from qdcnn.experiments.reproduce.plots import image_grid
    from qdcnn.pipeline import process_frame
    from qdcnn.vision.overlays import draw_lane_overlay

    cfg = ctx.configs["paper"]
    grid: list[tuple[str, list[tuple[str, NDArray[np.uint8] | None]]]] = []
    rows: list[list[Cell]] = []
    data: dict[str, Any] = {}
    for entry in ctx.datasets:
        try:
            i = _grouping_frame(ctx, entry)
            frames = ctx.frames(entry)
            image = frames.image(i)
        except QdcnnError as exc:
            section.error(str(exc))
            continue
        result = process_frame(image, cfg, FIG4_ORDER, rng=ctx.spec.seed)
        panels: list[tuple[str, NDArray[np.uint8] | None]] = []
        data[entry.key] = {"frame": i, "source": frames.sources[i], "groupings": {}}
        for g in FIG4_ORDER:
            lanes = result.lanes[g]
            overlay = draw_lane_overlay(image, result.segments, lanes, roi=cfg.lanes.roi, scale=2)
            panels.append((f"{g} ({lanes.status})", overlay))
            slopes = [None if not np.isfinite(v) else float(v) for v in lanes.features[:2]]
            data[entry.key]["groupings"][g] = {"status": lanes.status, "slopes": slopes}
            rows.append(
                [
                    entry.title,
                    frames.name,
                    str(i),
                    g,
                    lanes.status,
                    str(lanes.n_segments),
                    cell(", ".join("—" if s is None else f"{s:+.3f}" for s in slopes), "measured"),
                ]
            )
        grid.append((f"{entry.title}: {frames.name}, frame {i}", panels))
    section.data = {"frames": data}
    if not grid:
        section.status = "failed"
        return
    section.text(
        "The paper's pipeline on one frame per dataset (a frame where all three groupings find "
        "two lines that can border a road, in the longest bend when there is one; a status "
        "'crossed' or 'wrong-side' flags two lines that cannot): ROI (white), Hough segments "
        "coloured by group (orange left, blue right), fitted lines (yellow, cyan); image-split "
        "also draws the split (dashed green) and the centre line (green). Order as in the paper: "
        "(a) k-means, (b) image-split, (c) spectral."
    )
    section.figure(
        ctx.save_figure(image_grid(grid, "Lane groupings (Fig. 4)"), "fig-4-groupings"),
        "Hough segments and fitted lines per grouping.",
        alt="lane groupings",
    )
    section.table(
        [
            "dataset",
            "name",
            "frame",
            "grouping",
            "status",
            "segments",
            "slopes dx/dy (left, right)",
        ],
        rows,
    )
