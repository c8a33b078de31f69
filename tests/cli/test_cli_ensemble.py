"""``--ensemble K``: K networks that vote, for CNNs and hybrids; told apart in the fold
cache; refused in one line where it changes nothing or is out of range."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from qdcnn.cli import app
from qdcnn.config import PipelineConfig
from qdcnn.direction.methods import TrainingOptions, ensemble_note, get_method
from qdcnn.errors import ParameterError
from qdcnn.experiments.evaluate import fold_store

runner = CliRunner()


def test_the_note_says_what_trains_as_usual_and_refuses_where_it_does_nothing() -> None:
    options = TrainingOptions(params={"ensemble": 3})
    methods = [get_method(n) for n in ("dnn-pilotnet", "qdcnn-head-linear", "image-split-uu")]
    assert ensemble_note(methods[:2], options) is None
    assert ensemble_note(methods, options) == (
        "--ensemble 3 applies to the CNNs and hybrids; image-split-uu trains as usual"
    )
    with pytest.raises(ParameterError) as err:
        ensemble_note([get_method("hog-logreg")], options)
    assert str(err.value) == (
        "--ensemble 3='set' is invalid: unset: hog-logreg is not a CNN or a hybrid"
    )
    assert ensemble_note(methods, TrainingOptions()) is None


def test_cached_folds_tell_ensembles_apart() -> None:
    def key(name: str, options: TrainingOptions) -> str:
        return fold_store(get_method(name), PipelineConfig(), options, {}, "data", True).key

    three = TrainingOptions(params={"ensemble": 3})
    for name in ("dnn-pilotnet", "qdcnn-head", "qdcnn-head-classical"):
        assert key(name, TrainingOptions()) != key(name, three)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--method", "image-split-uu", "--ensemble", "2"], "image-split-uu is not a CNN"),
        (["--method", "dnn-pilotnet", "--ensemble", "0"], "ensemble=0 is invalid: 1 to 9"),
        (["--method", "dnn-pilotnet", "--ensemble", "10"], "ensemble=10 is invalid: 1 to 9"),
    ],
)
@pytest.mark.parametrize("command", ["train-direction", "evaluate"])
def test_a_useless_or_bad_ensemble_is_refused_in_one_line(
    command: str, args: list[str], message: str, tmp_path: Path
) -> None:
    out = ["--out", str(tmp_path / "m.safetensors")] if command == "train-direction" else []
    result = runner.invoke(app, [command, "--data", "synthetic:track2:10", *args, *out])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and message in lines[0], result.output
    assert not (tmp_path / "m.safetensors").exists()


def test_train_direction_saves_the_networks_that_vote(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    from qdcnn.data.frames import load_frameset, stack_images
    from qdcnn.direction.model import DirectionModel

    out = tmp_path / "two.safetensors"
    args = ["train-direction", "--data", "synthetic:track2:24", "--method", "dnn-pilotnet"]
    args += ["--ensemble", "2", "--epochs", "1", "--threads", "1", "--out", str(out), "-q"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    model = DirectionModel.load(out)
    members = model.estimator.members_
    assert model.estimator.ensemble == 2 and [m.seed_ for m in members] == [0, 1000]
    images, _, _ = stack_images(load_frameset("synthetic:track2:24", seed=3))
    mean = np.mean([m.predict_proba(images) for m in members], axis=0)
    np.testing.assert_array_equal(model.predict(images), np.argmax(mean, axis=1))
