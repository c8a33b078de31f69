"""Seed ensembles: the vote, the members each seed trains, and their model files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from qdcnn.errors import InputError
from qdcnn.models.ensemble import joined_arrays, member_seed, split_arrays


def test_the_networks_seeds_stay_clear_of_restarts_and_seeds() -> None:
    assert [member_seed(3, k) for k in range(3)] == [3, 1003, 2003]


def test_arrays_of_several_networks_split_back() -> None:
    nets = [{"trunk.w": np.full(2, k), "head.b": np.full(1, 10 + k)} for k in range(3)]
    joined = joined_arrays(nets)
    assert set(joined) >= {"trunk.w", "member1.trunk.w", "member2.head.b"}
    parts = split_arrays(joined, 3, "m.safetensors")
    for part, net in zip(parts, nets, strict=True):
        assert part.keys() == net.keys()
        assert all(np.array_equal(part[k], net[k]) for k in net)
    with pytest.raises(
        InputError, match=r"^m.safetensors: holds arrays of network 3, its header says 2$"
    ):
        split_arrays(joined, 2, "m.safetensors")
    with pytest.raises(
        InputError, match=r"^m.safetensors: holds arrays of fewer networks than its header's 4$"
    ):
        split_arrays(joined, 4, "m.safetensors")


# ---------------------------------------------------------------- the classifier

torch_needed = pytest.mark.skipif(
    __import__("importlib").util.find_spec("torch") is None, reason="torch is not installed"
)


@pytest.fixture(scope="module")
def lines() -> tuple[np.ndarray, np.ndarray]:
    from tests.models.test_training import line_frames

    return line_frames(48, np.random.default_rng(5))


def _small(**kw: object) -> object:
    from tests.models.test_training import small

    return small(**{"epochs": 2, **kw})


@torch_needed
def test_each_network_is_the_run_of_its_seed_and_the_ensemble_averages_them(
    lines: tuple[np.ndarray, np.ndarray],
) -> None:
    x, y = lines
    ensemble = _small(ensemble=3).fit(x, y)  # type: ignore[attr-defined]
    singles = [_small(seed=member_seed(3, k)).fit(x, y) for k in range(3)]  # type: ignore[attr-defined]
    for member, single in zip(ensemble.members_, singles, strict=True):
        np.testing.assert_array_equal(member.predict_proba(x), single.predict_proba(x))
    mean = np.mean([s.predict_proba(x) for s in singles], axis=0)
    np.testing.assert_allclose(ensemble.predict_proba(x), mean)
    np.testing.assert_array_equal(ensemble.predict(x), np.argmax(mean, axis=1))
    labels, proba = ensemble.predict_with_proba(x)
    np.testing.assert_array_equal(labels, np.argmax(proba, axis=1))
    assert ensemble.seed_ == 3 and [m.seed_ for m in ensemble.members_] == [3, 1003, 2003]
    one = ensemble.set_params(ensemble=1).fit(x, y)  # a refit as one network: no old networks
    assert not hasattr(one, "members_")
    np.testing.assert_array_equal(one.predict_proba(x), singles[0].predict_proba(x))


@torch_needed
def test_each_network_keeps_its_checkpoints_apart(
    lines: tuple[np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    x, y = lines
    _small(ensemble=2, epochs=1, checkpoint_dir=tmp_path).fit(x, y)  # type: ignore[attr-defined]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["network0", "network1"]
    assert all((tmp_path / d / "last.safetensors").is_file() for d in ("network0", "network1"))


@torch_needed
def test_an_ensemble_model_file_round_trips_and_bad_ones_are_named(
    lines: tuple[np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    from qdcnn.config import PipelineConfig
    from qdcnn.direction.model import FORMAT_VERSION, KIND, DirectionModel
    from qdcnn.errors import ParameterError
    from qdcnn.persistence import load_model, save_model

    x, y = lines
    clf = _small(ensemble=2).fit(x, y)  # type: ignore[attr-defined]
    model = DirectionModel("dnn-pilotnet", PipelineConfig(), clf, "lines")
    path = model.save(tmp_path / "two.safetensors")
    loaded = DirectionModel.load(path)
    np.testing.assert_array_equal(loaded.predict(x), clf.predict(x))
    np.testing.assert_array_equal(loaded.predict_proba(x), clf.predict_proba(x))
    assert [m.seed_ for m in loaded.estimator.members_] == [3, 1003]
    assert [m.seed for m in loaded.estimator.members_] == [3, 1003]
    with pytest.raises(ParameterError, match="ensemble"):
        clf.save(tmp_path / "network.safetensors")
    header, arrays = load_model(path, KIND, {FORMAT_VERSION})
    meta = dict(header.meta)
    meta["params"] = {**meta["params"], "ensemble": 3}
    bad = tmp_path / "bad.safetensors"
    save_model(bad, KIND, FORMAT_VERSION, meta, arrays)
    with pytest.raises(InputError) as err:
        DirectionModel.load(bad)
    assert str(err.value) == f"{bad}: holds 2 networks, its settings say ensemble=3"
    meta["params"] = {**meta["params"], "ensemble": 1}
    save_model(bad, KIND, FORMAT_VERSION, meta, arrays)
    with pytest.raises(InputError) as err:
        DirectionModel.load(bad)
    assert str(err.value) == f"{bad}: holds 2 networks, its settings say ensemble=1"
