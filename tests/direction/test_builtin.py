"""The built-in direction model: all three presets, scored by the protocol, cached."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from qdcnn.config import PipelineConfig
from qdcnn.direction.builtin import (
    DEFAULT_METHOD,
    default_direction_model,
    default_model_path,
    direction_model,
)
from qdcnn.errors import InputError, ParameterError
from qdcnn.experiments.evaluate import EvaluationSpec, run_evaluation
from qdcnn.runtime.reporting import Reporter

SMALL = ("synthetic:track1:100", "synthetic:rain:100")


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path))
    return tmp_path


def test_trained_on_every_preset_and_scored_like_evaluate(cache: Path) -> None:
    model = default_direction_model(DEFAULT_METHOD, 0, data=SMALL)
    assert model.trained_on == " + ".join(SMALL)
    assert model.summary["n"] == 200
    cv = model.summary["cross_validation"]
    # the score is evaluate's protocol on the presets in a row (a spec of one preset here)
    one = default_direction_model(DEFAULT_METHOD, 0, data=SMALL[:1])
    ref = run_evaluation(EvaluationSpec(SMALL[0], methods=(DEFAULT_METHOD,)))
    assert one.summary["cross_validation"]["accuracy"] == pytest.approx(ref.results[0].accuracy)
    assert 0.0 <= cv["majority_baseline"] <= 1.0 and (cv["folds"], cv["gap"]) == (5, 5)


def test_the_second_use_reads_the_cached_file(cache: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    first = default_direction_model(DEFAULT_METHOD, 0, data=SMALL)
    path = default_model_path(DEFAULT_METHOD, 0, SMALL)
    assert path.is_file() and path.parent == cache / "models"
    import qdcnn.direction.builtin as dm

    def no_training(*_: object) -> None:
        raise AssertionError("trained again")

    monkeypatch.setattr(dm, "_train_and_score", no_training)
    again = default_direction_model(DEFAULT_METHOD, 0, data=SMALL)
    x = np.random.default_rng(0).uniform(-1, 1, (50, 2))
    np.testing.assert_array_equal(again.predict(x), first.predict(x))
    assert again.summary == first.summary


def test_a_broken_cache_file_is_trained_again(cache: Path) -> None:
    path = default_model_path(DEFAULT_METHOD, 0, SMALL)
    path.parent.mkdir(parents=True)
    path.write_bytes(b"not a model")
    model = default_direction_model(DEFAULT_METHOD, 0, data=SMALL)
    assert model.summary["n"] == 200 and path.stat().st_size > 100


def test_the_key_follows_method_seed_and_data(cache: Path) -> None:
    keys = {
        default_model_path(DEFAULT_METHOD, 0, SMALL),
        default_model_path("kmeans-uu", 0, SMALL),
        default_model_path(DEFAULT_METHOD, 1, SMALL),
        default_model_path(DEFAULT_METHOD, 0, SMALL[:1]),
    }
    assert len(keys) == 4


def test_the_key_and_the_model_follow_the_pipeline_config(cache: Path) -> None:
    rgb = PipelineConfig().with_lane_options(edges="rgb")
    assert default_model_path(DEFAULT_METHOD, 0, SMALL) == default_model_path(
        DEFAULT_METHOD, 0, SMALL, PipelineConfig()
    )  # the default config keeps the keys of earlier versions
    assert default_model_path(DEFAULT_METHOD, 0, SMALL) != default_model_path(
        DEFAULT_METHOD, 0, SMALL, rgb
    )
    model = default_direction_model(DEFAULT_METHOD, 0, data=SMALL[:1], config=rgb)
    assert model.config == rgb


def test_a_model_file_refuses_other_lane_settings(tmp_path: Path) -> None:
    notes: list[str] = []
    with pytest.raises(ParameterError, match="carries the lane settings it was trained with"):
        direction_model(
            tmp_path / "m.qdcnn", DEFAULT_METHOD, 0, PipelineConfig.paper(), notes.append
        )
    assert notes == []


class _StepCounter(Reporter):
    def __init__(self) -> None:
        self.steps: list[tuple[str, int, int]] = []

    @contextmanager
    def progress(self, total: int, description: str) -> Iterator[Callable[..., None]]:
        done = [0]
        yield lambda *_: done.__setitem__(0, done[0] + 1)
        self.steps.append((description, total, done[0]))


def test_no_cache_writes_nothing_and_image_methods_need_a_file(cache: Path) -> None:
    counter = _StepCounter()
    default_direction_model(DEFAULT_METHOD, 0, data=SMALL[:1], use_cache=False, reporter=counter)
    assert not (cache / "models").exists()
    # the training reports its progress: the preset's features, the fit, the score
    assert counter.steps == [(f"built-in model {DEFAULT_METHOD}: train, score", 3, 3)]
    with pytest.raises(InputError, match="needs a trained model file"):
        default_direction_model("dnn-pilotnet")


def test_the_video_processor_defaults_to_the_built_in_model(
    cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from qdcnn.direction import builtin as default_model
    from qdcnn.direction.processor import LaneDirectionProcessor

    monkeypatch.setattr(default_model, "DEFAULT_TRAINING_DATA", SMALL)
    processor = LaneDirectionProcessor.train()
    assert processor.model.method == DEFAULT_METHOD
    assert processor.model.trained_on == " + ".join(SMALL)
    assert default_model_path(DEFAULT_METHOD, 0, SMALL).is_file()


def test_an_unwritable_cache_gives_a_note_and_the_trained_model(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from qdcnn.runtime.reporting import Collector

    (tmp_path / "models").write_text("a file where the models folder would be")
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path))
    collector = Collector()
    model = default_direction_model(DEFAULT_METHOD, 0, data=SMALL[:1], reporter=collector)
    assert model.summary["n"] == 100
    notes = [n for n in collector.notes if "not kept in the cache" in n]
    assert len(notes) == 1 and "QDCNN_CACHE" in notes[0], collector.notes
