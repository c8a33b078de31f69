"""Trainer: trains any (B, C, H, W) -> (B, 3) module; extras train only; context; determinism."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from torch import nn  # noqa: E402

from qdcnn.errors import InputError, ParameterError  # noqa: E402
from qdcnn.models.samples import split_train_val  # noqa: E402
from qdcnn.models.trainer import FrameSamples, Trainer, TrainSettings  # noqa: E402


def bar_frames(n: int, rng: np.random.Generator, h: int = 16, w: int = 32) -> tuple[Any, Any]:
    """Noisy dark frames with a bright bar in the left (label 0) or right (label 2) third.

    A mirrored frame is a frame of the other class, as the flip augmentation assumes.
    """
    labels = np.where(np.arange(n) % 2 == 0, 0, 2)
    frames = rng.integers(0, 60, (n, 3, h, w)).astype(np.uint8)
    for i, label in enumerate(labels):
        x = int(rng.integers(1, w // 3 - 3)) if label == 0 else int(rng.integers(2 * w // 3, w - 4))
        frames[i, :, :, x : x + 3] = 230
    return torch.from_numpy(frames), labels


class TinyCNN(nn.Module):
    """Two convolutions and a linear head on 16x32 frames."""

    def __init__(self, in_channels: int = 3) -> None:
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(in_channels, 8, 3, stride=2, padding=1),
            nn.ReLU(),
            nn.Conv2d(8, 8, 3, stride=2, padding=1),
            nn.ReLU(),
            nn.Flatten(),
            nn.Dropout(0.2),
            nn.Linear(8 * 4 * 8, 3),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out: torch.Tensor = self.body(x)
        return out


def tiny(seed: int = 0) -> TinyCNN:
    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(seed)
        return TinyCNN()


def scaled(x: torch.Tensor) -> torch.Tensor:
    return x.float() / 255.0


def settings(**kw: Any) -> TrainSettings:
    base: dict[str, Any] = {"epochs": 6, "batch_size": 16, "lr": 3e-3, "num_threads": 1}
    return TrainSettings(**{**base, **kw})


def test_trains_a_custom_network_to_high_accuracy() -> None:
    frames, labels = bar_frames(120, np.random.default_rng(0))
    result = Trainer(settings(epochs=15, patience=0), transform=scaled).fit(
        tiny(), FrameSamples.sequence(frames, labels)
    )
    test_frames, test_labels = bar_frames(60, np.random.default_rng(1))
    with torch.inference_mode():
        predicted = result.network(scaled(test_frames)).argmax(1).numpy()
    assert np.mean(predicted == test_labels) >= 0.95
    assert not result.network.training
    losses = [h["train_loss"] for h in result.history]
    assert losses[-1] < 0.5 * losses[0]
    assert set(result.history[0]) == {
        "epoch",
        "train_loss",
        "val_loss",
        "val_accuracy",
        "val_balanced_accuracy",
        "val_predictions",
        "lr",
        "grad_norm_trunk",
        "grad_norm_head",
        "angle_std",
        "angle_min",
        "angle_max",
        "feature_std",
        "feature_min",
        "feature_max",
        "seconds",
    }
    assert sum(result.history[0]["val_predictions"]) == result.n_val
    assert result.history[0]["grad_norm_head"] is None  # TinyCNN has no head
    assert (result.n_train, result.n_val, result.n_extra) == (
        len(split_train_val(120, 0.15, blocks=4, gap=5)[0]),
        len(split_train_val(120, 0.15, blocks=4, gap=5)[1]),
        0,
    )


def test_same_seed_same_weights_other_seed_other_weights() -> None:
    frames, labels = bar_frames(48, np.random.default_rng(2))
    samples = FrameSamples.sequence(frames, labels)

    def run(seed: int) -> dict[str, torch.Tensor]:
        net = Trainer(settings(epochs=2, seed=seed), transform=scaled).fit(tiny(), samples).network
        return net.state_dict()

    a, b, c = run(3), run(3), run(4)
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not all(torch.equal(a[k], c[k]) for k in a)


class Recorder(nn.Module):
    """Records the first pixel of every channel it is fed, in training and in eval mode."""

    def __init__(self, in_channels: int) -> None:
        super().__init__()
        self.linear = nn.Linear(in_channels, 3)
        self.seen: list[tuple[bool, np.ndarray]] = []

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        self.seen.append((self.training, x[:, :, 0, 0].detach().numpy().astype(np.int64)))
        out: torch.Tensor = self.linear(x.mean((2, 3)) / 255.0)
        return out

    def rows(self, training: bool) -> np.ndarray:
        return np.concatenate([rows for mode, rows in self.seen if mode == training])


def tagged(n: int, view: int) -> torch.Tensor:
    """Constant frames whose channel 0 is the frame index and channel 1 the view."""
    frames = torch.zeros((n, 3, 2, 2), dtype=torch.uint8)
    frames[:, 0] = torch.arange(n, dtype=torch.uint8).view(n, 1, 1)
    frames[:, 1] = view
    return frames


def test_extra_samples_train_only_with_their_own_frame() -> None:
    n = 40
    labels = np.arange(n) % 3
    main = FrameSamples.sequence(tagged(n, 0), labels)
    extra_pool = torch.cat([tagged(n, 1), tagged(n, 2)])
    windows = torch.cat([torch.arange(n), torch.arange(n) + n]).view(-1, 1)
    extra = FrameSamples(extra_pool, windows, torch.from_numpy(np.tile((labels + 1) % 3, 2)))
    recorder = Recorder(3)
    cfg = settings(epochs=2, augment=False, val_fraction=0.25, val_blocks=1, val_gap=2)
    result = Trainer(cfg).fit(recorder, main, extra=extra, extra_of=np.tile(np.arange(n), 2))
    train, val = split_train_val(n, 0.25, blocks=1, gap=2)
    assert val.tolist() == list(range(30, 40)) and train.tolist() == list(range(28))
    seen_train = recorder.rows(True)[:, :2]
    expected = sorted((int(i), v) for i in train for v in (0, 1, 2))
    assert sorted(map(tuple, seen_train.tolist())) == sorted(expected * 2)  # each once per epoch
    seen_val = recorder.rows(False)[:, :2]
    assert sorted(map(tuple, seen_val.tolist())) == sorted([(int(i), 0) for i in val] * 2)
    assert result.n_extra == 2 * len(train)


def test_context_stacks_the_frames_before_each_frame() -> None:
    n, k = 30, 3
    main = FrameSamples.sequence(tagged(n, 0), np.arange(n) % 3, context=k)
    extra = FrameSamples.sequence(tagged(n, 1), np.arange(n) % 3, context=k)
    recorder = Recorder(3 * k)
    cfg = settings(epochs=1, augment=False, val_fraction=0.2, val_blocks=1, val_gap=0)
    Trainer(cfg).fit(recorder, main, extra=extra, extra_of=np.arange(n))
    rows = np.concatenate([recorder.rows(True), recorder.rows(False)])
    for row in rows:
        ids, views = row[0::3], row[1::3]  # channel 0 and 1 of each of the K frames
        newest = ids[-1]
        assert ids.tolist() == [max(newest - 2, 0), max(newest - 1, 0), newest]
        assert len(set(views.tolist())) == 1  # a sample never mixes views
    assert len(rows) == n + n - 6  # extras of the 6 validation frames never ran


def test_callbacks_report_every_step_and_epoch() -> None:
    frames, labels = bar_frames(40, np.random.default_rng(3))
    steps: list[tuple[int, int]] = []
    epochs: list[tuple[Mapping[str, Any], int]] = []
    result = Trainer(
        settings(epochs=3, val_fraction=0.0),
        transform=scaled,
        on_step=lambda step, total: steps.append((step, total)),
        on_epoch=lambda record, n: epochs.append((record, n)),
    ).fit(tiny(), FrameSamples.sequence(frames, labels))
    assert steps == [(i, 9) for i in range(1, 10)]  # 40 frames: batches of 16, 16, 8
    assert [(dict(r), n) for r, n in epochs] == [(h, 3) for h in result.history]
    assert result.best_epoch == 3  # without validation the last epoch is kept
    assert result.history[-1]["lr"] == pytest.approx(0.0, abs=1e-12)  # cosine, per step


def test_bad_extras_and_settings() -> None:
    frames, labels = bar_frames(20, np.random.default_rng(4))
    samples = FrameSamples.sequence(frames, labels)
    trainer = Trainer(settings(epochs=1))
    with pytest.raises(ParameterError) as err:
        trainer.fit(tiny(), samples, extra=samples)
    assert str(err.value) == "extra_of=None is invalid: the sample index of every extra sample"
    with pytest.raises(InputError) as err:
        trainer.fit(tiny(), samples, extra=samples, extra_of=np.arange(5))
    assert str(err.value) == "extra_of: expected 20 indices into 20 samples, got shape (5,)"
    with pytest.raises(ParameterError) as err:
        Trainer(settings(epochs=0)).fit(tiny(), samples)
    assert str(err.value) == "epochs=0 is invalid: an integer in [1, 100000]"
    with pytest.raises(ParameterError) as err:
        Trainer(settings(batch_size=1), min_batch_size=2).fit(tiny(), samples)
    assert str(err.value) == "batch_size=1 is invalid: an integer in [2, 65536]"
    with pytest.raises(InputError) as err:
        FrameSamples.sequence(frames, np.full(20, 3))
    assert str(err.value) == "labels: values must be 0 (left), 1 (straight) or 2 (right)"


# ------------------------------------------ diagnostics, selection, restarts (issue 20)


class OneClass(nn.Module):
    """A TinyCNN whose logits carry a fixed, untrainable push to ``straight``: it predicts
    one class whatever it learns (a degenerate start)."""

    def __init__(self, push: float) -> None:
        super().__init__()
        self.cnn = tiny()
        self.register_buffer("push", torch.tensor([0.0, push, 0.0]))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out: torch.Tensor = self.cnn(x) + self.push
        return out


def test_a_run_predicting_one_class_restarts_with_the_next_seed() -> None:
    frames, labels = bar_frames(96, np.random.default_rng(5))
    samples = FrameSamples.sequence(frames, labels)
    built: list[int] = []

    def rebuild(seed: int) -> nn.Module:
        built.append(seed)
        return OneClass(0.0)

    trainer = Trainer(settings(epochs=2, restarts=2, seed=3), transform=scaled)
    result = trainer.fit(OneClass(1e4), samples, rebuild=rebuild)
    assert built == [4] and result.seed == 4
    assert [(r["seed"], r["next_seed"]) for r in result.restarts] == [(3, 4)]
    assert result.restarts[0]["val_predictions"] == [0, result.n_val, 0]
    assert sum(1 for c in result.history[result.best_epoch - 1]["val_predictions"] if c) > 1
    # no restarts asked for, or no way to rebuild: the collapsed run is kept as it is
    for kw in ({"restarts": 0}, {"restarts": 2}):
        rebuild_or_none = rebuild if kw["restarts"] == 0 else None
        kept = Trainer(settings(epochs=1, seed=3, **kw), transform=scaled).fit(
            OneClass(1e4), samples, rebuild=rebuild_or_none
        )
        assert kept.restarts == [] and kept.seed == 3
        assert kept.history[0]["val_predictions"] == [0, kept.n_val, 0]


class Scripted(nn.Module):
    """Reads each frame's label from its first pixel. Epoch 1 answers 'straight' with a
    margin of 5 (a low loss when most frames are straight, balanced accuracy 1/k); later
    epochs answer right with a margin of 0.1 (a higher loss, balanced accuracy 1)."""

    def __init__(self) -> None:
        super().__init__()
        self.w = nn.Parameter(torch.zeros(3))
        self.epochs_started = 0

    def train(self, mode: bool = True) -> Scripted:
        self.epochs_started += int(mode)
        return super().train(mode)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.training:
            return self.w.expand(len(x), 3)
        label = x[:, 0, 0, 0].round().long()
        if self.epochs_started == 1:
            return torch.tensor([0.0, 5.0, 0.0]).expand(len(x), 3)
        return torch.nn.functional.one_hot(label, 3).float() * 0.1


@pytest.mark.parametrize(("select", "kept"), [("loss", 1), ("balanced_accuracy", 2)])
def test_the_kept_epoch_follows_the_selection(select: str, kept: int) -> None:
    n = 200
    labels = np.ones(n, dtype=np.int64)
    labels[::10] = 0  # 10 % left, everywhere (so in every validation block)
    frames = torch.zeros((n, 3, 2, 2), dtype=torch.uint8)
    frames[:, 0, 0, 0] = torch.from_numpy(labels).to(torch.uint8)
    s = settings(epochs=2, select=select, augment=False, label_smoothing=0.0)
    result = Trainer(s).fit(Scripted(), FrameSamples.sequence(frames, labels))
    first, second = result.history
    assert first["val_loss"] < second["val_loss"]
    assert first["val_balanced_accuracy"] == 0.5 and second["val_balanced_accuracy"] == 1.0
    assert result.best_epoch == kept
    with pytest.raises(ParameterError, match="select='accuracy' is invalid"):
        Trainer(settings(select="accuracy")).fit(Scripted(), FrameSamples.sequence(frames, labels))


def test_class_balanced_loss_weights_classes_by_their_training_counts() -> None:
    from qdcnn.models.samples import class_weights

    n = 120
    labels = np.where(np.arange(n) % 4 == 0, 0, 1)  # 25 % left, 75 % straight
    frames = torch.zeros((n, 3, 2, 2), dtype=torch.uint8)
    samples = FrameSamples.sequence(frames, labels)

    class Fixed(nn.Module):  # the same logits for every frame; lr tiny: they stay
        def __init__(self) -> None:
            super().__init__()
            self.w = nn.Parameter(torch.tensor([0.3, -0.2, 0.1]))

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return self.w.expand(len(x), 3)

    losses = {}
    for weighting in ("balanced", None):
        s = settings(epochs=1, lr=1e-9, augment=False, label_smoothing=0.0, class_weight=weighting)
        losses[weighting] = Trainer(s).fit(Fixed(), samples).history[0]["train_loss"]
    train_idx, _ = split_train_val(n, 0.15, blocks=4, gap=5)
    y = labels[train_idx]
    ce = -torch.log_softmax(torch.tensor([0.3, -0.2, 0.1]), 0).numpy()
    w = class_weights(y)
    assert w[0] == pytest.approx(len(y) / (2 * np.sum(y == 0)))
    assert losses["balanced"] == pytest.approx(np.sum(w[y] * ce[y]) / np.sum(w[y]), rel=1e-5)
    assert losses[None] == pytest.approx(np.mean(ce[y]), rel=1e-5)


def test_history_reports_a_hybrid_heads_gradients_and_spreads() -> None:
    from qdcnn.models.hybrid import HybridNet
    from qdcnn.models.quantum_layers import QuantumHead

    frames, labels = bar_frames(48, np.random.default_rng(1))
    torch.manual_seed(0)
    trunk = nn.Sequential(nn.Flatten(), nn.Linear(3 * 16 * 32, 5), nn.ELU())
    net = HybridNet(None, trunk, QuantumHead(5, 2, 1))
    result = Trainer(settings(epochs=1), transform=scaled).fit(
        net, FrameSamples.sequence(frames, labels)
    )
    record = result.history[0]
    assert record["grad_norm_head"] > 0 and record["grad_norm_trunk"] > 0
    assert 0 < record["angle_std"] and -np.pi < record["angle_min"] <= record["angle_max"] < np.pi
    assert -1 <= record["feature_min"] <= record["feature_max"] <= 1
    assert record["feature_std"] > 0
