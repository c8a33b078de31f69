"""CNNDirectionClassifier: learning, determinism, persistence, checkpoints, input errors.

The estimator composes network, trainer and model file; the parts have their own
tests (test_networks, test_trainer, test_model_files, test_samples).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")
cv2 = pytest.importorskip("cv2")

from sklearn.base import clone  # noqa: E402
from sklearn.exceptions import NotFittedError  # noqa: E402

from qdcnn.errors import InputError, ParameterError  # noqa: E402
from qdcnn.models import CNNDirectionClassifier  # noqa: E402
from qdcnn.models.networks import build_network  # noqa: E402
from qdcnn.models.persistence import load_checkpoint  # noqa: E402
from qdcnn.models.training import class_weights, split_train_val  # noqa: E402

PICKLE_REFUSAL = (
    "a pickle-based file (an older qdcnn model or a torch file); it is never loaded "
    "because unpickling can run code: retrain the model with this qdcnn version"
)


def line_frames(
    n: int, rng: np.random.Generator, h: int = 40, w: int = 80
) -> tuple[np.ndarray, np.ndarray]:
    """Dark noisy frames with one bright line from the bottom centre, leaning with the label.

    Label 0 (left) leans left, 1 (straight) is vertical, 2 (right) leans right, so a
    horizontal flip of a frame is a frame of the swapped label, as the augmentation assumes.
    """
    labels = np.arange(n) % 3
    images = np.empty((n, h, w, 3), np.uint8)
    for i, label in enumerate(labels):
        img = (60 + rng.integers(0, 20, (h, w, 3))).astype(np.uint8)
        x_bottom = w / 2 + rng.uniform(-6, 6)
        lean = (-1, 0, 1)[label] * rng.uniform(0.6, 1.0) * w / 2
        cv2.line(img, (int(x_bottom), h - 1), (int(x_bottom + lean), 0), (240, 240, 240), 3)
        images[i] = img
    return images, labels


def small(**kw: object) -> CNNDirectionClassifier:
    settings: dict[str, object] = {
        "epochs": 1,
        "batch_size": 16,
        "progress": False,
        "num_threads": 1,
        "seed": 3,
    }
    settings.update(kw)
    return CNNDirectionClassifier("pilotnet", **settings)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray]:
    return line_frames(60, np.random.default_rng(0))


@pytest.fixture(scope="module")
def fitted(data: tuple[np.ndarray, np.ndarray]) -> CNNDirectionClassifier:
    return small(epochs=4, lr_schedule="constant").fit(*data)  # 4 epochs: no annealing


def test_training_lowers_the_loss_and_learns_the_lean(fitted: CNNDirectionClassifier) -> None:
    losses = [h["train_loss"] for h in fitted.history_]
    assert len(losses) == 4
    assert losses[-1] < 0.8 * losses[0]
    test_x, test_y = line_frames(30, np.random.default_rng(1))
    assert fitted.score(test_x, test_y) >= 0.8
    proba = fitted.predict_proba(test_x)
    assert proba.shape == (30, 3)
    np.testing.assert_allclose(proba.sum(axis=1), 1.0, atol=1e-6)
    assert fitted.predict(test_x).dtype == np.int64


def test_best_validation_epoch_is_kept(fitted: CNNDirectionClassifier) -> None:
    val_losses = [h["val_loss"] for h in fitted.history_]
    assert fitted.best_epoch_ == int(np.argmin(val_losses)) + 1
    assert all(0.0 <= h["val_accuracy"] <= 1.0 for h in fitted.history_)


def test_same_seed_gives_identical_predictions(data: tuple[np.ndarray, np.ndarray]) -> None:
    x, y = data
    a = small(epochs=2).fit(x, y)
    b = small(epochs=2).fit(x, y)
    c = small(epochs=2, seed=4).fit(x, y)
    np.testing.assert_array_equal(a.predict_proba(x), b.predict_proba(x))
    assert [h["train_loss"] for h in a.history_] == [h["train_loss"] for h in b.history_]
    assert not np.array_equal(a.predict_proba(x), c.predict_proba(x))


def test_fit_leaves_global_torch_state_alone(data: tuple[np.ndarray, np.ndarray]) -> None:
    torch.manual_seed(123)
    expected = torch.rand(3)
    threads = torch.get_num_threads()
    torch.manual_seed(123)
    small(num_threads=1, val_fraction=0.0).fit(*data)
    assert torch.equal(torch.rand(3), expected)
    assert torch.get_num_threads() == threads
    assert not torch.are_deterministic_algorithms_enabled()


def test_save_load_round_trip(fitted: CNNDirectionClassifier, tmp_path: Path) -> None:
    x, _ = line_frames(12, np.random.default_rng(2))
    path = tmp_path / "pilotnet.safetensors"
    assert fitted.save(path) == path
    loaded = CNNDirectionClassifier.load(path)
    np.testing.assert_array_equal(loaded.predict_proba(x), fitted.predict_proba(x))
    assert loaded.get_params() == fitted.get_params()
    assert loaded.history_ == fitted.history_
    assert loaded.best_epoch_ == fitted.best_epoch_


def test_load_refuses_torch_files_and_missing_ones(tmp_path: Path) -> None:
    # an old qdcnn model (torch.save of a dict) is a zip of pickles: refused, never unpickled
    old = tmp_path / "pilotnet.pt"
    torch.save({"format": "qdcnn-cnn-direction-classifier/1", "w": torch.zeros(2)}, old)
    with pytest.raises(InputError) as err:
        CNNDirectionClassifier.load(old)
    assert str(err.value) == f"{old}: {PICKLE_REFUSAL}"
    missing = tmp_path / "none.safetensors"
    with pytest.raises(InputError) as err:
        CNNDirectionClassifier.load(missing)
    assert str(err.value) == f"{missing}: model file not found"


def test_checkpoints_hold_the_best_model_and_the_optimiser(
    data: tuple[np.ndarray, np.ndarray], tmp_path: Path
) -> None:
    clf = small(epochs=2, checkpoint_dir=tmp_path / "ckpt").fit(*data)
    assert sorted(p.name for p in (tmp_path / "ckpt").iterdir()) == [
        "best.safetensors",
        "last.safetensors",
    ]
    best = CNNDirectionClassifier.load(tmp_path / "ckpt" / "best.safetensors")
    np.testing.assert_array_equal(best.predict_proba(data[0]), clf.predict_proba(data[0]))
    assert best.best_epoch_ == clf.best_epoch_
    assert best.history_ == clf.history_[: clf.best_epoch_]  # written when that epoch ended
    network = build_network("pilotnet")
    optimiser = torch.optim.AdamW(network.parameters())
    meta = load_checkpoint(tmp_path / "ckpt" / "last.safetensors", network, optimiser)
    assert meta["epoch"] == 2 and len(meta["history"]) == 2
    assert meta["architecture"] == "pilotnet"
    state = optimiser.state_dict()["state"]
    assert len(state) == len(list(network.parameters()))  # AdamW moments were saved
    # 46 training frames in batches of 16: 3 steps per epoch
    assert all(float(entry["step"]) == 2 * 3 for entry in state.values())


@pytest.mark.parametrize("lr", [0.05, 0.5])
def test_early_stopping_respects_patience(data: tuple[np.ndarray, np.ndarray], lr: float) -> None:
    clf = small(epochs=6, patience=1, lr=lr).fit(*data)
    losses = [r["val_loss"] for r in clf.history_]
    assert clf.best_epoch_ == 1 + int(np.argmin(losses))  # the best epoch's weights are kept
    if len(losses) < 6:  # stopped early: exactly one epoch without a new minimum
        assert len(losses) == clf.best_epoch_ + 1 and losses[-1] >= losses[-2]
    else:  # ran to the end: no epoch before the last went without a new minimum
        assert all(losses[i] < min(losses[:i]) for i in range(1, 5))


def test_progress_bar_goes_to_stderr(
    data: tuple[np.ndarray, np.ndarray], capsys: pytest.CaptureFixture[str]
) -> None:
    small(progress=True, val_fraction=0.0).fit(*data)
    out = capsys.readouterr()
    assert "pilotnet epoch 1/1 loss" in out.err
    assert out.out == ""
    small(progress=False, val_fraction=0.0).fit(*data)
    assert capsys.readouterr().err == ""


def test_progress_bar_names_a_classical_twin() -> None:
    twin = CNNDirectionClassifier("qdcnn-head", network_params={"head": "classical"})
    assert twin._label() == "qdcnn-head-classical"
    assert CNNDirectionClassifier("qdcnn-head")._label() == "qdcnn-head"


def test_flip_averaging_is_mirror_symmetric(fitted: CNNDirectionClassifier) -> None:
    x, _ = line_frames(9, np.random.default_rng(5))
    params = {**fitted.get_params(), "tta": True}
    tta = CNNDirectionClassifier.from_network(fitted.model_, **params)  # same trained network
    proba = tta.predict_proba(x)
    mirrored = tta.predict_proba(np.ascontiguousarray(x[:, :, ::-1]))
    np.testing.assert_allclose(mirrored, proba[:, [2, 1, 0]], atol=1e-6)
    plain, flipped = fitted.predict_proba(x), fitted.predict_proba(x[:, :, ::-1].copy())
    np.testing.assert_allclose(proba, (plain + flipped[:, [2, 1, 0]]) / 2, atol=1e-6)


def test_cosine_schedule_anneals_to_zero(data: tuple[np.ndarray, np.ndarray]) -> None:
    cosine = small(epochs=3, patience=0, lr=0.002, lr_schedule="cosine").fit(*data)
    rates = [h["lr"] for h in cosine.history_]
    assert rates[0] < 0.002 and rates[1] < rates[0] and rates[2] == pytest.approx(0.0, abs=1e-12)
    constant = small(epochs=2, patience=0, lr=0.002, lr_schedule="constant").fit(*data)
    assert [h["lr"] for h in constant.history_] == [0.002, 0.002]


def test_unweighted_smoothed_loss_learns_and_is_reported(
    data: tuple[np.ndarray, np.ndarray],
) -> None:
    x, y = data
    eps = 0.2
    clf = small(epochs=4, class_weight=None, label_smoothing=eps, max_shift=0.05).fit(x, y)
    test_x, test_y = line_frames(30, np.random.default_rng(1))
    assert clf.score(test_x, test_y) >= 0.8
    # the kept epoch's validation loss is the smoothed, unweighted cross-entropy of the
    # last 15 % of the frames: -(1 - eps) log p_y - (eps / 3) sum_c log p_c
    _, val = split_train_val(len(y), clf.val_fraction)
    logp = np.log(clf.predict_proba(x[val]))
    expected = np.mean(-(1 - eps) * logp[np.arange(len(val)), y[val]] - eps / 3 * logp.sum(1))
    assert clf.history_[clf.best_epoch_ - 1]["val_loss"] == pytest.approx(expected, rel=1e-4)


def test_colour_augment_reaches_the_training_steps(
    data: tuple[np.ndarray, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    from qdcnn.models import augment

    seen: list[object] = []
    real = augment.augment_batch

    def spy(*args: Any, **kw: Any) -> Any:
        seen.append(kw.get("colour"))
        return real(*args, **kw)

    monkeypatch.setattr(augment, "augment_batch", spy)
    small(colour_augment=True).fit(*data)
    assert seen and all(c is True for c in seen)
    seen.clear()
    small().fit(*data)
    assert seen and all(c is False for c in seen)


def test_a_hybrids_stage_one_keeps_colour_augment() -> None:
    hybrid = CNNDirectionClassifier(
        "qdcnn-head", transfer=True, colour_augment=True, classical_recipe={"class_weight": None}
    )
    first = hybrid._classical_estimator("pilotnet")
    assert first.colour_augment is True and first.class_weight is None


def test_colour_randomised_training_still_learns_the_shapes(
    data: tuple[np.ndarray, np.ndarray],
) -> None:
    clf = small(epochs=4, colour_augment=True).fit(*data)
    test_x, test_y = line_frames(30, np.random.default_rng(1))
    assert clf.score(test_x, test_y) >= 0.8


def test_contiguous_validation_split() -> None:
    # 0.15 -> the last of round(1 / 0.15) = 7 contiguous folds (KFold sizes 15, 15, 14, ...)
    train, val = split_train_val(100, 0.15)
    np.testing.assert_array_equal(train, np.arange(86))
    np.testing.assert_array_equal(val, np.arange(86, 100))
    assert len(split_train_val(5, 0.1)[1]) == 1
    assert len(split_train_val(5, 0.0)[1]) == 0
    with pytest.raises(InputError, match="2 frames leave 1 for training; need at least 2"):
        split_train_val(2, 0.5)


def test_validation_blocks_are_spread_and_fenced_by_gaps() -> None:
    train, val = split_train_val(100, 0.2, blocks=4, gap=2)
    blocks = np.split(val, np.flatnonzero(np.diff(val) > 1) + 1)
    assert [b.tolist() for b in blocks] == [list(range(e - 5, e)) for e in (25, 50, 75, 100)]
    gaps = {i for b in blocks for i in range(b[0] - 2, b[-1] + 3)} - set(val.tolist())
    assert set(train.tolist()) == set(range(100)) - set(val.tolist()) - gaps
    assert min(abs(int(t) - int(v)) for t in train for v in val) == 3
    # a class present only in the middle of the recording is validated on
    labels = np.ones(100, np.int64)
    labels[40:50] = 0
    assert 0 in labels[val] and 0 not in labels[split_train_val(100, 0.2)[1]]
    # short inputs: one block when blocks would be shorter than 2 * gap, shorter gaps
    train, val = split_train_val(60, 0.15, blocks=4, gap=5)
    assert val.tolist() == list(range(52, 60)) and train.tolist() == list(range(47))
    train, val = split_train_val(6, 0.15, blocks=4, gap=5)
    assert val.tolist() == [5] and train.tolist() == [0, 1, 2, 3]


def test_class_weights_are_balanced() -> None:
    weights = class_weights(np.array([1, 1, 1, 1, 1, 1, 0, 2]))
    np.testing.assert_allclose(weights, [8 / 3, 8 / 18, 8 / 3])
    np.testing.assert_allclose(class_weights(np.array([0, 1, 1, 1])), [2.0, 2 / 3, 0.0])
    # flips pool left and right: counts (1.5, 1, 1.5) of 4 frames
    mirrored = class_weights(np.array([0, 0, 0, 1]), mirrored=True)
    np.testing.assert_allclose(mirrored, [4 / 4.5, 4 / 3, 4 / 4.5])


def test_input_errors(data: tuple[np.ndarray, np.ndarray]) -> None:
    x, y = data
    with pytest.raises(InputError) as err:
        small().fit(x, np.where(y == 2, 5, y))
    assert str(err.value) == "labels: values must be 0 (left), 1 (straight) or 2 (right); found 5"
    with pytest.raises(InputError) as err:
        small().fit(x.astype(np.float32), y)
    assert str(err.value) == (
        "images: expected a non-empty uint8 RGB array of shape (N, H, W, 3), "
        "got float32 of shape (60, 40, 80, 3)"
    )
    with pytest.raises(InputError) as err:
        small().fit(x, y[:10])
    assert str(err.value) == "labels: expected 60 labels (one per image), got shape (10,)"
    with pytest.raises(NotFittedError):
        small().predict(x)


def fit_error(**params: object) -> str:
    """The ParameterError message of ``fit`` for ``params`` (which ``__init__`` accepts)."""
    frames, labels = line_frames(6, np.random.default_rng(0))
    clf = CNNDirectionClassifier(**params)  # type: ignore[arg-type]
    with pytest.raises(ParameterError) as err:
        clf.fit(frames, labels)
    return str(err.value)


def test_parameter_errors_are_raised_by_fit() -> None:
    assert (
        fit_error(arch="vgg")
        == "arch='vgg' is invalid: one of 'pilotnet', 'resnet50', 'qdcnn-head', 'qdcnn-uuconv', "
        "'qdcnn-quanv'"
    )
    assert fit_error(val_fraction=1.5) == (
        "val_fraction=1.5 is invalid: a finite number in [0, 0.9]"
    )
    assert fit_error(arch="resnet50", batch_size=1) == (
        "batch_size=1 is invalid: an integer in [2, 65536]"
    )
    assert fit_error(crop=(0.8, 0.2)) == (
        "crop=(0.8, 0.2) is invalid: (top, bottom) with 0 <= top < bottom <= 1"
    )
    assert fit_error(class_weight="auto") == "class_weight='auto' is invalid: 'balanced' or None"
    assert fit_error(label_smoothing=0.5) == (
        "label_smoothing=0.5 is invalid: a finite number in [0, 0.5)"
    )
    assert fit_error(lr_schedule="step") == (
        "lr_schedule='step' is invalid: one of 'constant', 'cosine'"
    )
    assert fit_error(max_shift=-0.1) == "max_shift=-0.1 is invalid: a finite number in [0, 0.5]"
    assert fit_error(colour_augment="yes") == "colour_augment='yes' is invalid: True or False"
    assert fit_error(val_blocks=0) == "val_blocks=0 is invalid: an integer in [1, 1000]"
    assert fit_error(epochs=True) == "epochs=True is invalid: an integer in [1, 100000]"
    assert fit_error(context=0) == "context=0 is invalid: an integer in [1, 64]"
    assert fit_error(seed=-1) == "seed=-1 is invalid: an integer in [0, 4294967295]"
    assert fit_error(tta="yes") == "tta='yes' is invalid: True or False"
    assert fit_error(device="") == (
        "device='' is invalid: 'auto', 'cpu', 'cuda', 'cuda:N' or 'mps'"
    )
    assert fit_error(weights=3) == "weights=3 is invalid: a weights file path or None"


def test_clone_keeps_invalid_params_and_fit_rejects_them() -> None:
    frames, labels = line_frames(6, np.random.default_rng(0))
    bad = CNNDirectionClassifier(epochs=0, lr=-1.0)  # scikit-learn: __init__ only stores
    twin = clone(bad)
    assert twin.get_params()["epochs"] == 0 and twin.get_params()["lr"] == -1.0
    with pytest.raises(ParameterError, match=r"^epochs=0 is invalid: an integer in \[1, 100000\]$"):
        twin.fit(frames, labels)
    assert not hasattr(twin, "model_")


def test_is_a_scikit_learn_estimator() -> None:
    clf = CNNDirectionClassifier("resnet50", epochs=3, weights="w.pth")
    twin = clone(clf)
    assert twin.get_params() == clf.get_params()
    assert twin.get_params()["weights"] == "w.pth"


def test_inference_fps_checks_its_arguments() -> None:
    from qdcnn.models.training import inference_fps

    fps = inference_fps("pilotnet", n=4, size=(40, 80), batch_size=2, num_threads=1, clock="cpu")
    assert np.isfinite(fps) and fps > 0
    with pytest.raises(ParameterError) as err:
        inference_fps("pilotnet", n=4, size=(40, 80), clock="gpu")  # type: ignore[arg-type]
    assert str(err.value) == "clock='gpu' is invalid: one of 'wall', 'cpu'"
    with pytest.raises(ParameterError, match="n=0 is invalid"):
        inference_fps("pilotnet", n=0)
