"""Transfer training of hybrids: the three stages, the frozen trunk, the shared trunk cache."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from torch import nn  # noqa: E402

from qdcnn.errors import ParameterError  # noqa: E402
from qdcnn.models import transfer  # noqa: E402
from qdcnn.models.hybrid import HybridNet, _make_head  # noqa: E402
from qdcnn.models.trainer import FrameSamples, Trainer, TrainSettings  # noqa: E402
from qdcnn.models.transfer import (  # noqa: E402
    ClassicalStage,
    cached_epochs,
    cached_trunk,
    data_key,
    fit_transfer,
    freeze_trunk,
    keep_trunk,
    load_trunk,
    stage_epochs,
    trunk_state,
)


def build(head: str, seed: int) -> nn.Module:
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        trunk = nn.Sequential(nn.Flatten(), nn.Linear(3 * 4 * 4, 6), nn.ELU())
        return HybridNet(None, trunk, _make_head(head, 6, n_qubits=2, n_layers=1))


def samples(n: int = 60) -> FrameSamples:
    rng = np.random.default_rng(0)
    labels = np.arange(n) % 3
    frames = rng.integers(0, 40, (n, 3, 4, 4)).astype(np.uint8)
    frames[np.arange(n), labels, :, :] = 220  # the label's channel is bright
    return FrameSamples.sequence(torch.from_numpy(frames), labels)


@pytest.fixture(autouse=True)
def own_trunk_cache(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test starts with an empty trunk cache and leaves none behind."""
    monkeypatch.setattr(transfer, "_TRUNKS", {})


def trainer(**kw: Any) -> Trainer:
    s = TrainSettings(**{"epochs": 4, "batch_size": 16, "lr": 1e-2, "num_threads": 1, **kw})
    return Trainer(s, transform=lambda x: x.float() / 255.0)


def test_three_stages_and_a_trunk_frozen_while_the_head_trains() -> None:
    assert stage_epochs(25) == (6, 6) and stage_epochs(2) == (1, 1)
    result, trunk = fit_transfer(trainer(), build, "quantum", samples())
    stages = [r["stage"] for r in result.history]
    assert stages == ["classical"] * 4 + ["head"] + ["finetune"]
    assert result.history[result.best_epoch - 1]["stage"] == "finetune"
    assert set(trunk) == {"trunk.1.weight", "trunk.1.bias"}
    final = trunk_state(result.network)
    assert not torch.equal(final["trunk.1.weight"], trunk["trunk.1.weight"])  # fine-tuned
    assert all(p.requires_grad for p in result.network.parameters())


def test_the_head_stage_runs_at_a_higher_rate_and_the_fine_tuning_at_a_lower(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    rates: dict[str, float] = {}
    run_stage = transfer._stage

    def spy(trainer: Trainer, settings: TrainSettings, name: str, *args: Any) -> Any:
        rates[name] = settings.lr
        return run_stage(trainer, settings, name, *args)

    monkeypatch.setattr(transfer, "_stage", spy)
    fit_transfer(trainer(epochs=2), build, "quantum", samples())
    assert rates["classical"] == 1e-2
    assert rates["head"] == pytest.approx(1e-2 * transfer.HEAD_STAGE_LR_FACTOR)
    assert rates["finetune"] == pytest.approx(1e-3)


def test_a_frozen_trunk_stays_as_it_was() -> None:
    net = build("quantum", 0)
    before = {k: v.clone() for k, v in trunk_state(net).items()}
    head_before = net.head.weights.detach().clone()
    freeze_trunk(net, True)
    trainer(epochs=1).fit(net, samples())
    after = trunk_state(net)
    assert all(torch.equal(before[k], after[k]) for k in before)
    assert not torch.equal(head_before, net.head.weights.detach())


def test_twin_and_ablations_share_the_cached_trunk() -> None:
    t = trainer(epochs=2)
    key = data_key(samples(), t.settings, "tiny")
    _, trunk = fit_transfer(t, build, "quantum", samples(), cache_key=key)
    assert cached_trunk(key) is trunk
    twin, twin_trunk = fit_transfer(t, build, "classical", samples(), cache_key=key)
    assert twin_trunk is trunk and {r["stage"] for r in twin.history} == {"head", "finetune"}
    assert data_key(samples(), trainer(epochs=3).settings, "tiny") != key
    given, _ = fit_transfer(t, build, "linear", samples(), trunk=trunk)
    assert "classical" not in {r["stage"] for r in given.history}


def test_later_stages_take_a_quarter_of_the_epochs_stage_one_ran() -> None:
    t = trainer(epochs=25)
    key = data_key(samples(), t.settings, "stopped early")
    keep_trunk(key, trunk_state(build("linear", 0)), 8)  # as if stage 1 stopped after 8
    assert cached_epochs(key) == 8
    result, _ = fit_transfer(t, build, "quantum", samples(), cache_key=key)
    assert [r["stage"] for r in result.history] == ["head"] * 2 + ["finetune"] * 2
    given, _ = fit_transfer(t, build, "quantum", samples(), trunk=cached_trunk(key))
    assert [r["stage"] for r in given.history] == ["head"] * 6 + ["finetune"] * 6
    stopping = trainer(epochs=25, patience=1, val_fraction=0.25, lr=0.5)
    fresh, _ = fit_transfer(stopping, build, "quantum", samples())
    ran = sum(r["stage"] == "classical" for r in fresh.history)
    assert ran < 25  # stopped early
    later = max(1, ran // 4)
    assert [r["stage"] for r in fresh.history][ran:] == ["head"] * later + ["finetune"] * later


def test_stage_one_can_be_another_networks_own_training() -> None:
    def plain(seed: int) -> nn.Module:  # the hybrid's trunk and a linear class layer
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            return nn.Sequential(nn.Flatten(), nn.Linear(3 * 4 * 4, 6), nn.ELU(), nn.Linear(6, 3))

    def trunk_of(network: nn.Module) -> dict[str, torch.Tensor]:
        return {f"trunk.1.{k}": v.clone() for k, v in network[1].state_dict().items()}

    own = TrainSettings(epochs=3, batch_size=8, lr=5e-2, num_threads=1)
    stage = ClassicalStage(plain, own, trunk_of)
    t = trainer(epochs=8)  # the hybrid's own settings: not stage 1's
    key = data_key(samples(), own, "plain")
    result, trunk = fit_transfer(t, build, "quantum", samples(), cache_key=key, classical=stage)
    assert [r["stage"] for r in result.history] == ["classical"] * 3 + ["head", "finetune"]
    alone = Trainer(own, transform=lambda x: x.float() / 255.0).fit(plain(0), samples())
    assert all(torch.equal(trunk[k], v) for k, v in trunk_of(alone.network).items())
    assert cached_trunk(key) is trunk and cached_epochs(key) == 3


def test_a_trunk_of_another_network_is_refused() -> None:
    other = HybridNet(None, nn.Sequential(nn.Flatten(), nn.Linear(3 * 4 * 4, 7)), nn.Identity())
    with pytest.raises(ParameterError, match="trunk"):
        load_trunk(build("quantum", 0), trunk_state(other))


def test_a_trunk_kept_in_a_folder_serves_a_later_process(
    tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    t = trainer(epochs=2)
    key = data_key(samples(), t.settings, "on disk")
    first, trunk = fit_transfer(t, build, "quantum", samples(), cache_key=key, folder=tmp_path)
    assert (tmp_path / f"{key}.safetensors").is_file()
    monkeypatch.setattr(transfer, "_TRUNKS", {})  # as in a resumed run or another worker
    assert cached_epochs(key) is None and cached_epochs(key, tmp_path) == 2
    again, read = fit_transfer(t, build, "quantum", samples(), cache_key=key, folder=tmp_path)
    assert all(torch.equal(read[k], v) for k, v in trunk.items())
    assert [r["stage"] for r in again.history] == ["head", "finetune"]
    mine, theirs = first.network.state_dict(), again.network.state_dict()
    assert all(torch.equal(mine[k], theirs[k]) for k in mine)  # the same network either way


def test_an_unreadable_kept_trunk_is_trained_again(
    tmp_path: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    t = trainer(epochs=2)
    key = data_key(samples(), t.settings, "damaged")
    keep_trunk(key, trunk_state(build("linear", 0)), 2, tmp_path)
    (tmp_path / f"{key}.safetensors").write_bytes(b"\x08\x00\x00\x00\x00\x00\x00\x00{broken")
    monkeypatch.setattr(transfer, "_TRUNKS", {})
    assert cached_trunk(key, tmp_path) is None
    result, _ = fit_transfer(t, build, "quantum", samples(), cache_key=key, folder=tmp_path)
    assert result.history[0]["stage"] == "classical"
    monkeypatch.setattr(transfer, "_TRUNKS", {})
    assert cached_epochs(key, tmp_path) == 2  # rewritten


def test_a_folder_that_cannot_be_written_only_keeps_nothing(tmp_path: Any) -> None:
    blocked = tmp_path / "trunks"
    blocked.write_text("a file where the folder would be")
    t = trainer(epochs=2)
    key = data_key(samples(), t.settings, "blocked")
    result, _ = fit_transfer(t, build, "quantum", samples(), cache_key=key, folder=blocked)
    assert result.history[0]["stage"] == "classical" and cached_epochs(key) == 2  # in memory


def test_the_trunk_key_ignores_where_and_on_how_many_threads_it_ran(tmp_path: Any) -> None:
    t = trainer(epochs=2)
    key = data_key(samples(), t.settings, "here")
    elsewhere = replace(t.settings, num_threads=2, checkpoint_dir=str(tmp_path))
    assert data_key(samples(), elsewhere, "here") == key
    assert data_key(samples(), replace(t.settings, seed=1), "here") != key
