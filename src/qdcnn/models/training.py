"""Training and inference of the CNN direction classifiers (PilotNet, ResNet-50).

:class:`CNNDirectionClassifier` is a scikit-learn estimator (``get_params``,
``clone``, ``score``) that maps RGB frames to 0 = left, 1 = straight, 2 = right.
This module imports without torch; torch is loaded when a model is built.
"""

from __future__ import annotations

import copy
import math
import os
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.utils.validation import check_is_fitted

from qdcnn._optional import require
from qdcnn.data.labels import DIRECTIONS, LEFT, RIGHT, STRAIGHT
from qdcnn.errors import InputError, ParameterError

if TYPE_CHECKING:
    import torch
    from torch import nn

    from qdcnn.models.preprocess import InputSpec

Arch = Literal["pilotnet", "resnet50"]
ARCHS: tuple[str, ...] = ("pilotnet", "resnet50")
N_CLASSES = len(DIRECTIONS)
FILE_FORMAT = "qdcnn-cnn-direction-classifier/1"
_RESNET_WEIGHTS_NAME = "torchvision ResNet-50"


def _torch(purpose: str) -> Any:
    return require("torch", purpose)


def _default_threads() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _check_int(name: str, value: object, lo: int, hi: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not lo <= value <= hi:
        raise ParameterError(name, value, f"an integer in [{lo}, {hi}]")


def _check_float(name: str, value: object, lo: float, hi: float, *, open_lo: bool = False) -> None:
    ok = (
        isinstance(value, int | float | np.floating)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and (lo < value if open_lo else lo <= value)
        and value <= hi
    )
    if not ok:
        allowed = f"a number in ({lo}, {hi}]" if open_lo else f"a number in [{lo}, {hi}]"
        raise ParameterError(name, value, allowed)


def _as_images(images: ArrayLike | Sequence[NDArray[np.uint8]]) -> NDArray[np.uint8]:
    if isinstance(images, np.ndarray):
        arr = images
    else:
        try:
            arr = np.stack([np.asarray(im) for im in images])  # type: ignore[union-attr]
        except (TypeError, ValueError):
            raise InputError(
                "images", "expected a uint8 array (N, H, W, 3) or a list of equal-size frames"
            ) from None
    if arr.dtype != np.uint8 or arr.ndim != 4 or arr.shape[-1] != 3 or 0 in arr.shape:
        raise InputError(
            "images",
            f"expected a non-empty uint8 RGB array of shape (N, H, W, 3), "
            f"got {arr.dtype} of shape {arr.shape}",
        )
    return arr


def _as_labels(labels: ArrayLike, n: int) -> NDArray[np.int64]:
    y = np.asarray(labels)
    if y.ndim != 1 or len(y) != n:
        raise InputError("labels", f"expected {n} labels (one per image), got shape {y.shape}")
    if y.dtype.kind == "f" and np.all(np.isfinite(y)) and np.all(y == np.round(y)):
        y = y.astype(np.int64)
    if y.dtype.kind not in "iu" or np.any((y < 0) | (y >= N_CLASSES)):
        bad = y[0] if y.dtype.kind not in "iu" else y[(y < 0) | (y >= N_CLASSES)][0]
        raise InputError(
            "labels", f"values must be 0 (left), 1 (straight) or 2 (right); found {bad.item()!r}"
        )
    return y.astype(np.int64)


def class_weights(labels: NDArray[np.int64], *, mirrored: bool = False) -> NDArray[np.float64]:
    """Balanced class weights ``n / (k * n_c)`` (scikit-learn's rule); 0 for absent classes.

    Parameters
    ----------
    labels : (N,) int ndarray
        Training labels, 0 = left, 1 = straight, 2 = right.
    mirrored : bool
        Count left and right as the flip augmentation sees them: each half of
        ``n_left + n_right``, so frames flipped into a rare class are not over-weighted.

    Examples
    --------
    >>> class_weights(np.array([0, 1, 1, 1]))
    array([2.        , 0.66666667, 0.        ])
    >>> class_weights(np.array([0, 1, 1, 1]), mirrored=True)
    array([2.66666667, 0.44444444, 2.66666667])
    """
    counts = np.bincount(labels, minlength=N_CLASSES).astype(np.float64)
    if mirrored:
        counts[LEFT] = counts[RIGHT] = (counts[LEFT] + counts[RIGHT]) / 2
    present = counts > 0
    weights = np.zeros(N_CLASSES)
    weights[present] = len(labels) / (present.sum() * counts[present])
    return weights


def split_train_val(
    n: int, val_fraction: float, *, blocks: int = 1, gap: int = 0
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Indices of a contiguous-block split of ``n`` frames in recording order.

    ``val_fraction`` of the frames validate, as ``blocks`` contiguous blocks
    spread evenly over the recording, the last one ending at the last frame
    (``blocks=1``: the last frames). The ``gap`` frames on each side of a block
    neither train nor validate. Frames are video: a random split would put
    near-identical neighbours on both sides, and labels smoothed over
    neighbouring frames leak across a block edge without the gap. One block at
    the end of a short recording can miss a class altogether (a left bend, say),
    so early stopping would favour epochs that never predict it; several blocks
    sample several stretches of road. On short inputs the split degrades
    gracefully: a block is at least ``2 * gap`` frames long (fewer blocks
    otherwise), and the gaps are shortened so that they take at most half of
    the frames that do not validate. At least one frame validates when
    ``val_fraction > 0`` and ``n >= 3``.

    Examples
    --------
    >>> train, val = split_train_val(10, 0.2)
    >>> train.tolist(), val.tolist()
    ([0, 1, 2, 3, 4, 5, 6, 7], [8, 9])
    >>> train, val = split_train_val(20, 0.2, blocks=2, gap=1)
    >>> train.tolist(), val.tolist()
    ([0, 1, 2, 3, 4, 5, 6, 11, 12, 13, 14, 15, 16], [8, 9, 18, 19])
    """
    n_val = round(n * val_fraction)
    if val_fraction > 0 and n_val == 0 and n >= 3:
        n_val = 1
    n_blocks = max(1, min(blocks, n_val // max(1, 2 * gap)))
    gap = min(gap, (n - n_val) // (4 * n_blocks))
    sizes = np.diff(np.linspace(0, n_val, n_blocks + 1).round().astype(np.int64))
    ends = np.linspace(0, n, n_blocks + 1).round().astype(np.int64)[1:]
    in_val = np.zeros(n, dtype=bool)
    near_val = np.zeros(n, dtype=bool)
    for end, size in zip(ends, sizes, strict=True):
        if size:
            in_val[end - size : end] = True
            near_val[max(end - size - gap, 0) : min(end + gap, n)] = True
    train = np.flatnonzero(~near_val).astype(np.int64)
    if len(train) < 2:
        raise InputError("images", f"{n} frames leave {len(train)} for training; need at least 2")
    return train, np.flatnonzero(in_val).astype(np.int64)


def _batches(order: NDArray[np.int64], batch_size: int) -> list[NDArray[np.int64]]:
    """Consecutive batches of ``order``; a last batch of one joins the one before.

    BatchNorm cannot normalise a batch of one frame in training mode.
    """
    chunks = [order[i : i + batch_size] for i in range(0, len(order), batch_size)]
    if len(chunks) > 1 and len(chunks[-1]) == 1:
        chunks[-2] = np.concatenate(chunks[-2:])
        chunks.pop()
    return chunks


@contextmanager
def _torch_session(num_threads: int, seed: int | None, device: torch.device) -> Iterator[None]:
    """Set threads, seeds and deterministic kernels for one call; restore them afterwards."""
    torch = _torch("the CNN baselines")
    old_threads = torch.get_num_threads()
    old_deterministic = torch.are_deterministic_algorithms_enabled()
    old_warn = torch.is_deterministic_algorithms_warn_only_enabled()
    old_cudnn = (torch.backends.cudnn.deterministic, torch.backends.cudnn.benchmark)
    devices = [device.index or 0] if device.type == "cuda" else []
    torch.set_num_threads(num_threads)
    try:
        with torch.random.fork_rng(devices=devices):
            if seed is not None:
                torch.manual_seed(seed)
                torch.use_deterministic_algorithms(True, warn_only=True)
                torch.backends.cudnn.deterministic = True
                torch.backends.cudnn.benchmark = False
            yield
    finally:
        torch.set_num_threads(old_threads)
        torch.use_deterministic_algorithms(old_deterministic, warn_only=old_warn)
        torch.backends.cudnn.deterministic, torch.backends.cudnn.benchmark = old_cudnn


def build_model(arch: str, num_classes: int = N_CLASSES) -> nn.Module:
    """A freshly initialised PilotNet or ResNet-50 with ``num_classes`` outputs."""
    if arch == "pilotnet":
        from qdcnn.models.pilotnet import PilotNet

        return PilotNet(num_classes=num_classes)
    if arch == "resnet50":
        from qdcnn.models.resnet import resnet50

        return resnet50(num_classes=num_classes)
    raise ParameterError("arch", arch, "'pilotnet' or 'resnet50'")


def input_spec(arch: str, crop: tuple[float, float] | None = None) -> InputSpec:
    """Preprocessing of ``arch`` (:mod:`qdcnn.models.preprocess`), optionally with another crop."""
    from dataclasses import replace

    from qdcnn.models.preprocess import PILOTNET_INPUT, RESNET50_INPUT

    spec = PILOTNET_INPUT if arch == "pilotnet" else RESNET50_INPUT
    return spec if crop is None else replace(spec, crop=(float(crop[0]), float(crop[1])))


class CNNDirectionClassifier(ClassifierMixin, BaseEstimator):
    """Direction classifier (left / straight / right) on RGB road frames with a CNN.

    Frames are cropped to the road (sky and car hood removed, rows relative to
    the frame height), resized to the network input and colour-normalised
    (:mod:`qdcnn.models.preprocess`). Training uses AdamW with a per-step
    cosine learning rate, cross-entropy with label smoothing (optionally
    class-weighted: :func:`class_weights`), seeded augmentation
    (:mod:`qdcnn.models.augment`) and early stopping on contiguous validation
    blocks spread over the training frames, fenced by gaps
    (:func:`split_train_val`): the frames are a video, and a random split would
    put near-duplicate neighbours on both sides. The weights of the epoch with
    the lowest validation loss are kept.

    The defaults suit recordings of a few hundred to a few thousand frames:
    small batches give enough optimisation steps in 25 epochs (a 600-frame
    recording gives 8 steps per epoch at 64 frames), the unweighted loss targets
    accuracy (the metric of the paper's table), smoothing softens labels from
    keyboard steering, and several validation blocks keep early stopping from
    judging on one stretch of road. They were compared on inner contiguous
    splits of the mountain recording (``benchmarks/cnn_study.py --parts dev``),
    never on test folds.

    Parameters
    ----------
    arch : {"pilotnet", "resnet50"}
        PilotNet (Bojarski et al. 2016, 66x200 YUV input) or ResNet-50 (He et
        al. 2016, 224x224 ImageNet-normalised input; the paper's baseline).
    epochs : int
        Maximum training epochs (the paper: 25).
    batch_size : int
        Frames per optimisation step (at least 2 for ResNet-50's BatchNorm).
        Inference runs in chunks of ``max(batch_size, 64)`` frames.
    lr, weight_decay : float
        AdamW learning rate and decoupled weight decay.
    val_fraction : float
        Fraction of the training frames held out for early stopping, as
        ``val_blocks`` contiguous blocks (:func:`split_train_val`); 0 trains on
        everything for ``epochs`` epochs.
    val_blocks : int
        Validation blocks spread over the recording (1: its last frames).
    val_gap : int
        Frames on each side of a validation block left out of training (labels
        are steering smoothed over neighbouring frames).
    patience : int
        Stop after this many epochs without a lower validation loss; 0 never stops early.
    augment : bool
        Flip (swapping left and right), brightness and shadow augmentation.
    max_shift : float
        Largest random horizontal shift of a training frame, as a fraction of its
        width (labels kept; 0 disables shifts). Only with ``augment``.
    class_weight : {"balanced", None}
        ``"balanced"`` weights the cross-entropy by :func:`class_weights`, which
        trades accuracy for recall of the rare turns; ``None`` (plain
        cross-entropy) targets accuracy.
    label_smoothing : float
        Cross-entropy label smoothing in [0, 0.5): direction labels from
        keyboard steering are noisy near the class thresholds.
    lr_schedule : {"constant", "cosine"}
        Learning rate held at ``lr``, or cosine-annealed per step from ``lr``
        to 0 over ``epochs`` (early stopping may end training sooner).
    tta : bool
        Test-time flip averaging: the probabilities of a frame and of its mirror
        image (left and right swapped) are averaged. Doubles inference cost.
    weights : path or None
        Initial weights from a local file. For ResNet-50 a torchvision-format
        ImageNet ``state_dict`` whose ``fc`` layer is replaced by a 3-class head;
        for PilotNet a complete PilotNet ``state_dict``. Never downloaded.
    device : str
        ``"auto"`` (CUDA, then Apple MPS, then CPU) or a torch device string.
    seed : int
        Seeds initialisation, dropout, shuffling and augmentation; the same seed
        gives identical predictions on the same device and thread count.
    checkpoint_dir : path or None
        When set, ``last.pt`` (model, optimiser, history) is written after each
        epoch and ``best.pt`` (loadable with :meth:`load`) whenever validation improves.
    progress : bool
        Show a Rich progress bar on stderr while fitting.
    num_threads : int or None
        CPU threads torch uses during ``fit``/``predict`` (default: the CPUs this
        process may run on); restored afterwards.
    crop : (float, float) or None
        Rows kept, as fractions of the frame height; default ``(0.375, 0.84375)``
        (rows 60..135 of a 160-row Udacity frame).

    Attributes
    ----------
    model_ : torch.nn.Module
        The trained network (in eval mode).
    history_ : list of dict
        Per epoch: ``epoch``, ``train_loss``, ``val_loss``, ``val_accuracy``
        (``None`` without validation), ``lr`` (the learning rate at the epoch's
        end), ``seconds``.
    best_epoch_ : int
        The epoch whose weights were kept (1-based).
    classes_ : ndarray
        ``[0, 1, 2]``.

    Examples
    --------
    >>> clf = CNNDirectionClassifier("pilotnet", epochs=1, progress=False)
    >>> clf.get_params()["arch"]
    'pilotnet'
    """

    def __init__(
        self,
        arch: Arch = "pilotnet",
        *,
        epochs: int = 25,
        batch_size: int = 16,
        lr: float = 1e-3,
        weight_decay: float = 1e-4,
        val_fraction: float = 0.15,
        val_blocks: int = 4,
        val_gap: int = 5,
        patience: int = 8,
        augment: bool = True,
        max_shift: float = 0.0,
        class_weight: Literal["balanced"] | None = None,
        label_smoothing: float = 0.1,
        lr_schedule: Literal["constant", "cosine"] = "cosine",
        tta: bool = False,
        weights: str | Path | None = None,
        device: str = "auto",
        seed: int = 0,
        checkpoint_dir: str | Path | None = None,
        progress: bool = True,
        num_threads: int | None = None,
        crop: tuple[float, float] | None = None,
    ) -> None:
        self.arch = arch
        self.epochs = epochs
        self.batch_size = batch_size
        self.lr = lr
        self.weight_decay = weight_decay
        self.val_fraction = val_fraction
        self.val_blocks = val_blocks
        self.val_gap = val_gap
        self.patience = patience
        self.augment = augment
        self.max_shift = max_shift
        self.class_weight = class_weight
        self.label_smoothing = label_smoothing
        self.lr_schedule = lr_schedule
        self.tta = tta
        self.weights = weights
        self.device = device
        self.seed = seed
        self.checkpoint_dir = checkpoint_dir
        self.progress = progress
        self.num_threads = num_threads
        self.crop = crop
        self._check_params()

    # ----------------------------------------------------------------- checks
    def _check_params(self) -> None:
        if self.arch not in ARCHS:
            raise ParameterError("arch", self.arch, "'pilotnet' or 'resnet50'")
        _check_int("epochs", self.epochs, 1, 100_000)
        _check_int("batch_size", self.batch_size, 2 if self.arch == "resnet50" else 1, 65_536)
        _check_float("lr", self.lr, 0.0, 10.0, open_lo=True)
        _check_float("weight_decay", self.weight_decay, 0.0, 10.0)
        _check_float("val_fraction", self.val_fraction, 0.0, 0.9)
        _check_int("val_blocks", self.val_blocks, 1, 1000)
        _check_int("val_gap", self.val_gap, 0, 100_000)
        _check_int("patience", self.patience, 0, 100_000)
        _check_float("max_shift", self.max_shift, 0.0, 0.5)
        _check_float("label_smoothing", self.label_smoothing, 0.0, 0.49)
        if self.class_weight not in ("balanced", None):
            raise ParameterError("class_weight", self.class_weight, "'balanced' or None")
        if self.lr_schedule not in ("constant", "cosine"):
            raise ParameterError("lr_schedule", self.lr_schedule, "'constant' or 'cosine'")
        _check_int("seed", self.seed, 0, 2**63 - 1)
        if self.num_threads is not None:
            _check_int("num_threads", self.num_threads, 1, 4096)
        if not isinstance(self.device, str) or not self.device:
            raise ParameterError("device", self.device, "'auto', 'cpu', 'cuda', 'cuda:N' or 'mps'")
        if self.crop is not None:
            ok = (
                isinstance(self.crop, tuple | list)
                and len(self.crop) == 2
                and all(isinstance(c, int | float) for c in self.crop)
                and 0.0 <= self.crop[0] < self.crop[1] <= 1.0
            )
            if not ok:
                raise ParameterError("crop", self.crop, "(top, bottom) with 0 <= top < bottom <= 1")

    def _resolve_device(self) -> torch.device:
        torch = _torch("the CNN baselines")
        if self.device == "auto":
            if torch.cuda.is_available():
                return torch.device("cuda")
            mps = getattr(torch.backends, "mps", None)
            return torch.device("mps" if mps is not None and mps.is_available() else "cpu")
        try:
            dev = torch.device(self.device)
        except (RuntimeError, ValueError):
            raise ParameterError(
                "device", self.device, "'auto', 'cpu', 'cuda', 'cuda:N' or 'mps'"
            ) from None
        if dev.type == "cuda" and not torch.cuda.is_available():
            raise ParameterError("device", self.device, "a device present here (no CUDA GPU found)")
        return dev

    def _threads(self) -> int:
        return self.num_threads if self.num_threads is not None else _default_threads()

    def _new_model(self) -> nn.Module:
        model = build_model(self.arch)
        if self.weights is not None:
            from qdcnn.models.weights import load_weights

            if self.arch == "resnet50":
                load_weights(model, self.weights, name=_RESNET_WEIGHTS_NAME, skip_prefixes=("fc.",))
            else:
                load_weights(model, self.weights, name="qdcnn PilotNet")
        return model

    # -------------------------------------------------------------- training
    def fit(
        self, images: ArrayLike | Sequence[NDArray[np.uint8]], labels: ArrayLike
    ) -> CNNDirectionClassifier:
        """Train on frames in recording order.

        Parameters
        ----------
        images : (N, H, W, 3) uint8 array or sequence of equal-size frames
            RGB frames in the order they were recorded.
        labels : (N,) int array
            0 = left, 1 = straight, 2 = right.

        Returns
        -------
        self
        """
        self._check_params()
        torch = _torch("training a CNN direction classifier")
        from torch.nn import functional as F

        from qdcnn.models.augment import augment_batch
        from qdcnn.models.preprocess import crop_resize, normalise

        x_np = _as_images(images)
        y_np = _as_labels(labels, len(x_np))
        n = len(x_np)
        train_idx, val_idx = split_train_val(
            n, self.val_fraction, blocks=self.val_blocks, gap=self.val_gap
        )
        n_train, n_val = len(train_idx), len(val_idx)
        spec = input_spec(self.arch, self.crop)
        device = self._resolve_device()

        with _torch_session(self._threads(), self.seed, device):
            model = _place(self._new_model(), device)  # first: a bad weights file fails fast
            frames = crop_resize(x_np, spec)
            targets = torch.from_numpy(y_np)
            optimiser = torch.optim.AdamW(
                model.parameters(), lr=self.lr, weight_decay=self.weight_decay
            )
            weight_cpu = torch.tensor(
                class_weights(y_np[train_idx], mirrored=self.augment)
                if self.class_weight == "balanced"
                else np.ones(N_CLASSES),
                dtype=torch.float32,
            )
            weight = weight_cpu.to(device)
            smoothing = float(self.label_smoothing)
            shuffle_gen = torch.Generator().manual_seed(self.seed)
            augment_gen = torch.Generator().manual_seed(self.seed + 1)

            def evaluate(idx: NDArray[np.int64]) -> tuple[float, float]:
                model.eval()
                loss_sum, correct = 0.0, 0
                with torch.inference_mode():
                    for chunk in _batches(idx, max(self.batch_size, 64)):
                        rows = torch.from_numpy(chunk)
                        xb = normalise(frames[rows].to(device), spec)
                        yb = targets[rows].to(device)
                        logits = model(xb)
                        loss_sum += float(
                            F.cross_entropy(
                                logits,
                                yb,
                                weight=weight,
                                reduction="sum",
                                label_smoothing=smoothing,
                            )
                        )
                        correct += int((logits.argmax(1) == yb).sum())
                # normalise as the weighted mean reduction does
                denominator = float(weight_cpu[targets[torch.from_numpy(idx)]].sum()) or 1.0
                return loss_sum / denominator, correct / len(idx)

            history: list[dict[str, Any]] = []
            best_loss, best_epoch, best_state = math.inf, 0, None
            n_steps = self.epochs * len(_batches(np.arange(n_train), self.batch_size))
            scheduler = (
                torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, T_max=n_steps)
                if self.lr_schedule == "cosine"
                else None
            )
            with _progress_bar(self.progress) as bar:
                task = bar.add_task(f"{self.arch} epoch 1/{self.epochs}", total=n_steps)
                for epoch in range(1, self.epochs + 1):
                    start = time.perf_counter()
                    model.train()
                    order = train_idx[torch.randperm(n_train, generator=shuffle_gen).numpy()]
                    loss_sum, weight_sum = 0.0, 0.0
                    for idx in _batches(order, self.batch_size):
                        rows = torch.from_numpy(idx)
                        xb, yb = frames[rows].to(device), targets[rows].to(device)
                        if self.augment:
                            xb, yb = augment_batch(
                                xb, yb, augment_gen, max_shift=float(self.max_shift)
                            )
                        loss = F.cross_entropy(
                            model(normalise(xb, spec)),
                            yb,
                            weight=weight,
                            label_smoothing=smoothing,
                        )
                        optimiser.zero_grad(set_to_none=True)
                        loss.backward()
                        optimiser.step()
                        if scheduler is not None:
                            scheduler.step()
                        w = float(weight[yb].sum())
                        loss_sum += loss.item() * w
                        weight_sum += w
                        bar.advance(task)
                    record: dict[str, Any] = {
                        "epoch": epoch,
                        "train_loss": loss_sum / (weight_sum or 1.0),
                        "val_loss": None,
                        "val_accuracy": None,
                        "lr": optimiser.param_groups[0]["lr"],
                    }
                    if n_val:
                        record["val_loss"], record["val_accuracy"] = evaluate(val_idx)
                    record["seconds"] = time.perf_counter() - start
                    history.append(record)
                    score = record["val_loss"] if n_val else -epoch  # no validation: keep the last
                    improved = score < best_loss
                    if improved:
                        best_loss, best_epoch = score, epoch
                        best_state = copy.deepcopy(model.state_dict())
                    bar.update(task, description=_describe(self.arch, record, self.epochs))
                    if self.checkpoint_dir is not None:
                        self._write_checkpoints(model, optimiser, history, best_epoch, improved)
                    if n_val and self.patience and epoch - best_epoch >= self.patience:
                        break
            assert best_state is not None  # at least one epoch ran
            model.load_state_dict(best_state)
            model.eval()

        self.model_ = model
        self.device_ = device
        self.history_ = history
        self.best_epoch_ = best_epoch
        self.classes_ = np.arange(N_CLASSES)
        return self

    def _write_checkpoints(
        self,
        model: nn.Module,
        optimiser: torch.optim.Optimizer,
        history: list[dict[str, Any]],
        best_epoch: int,
        improved: bool,
    ) -> None:
        torch = _torch("writing checkpoints")
        folder = Path(self.checkpoint_dir)  # type: ignore[arg-type]
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputError(folder, f"cannot create checkpoint folder: {exc.strerror}") from None
        state = {k: v.detach().cpu() for k, v in model.state_dict().items()}
        if improved:
            _atomic_save(torch, self._payload(state, history, best_epoch), folder / "best.pt")
        last = {
            "format": FILE_FORMAT + "+checkpoint",
            "arch": self.arch,
            "epoch": len(history),
            "best_epoch": best_epoch,
            "state_dict": state,
            "optimizer": optimiser.state_dict(),
            "history": history,
        }
        _atomic_save(torch, last, folder / "last.pt")

    # -------------------------------------------------------------- inference
    def predict_proba(self, images: ArrayLike | Sequence[NDArray[np.uint8]]) -> NDArray[np.float64]:
        """Class probabilities ``(N, 3)`` for left, straight, right."""
        check_is_fitted(self, "model_")
        torch = _torch("CNN inference")
        from qdcnn.models.preprocess import crop_resize, normalise

        x_np = _as_images(images)
        spec = input_spec(self.arch, self.crop)
        out = np.empty((len(x_np), N_CLASSES), dtype=np.float64)
        step = max(self.batch_size, 64)
        self.model_.eval()
        with _torch_session(self._threads(), None, self.device_), torch.inference_mode():
            for start in range(0, len(x_np), step):
                xb = normalise(crop_resize(x_np[start : start + step], spec).to(self.device_), spec)
                proba = torch.softmax(self.model_(xb).float(), 1)
                if self.tta:
                    mirrored = torch.softmax(self.model_(xb.flip(-1)).float(), 1)
                    proba = (proba + mirrored[:, [RIGHT, STRAIGHT, LEFT]]) / 2
                out[start : start + step] = proba.cpu().numpy()
        return out

    def predict(self, images: ArrayLike | Sequence[NDArray[np.uint8]]) -> NDArray[np.int64]:
        """Direction per frame: 0 = left, 1 = straight, 2 = right."""
        return np.argmax(self.predict_proba(images), axis=1).astype(np.int64)

    def score(
        self,
        images: ArrayLike | Sequence[NDArray[np.uint8]],
        labels: ArrayLike,
        sample_weight: ArrayLike | None = None,
    ) -> float:
        """Accuracy of :meth:`predict` against ``labels``."""
        x_np = _as_images(images)
        y = _as_labels(labels, len(x_np))
        hits = (self.predict(x_np) == y).astype(np.float64)
        if sample_weight is None:
            return float(hits.mean())
        return float(np.average(hits, weights=np.asarray(sample_weight, dtype=np.float64)))

    # ------------------------------------------------------------ persistence
    def _payload(
        self, state: dict[str, torch.Tensor], history: list[dict[str, Any]], best_epoch: int
    ) -> dict[str, Any]:
        params = {
            k: (str(v) if isinstance(v, Path) else (list(v) if isinstance(v, tuple) else v))
            for k, v in self.get_params().items()
        }
        return {
            "format": FILE_FORMAT,
            "arch": self.arch,
            "params": params,
            "state_dict": state,
            "history": history,
            "best_epoch": best_epoch,
        }

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the trained model, its settings and history to ``path`` (a torch file)."""
        check_is_fitted(self, "model_")
        torch = _torch("saving a CNN direction classifier")
        state = {k: v.detach().cpu() for k, v in self.model_.state_dict().items()}
        _atomic_save(torch, self._payload(state, self.history_, self.best_epoch_), Path(path))

    @classmethod
    def load(
        cls, path: str | os.PathLike[str], *, device: str | None = None
    ) -> CNNDirectionClassifier:
        """Read a classifier written by :meth:`save` (or a ``best.pt`` checkpoint).

        Parameters
        ----------
        path : str or path-like
            The file.
        device : str or None
            Override the saved device setting (for example ``"cpu"``).

        Raises
        ------
        InputError
            The file is missing, corrupt or not a saved classifier.
        """
        from qdcnn.models.weights import as_state_dict, check_state_dict, read_weights_file

        obj = read_weights_file(path)
        if not isinstance(obj, dict) or obj.get("format") != FILE_FORMAT:
            raise InputError(path, "not a saved qdcnn CNN direction classifier")
        params = dict(obj.get("params") or {})
        if params.get("crop") is not None:
            params["crop"] = tuple(params["crop"])
        if device is not None:
            params["device"] = device
        try:
            clf = cls(**params)
        except (TypeError, ParameterError) as exc:
            raise InputError(path, f"saved settings are invalid: {exc}") from None
        model = build_model(clf.arch)
        state = as_state_dict(obj.get("state_dict"), path)
        checked = check_state_dict(state, model, path, name=f"qdcnn {clf.arch}")
        model.load_state_dict(checked, strict=False)
        clf.device_ = clf._resolve_device()
        clf.model_ = _place(model, clf.device_).eval()
        clf.history_ = list(obj.get("history") or [])
        clf.best_epoch_ = int(obj.get("best_epoch") or 0)
        clf.classes_ = np.arange(N_CLASSES)
        return clf

    def _init_untrained(self) -> CNNDirectionClassifier:
        """Make the estimator usable for inference with initial weights (benchmarks)."""
        self._check_params()
        self.device_ = self._resolve_device()
        with _torch_session(self._threads(), self.seed, self.device_):
            self.model_ = _place(self._new_model(), self.device_).eval()
        self.history_, self.best_epoch_, self.classes_ = [], 0, np.arange(N_CLASSES)
        return self


def _place(model: nn.Module, device: torch.device) -> nn.Module:
    """Move ``model`` to ``device``, channels-last on CPU and CUDA (faster convolutions)."""
    torch = _torch("the CNN baselines")
    if device.type in ("cpu", "cuda"):
        # memory_format is a documented keyword that torch's type stubs omit
        return model.to(device, memory_format=torch.channels_last)  # type: ignore[call-overload]
    return model.to(device)


def _describe(arch: str, record: dict[str, Any], epochs: int) -> str:
    text = f"{arch} epoch {record['epoch']}/{epochs} loss {record['train_loss']:.3f}"
    if record["val_loss"] is not None:
        text += f" val {record['val_loss']:.3f} acc {record['val_accuracy']:.2f}"
    return text


@contextmanager
def _progress_bar(enabled: bool) -> Iterator[Any]:
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        disable=not enabled,
    ) as bar:
        yield bar


def _atomic_save(torch: Any, payload: dict[str, Any], path: Path) -> None:
    tmp = path.with_name(path.name + ".tmp")
    try:
        torch.save(payload, tmp)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise InputError(path, f"cannot write: {exc.strerror or exc}") from None


def inference_fps(
    arch: Arch = "pilotnet",
    *,
    n: int = 256,
    size: tuple[int, int] = (160, 320),
    batch_size: int = 64,
    num_threads: int | None = None,
    seed: int = 0,
    tta: bool = False,
    clock: Literal["wall", "cpu"] = "wall",
) -> float:
    """Frames per second of :meth:`CNNDirectionClassifier.predict` on the CPU.

    Times preprocessing and the forward pass of an untrained network (the cost
    does not depend on the weights) on ``n`` random ``size`` = (H, W) RGB frames,
    after one warm-up batch.

    Parameters
    ----------
    arch : {"pilotnet", "resnet50"}
        The network.
    n, size, batch_size : int, (int, int), int
        Frames timed, their (height, width), and frames per forward pass.
    num_threads : int or None
        torch CPU threads (default: the CPUs this process may run on).
    seed : int
        Seeds the random frames and the initial weights.
    tta : bool
        Time flip-averaged prediction (two forward passes per frame).
    clock : {"wall", "cpu"}
        Elapsed time, or this process's CPU time: on a shared machine the CPU
        time of a one-thread run is close to the wall time of an idle core.

    Examples
    --------
    >>> inference_fps("pilotnet", n=8, size=(80, 160)) > 0  # doctest: +SKIP
    True
    """
    _check_int("n", n, 1, 10**7)
    if clock not in ("wall", "cpu"):
        raise ParameterError("clock", clock, "'wall' or 'cpu'")
    if len(size) != 2 or min(size) < 1:
        raise ParameterError("size", size, "(height, width) with positive integers")
    clf = CNNDirectionClassifier(
        arch,
        batch_size=batch_size,
        device="cpu",
        num_threads=num_threads,
        seed=seed,
        progress=False,
        tta=tta,
    )._init_untrained()
    timer = time.perf_counter if clock == "wall" else time.process_time
    frames = np.random.default_rng(seed).integers(0, 256, (n, *size, 3), dtype=np.uint8)
    clf.predict(frames[: min(n, batch_size)])
    start = timer()
    clf.predict(frames)
    return n / (timer() - start)
