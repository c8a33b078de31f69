"""Markdown tables for the README, generated from a ``qdcnn reproduce`` report.json.

README's result tables are this script's output, so they never drift from what the code
computes: run ``qdcnn reproduce ... --out DIR`` and paste (or ``--out FILE``) what

    python benchmarks/readme_tables.py DIR/report.json [--out FILE]

prints: direction accuracy next to the paper's (Tables I and III), the comparison (Table
II), measured shadow-detection times (Table IV) and the hardware-time estimates in a table
of their own, the noise sweep's range per channel (Fig. 7) and the shadow BER table. Only
numbers stored in report.json are printed; nothing is recomputed.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from qdcnn.experiments.reproduce.accuracy import MAJORITY_NOTE, majority_text, result_text

TITLES = {"track1": "Track 1", "track2": "Track 2", "carla": "CARLA"}


def _row(cells: Sequence[Any]) -> str:
    return "| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |"


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]], numeric: int = 1) -> str:
    """A GitHub Markdown table; columns from ``numeric`` on are right-aligned."""
    align = ["---" if i < numeric else "---:" for i in range(len(header))]
    return "\n".join([_row(header), _row(align), *(_row(r) for r in rows)])


def _acc(res: dict[str, Any] | None) -> str:
    return "" if res is None else result_text(res)


def accuracy_table(report: dict[str, Any], sid: str) -> str | None:
    """Table I or III: a row per method, per dataset the paper's value and both pipelines."""
    section = report["sections"].get(sid)
    if section is None or not section["data"].get("datasets"):
        return None
    data = section["data"]
    paper = report["paper_values"]["accuracy"]
    datasets = [d for d in data["datasets"].values() if "error" not in d]
    if not datasets:
        return None
    header = ["method"]
    for d in datasets:
        header += [
            f"paper, {TITLES[d['label']]}",
            f"{d['name']}: paper pipeline",
            f"{d['name']}: named options",
        ]
    rows: list[list[Any]] = []
    for method in data["methods"]:
        row: list[Any] = [method]
        for d in datasets:
            value = paper.get(d["label"], {}).get(method)
            row += [
                "" if value is None else f"{value:.2f}",
                _acc(d["results"]["paper"].get(method)) or _missing(d, "paper", method),
                _acc(d["results"]["named"].get(method)),
            ]
        rows.append(row)
    for title, fmt in (
        ("majority class of the training folds", majority_text),
        ("chance", lambda d: "0.33; acc —"),
        (
            "class balance (left / straight / right)",
            lambda d: " / ".join(str(v) for v in d["class_balance"].values()),
        ),
        ("frames", lambda d: str(d["n"])),
    ):
        row = [title]
        for d in datasets:
            row += ["", fmt(d) if d.get("majority_baseline") is not None else "", ""]
        rows.append(row)
    return markdown_table(header, rows) + "\n\n" + MAJORITY_NOTE


def _missing(d: dict[str, Any], mode: str, method: str) -> str:
    return "failed" if method in d.get("errors", {}).get(mode, {}) else "not run"


def comparison_table(report: dict[str, Any]) -> str | None:
    """Table II with what qdcnn measured (percent)."""
    section = report["sections"].get("table-ii")
    if section is None or not section["data"]:
        return None
    measured = section["data"]["measured"]
    rows = []
    for item in section["data"]["paper"]:
        values = measured.get(item["algorithm"], [])
        text = "; ".join(f"{v['percent']:.1f} ({v['dataset']}, {v['mode']})" for v in values)
        rows.append(
            [
                item["algorithm"],
                f"{item['percent']:.2f}",
                text if item["ours"] else "not reimplemented",
            ]
        )
    for title, values in measured.items():
        if title.startswith("qdcnn:"):
            text = "; ".join(f"{v['percent']:.1f} ({v['dataset']}, {v['method']})" for v in values)
            rows.append([title, "", text])
    return markdown_table(["algorithm", "paper (%)", "qdcnn, measured (%)"], rows)


def timing_tables(report: dict[str, Any]) -> str | None:
    """Table IV: measured ms per frame per size; the estimates in a separate table."""
    section = report["sections"].get("table-iv")
    if section is None or not section["data"]:
        return None
    data = section["data"]
    rows_in = data["measured"]["rows"]
    paper = data["paper"]
    names = list(rows_in[0]["seconds"])
    header = ["detector (measured, this machine)", "paper, Table IV (ms)"]
    header += [f"{r['size']}, ms / frame" for r in rows_in]
    rows = []
    for name in names:
        key = "qdcnn" if name == "uu-exact" else name
        p = paper.get(key)
        shown = (
            ""
            if p is None
            else ("estimate, below" if p["kind"] == "estimate" else f"{1e3 * p['seconds']:g}")
        )
        rows.append([name, shown, *(f"{1e3 * r['seconds'][name]:.3f}" for r in rows_in)])
    if any("aer_per_block" in r for r in rows_in):
        rows.append(
            [
                "aer-per-block (1024 shots)",
                "",
                *(
                    f"{1e3 * r['aer_per_block']['seconds_per_frame']:.1f}"
                    if "aer_per_block" in r
                    else ""
                    for r in rows_in
                ),
            ]
        )
    measured = markdown_table(header, rows, numeric=1)
    estimates = markdown_table(
        ["profile (**estimate**, not measured)", "seconds per frame"],
        [["QDCNN as printed in Table IV", f"{paper['qdcnn']['seconds']:g}"]]
        + [[e["profile"], f"{e['seconds']:.6g}"] for e in data["estimates"]["profiles"]],
    )
    return measured + "\n\n" + estimates


def noise_table(report: dict[str, Any]) -> str | None:
    """Fig. 7 in numbers: per dataset, series and channel the accuracy at p = 0 and its range."""
    section = report["sections"].get("fig-7")
    if section is None or not section["data"].get("direction"):
        return None
    rows = []
    for key, points in section["data"]["direction"].items():
        series: dict[tuple[str, str], list[tuple[float, float]]] = {}
        for r in points:
            label = f"{r['grouping']}-{r['method']}" if r.get("grouping") else r["method"]
            series.setdefault((label, r["channel"]), []).append((r["p"], r["accuracy"]))
        for (label, channel), values in series.items():
            values.sort()
            lo, hi = min(values, key=lambda t: t[1]), max(values, key=lambda t: t[1])
            rows.append(
                [
                    key,
                    label,
                    channel,
                    f"{values[0][1]:.3f}",
                    f"{lo[1]:.3f} (p={lo[0]:g})",
                    f"{hi[1]:.3f} (p={hi[0]:g})",
                ]
            )
    return markdown_table(
        ["dataset", "series", "channel", "p = 0", "lowest", "highest"], rows, numeric=3
    )


def shadow_table(report: dict[str, Any]) -> str | None:
    """Shadow detection quality on the report's shadow set (BER in percent, measured ms)."""
    section = report["sections"].get("shadows")
    if section is None or not section["data"].get("scores"):
        return None
    rows = [
        [
            name,
            f"{s['ber']:.1f}",
            f"{s['shadow_error']:.1f}",
            f"{s['nonshadow_error']:.1f}",
            f"{s['ms_per_frame']:.2f}",
        ]
        for name, s in section["data"]["scores"].items()
    ]
    return markdown_table(["detector", "BER", "shadow err.", "non-shadow err.", "ms / frame"], rows)


TABLES: tuple[tuple[str, Callable[[dict[str, Any]], str | None]], ...] = (
    ("Table I: direction accuracy, Track 1 and Track 2", lambda r: accuracy_table(r, "table-i")),
    ("Table II: comparison", comparison_table),
    ("Table III: direction accuracy, CARLA", lambda r: accuracy_table(r, "table-iii")),
    ("Table IV: shadow-detection time per frame", timing_tables),
    ("Fig. 7: accuracy against noise strength", noise_table),
    ("Shadow detection quality", shadow_table),
)


def render(report: dict[str, Any]) -> str:
    """Every table the report has numbers for, each under a heading, with its provenance."""
    spec = report["spec"]
    data = ", ".join(f"{d['label']}={d['spec']}" for d in spec["data"])
    parts = [
        f"<!-- generated by benchmarks/readme_tables.py from a qdcnn reproduce report.json "
        f"({report['created']}, profile {spec['profile']['name']}, seed {spec['seed']}, "
        f"data {data}); do not edit by hand -->"
    ]
    for title, make in TABLES:
        table = make(report)
        if table:
            parts += [f"#### {title}", table]
    return "\n\n".join(parts) + "\n"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", type=Path, help="report.json of a qdcnn reproduce run")
    parser.add_argument("--out", type=Path, help="write the Markdown here instead of stdout")
    args = parser.parse_args(argv)
    try:
        report = json.loads(args.report.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        print(f"error: {args.report}: not a readable report.json ({exc})", file=sys.stderr)
        return 2
    if report.get("kind") != "qdcnn reproduce report":
        print(f"error: {args.report}: not a qdcnn reproduce report.json", file=sys.stderr)
        return 2
    text = render(report)
    if args.out is None:
        sys.stdout.write(text)
    else:
        args.out.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
