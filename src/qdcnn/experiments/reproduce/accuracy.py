"""Tables I, II and III: direction accuracy per method per dataset, next to the paper's.

Every method of the registry (:mod:`qdcnn.direction.methods`) gets a row, so methods
registered later (hybrids) appear without changes here: lane methods always, frame
methods (CNNs) when the run asks for them. Each is scored by the one protocol of
:mod:`qdcnn.direction.protocol` through :func:`~qdcnn.experiments.evaluate.evaluate_features`
and :func:`~qdcnn.experiments.evaluate.evaluate_frames`, with the paper's pipeline and,
for the profile's classifier kinds, with the named options.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from qdcnn._optional import has_gpu, has_torch
from qdcnn.config import PipelineConfig
from qdcnn.data.labels import class_balance
from qdcnn.direction.lane_data import LaneData
from qdcnn.direction.methods import (
    DirectionMethod,
    TrainingOptions,
    get_method,
    method_names,
    select_methods,
)
from qdcnn.direction.protocol import ContiguousKFold
from qdcnn.errors import QdcnnError
from qdcnn.experiments.evaluate import evaluate_features, evaluate_frames
from qdcnn.experiments.reproduce.context import DatasetUnavailable, RunContext
from qdcnn.experiments.reproduce.model import Cell, Section, cell
from qdcnn.experiments.reproduce.paper_values import COMPARISON, TEXT_DISAGREES, paper_accuracy
from qdcnn.experiments.reproduce.spec import PAPER_CNNS, DatasetEntry

__all__ = [
    "MAJORITY_NOTE",
    "PROTOCOL",
    "accuracy_section",
    "comparison_section",
    "majority_text",
    "result_text",
]

#: The evaluation protocol of every accuracy (``qdcnn evaluate``'s defaults).
PROTOCOL: dict[str, int] = {"folds": 5, "gap": 5, "inner_folds": 3}


def frame_methods(ctx: RunContext) -> tuple[list[DirectionMethod], list[str]]:
    """The frame methods (CNNs) this run evaluates, and notes on those it leaves out."""
    names = method_names(inputs="frames")
    if not names:
        return [], []
    wanted = ctx.spec.cnn if ctx.spec.cnn is not None else has_torch() and not ctx.spec.quick
    if not wanted:
        if ctx.spec.cnn is False:
            why = "--no-cnn"
        elif not has_torch():
            why = "torch is not installed (pip install 'qdcnn[dnn]')"
        else:
            why = "--quick (ask for them with --cnn)"
        return [], [f"frame methods ({', '.join(names)}) not run: {why}"]
    chosen = ctx.spec.cnn_methods
    methods, notes = select_methods(
        "all" if chosen in ("paper", "all") else chosen, has_torch=has_torch(), has_gpu=has_gpu()
    )
    # the report's frame methods are the networks (Fig. 5 draws their training histories)
    frames = [m for m in methods if m.inputs == "frames" and m.kind != "logreg"]
    if chosen == "paper":
        left = [m.name for m in frames if m.name not in PAPER_CNNS]
        frames = [m for m in frames if m.name in PAPER_CNNS]
        notes = [n for n in notes if any(p in n for p in PAPER_CNNS)]
        if left:
            notes.append(f"hybrid methods ({', '.join(left)}) not run: ask with --cnn-methods all")
    return frames, notes


def _recording_method(method: DirectionMethod, sink: list[list[dict[str, Any]]]) -> DirectionMethod:
    """``method`` whose estimators append their per-epoch ``history_`` to ``sink`` when fitted.

    :func:`~qdcnn.experiments.evaluate.evaluate_frames` keeps no training histories; this
    subclass of the method's own estimator class records them (Fig. 5) and changes nothing
    else: same parameters, same fit.
    """

    def build(config: PipelineConfig, options: TrainingOptions) -> Any:
        estimator, grid = method.build(config, options)
        base = type(estimator)

        class Recording(base):  # type: ignore[misc, valid-type]
            def fit(self, X: Any, y: Any, *args: Any, **kwargs: Any) -> Any:
                fitted = super().fit(X, y, *args, **kwargs)
                sink.append([dict(r) for r in getattr(self, "history_", [])])
                return fitted

        Recording.__name__ = Recording.__qualname__ = base.__name__
        return Recording(**estimator.get_params(deep=False)), grid

    return replace(method, build=build)


def _lane_result(
    ctx: RunContext, method: DirectionMethod, lanes: LaneData, mode: str
) -> dict[str, Any]:
    assert method.grouping is not None
    res = evaluate_features(
        method,
        lanes.frames.name,
        lanes.features(method.grouping),
        lanes.y,
        config=ctx.configs[mode],
        frames_without_lines=lanes.table.frames_without_lines(method.grouping),
        folds=PROTOCOL["folds"],
        gap=PROTOCOL["gap"],
        inner_folds=PROTOCOL["inner_folds"],
    )
    res.extra["pipeline_ms_per_frame"] = 1e3 * lanes.table.seconds_per_frame
    return res.to_dict()


def _named_methods(ctx: RunContext, lane: list[DirectionMethod]) -> list[DirectionMethod]:
    kinds = ctx.profile.named_kinds
    return [m for m in lane if kinds is None or m.kind in kinds]


def _evaluate_dataset(
    ctx: RunContext,
    section: Section,
    entry: DatasetEntry,
    lane: list[DirectionMethod],
    frames_methods: list[DirectionMethod],
) -> dict[str, Any]:
    """Every method's result on one dataset; a method that fails gets its error."""
    lanes = ctx.lane_data(entry, "paper")
    _check_protocol(entry, lanes)
    out: dict[str, Any] = {
        **entry.to_dict(),
        "name": lanes.frames.name,
        "n": int(lanes.y.size),
        "class_balance": class_balance(lanes.y),
        "unreadable_frames": len(lanes.table.failures),
        "results": {"paper": {}, "named": {}},
        "errors": {"paper": {}, "named": {}},
        "cnn_history": {},
    }
    for f in lanes.failures:
        ctx.reporter.failure(f)

    def run(mode: str, method: DirectionMethod, compute: Any) -> None:
        try:
            result = compute()
        except QdcnnError as exc:
            out["errors"][mode][method.name] = str(exc)
            section.error(f"{entry.title} ({lanes.frames.name}), {method.name}: {exc}")
            return
        out["results"][mode][method.name] = result
        ctx.reporter.result(
            {"section": section.id, "dataset": entry.key, "mode": mode}
            | {k: result[k] for k in ("method", "accuracy", "accuracy_std", "majority_baseline")}
            | {"seconds": result["seconds"]}
        )

    named = _named_methods(ctx, lane)
    total = len(lane) + len(named) + len(frames_methods)
    what = f"{section.id} methods, {entry.key} ({lanes.frames.name})"
    with ctx.reporter.progress(total, what) as step:
        for m in lane:
            run("paper", m, lambda m=m: _lane_result(ctx, m, lanes, "paper"))
            step()
        if named:
            try:
                named_lanes = ctx.lane_data(entry, "named")
            except DatasetUnavailable as exc:
                section.error(f"named options: {exc}")
            else:
                for m in named:
                    run("named", m, lambda m=m: _lane_result(ctx, m, named_lanes, "named"))
                    step()
        for m in frames_methods:
            run("paper", m, lambda m=m: _frame_result(ctx, m, entry, out))
            step()
    majorities = [r["majority_baseline"] for r in out["results"]["paper"].values()]
    out["majority_baseline"] = majorities[0] if majorities else None
    return out


def _check_protocol(entry: DatasetEntry, lanes: LaneData) -> None:
    """One error for the dataset when the protocol's folds cannot score it (not one per method)."""
    cv = ContiguousKFold(PROTOCOL["folds"], PROTOCOL["gap"])
    try:
        cv.check(int(lanes.y.size))
    except QdcnnError as exc:
        raise DatasetUnavailable(entry, f"cannot be scored: {exc}") from None


def _frame_result(
    ctx: RunContext, method: DirectionMethod, entry: DatasetEntry, out: dict[str, Any]
) -> dict[str, Any]:
    frames = ctx.frames(entry)
    cfg = ctx.configs["paper"]
    sink: list[list[dict[str, Any]]] = []
    options = TrainingOptions(epochs=ctx.spec.epochs, threads=ctx.spec.threads)
    networks = method.kind != "logreg"  # Fig. 5 draws the networks' epochs, not the references
    res, failures = evaluate_frames(
        _recording_method(method, sink) if networks else method,
        frames,
        frames.labels(cfg.labels),
        config=cfg,
        options=options,
        folds=PROTOCOL["folds"],
        gap=PROTOCOL["gap"],
    )
    for f in failures:
        ctx.reporter.failure(f)
    if networks:
        out["cnn_history"][method.name] = sink
    return res.to_dict()


def accuracy_section(ctx: RunContext, section: Section, labels: tuple[str, ...]) -> None:
    """Table I (``labels`` track1, track2) or Table III (carla)."""
    entries = [e for e in ctx.datasets if e.label in labels]
    if not entries:
        section.status = "skipped"
        section.note(
            f"no dataset labelled {' or '.join(labels)}: give one with --data {labels[0]}=KIND:PATH"
        )
        return
    lane = [get_method(n) for n in method_names(inputs="lanes")]
    frames_methods, notes = frame_methods(ctx)
    frames_methods = _references() + frames_methods
    for n in notes:
        section.note(n)
    results: dict[str, Any] = {}
    for entry in entries:
        try:
            results[entry.key] = _evaluate_dataset(ctx, section, entry, lane, frames_methods)
        except DatasetUnavailable as exc:
            section.error(str(exc))
            results[entry.key] = {**entry.to_dict(), "error": exc.reason}
    methods = [m.name for m in lane + frames_methods]
    section.data = {"protocol": PROTOCOL, "methods": methods, "datasets": results}
    section.data["configs"] = {mode: cfg.to_dict() for mode, cfg in ctx.configs.items()}
    if all("error" in r for r in results.values()):
        section.status = "failed"
        return
    _describe(ctx, section)
    for e in entries:  # one table per dataset, as the paper's Table I lists Track 1 then 2
        if "error" not in results[e.key]:
            r = results[e.key]
            section.table(
                *_accuracy_table([e], results, lane + frames_methods),
                caption=f"{e.title}: {r['name']} ({r['n']} frames scored)",
            )
    section.text(MAJORITY_NOTE)
    section.table(*_fold_table(entries, results), caption="per-fold accuracy", collapsed=True)
    from qdcnn.experiments.reproduce.plots import accuracy_bars

    name = section.id
    section.figure(
        ctx.save_figure(accuracy_bars(entries, results, methods), name),
        "Measured accuracy per method (bars: mean over folds, error bars: fold standard "
        "deviation; paper pipeline and named options), the paper's value (black diamond) "
        "and the majority class of the training folds (dashed).",
        alt=f"{section.title} bar chart",
    )
    _disagreements(section, labels)


def _references() -> list[DirectionMethod]:
    """The non-deep frame references (HOG + logistic regression): in every table, torch or not."""
    return [get_method(n) for n in method_names(inputs="frames") if get_method(n).kind == "logreg"]


def _describe(ctx: RunContext, section: Section) -> None:
    kinds = ctx.profile.named_kinds
    which = "every lane method" if kinds is None else "the " + "/".join(kinds) + " methods"
    section.text(
        f"{PROTOCOL['folds']} contiguous folds with a {PROTOCOL['gap']}-frame gap on each side "
        "of each test block; hyperparameters chosen by an inner contiguous CV on the training "
        "folds only. Each cell: balanced accuracy (mean per-class recall, the main figure; "
        "best in bold), then accuracy, both pooled over all test frames with a 95 % interval "
        "from a block bootstrap over contiguous blocks of test frames (per-fold accuracies in "
        "the collapsed table). The paper's figures are accuracies. "
        "*paper pipeline*: the paper's settings (UU† shadow removal, grey Canny, the two "
        "slopes). *named options* (not the paper's, shown for "
        f"{which}): `--features road-centre --edges rgb --no-shadow-removal`. Labels from "
        "steering smoothed over ±5 frames, left / straight / right at 0.05."
    )


def result_text(result: dict[str, Any] | None) -> str:
    """Balanced accuracy first (the main figure), then accuracy, each with its interval."""
    if result is None:
        return "—"
    from qdcnn.direction.scores import format_metric

    ba, acc = format_metric(result, "balanced_accuracy"), format_metric(result, "accuracy")
    return f"{ba}; acc {acc}"


def _rank(result: dict[str, Any]) -> float:
    """What "best" means in the tables: balanced accuracy (accuracy where it is undefined)."""
    value = result.get("balanced_accuracy")
    return float(result["accuracy"] if value is None else value)


def _accuracy_table(
    entries: list[DatasetEntry],
    results: dict[str, Any],
    methods: list[DirectionMethod],
) -> tuple[list[str], list[list[Cell]]]:
    header = ["method"]
    for e in entries:
        header += [f"paper, {e.title}", "measured: paper pipeline", "measured: named options"]
    best = {
        e.key: max(
            (_rank(r) for mode in ("paper", "named") for r in _modes(results[e.key], mode)),
            default=None,
        )
        for e in entries
    }
    rows: list[list[Cell]] = []
    for m in methods:
        row: list[Cell] = [cell(m.name, "method")]
        for e in entries:
            r = results[e.key]
            paper = paper_accuracy(e.label, m.name)
            row.append(cell("" if paper is None else f"{paper:.2f}", "paper"))
            if "error" in r:
                row += [cell("dataset failed", "na"), cell("", "na")]
                continue
            for mode in ("paper", "named"):
                res = r["results"][mode].get(m.name)
                err = r["errors"][mode].get(m.name)
                text = "failed" if err else result_text(res)
                is_best = res is not None and _rank(res) == best[e.key]
                row.append(cell(text, "best" if is_best else "measured" if res else "na"))
        rows.append(row)
    rows += _summary_rows(entries, results)
    return header, rows


def _modes(r: dict[str, Any], mode: str) -> list[dict[str, Any]]:
    return list(r.get("results", {}).get(mode, {}).values())


def _summary_rows(entries: list[DatasetEntry], results: dict[str, Any]) -> list[list[Cell]]:
    rows: list[list[Cell]] = []
    specs = (
        ("majority class of the training folds", majority_text),
        ("chance", lambda r: "0.33; acc —"),
        (
            "class balance (left / straight / right)",
            lambda r: " / ".join(str(v) for v in r["class_balance"].values()),
        ),
        ("frames scored", lambda r: str(r["n"])),
    )
    for title, fmt in specs:
        row: list[Cell] = [cell(title, "method")]
        for e in entries:
            r = results[e.key]
            ok = "error" not in r and r.get("majority_baseline") is not None
            row += ["", cell(fmt(r) if ok else "—", "measured"), ""]
        rows.append(row)
    return rows


def majority_text(r: dict[str, Any]) -> str:
    """The majority row's cell: its balanced accuracy and accuracy over the pooled test frames."""
    from qdcnn.direction.scores import format_metric

    first: dict[str, Any] = next(iter(r["results"]["paper"].values()), {})
    ba = format_metric(first.get("majority", {}), "balanced_accuracy")
    return f"{ba}; acc {r['majority_baseline']:.2f}"


#: One line under each accuracy table: what the majority row is and why it can be low.
MAJORITY_NOTE = (
    "Baselines: *majority class of the training folds* predicts, for every frame of a test "
    "block, the class most frequent in that fold's training frames. Contiguous folds cut a "
    "drive into stretches, so that class can be rare in the test stretch (a stretch of turns "
    "after a mostly straight drive): its accuracy can then fall below chance, while its "
    "balanced accuracy stays near 1/3. *chance*: balanced accuracy 1/3 (three classes)."
)


def _fold_table(
    entries: list[DatasetEntry], results: dict[str, Any]
) -> tuple[list[str], list[list[Cell]]]:
    rows: list[list[Cell]] = []
    n_folds = PROTOCOL["folds"]
    for e in entries:
        r = results[e.key]
        for mode in ("paper", "named"):
            for method, res in r.get("results", {}).get(mode, {}).items():
                folds = [f"{a:.3f}" for a in res["fold_accuracies"]]
                rows.append([e.title, r["name"], mode, method, *folds])
    header = ["dataset", "name", "pipeline", "method", *(f"fold {i + 1}" for i in range(n_folds))]
    return header, rows


def _disagreements(section: Section, labels: tuple[str, ...]) -> None:
    pairs = [(k, v) for k, v in TEXT_DISAGREES.items() if k[0] in labels]
    if pairs:
        listed = "; ".join(
            f"{method} on {label}: table {paper_accuracy(label, method)}, text {value}"
            for (label, method), value in pairs
        )
        section.note(f"The paper's text and table disagree ({listed}); the table is shown.")


# ---------------------------------------------------------------- Table II


def comparison_section(ctx: RunContext, section: Section) -> None:
    """Table II: the paper's comparison, with what qdcnn measured where it can."""
    table = ctx.sections.get("table-i")
    datasets = {} if table is None else table.data.get("datasets", {})
    track1 = [d for d in datasets.values() if d.get("label") == "track1" and "error" not in d]
    section.text(
        "Table II compares the paper's UU† accuracy with other papers' methods on their own "
        "data. Those methods are not reimplemented here; the UU† row is image-split-UU† on "
        "Track 1 (the paper's 0.70 of Table I), as measured in Table I, in percent."
    )
    rows: list[list[Cell]] = []
    measured: dict[str, Any] = {}
    for item in COMPARISON:
        if item["ours"]:
            values = _ours(track1, "image-split-uu")
            measured[item["algorithm"]] = values
            text = "; ".join(f"{v['percent']:.1f} ({v['dataset']}, {v['mode']})" for v in values)
            rows.append(
                [item["algorithm"], cell(f"{item['percent']:.2f}", "paper"), cell(text or "—")]
            )
        else:
            rows.append(
                [
                    item["algorithm"],
                    cell(f"{item['percent']:.2f}", "paper"),
                    cell("not reimplemented (another paper's method and data)", "na"),
                ]
            )
    for title, values in _best_rows(track1).items():
        measured[title] = values
        text = "; ".join(f"{v['percent']:.1f} ({v['dataset']}, {v['method']})" for v in values)
        rows.append([title, cell("", "paper"), cell(text, "measured")])
    section.data = {"paper": list(COMPARISON), "measured": measured}
    if not track1:
        section.error("no Table I result on a Track 1 dataset to compare")
    section.table(["algorithm", "paper (%)", "qdcnn, measured (%)"], rows)


def _ours(track1: list[dict[str, Any]], method: str) -> list[dict[str, Any]]:
    out = []
    for d in track1:
        for mode in ("paper", "named"):
            res = d["results"][mode].get(method)
            if res is not None:
                out.append(
                    {
                        "dataset": d["name"],
                        "mode": f"{mode} pipeline" if mode == "paper" else "named options",
                        "percent": 100 * res["accuracy"],
                    }
                )
    return out


def _best_rows(track1: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """qdcnn's best quantum and best classical method on each Track 1 dataset."""
    titles = {
        True: "qdcnn: best quantum method, Track 1",
        False: "qdcnn: best classical CNN, Track 1",
    }
    rows: dict[str, list[dict[str, Any]]] = {t: [] for t in titles.values()}
    for d in track1:
        for quantum, title in titles.items():
            candidates = [
                (res["accuracy"], f"{name} ({mode})")
                for mode in ("paper", "named")
                for name, res in d["results"][mode].items()
                if _known(name) and _in_row(get_method(name), quantum)
            ]
            if candidates:
                acc, which = max(candidates)
                rows[title].append({"dataset": d["name"], "method": which, "percent": 100 * acc})
    return {k: v for k, v in rows.items() if v}


def _in_row(method: DirectionMethod, quantum: bool) -> bool:
    """Quantum methods for the quantum row; the classical row compares CNNs, so the
    non-deep references (hog-logreg, lines-logreg) stay out of it."""
    return method.quantum if quantum else method.needs_torch and not method.quantum


def _known(name: str) -> bool:
    try:
        get_method(name)
    except QdcnnError:
        return False
    return True
