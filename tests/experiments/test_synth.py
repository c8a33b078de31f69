"""``qdcnn synth`` never destroys data: a non-empty --out needs --force, the folder is locked."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.errors import InputError
from qdcnn.experiments.synth import SynthSpec, run_synth
from qdcnn.outputs import OutputFolder, OutputLockedError

runner = CliRunner()


def _synth(out: Path, *extra: str, n: int = 4) -> tuple[int, str]:
    args = ["synth", "--n", str(n), "--width", "64", "--height", "32", "--out", str(out)]
    res = runner.invoke(app, [*args, "--layout", "udacity", *extra])
    return res.exit_code, res.stderr


def test_an_existing_recording_is_refused_and_left_as_it_was(tmp_path: Path) -> None:
    out = tmp_path / "rec"
    assert _synth(out, n=6)[0] == 0
    log = (out / "driving_log.csv").read_bytes()
    images = sorted(p.name for p in (out / "IMG").iterdir())
    code, err = _synth(out, n=2)
    assert code == 2
    assert err.strip() == f"error: {out}: folder exists and is not empty: use --force to replace "\
        "what it holds"
    assert (out / "driving_log.csv").read_bytes() == log
    assert sorted(p.name for p in (out / "IMG").iterdir()) == images


def test_force_replaces_everything_the_folder_held(tmp_path: Path) -> None:
    out = tmp_path / "rec"
    assert _synth(out, n=6)[0] == 0
    (out / "notes.txt").write_text("old")
    assert _synth(out, "--force", n=2)[0] == 0
    assert len((out / "driving_log.csv").read_text().splitlines()) == 2
    assert len(list((out / "IMG").iterdir())) == 2  # the old frames are gone
    assert not (out / "notes.txt").exists()


def test_a_second_run_into_a_locked_folder_is_refused(tmp_path: Path) -> None:
    out = tmp_path / "rec"
    with OutputFolder(out), pytest.raises(OutputLockedError, match="another qdcnn run"):
        run_synth(SynthSpec(out, n=2, width=32, height=16, layout="udacity"))


@pytest.mark.parametrize("target", ["file", "devnull"])
def test_an_output_that_is_not_a_folder_is_one_line(tmp_path: Path, target: str) -> None:
    out = tmp_path / "f.txt" if target == "file" else Path("/dev/null")
    if target == "file":
        out.write_text("x")
    with pytest.raises(InputError, match="exists and is not a folder"):
        run_synth(SynthSpec(out, n=2, width=32, height=16, layout="udacity"))
    code, err = _synth(out)
    assert code == 2 and err.count("error:") == 1 and "Traceback" not in err


def test_stale_temporaries_of_a_killed_run_are_removed(tmp_path: Path) -> None:
    out = tmp_path / "rec"
    out.mkdir()
    stale = out / ".driving_log.csv.0123456789ab.tmp"
    stale.write_text("half")
    code, _ = _synth(out, "--force")
    assert code == 0 and not stale.exists()
