"""``train-direction --from``: a trunk of another network or a non-hybrid method is refused
in one line with exit status 2, before any frame is read."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

torch = pytest.importorskip("torch")

from qdcnn.cli import app  # noqa: E402
from qdcnn.config import PipelineConfig  # noqa: E402
from qdcnn.direction.model import DirectionModel  # noqa: E402
from qdcnn.models import CNNDirectionClassifier  # noqa: E402
from qdcnn.models.networks import build_network  # noqa: E402

runner = CliRunner()


def saved_head(path: Path) -> Path:
    network = build_network("qdcnn-head", seed=0, head="quantum")
    clf = CNNDirectionClassifier.from_network(
        network, "qdcnn-head", device="cpu", network_params={"head": "quantum"}
    )
    return DirectionModel("qdcnn-head", PipelineConfig(), clf, "toy", {}).save(path)


@pytest.mark.parametrize(
    ("method", "extra", "message"),
    [
        (
            "qdcnn-quanv",
            [],
            "--from: its architecture is 'qdcnn-head', this network's 'qdcnn-quanv'",
        ),
        ("qdcnn-head-classical", ["--context", "2"], "its frames per input (context) is 1"),
        ("dnn-pilotnet", [], "dnn-pilotnet is not a hybrid method"),
    ],
)
def test_from_refuses_another_network_in_one_line(
    tmp_path: Path, method: str, extra: list[str], message: str
) -> None:
    model = saved_head(tmp_path / "head.safetensors")
    args = ["train-direction", "--data", "synthetic:track2:10", "--method", method]
    args += ["--from", str(model), "--out", str(tmp_path / "out.safetensors"), *extra]
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    errors = [line for line in result.output.splitlines() if line.strip()]
    assert len(errors) == 1 and message in errors[0]
    assert not (tmp_path / "out.safetensors").exists()


def test_from_a_model_without_a_network_is_refused_in_one_line(tmp_path: Path) -> None:
    import numpy as np

    from qdcnn.direction.model import train_direction_model

    rng = np.random.default_rng(0)
    x, y = rng.uniform(-1, 1, (60, 2)), np.arange(60) % 3
    lane = train_direction_model("lines-logreg", x, y, PipelineConfig(), "toy")
    path = lane.save(tmp_path / "lines.safetensors")
    args = ["train-direction", "--data", "synthetic:track2:10", "--method", "qdcnn-head"]
    args += ["--from", str(path), "--out", str(tmp_path / "out.safetensors")]
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    errors = [line for line in result.output.splitlines() if line.strip()]
    assert errors == [f"error: {path}: the model's method 'lines-logreg' has no trained network"]
    assert not (tmp_path / "out.safetensors").exists()


REFUSED_FLAGS = {
    "--balanced": (
        "lines-logreg",
        "error: --balanced='set' is invalid: unset: lines-logreg is not a CNN or a hybrid with "
        "PilotNet as stage 1 under --transfer",
    ),
    "--standardise-frames": (
        "qdcnn-quanv",
        "error: --standardise-frames='set' is invalid: unset: qdcnn-quanv is not PilotNet or a "
        "qdcnn-head network",
    ),
    "--edge-frames": (
        "hog-logreg",
        "error: --edge-frames='set' is invalid: unset: hog-logreg is not PilotNet or a "
        "qdcnn-head network",
    ),
}


@pytest.mark.parametrize("flag", list(REFUSED_FLAGS))
@pytest.mark.parametrize("command", ["train-direction", "evaluate"])
def test_a_flag_that_changes_no_method_is_refused_in_one_line(
    tmp_path: Path, command: str, flag: str
) -> None:
    method, message = REFUSED_FLAGS[flag]
    args = [command, "--data", "synthetic:track2:10", "--method", method, flag]
    if command == "train-direction":
        args += ["--out", str(tmp_path / "out.safetensors")]
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    assert [line for line in result.output.splitlines() if line.strip()] == [message]
    assert not (tmp_path / "out.safetensors").exists()
