"""``qdcnn reproduce`` and ``qdcnn demo``: options, exit statuses, one code path.

The sections are replaced by two cheap ones here (the runner's own tests run the real
sections); what is tested is the command: option checks, exit status, JSON on stdout
and a line per stage on stderr.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.experiments.reproduce import runner as runner_module
from qdcnn.experiments.reproduce.model import Section
from qdcnn.experiments.reproduce.runner import SectionDef

runner = CliRunner()


def _ok(ctx, section: Section) -> None:
    section.text(f"datasets: {', '.join(e.spec for e in ctx.datasets)}")


def _broken(ctx, section: Section) -> None:
    raise RuntimeError("boom")


@pytest.fixture
def cheap_sections(monkeypatch: pytest.MonkeyPatch) -> list[SectionDef]:
    defs = [SectionDef("table-i", "Table I: cheap", _ok)]
    monkeypatch.setattr(runner_module, "SECTIONS", tuple(defs))
    monkeypatch.setattr(runner_module, "PAGE_ORDER", ("table-i",))
    return defs


def _lines(text: str) -> list[dict]:
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def test_reproduce_writes_the_report_and_prints_json(cheap_sections, tmp_path: Path) -> None:
    out = tmp_path / "r"
    res = runner.invoke(
        app, ["reproduce", "--data", "track2=synthetic:track2:60", "--out", str(out), "--json"]
    )
    assert res.exit_code == 0, res.stderr
    lines = _lines(res.stdout)
    assert lines[0]["section"] == "table-i" and lines[0]["status"] == "ok"
    assert lines[-1]["summary"] and lines[-1]["html"] == str(out / "index.html")
    assert "[1/1] Table I: cheap" in res.stderr
    assert "synthetic:track2:60" in (out / "index.html").read_text()


def test_a_failing_section_gives_exit_1_and_the_report(cheap_sections, monkeypatch, tmp_path):
    monkeypatch.setattr(
        runner_module, "SECTIONS", (SectionDef("table-i", "Table I: broken", _broken),)
    )
    res = runner.invoke(app, ["reproduce", "--out", str(tmp_path / "r")])
    assert res.exit_code == 1
    assert "error: RuntimeError: boom" in res.stderr
    assert "Error: RuntimeError: boom" in (tmp_path / "r" / "index.html").read_text()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ["--data", "track3=udacity:x"],
            "data label='track3' is invalid: one of track1, track2, carla",
        ),
        (["--data", "udacity:x"], "LABEL=SPEC, e.g. track1=udacity:PATH"),
        (["--data", "track1=video:x"], "data='video:x' is invalid"),
        (["--force", "--resume"], "at most one of --force and --resume"),
        (["--epochs", "0"], "epochs=0 is invalid"),
    ],
)
def test_bad_options_exit_2_with_one_line(cheap_sections, tmp_path, args, message) -> None:
    res = runner.invoke(app, ["reproduce", "--out", str(tmp_path / "r"), *args])
    assert res.exit_code == 2
    assert message in res.stderr and res.stderr.count("\n") == 1
    assert not (tmp_path / "r").exists()


def test_an_existing_folder_needs_force_or_resume(cheap_sections, tmp_path: Path) -> None:
    out = tmp_path / "r"
    out.mkdir()
    (out / "old.txt").write_text("x")
    res = runner.invoke(app, ["reproduce", "--out", str(out)])
    assert res.exit_code == 2
    assert "folder exists and is not empty: use --force" in res.stderr
    assert runner.invoke(app, ["reproduce", "--out", str(out), "--force"]).exit_code == 0
    res = runner.invoke(app, ["reproduce", "--out", str(out), "--resume", "--json"])
    assert res.exit_code == 0 and _lines(res.stdout)[-1]["reused"] == ["table-i"]


def test_demo_is_reproduce_quick_on_the_synthetic_presets(cheap_sections, tmp_path) -> None:
    out = tmp_path / "demo"
    res = runner.invoke(app, ["demo", "--out", str(out), "--seed", "3"])
    assert res.exit_code == 0, res.stderr
    state = json.loads((out / "sections" / "run.json").read_text())["spec"]
    assert state["quick"] and state["seed"] == 3
    assert [d["spec"] for d in state["data"]] == [
        "synthetic:track1:300",
        "synthetic:track2:300",
        "synthetic:rain:300",
    ]
    assert "report:" in res.stdout
