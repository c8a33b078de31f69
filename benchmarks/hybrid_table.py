"""The hybrid table: PilotNet, the quantum-head hybrid, its twin and its ablations, per recording.

One ``qdcnn evaluate`` run per recording of ``--data-root`` (5 contiguous folds, gap 5, the
transfer recipe for the hybrids, ``--paired``): 3 seeds on the two small recordings (the
mountain track and the real sample), one on the two large ones. Each run's JSON lines go to
``--out`` without the per-frame predictions, plus what the predictions say per fold (the
share of the most frequent answer, for the collapse check) and the run's wall and CPU time.
``--table`` prints README's tables from those files without recomputing anything::

    python benchmarks/hybrid_table.py --data-root ../shared/data --cache ~/.cache/hybrid-table
    python benchmarks/hybrid_table.py --table
    python benchmarks/hybrid_table.py --standardise-frames --out docs/results/hybrid-standardised

Results go to ``--cache`` (default: qdcnn's own, ``$QDCNN_CACHE`` or
``~/.cache/qdcnn``; kept per method, fold, seed and recording), so a stopped run
resumes where it stopped, and its times are then those of the resumed part.
"""

from __future__ import annotations

import argparse
import json
import subprocess
from pathlib import Path
from typing import Any

import numpy as np

from cross_recording import _record, lighten, read, run_one
from qdcnn.data.splits import ContiguousKFold
from qdcnn.direction.features import cache_dir
from qdcnn.direction.scores import collapsed, format_metric, one_answer_share
from readme_tables import markdown_table

HYBRID = "qdcnn-head"
ABLATIONS = [f"{HYBRID}-noent", f"{HYBRID}-fixed", f"{HYBRID}-linear"]
#: Recording -> (label suffix, seeds, methods; ``--head both`` adds the hybrid's twin). The
#: real sample's threshold, 0.029 rad, is the 33rd percentile of |smoothed steering| over
#: the whole recording (at its unit's default, 889 of 1,000 frames are "straight"; a
#: percentile spec is refused inside one recording, where the training frames differ by
#: fold). Its steering is positive to the left (``left=positive``; the runs kept in
#: docs/results before 5cc9212 took it the other way, which within one recording only
#: swaps the names left and right). The ablations are left out on the 6,180-frame dark
#: mountain track for time (one ablation costs about 440 s of training per seed on the
#: 5,113-frame lake track).
RECORDINGS: dict[str, tuple[str, int, list[str]]] = {
    "udacity-mountain-track": ("", 3, ["dnn-pilotnet", HYBRID, *ABLATIONS]),
    "real-dashcam-sample": (
        "@unit=rad,threshold=0.029,left=positive",
        3,
        ["dnn-pilotnet", HYBRID, *ABLATIONS],
    ),
    "udacity-lake-track": ("", 1, ["dnn-pilotnet", HYBRID, *ABLATIONS]),
    "udacity-dark-mountain-track": ("", 1, ["dnn-pilotnet", HYBRID]),
}
FOLDS, GAP = 5, 5


def fold_shares(item: dict[str, Any]) -> list[dict[str, Any]]:
    """Per seed and fold: the share of the most frequent answer and whether it collapsed."""
    truth = np.asarray(item["test_labels"])
    out = []
    if (item.get("folds"), item.get("gap")) != (FOLDS, GAP):
        raise SystemExit(f"{item['method']}: not {FOLDS} contiguous folds with gap {GAP}")
    splits = list(ContiguousKFold(FOLDS, gap=GAP).split(np.arange(truth.size)))
    for seed, predictions in zip(item["seeds"], item["predictions"], strict=True):
        answers = np.asarray(predictions)
        for fold, (_, test) in enumerate(splits):
            top, mixed = one_answer_share(truth[test], answers[test])
            out.append(
                {
                    "seed": seed,
                    "fold": fold + 1,
                    "top_share": round(top, 3),
                    "mixed": mixed,
                    "collapsed": collapsed(truth[test], answers[test]),
                }
            )
    return out


def with_fold_shares(item: dict[str, Any]) -> dict[str, Any]:
    """A result without its per-frame lists, with :func:`fold_shares` in their place."""
    if "predictions" in item:
        item = {**item, "folds_checked": fold_shares(item)}
    return lighten(item)


def measure(args: argparse.Namespace) -> None:
    """Run each chosen recording's evaluation; keep its light lines and its times."""
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.recordings.split(","):
        suffix, seeds, methods = RECORDINGS[name]
        spec = f"udacity:{args.data_root / name}{suffix}"
        common = [
            "--method",
            ",".join(methods),
            "--head",
            "both",
            "--transfer",
            "--seeds",
            str(seeds),
            "--threads",
            str(args.threads),
            *(["--balanced"] if args.balanced else []),
            *(["--standardise-frames"] if args.standardise_frames else []),
        ]
        wall, cpu = run_one(name, ["--data", spec], args.out, args.cache, common, with_fold_shares)
        # stage 1 is dnn-pilotnet's run: the hybrid's seconds count stages 2 and 3 only
        _record(
            args.out / "timing.json",
            name,
            methods,
            args.threads,
            None,
            wall,
            cpu,
            commit=_commit(),
            stage1="dnn-pilotnet",
            balanced=args.balanced,
            standardised=args.standardise_frames,
        )


def _commit() -> str | None:
    done = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
    )
    return done.stdout.strip() or None


def adopt(args: argparse.Namespace) -> None:
    """Keep runs made outside this script with the same evaluate arguments: for each name,
    ``DIR/NAME.jsonl`` (``qdcnn evaluate --json``, predictions included) and ``DIR/NAME.err``
    (its stderr, ending with ``/usr/bin/time -v``'s report and a ``wall=SECONDS`` line)."""
    args.out.mkdir(parents=True, exist_ok=True)
    for pair in args.adopt.split(","):
        name, short = pair.split("=")
        source = args.adopt_dir / f"{short}.jsonl"
        lines = [json.loads(x) for x in source.read_text(encoding="utf-8").splitlines() if x]
        text = "".join(json.dumps(with_fold_shares(item)) + "\n" for item in lines)
        (args.out / f"{name}.jsonl").write_text(text, encoding="utf-8")
        log = (args.adopt_dir / f"{short}.err").read_text(encoding="utf-8")
        cpu = sum(float(_after(log, f"{k} time (seconds): ")) for k in ("User", "System"))
        wall = float(_after(log, "wall="))
        methods = RECORDINGS[name][2]
        _record(args.out / "timing.json", name, methods, args.threads, None, wall, cpu, False)


def _after(text: str, marker: str) -> str:
    if marker not in text:
        raise SystemExit(f"--adopt: no {marker!r} in the run's log")
    return text.split(marker)[-1].split()[0]


def _seconds(results: list[dict[str, Any]], method: str) -> float:
    return next(r["seconds"] for r in results if r["method"] == method)


def tables(out: Path) -> None:
    """README's tables from the kept files."""
    timing = json.loads((out / "timing.json").read_text(encoding="utf-8"))
    names = [n for n in RECORDINGS if n in timing]
    runs = {n: read(out / f"{n}.jsonl") for n in names}
    methods = list(dict.fromkeys(r["method"] for n in names for r in runs[n][0]))
    cells = {
        (r["method"], n): format_metric(r, "balanced_accuracy") for n in names for r in runs[n][0]
    }
    rows = [[m, *(cells.get((m, n), "") for n in names)] for m in methods]
    major = {n: runs[n][0][0]["majority"]["balanced_accuracy"] for n in names}
    rows.append(["majority class of the training folds", *(f"{major[n]:.2f}" for n in names)])
    header = ["balanced accuracy [95 %]", *(_column(n, timing[n]) for n in names)]
    print(markdown_table(header, rows))
    pairs = list(dict.fromkeys((c["a"], c["b"]) for n in names for c in runs[n][1]))
    diff = {(c["a"], c["b"], n): c["text"] for n in names for c in runs[n][1]}
    print()
    print(
        markdown_table(
            ["paired difference", *names],
            [[f"{a} - {b}", *(diff.get((a, b, n), "") for n in names)] for a, b in pairs],
        )
    )
    print()
    print(collapse_table(runs, names, methods))
    print()
    print(time_table(runs, names, timing))


def _column(name: str, timing: dict[str, Any]) -> str:
    """A recording's column: its seeds, and whether the run had ``--balanced`` or
    ``--standardise-frames``."""
    flags = "".join(f", --{f}" for f in ("balanced", "standardise-frames") if _had(timing, f))
    return f"{name} ({RECORDINGS[name][1]} seed(s){flags})"


def _had(timing: dict[str, Any], flag: str) -> bool:
    return bool(timing.get("standardised" if flag == "standardise-frames" else flag))


def collapse_table(runs: dict[str, Any], names: list[str], methods: list[str]) -> str:
    """Per method and recording: collapsed folds / checked folds, and the largest share."""
    rows = []
    for m in methods:
        row = [m]
        for n in names:
            item = next((r for r in runs[n][0] if r["method"] == m), None)
            checks = [] if item is None else item.get("folds_checked", [])
            mixed = [c for c in checks if c["mixed"]]
            top = max((c["top_share"] for c in mixed), default=float("nan"))
            bad = sum(c["collapsed"] for c in mixed)
            text = f"{bad} of {len(mixed)} (largest share {top:.2f})" if mixed else "no mixed fold"
            row.append(text if checks else "")
        rows.append(row)
    return markdown_table(["collapsed (seed, fold) pairs", *names], rows)


def time_table(runs: dict[str, Any], names: list[str], timing: dict[str, Any]) -> str:
    """Training seconds of PilotNet and of the whole transfer recipe, their ratio, the
    twin's, and each run's wall and CPU time. Where stage 1 is ``dnn-pilotnet``'s own run
    the recipe is PilotNet's seconds plus the hybrid's (stages 2 and 3); in runs made
    before that, the hybrid's seconds include its own stage 1. "balanced": the run had
    ``--balanced``."""
    rows = []
    for n in names:
        results, t = runs[n][0], timing[n]
        pilot, hybrid = _seconds(results, "dnn-pilotnet"), _seconds(results, HYBRID)
        twin = _seconds(results, f"{HYBRID}-classical")
        shared = t.get("stage1") == "dnn-pilotnet"
        recipe = pilot + hybrid if shared else hybrid
        stage1 = "PilotNet's run" if shared else "its own"
        rows.append(
            [
                n,
                t.get("commit", "not recorded"),
                f"{stage1}, balanced" if t.get("balanced") else stage1,
                f"{pilot:.0f}",
                f"{recipe:.0f}",
                f"{recipe / pilot:.2f}",
                f"{twin:.0f}",
                f"{t['wall_seconds']:.0f} / {t['cpu_seconds']:.0f}",
            ]
        )
    header = [
        "recording",
        "commit",
        "stage 1",
        "PilotNet s",
        "transfer recipe s",
        "ratio",
        "twin s (stages 2-3)",
        "run wall / CPU s",
    ]
    return markdown_table(header, rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data-root", type=Path, default=Path("../shared/data"))
    parser.add_argument("--out", type=Path, default=Path("docs/results/hybrid"))
    parser.add_argument("--cache", type=Path, default=cache_dir(), help="default: qdcnn's cache")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--recordings", default=",".join(RECORDINGS))
    parser.add_argument("--table", action="store_true", help="only print the tables")
    parser.add_argument(
        "--balanced", action="store_true", help="PilotNet (and stage 1) trained with --balanced"
    )
    parser.add_argument(
        "--standardise-frames",
        action="store_true",
        help="PilotNet and the qdcnn-head networks put each frame on its own scale first",
    )
    parser.add_argument("--adopt", help="NAME=SHORT,...: keep runs made outside (see adopt)")
    parser.add_argument("--adopt-dir", type=Path, default=Path("."))
    args = parser.parse_args()
    if args.standardise_frames and args.out.resolve() == Path("docs/results/hybrid").resolve():
        parser.error("--standardise-frames: give --out (not README's docs/results/hybrid)")
    if args.adopt:
        adopt(args)
    elif not args.table:
        measure(args)
    tables(args.out)


if __name__ == "__main__":
    main()
