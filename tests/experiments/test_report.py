"""``reproduce``: a tiny run renders every section; failures stay inside their section.

One tiny run (``TINY`` profile: two synthetic datasets of 120 frames, one recording that
does not exist, a toy frame method standing in for a CNN) is shared by the tests here and
by the browser test (``tiny_report``).
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from sklearn.base import BaseEstimator, ClassifierMixin

from qdcnn.config import PipelineConfig
from qdcnn.direction.methods import DirectionMethod, register, unregister
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.evaluate import EvaluationSpec, run_evaluation
from qdcnn.experiments.reproduce import (
    PAGE_ORDER,
    TINY,
    ReproduceSpec,
    Section,
    named_options_config,
    parse_data_option,
    run_reproduce,
)
from qdcnn.experiments.reproduce import runner as runner_module
from qdcnn.experiments.reproduce.figures import representative
from qdcnn.experiments.reproduce.paper_values import ACCURACY
from qdcnn.experiments.reproduce.runner import SectionDef

MISSING = "/nonexistent/qdcnn-recording"
TINY_DATA = {
    "track1": "synthetic:track1:120",
    "track2": f"udacity:{MISSING}",
    "carla": "synthetic:rain:120",
}


class MajorityWithHistory(ClassifierMixin, BaseEstimator):
    """A toy frame method: predicts the training majority; records a two-epoch history."""

    def __init__(self, epochs: int = 2) -> None:
        self.epochs = epochs

    def fit(self, X, y):
        y = np.asarray(y)
        self.majority_ = int(np.bincount(y, minlength=3).argmax())
        self.classes_ = np.arange(3)
        self.history_ = [
            {"epoch": e, "train_loss": 1.0 / e, "val_loss": 1.2 / e, "val_accuracy": 0.3 + 0.1 * e}
            for e in range(1, self.epochs + 1)
        ]
        return self

    def predict(self, X):
        return np.full(len(X), self.majority_)


TOY = DirectionMethod(
    "toy-frames",
    "frames",
    lambda config, options: (MajorityWithHistory(), {}),
    "cnn",
    summary="a toy frame method (majority class) with a training history",
)


def tiny_report(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    """The shared tiny run: its folder and ``run_reproduce``'s summary (built once)."""
    out = tmp_path_factory.getbasetemp() / "tiny-report"
    summary = out / "summary.json"
    if summary.is_file():
        return out, json.loads(summary.read_text())
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("QDCNN_CACHE", str(tmp_path_factory.getbasetemp() / "cache"))
        # the toy stands in for the CNNs, which would take minutes
        mp.setattr("qdcnn.experiments.reproduce.accuracy.has_torch", lambda: False)
        register(TOY)
        try:
            spec = ReproduceSpec(
                out / "report", TINY_DATA, cnn=True, cnn_methods="all", custom_profile=TINY
            )
            result = run_reproduce(spec)
        finally:
            unregister(TOY.name)
    data = result.to_dict() | {"exit_code": result.exit_code}
    summary.write_text(json.dumps(data))
    return out, data


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out, summary = tiny_report(tmp_path_factory)
    return out / "report", summary


def _section(folder: Path, sid: str) -> dict:
    return json.loads((folder / "sections" / f"{sid}.json").read_text())


@pytest.mark.slow
def test_every_section_renders_and_the_bad_dataset_stays_in_its_sections(tiny) -> None:
    folder, summary = tiny
    expected = {sid: "ok" for sid in PAGE_ORDER} | {"table-i": "partial", "fig-3": "partial"}
    expected |= {"fig-4": "partial", "fig-6": "partial", "fig-7": "partial"}
    assert summary["sections"] == expected
    assert summary["exit_code"] == 1
    errors = {f["file"] for f in summary["failures"]}
    assert errors == {"table-i", "fig-3", "fig-4", "fig-6", "fig-7"}
    assert all(MISSING in f["error"] for f in summary["failures"])
    page = (folder / "index.html").read_text()
    for sid in PAGE_ORDER:
        assert f'<section id="{sid}">' in page
    assert page.count(f"udacity:{MISSING}") >= 5 and "Error: Track 2" in page


@pytest.mark.slow
def test_report_json_holds_config_versions_machine_and_times_apart_from_estimates(tiny) -> None:
    folder, _ = tiny
    report = json.loads((folder / "report.json").read_text())
    assert PipelineConfig.from_dict(report["config"]["paper"]) == PipelineConfig()
    named = named_options_config(PipelineConfig())
    assert PipelineConfig.from_dict(report["config"]["named"]) == named
    assert report["versions"]["qdcnn"] and report["versions"]["numpy"]
    assert report["machine"]["cpus"] >= 1
    assert report["times"]["kind"] == "measured" and report["times"]["total_seconds"] > 0
    timing = report["sections"]["table-iv"]["data"]
    assert timing["measured"]["kind"] == "measured"
    assert {e["kind"] for e in timing["estimates"]["profiles"]} == {"estimate"}
    assert timing["paper"]["qdcnn"]["kind"] == "estimate"
    missing = next(d for d in report["datasets"] if d["label"] == "track2")
    assert "failed to load" in missing["error"]
    for sid in PAGE_ORDER:
        for figure in report["sections"][sid]["figures"]:
            png = (folder / figure).read_bytes()
            assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000


@pytest.mark.slow
def test_table_i_is_the_evaluate_runner_with_the_paper_beside_it(tiny, tmp_path, monkeypatch):
    folder, _ = tiny
    section = _section(folder, "table-i")
    track1 = section["data"]["datasets"]["track1"]
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path))
    direct = run_evaluation(
        EvaluationSpec("synthetic:track1:120", methods="image-split-uu,kmeans-vqc")
    )
    for res in direct.results:
        mine = track1["results"]["paper"][res.method]
        assert mine["accuracy"] == res.accuracy and mine["fold_accuracies"] == res.fold_accuracies
    assert set(track1["results"]["named"]) == {"image-split-uu", "kmeans-uu", "spectral-uu"}
    assert sum(track1["class_balance"].values()) == track1["n"] == 120
    table = next(b for b in section["blocks"] if b["kind"] == "table")
    row = next(r for r in table["rows"] if r[0]["text"] == "image-split-uu")
    assert row[1] == {"text": f"{ACCURACY['track1']['image-split-uu']:.2f}", "cls": "paper"}
    assert "toy-frames" in section["data"]["methods"]  # registered methods appear by themselves
    assert any("dnn-pilotnet" in n for n in section["notes"])  # and what was left out says why


@pytest.mark.slow
def test_fig5_draws_the_frame_methods_histories_and_table_ii_reads_table_i(tiny) -> None:
    folder, _ = tiny
    fig5 = _section(folder, "fig-5")
    assert [len(c["folds"]) for c in fig5["data"]["curves"]] == [5, 5]  # track1 and carla
    assert fig5["data"]["curves"][0]["folds"][0][1]["val_accuracy"] == pytest.approx(0.5)
    table_ii = _section(folder, "table-ii")
    ours = table_ii["data"]["measured"]["UU\u2020 (the paper's)"]
    table_i = _section(folder, "table-i")["data"]["datasets"]["track1"]["results"]
    assert ours[0]["percent"] == pytest.approx(100 * table_i["paper"]["image-split-uu"]["accuracy"])
    fig2 = _section(folder, "fig-2")
    assert (
        fig2["data"]["vqc"]["weights"]
        == (_section(folder, "fig-6")["data"]["fits"]["track1"]["image-split-vqc"]["weights"])
    )
    assert sum(fig2["data"]["vqc"]["probabilities"]) == pytest.approx(1.0)


@pytest.mark.slow
def test_resume_keeps_finished_sections_and_other_settings_are_refused(tiny, tmp_path) -> None:
    shared, summary = tiny
    folder = tmp_path / "copy"
    shutil.copytree(shared, folder)  # the shared report stays as it is for the other tests
    before = {sid: _section(folder, sid)["seconds"] for sid in PAGE_ORDER}
    spec = ReproduceSpec(
        folder, TINY_DATA, cnn=True, cnn_methods="all", custom_profile=TINY, resume=True
    )
    kept = [sid for sid, status in summary["sections"].items() if status in ("ok", "skipped")]
    calls: list[str] = []

    def compute(d: SectionDef, ctx: object) -> Section:
        calls.append(d.id)
        return Section(d.id, d.title, "skipped")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(runner_module, "_compute", compute)
        result = run_reproduce(spec)
    assert sorted(result.reused) == sorted(kept)
    assert sorted(calls) == sorted(set(PAGE_ORDER) - set(kept))  # partial ones run again
    assert all(_section(folder, sid)["seconds"] == before[sid] for sid in kept)
    with pytest.raises(ParameterError, match="holds another run: use --force"):
        run_reproduce(replace(spec, seed=1))
    with pytest.raises(InputError, match="use --force to overwrite it or --resume"):
        run_reproduce(replace(spec, resume=False))


@pytest.mark.slow
def test_readme_tables_print_the_reports_numbers(tiny, tmp_path) -> None:
    folder, _ = tiny
    script = Path(__file__).resolve().parents[2] / "benchmarks" / "readme_tables.py"
    run = subprocess.run(
        [sys.executable, str(script), str(folder / "report.json")], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr
    res = _section(folder, "table-i")["data"]["datasets"]["track1"]["results"]["paper"]
    acc = res["image-split-uu"]
    ba, ci = acc["balanced_accuracy"], acc["balanced_accuracy_ci"]
    cell = f"{ba:.2f} [{ci['low']:.2f}, {ci['high']:.2f}]; acc {acc['accuracy']:.2f} ["
    assert f"| image-split-uu | 0.70 | {cell}" in run.stdout
    assert "its accuracy can then fall below chance" in run.stdout
    for heading in ("Table I", "Table II", "Table III", "Table IV", "Fig. 7", "Shadow"):
        assert f"#### {heading}" in run.stdout
    assert "| profile (**estimate**, not measured) | seconds per frame |" in run.stdout
    bad = tmp_path / "x.json"
    bad.write_text("{}")
    run = subprocess.run([sys.executable, str(script), str(bad)], capture_output=True, text=True)
    assert run.returncode == 2 and "not a qdcnn reproduce report.json" in run.stderr


def _one_section(monkeypatch: pytest.MonkeyPatch, *defs: SectionDef) -> None:
    monkeypatch.setattr(runner_module, "SECTIONS", defs)
    monkeypatch.setattr(runner_module, "PAGE_ORDER", tuple(d.id for d in defs))


def _draws(ctx, section: Section) -> None:
    section.text("drawn")
    section.table(["a"], [["1"]])


def _raises(ctx, section: Section) -> None:
    raise RuntimeError("boom")


def test_a_section_that_raises_is_reported_inside_it(tmp_path, monkeypatch) -> None:
    _one_section(
        monkeypatch,
        SectionDef("fig-2", "Fig. 2: x", _raises),
        SectionDef("fig-3", "Fig. 3: y", _draws),
    )
    result = run_reproduce(ReproduceSpec(tmp_path / "r", custom_profile=TINY))
    assert [(s.id, s.status) for s in result.sections] == [("fig-2", "failed"), ("fig-3", "ok")]
    assert result.sections[0].errors == ["RuntimeError: boom"] and result.exit_code == 1
    page = (tmp_path / "r" / "index.html").read_text()
    assert "Error: RuntimeError: boom" in page and "<td>1</td>" in page


def test_force_removes_the_report_files_only(tmp_path, monkeypatch) -> None:
    _one_section(monkeypatch, SectionDef("fig-3", "Fig. 3: y", _draws))
    out = tmp_path / "r"
    (out / "figures").mkdir(parents=True)
    (out / "figures" / "stale.png").write_bytes(b"x")
    (out / "mine.txt").write_text("keep")
    with pytest.raises(InputError, match="folder exists and is not empty"):
        run_reproduce(ReproduceSpec(out, custom_profile=TINY))
    run_reproduce(ReproduceSpec(out, custom_profile=TINY, force=True))
    assert not (out / "figures" / "stale.png").exists() and (out / "mine.txt").read_text() == "keep"
    assert (out / "index.html").is_file() and (out / "sections" / "fig-3.json").is_file()
    with pytest.raises(InputError, match="holds no reproduce run to resume"):
        (out / "sections" / "run.json").unlink()
        run_reproduce(ReproduceSpec(out, custom_profile=TINY, resume=True))


def test_a_label_outside_the_paper_is_an_error() -> None:
    with pytest.raises(ParameterError, match="data label='track3' is invalid: one of track1"):
        parse_data_option("track3=udacity:x")
    with pytest.raises(ParameterError, match="LABEL=SPEC"):
        parse_data_option("udacity:x")
    with pytest.raises(ParameterError, match="data label='lake'"):
        ReproduceSpec("out", {"lake": "udacity:x"})
    with pytest.raises(ParameterError, match="data='video:x' is invalid"):
        parse_data_option("track1=video:x")


def test_a_label_may_hold_several_datasets_in_the_paper_order() -> None:
    spec = ReproduceSpec(
        "out",
        [
            parse_data_option(t)
            for t in ("carla=carla:c", "track2=udacity:a", "track2=udacity:b", "track1=udacity:l")
        ],
    )
    assert [(e.key, e.spec) for e in spec.datasets()] == [
        ("track1", "udacity:l"),
        ("track2", "udacity:a"),
        ("track2-2", "udacity:b"),
        ("carla", "carla:c"),
    ]
    synthetic = ReproduceSpec("out", quick=True).datasets()
    assert [e.spec for e in synthetic] == [
        "synthetic:track1:300",
        "synthetic:track2:300",
        "synthetic:rain:300",
    ]


def test_representative_frame_is_the_middle_of_the_longest_run() -> None:
    labels = np.array([0, 0, 1, 1, 1, 1, 1, 0, 2, 2, 1])
    assert [representative(labels, c) for c in (0, 1, 2)] == [0, 4, 8]
    assert representative(np.array([1, 1]), 0) is None


@pytest.mark.parametrize(
    ("chosen", "runs", "note"),
    [
        ("paper", ["dnn-pilotnet"], "hybrid methods (qdcnn-head, qdcnn-head-classical"),
        ("all", ["dnn-pilotnet", "qdcnn-head", "qdcnn-quanv-classical"], "skipping dnn-resnet50"),
        ("qdcnn-head,qdcnn-head-classical", ["qdcnn-head", "qdcnn-head-classical"], None),
    ],
)
def test_cnn_methods_choose_the_frame_methods(chosen, runs, note, monkeypatch, tmp_path) -> None:
    from types import SimpleNamespace

    from qdcnn.experiments.reproduce import accuracy

    monkeypatch.setattr(accuracy, "has_torch", lambda: True)
    monkeypatch.setattr(accuracy, "has_gpu", lambda: False)
    ctx = SimpleNamespace(spec=ReproduceSpec(tmp_path, cnn=True, cnn_methods=chosen))
    methods, notes = accuracy.frame_methods(ctx)  # type: ignore[arg-type]
    names = [m.name for m in methods]
    assert set(runs) <= set(names) and "dnn-resnet50" not in names
    if chosen == "paper":
        assert names == ["dnn-pilotnet"]
    if note is not None:
        assert any(n.startswith(note) for n in notes), notes


def test_cnn_methods_refuse_lane_methods_and_unknown_names(tmp_path) -> None:
    with pytest.raises(ParameterError, match="image-split-uu reads lanes"):
        ReproduceSpec(tmp_path, cnn_methods="image-split-uu")
    with pytest.raises(ParameterError, match="no-such-net"):
        ReproduceSpec(tmp_path, cnn_methods="dnn-pilotnet,no-such-net")
