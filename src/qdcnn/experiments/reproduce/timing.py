"""Table IV: shadow-detection time per frame, measured here, beside the paper's column.

Times come from :func:`qdcnn.experiments.shadow_bench.bench_shadows` (every detector in
one process on the same synthetic frames; per-block Aer when qiskit-aer is installed).
The hardware-time estimates of :mod:`qdcnn.quantum.hardware_time` are a separate table,
labelled as estimates: the paper's QDCNN value is one of them, not a measurement.
"""

from __future__ import annotations

from typing import Any

from qdcnn._optional import has_module
from qdcnn.experiments.reproduce.context import RunContext
from qdcnn.experiments.reproduce.model import Cell, Section, cell
from qdcnn.experiments.reproduce.paper_values import TIMING_SECONDS

__all__ = ["timing_section"]

#: bench_shadows' detector name -> (row title, the paper's Table IV key).
DETECTORS: dict[str, tuple[str, str | None]] = {
    "ibt": ("IBT (intensity-based thresholding)", "ibt"),
    "cbs": ("CBS (chromaticity-based)", "cbs"),
    "lbp": ("LBP (local binary pattern)", "lbp"),
    "uu-exact": ("QDCNN UU†, exact probabilities, given centroid", "qdcnn"),
    "uu-exact-calibrated": ("QDCNN UU†, exact, centroid calibrated per image", None),
    "uu-1024-shots": ("QDCNN UU†, 1024 shots, given centroid", None),
    "uu-1024-shots-calibrated": ("QDCNN UU†, 1024 shots, calibrated per image", None),
}


def timing_section(ctx: RunContext, section: Section) -> None:
    """Run the shadow benchmark and lay its measurements beside Table IV."""
    from qdcnn.experiments.shadow_bench import BENCH_FRAMES, BENCH_REPEATS, bench_shadows

    profile = ctx.profile
    aer = has_module("qiskit_aer")
    sizes = profile.bench_sizes
    with ctx.reporter.progress(len(sizes) * (1 + int(aer)), "Table IV timing") as step:
        result = bench_shadows(
            sizes,
            frames=profile.bench_frames,
            repeats=profile.bench_repeats,
            aer_blocks=profile.aer_blocks if aer else 0,
            include_lbp=True,
            seed=ctx.spec.seed,
            progress=lambda _m: step(),
        )
    section.data = {
        "measured": {"kind": "measured", "machine": result["machine"], "rows": result["results"]},
        "estimates": {"kind": "estimate", "profiles": result["hardware_estimates"]},
        "paper": TIMING_SECONDS,
    }
    section.text(
        f"Measured on this machine: median time per frame of {profile.bench_repeats} passes "
        f"over {profile.bench_frames} synthetic track2 frames per size. The paper's "
        "column is its Table IV (frame size and hardware not stated); its QDCNN value is an "
        "estimate of hardware time, not a measurement, so it is shown only in the estimates "
        "table below. The detectors take turns frame by frame, so a change of load falls on "
        "all of them alike (the order of the turns rotating from frame to frame); the frames "
        f"and passes are those of `qdcnn bench shadows` ({BENCH_FRAMES} and {BENCH_REPEATS}) "
        "or more, so its ratios to IBT agree with the benchmark's."
    )
    section.table(*_measured_table(result["results"]), caption="measured (this machine)")
    if not aer:
        section.note(
            "per-block Aer timing left out: qiskit-aer is not installed "
            "(pip install 'qdcnn[quantum]')"
        )
    for row in result["results"]:
        if "ratio_aer_per_block_to_uu_exact" in row:
            section.text(
                f"{row['size']}: per-block Aer (one AerSimulator.run call per block, 1024 shots, "
                f"{row['aer_per_block']['blocks_timed']} blocks timed and scaled to "
                f"{row['blocks']}) / UU† exact = {row['ratio_aer_per_block_to_uu_exact']:,.0f}x; "
                f"/ UU† 1024 shots = {row['ratio_aer_per_block_to_uu_shots']:,.0f}x (measured)."
            )
    section.table(
        *_estimate_table(result["hardware_estimates"]),
        caption="hardware time: estimates, not measurements",
    )


def _measured_table(rows: list[dict[str, Any]]) -> tuple[list[str], list[list[Cell]]]:
    header = ["detector", "paper, Table IV (ms)"]
    header += [f"measured, {r['size']} ({r['blocks']} blocks), ms" for r in rows]
    header += [f"x IBT, {r['size']}" for r in rows]
    out: list[list[Cell]] = []
    for name, (title, paper_key) in DETECTORS.items():
        paper = TIMING_SECONDS.get(paper_key or "")
        if paper is None:
            paper_cell = cell("", "paper")
        elif paper["kind"] == "estimate":
            paper_cell = cell("estimate only (below)", "estimate")
        else:
            paper_cell = cell(f"{1e3 * paper['seconds']:g}", "paper")
        seconds = [r["seconds"].get(name) for r in rows]
        line: list[Cell] = [title, paper_cell]
        line += [cell("—" if s is None else f"{1e3 * s:.3f}", "measured") for s in seconds]
        line += [
            cell("—" if s is None else f"{s / r['seconds']['ibt']:.2f}", "measured")
            for s, r in zip(seconds, rows, strict=True)
        ]
        out.append(line)
    aer = [r.get("aer_per_block") for r in rows]
    if any(aer):
        line = ["Qiskit Aer, one run call per block (1024 shots)", cell("", "paper")]
        line += [
            cell("—" if a is None else f"{1e3 * a['seconds_per_frame']:.1f}", "measured")
            for a in aer
        ]
        line += [
            cell(
                "—" if a is None else f"{a['seconds_per_frame'] / r['seconds']['ibt']:.0f}",
                "measured",
            )
            for a, r in zip(aer, rows, strict=True)
        ]
        out.append(line)
    return header, out


def _estimate_table(estimates: list[dict[str, Any]]) -> tuple[list[str], list[list[Cell]]]:
    paper = TIMING_SECONDS["qdcnn"]["seconds"]
    rows: list[list[Cell]] = [
        ["QDCNN as printed in Table IV", cell(f"{paper:g}", "paper"), "the paper (Table IV)"]
    ]
    for e in estimates:
        rows.append([e["profile"], cell(f"{e['seconds']:.6g}", "estimate"), e["source"]])
    return ["profile", "seconds per frame (estimate)", "source"], rows
