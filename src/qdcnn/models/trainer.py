"""A training loop for any network that maps frames ``(B, C, H, W)`` to direction logits ``(B, 3)``.

:class:`Trainer` trains a ``torch.nn.Module`` with AdamW, a per-step cosine (or
constant) learning rate, cross-entropy with label smoothing and optional class
weights, seeded augmentation (:mod:`qdcnn.models.augment`) and early stopping on
contiguous validation blocks fenced by gaps
(:func:`~qdcnn.models.samples.split_train_val`); the weights of the epoch with
the lowest validation loss are kept. It knows nothing of architectures or
estimators: samples come as :class:`FrameSamples` (windows into a pool of pixel
frames, so stacked context frames cost no copies), a ``transform`` turns
augmented pixels into the network's input, and progress goes to optional
``on_step`` / ``on_epoch`` callbacks (:func:`rich_progress` makes a Rich bar of them).
"""

from __future__ import annotations

import copy
import math
import os
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn._optional import require
from qdcnn._validation import (
    check_bool,
    check_choice,
    check_float,
    check_int,
    check_seed,
    has_shape,
)
from qdcnn.errors import InputError, ParameterError
from qdcnn.models.samples import N_CLASSES, class_weights, context_windows, split_train_val

require("torch", "training CNN direction classifiers")
import torch  # noqa: E402
from torch import nn  # noqa: E402
from torch.nn import functional as F  # noqa: E402

__all__ = [
    "EpochCallback",
    "FrameSamples",
    "StepCallback",
    "TrainResult",
    "TrainSettings",
    "Trainer",
    "class_weights",
    "default_threads",
    "place",
    "resolve_device",
    "rich_progress",
    "split_train_val",
    "torch_session",
]

#: ``on_step(step, total_steps)`` after every optimisation step (1-based).
StepCallback = Callable[[int, int], None]
#: ``on_epoch(record, epochs)`` after every epoch, ``record`` as in :attr:`TrainResult.history`.
EpochCallback = Callable[[Mapping[str, Any], int], None]
_DEVICES = "'auto', 'cpu', 'cuda', 'cuda:N' or 'mps'"
#: The largest learning rate the settings accept.
MAX_LR = 10.0
#: How the kept epoch is chosen: the lowest validation loss, or the highest validation
#: balanced accuracy (ties: the lower loss).
SELECTIONS: tuple[str, str] = ("loss", "balanced_accuracy")
#: ``rebuild(seed)``: a freshly initialised network for a restart with ``seed``.
Rebuild = Callable[[int], nn.Module]


def default_threads() -> int:
    """CPUs this process may run on (``taskset`` and cgroups respected on Linux)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def resolve_device(name: object) -> torch.device:
    """A torch device for ``name``: ``"auto"`` is CUDA, then Apple MPS, then the CPU.

    Raises
    ------
    ParameterError
        Not a device string, or a CUDA device on a machine without one.
    """
    if not isinstance(name, str) or not name:
        raise ParameterError("device", name, _DEVICES)
    if name == "auto":
        if torch.cuda.is_available():
            return torch.device("cuda")
        mps = getattr(torch.backends, "mps", None)
        return torch.device("mps" if mps is not None and mps.is_available() else "cpu")
    try:
        device = torch.device(name)
    except (RuntimeError, ValueError):
        raise ParameterError("device", name, _DEVICES) from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise ParameterError("device", name, "a device present here (no CUDA GPU found)")
    return device


def place(network: nn.Module, device: torch.device) -> nn.Module:
    """Move ``network`` to ``device``, channels-last on CPU and CUDA (faster convolutions)."""
    if device.type in ("cpu", "cuda"):
        # memory_format is a documented keyword that torch's type stubs omit
        return network.to(device, memory_format=torch.channels_last)  # type: ignore[call-overload]
    return network.to(device)


@contextmanager
def torch_session(num_threads: int, seed: int | None, device: torch.device) -> Iterator[None]:
    """Set threads, seeds and deterministic kernels for one call; restore them afterwards."""
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


@dataclass(frozen=True)
class TrainSettings:
    """Settings of :class:`Trainer`; the names and meanings of the estimator's parameters.

    See :class:`~qdcnn.models.training.CNNDirectionClassifier` for each field.
    ``checked()`` validates them (one :class:`ParameterError` naming the field).
    """

    epochs: int = 25
    batch_size: int = 16
    lr: float = 1e-3
    weight_decay: float = 1e-4
    val_fraction: float = 0.15
    val_blocks: int = 4
    val_gap: int = 5
    patience: int = 8
    augment: bool = True
    max_shift: float = 0.0
    colour_augment: bool = False
    class_weight: Literal["balanced"] | None = None
    label_smoothing: float = 0.1
    lr_schedule: Literal["constant", "cosine"] = "cosine"
    select: Literal["loss", "balanced_accuracy"] = "loss"
    restarts: int = 0
    seed: int = 0
    device: str = "cpu"
    num_threads: int | None = None
    checkpoint_dir: str | Path | None = None

    def checked(self, *, min_batch_size: int = 1) -> TrainSettings:
        """These settings validated and converted to plain Python types.

        Raises
        ------
        ParameterError
            The first invalid field (``batch_size`` below ``min_batch_size`` included).
        """
        if self.class_weight not in ("balanced", None):
            raise ParameterError("class_weight", self.class_weight, "'balanced' or None")
        if self.checkpoint_dir is not None and not isinstance(self.checkpoint_dir, str | Path):
            raise ParameterError("checkpoint_dir", self.checkpoint_dir, "a folder path or None")
        if self.num_threads is not None:
            check_int("num_threads", self.num_threads, 1, 4096)
        if not isinstance(self.device, str) or not self.device:
            raise ParameterError("device", self.device, _DEVICES)
        return replace(
            self,
            epochs=check_int("epochs", self.epochs, 1, 100_000),
            batch_size=check_int("batch_size", self.batch_size, min_batch_size, 65_536),
            lr=check_float("lr", self.lr, 0.0, MAX_LR, open_lo=True),
            weight_decay=check_float("weight_decay", self.weight_decay, 0.0, 10.0),
            val_fraction=check_float("val_fraction", self.val_fraction, 0.0, 0.9),
            val_blocks=check_int("val_blocks", self.val_blocks, 1, 1000),
            val_gap=check_int("val_gap", self.val_gap, 0, 100_000),
            patience=check_int("patience", self.patience, 0, 100_000),
            augment=check_bool("augment", self.augment),
            max_shift=check_float("max_shift", self.max_shift, 0.0, 0.5),
            colour_augment=check_bool("colour_augment", self.colour_augment),
            label_smoothing=check_float(
                "label_smoothing", self.label_smoothing, 0.0, 0.5, open_hi=True
            ),
            lr_schedule=check_choice("lr_schedule", self.lr_schedule, ("constant", "cosine")),  # type: ignore[arg-type]
            select=check_choice("select", self.select, SELECTIONS),  # type: ignore[arg-type]
            restarts=check_int("restarts", self.restarts, 0, 100),
            seed=check_seed("seed", self.seed),
        )


@dataclass(frozen=True)
class FrameSamples:
    """Labelled samples as windows into a pool of pixel frames.

    Sample ``s`` is the frames ``pool[windows[s]]`` stacked along channels (oldest
    first), so ``K`` context frames per sample share one pool.

    Attributes
    ----------
    pool : (P, C, H, W) tensor
        Pixel values in 0..255 (``uint8`` after :func:`~qdcnn.models.preprocess.crop_resize`).
    windows : (S, K) int64 tensor
        Pool rows of each sample.
    labels : (S,) int64 tensor
        0 = left, 1 = straight, 2 = right.
    """

    pool: torch.Tensor
    windows: torch.Tensor
    labels: torch.Tensor

    @classmethod
    def sequence(cls, frames: torch.Tensor, labels: ArrayLike, context: int = 1) -> FrameSamples:
        """One sample per frame of a recording, stacking ``context`` frames (frame 0 repeats)."""
        y = torch.as_tensor(np.asarray(labels, dtype=np.int64))
        windows = torch.from_numpy(context_windows(len(frames), context))
        return cls(frames, windows, y)

    def __post_init__(self) -> None:
        if not has_shape(self.windows, f"{len(self.labels)},W"):
            raise InputError(
                "samples",
                f"{tuple(self.windows.shape)} windows for {tuple(self.labels.shape)} labels",
            )
        if len(self.labels) and bool(((self.labels < 0) | (self.labels >= N_CLASSES)).any()):
            raise InputError("labels", "values must be 0 (left), 1 (straight) or 2 (right)")

    def __len__(self) -> int:
        return len(self.labels)

    @property
    def context(self) -> int:
        """Frames per sample."""
        return int(self.windows.shape[1])

    def inputs(self, rows: torch.Tensor) -> torch.Tensor:
        """Pixels of samples ``rows``: ``(B, K * C, H, W)``, frames stacked along channels."""
        stacked = self.pool[self.windows[rows]]  # (B, K, C, H, W)
        b, k, c, h, w = stacked.shape
        return stacked.reshape(b, k * c, h, w)


@dataclass
class TrainResult:
    """What :meth:`Trainer.fit` returns.

    Attributes
    ----------
    network : nn.Module
        The trained network with the kept epoch's weights, in eval mode.
    history : list of dict
        Per epoch: ``epoch``, ``train_loss``, ``val_loss``, ``val_accuracy``,
        ``val_balanced_accuracy`` and ``val_predictions`` (how many validation samples
        were given each class; all ``None`` without validation), ``lr`` (at the epoch's
        end), ``grad_norm_trunk`` and ``grad_norm_head`` (the mean over the epoch's steps
        of the gradient's L2 norm over the network's ``head`` and over everything else;
        ``grad_norm_head`` is ``None`` for a network without a ``head``), the spread
        of the head's encoded angles and of its features (``<Z_i>``) on the validation
        samples: ``angle_std``, ``angle_min``, ``angle_max``, ``feature_std``,
        ``feature_min``, ``feature_max`` (the std is the mean over qubits of the std over
        samples; ``None`` for heads without them), and ``seconds``.
    best_epoch : int
        The epoch whose weights were kept (1-based).
    n_train, n_val, n_extra : int
        Training and validation samples, and extra samples that trained.
    seed : int
        The seed of the run kept (another than the settings' after a restart).
    restarts : list of dict
        The runs given up because their validation predictions were all one class:
        ``seed``, ``best_epoch``, ``val_predictions``, ``next_seed``.
    """

    network: nn.Module
    history: list[dict[str, Any]] = field(default_factory=list)
    best_epoch: int = 0
    n_train: int = 0
    n_val: int = 0
    n_extra: int = 0
    seed: int = 0
    restarts: list[dict[str, Any]] = field(default_factory=list)


def _batches(order: NDArray[np.int64], batch_size: int) -> list[NDArray[np.int64]]:
    """Consecutive batches of ``order``; a last batch of one joins the one before.

    BatchNorm cannot normalise a batch of one frame in training mode.
    """
    chunks = [order[i : i + batch_size] for i in range(0, len(order), batch_size)]
    if len(chunks) > 1 and len(chunks[-1]) == 1:
        chunks[-2] = np.concatenate(chunks[-2:])
        chunks.pop()
    return chunks


def _to_float(x: torch.Tensor) -> torch.Tensor:
    return x.float()


class Trainer:
    """Train any network mapping frames ``(B, C, H, W)`` to logits ``(B, 3)``.

    Parameters
    ----------
    settings : TrainSettings
        Optimisation, validation and augmentation settings (validated by ``fit``).
    transform : callable or None
        Maps a batch of (augmented) pixels in 0..255 to the network input, on the
        training device (the CNNs: :func:`~qdcnn.models.preprocess.normalise`).
        Default: the pixels as float32.
    on_step, on_epoch : callable or None
        Progress callbacks (:data:`StepCallback`, :data:`EpochCallback`).
    checkpoint_meta : mapping or None
        Header fields of the checkpoints written to ``settings.checkpoint_dir``
        (the estimator's architecture and params, so that ``best.safetensors``
        loads with :meth:`CNNDirectionClassifier.load
        <qdcnn.models.training.CNNDirectionClassifier.load>`); ``history`` and
        ``best_epoch`` are added.
    min_batch_size : int
        Smallest allowed ``batch_size`` (2 for networks with BatchNorm).

    Examples
    --------
    >>> net = torch.nn.Sequential(torch.nn.Flatten(), torch.nn.Linear(3 * 4 * 4, 3))
    >>> frames = torch.randint(0, 256, (30, 3, 4, 4), dtype=torch.uint8)
    >>> samples = FrameSamples.sequence(frames, np.arange(30) % 3)
    >>> result = Trainer(TrainSettings(epochs=2, augment=False)).fit(net, samples)
    >>> [h["epoch"] for h in result.history]
    [1, 2]
    """

    def __init__(
        self,
        settings: TrainSettings | None = None,
        *,
        transform: Callable[[torch.Tensor], torch.Tensor] | None = None,
        on_step: StepCallback | None = None,
        on_epoch: EpochCallback | None = None,
        checkpoint_meta: Mapping[str, Any] | None = None,
        min_batch_size: int = 1,
    ) -> None:
        self.settings = settings if settings is not None else TrainSettings()
        self.transform = transform if transform is not None else _to_float
        self.on_step = on_step
        self.on_epoch = on_epoch
        self.checkpoint_meta = dict(checkpoint_meta or {})
        self.min_batch_size = min_batch_size

    def fit(
        self,
        network: nn.Module,
        samples: FrameSamples,
        *,
        extra: FrameSamples | None = None,
        extra_of: ArrayLike | None = None,
        rebuild: Rebuild | None = None,
    ) -> TrainResult:
        """Train ``network`` in place on ``samples`` (in recording order).

        Parameters
        ----------
        network : nn.Module
            Any network; it is moved to the settings' device.
        samples : FrameSamples
            The recording's samples; validation blocks are taken from these.
        extra : FrameSamples or None
            Further training samples (side-camera views): sample ``j`` trains only
            when sample ``extra_of[j]`` of ``samples`` does, so nothing a
            validation frame shows reaches training.
        extra_of : (E,) int array or None
            The sample of ``samples`` each extra sample accompanies.
        rebuild : callable or None
            ``rebuild(seed)`` gives a fresh network: with ``settings.restarts``, a run
            whose validation predictions (at the kept epoch) are all one class while
            the validation block holds two classes or more starts again from
            ``rebuild(seed + k)`` with seed ``seed + k`` (``k = 1, 2, ...``), up to
            ``restarts`` times (:attr:`TrainResult.restarts` says so). Without it
            nothing restarts.

        Returns
        -------
        TrainResult
        """
        s = self.settings.checked(min_batch_size=self.min_batch_size)
        device = resolve_device(s.device)
        train_idx, val_idx = split_train_val(
            len(samples), s.val_fraction, blocks=s.val_blocks, gap=s.val_gap
        )
        extra_rows = _eligible_extra(extra, extra_of, train_idx, len(samples))
        threads = s.num_threads if s.num_threads is not None else default_threads()
        val_classes = len(np.unique(samples.labels[torch.from_numpy(val_idx)].numpy()))
        restarts: list[dict[str, Any]] = []
        attempts = 1 + (s.restarts if rebuild is not None else 0)
        for attempt in range(attempts):
            run = replace(s, seed=(s.seed + attempt) % 2**32)
            if attempt:
                assert rebuild is not None
                network = rebuild(run.seed)
            with torch_session(threads, run.seed, device):
                loop = _Loop(self, run, place(network, device), device, samples, extra)
                result = loop.run(train_idx, val_idx, extra_rows)
            result.seed, result.restarts = run.seed, restarts
            if attempt + 1 == attempts or not _collapsed(result, val_classes):
                return result
            restarts.append(
                {
                    "seed": run.seed,
                    "best_epoch": result.best_epoch,
                    "val_predictions": result.history[result.best_epoch - 1]["val_predictions"],
                    "next_seed": run.seed + 1,
                }
            )
        raise AssertionError("unreachable: the last attempt returns")


def _collapsed(result: TrainResult, val_classes: int) -> bool:
    """All validation predictions of the kept epoch in one class, when two or more occur."""
    if val_classes < 2 or not result.best_epoch:
        return False
    counts = result.history[result.best_epoch - 1].get("val_predictions")
    return counts is not None and sum(1 for c in counts if c) == 1


def _eligible_extra(
    extra: FrameSamples | None,
    extra_of: ArrayLike | None,
    train_idx: NDArray[np.int64],
    n: int,
) -> NDArray[np.int64]:
    """Rows of ``extra`` whose own sample trains."""
    if extra is None:
        return np.zeros(0, dtype=np.int64)
    if extra_of is None:
        raise ParameterError("extra_of", None, "the sample index of every extra sample")
    of = np.asarray(extra_of)
    if of.shape != (len(extra),) or of.dtype.kind not in "iu" or (len(of) and of.max() >= n):
        raise InputError(
            "extra_of", f"expected {len(extra)} indices into {n} samples, got shape {of.shape}"
        )
    trains = np.zeros(n, dtype=bool)
    trains[train_idx] = True
    return np.flatnonzero(trains[of]).astype(np.int64)


class _Loop:
    """One run of :meth:`Trainer.fit`: state shared by the epoch, step and checkpoint code."""

    def __init__(
        self,
        trainer: Trainer,
        settings: TrainSettings,
        network: nn.Module,
        device: torch.device,
        samples: FrameSamples,
        extra: FrameSamples | None,
    ) -> None:
        self.t, self.s, self.net, self.device = trainer, settings, network, device
        self.samples, self.extra = samples, extra
        self.optimiser = torch.optim.AdamW(
            network.parameters(), lr=settings.lr, weight_decay=settings.weight_decay
        )
        self.shuffle_gen = torch.Generator().manual_seed(settings.seed)
        self.augment_gen = torch.Generator().manual_seed(settings.seed + 1)

    def batch(self, rows: NDArray[np.int64]) -> tuple[torch.Tensor, torch.Tensor]:
        """Pixels and labels of combined rows: ``< len(samples)`` main, the rest extra."""
        n = len(self.samples)
        main = rows < n
        if main.all() or self.extra is None:
            index = torch.from_numpy(rows)
            return self.samples.inputs(index), self.samples.labels[index]
        parts = [(self.samples, rows[main]), (self.extra, rows[~main] - n)]
        x = torch.cat([src.inputs(torch.from_numpy(r)) for src, r in parts])
        y = torch.cat([src.labels[torch.from_numpy(r)] for src, r in parts])
        back = np.argsort(np.concatenate([np.flatnonzero(main), np.flatnonzero(~main)]))
        order = torch.from_numpy(back)
        return x[order], y[order]

    def run(
        self,
        train_idx: NDArray[np.int64],
        val_idx: NDArray[np.int64],
        extra_rows: NDArray[np.int64],
    ) -> TrainResult:
        s = self.s
        pool = np.concatenate([train_idx, len(self.samples) + extra_rows])
        labels = torch.cat([self.samples.labels[train_idx], self._extra_labels(extra_rows)])
        weight_cpu = torch.tensor(
            class_weights(labels.numpy(), mirrored=s.augment)
            if s.class_weight == "balanced"
            else np.ones(N_CLASSES),
            dtype=torch.float32,
        )
        self.weight_cpu, self.weight = weight_cpu, weight_cpu.to(self.device)
        steps_per_epoch = len(_batches(np.arange(len(pool)), s.batch_size))
        self.total_steps = s.epochs * steps_per_epoch
        self.scheduler = (
            torch.optim.lr_scheduler.CosineAnnealingLR(self.optimiser, T_max=self.total_steps)
            if s.lr_schedule == "cosine"
            else None
        )
        history: list[dict[str, Any]] = []
        best_score: tuple[float, float] = (math.inf, math.inf)
        best_epoch, best_state = 0, None
        self.step = 0
        for epoch in range(1, s.epochs + 1):
            record = self.epoch(epoch, pool, val_idx)
            history.append(record)
            score = self.score(record, epoch, bool(len(val_idx)))
            improved = score < best_score
            if improved:
                best_score, best_epoch = score, epoch
                best_state = copy.deepcopy(self.net.state_dict())
            if self.t.on_epoch is not None:
                self.t.on_epoch(record, s.epochs)
            if s.checkpoint_dir is not None:
                self.write_checkpoints(Path(s.checkpoint_dir), history, best_epoch, improved)
            if len(val_idx) and s.patience and epoch - best_epoch >= s.patience:
                break
        assert best_state is not None  # at least one epoch ran
        self.net.load_state_dict(best_state)
        self.net.eval()
        return TrainResult(
            self.net, history, best_epoch, len(train_idx), len(val_idx), len(extra_rows)
        )

    def score(self, record: Mapping[str, Any], epoch: int, validated: bool) -> tuple[float, float]:
        """An epoch's rank (lower is better): without validation the last epoch wins."""
        if not validated:
            return (-float(epoch), 0.0)
        if self.s.select == "balanced_accuracy":
            return (-float(record["val_balanced_accuracy"]), float(record["val_loss"]))
        return (float(record["val_loss"]), 0.0)

    def _extra_labels(self, rows: NDArray[np.int64]) -> torch.Tensor:
        if self.extra is None or not len(rows):
            return torch.zeros(0, dtype=torch.int64)
        return self.extra.labels[torch.from_numpy(rows)]

    def epoch(
        self, epoch: int, pool: NDArray[np.int64], val_idx: NDArray[np.int64]
    ) -> dict[str, Any]:
        s = self.s
        start = time.perf_counter()
        self.net.train()
        order = pool[torch.randperm(len(pool), generator=self.shuffle_gen).numpy()]
        loss_sum, weight_sum = 0.0, 0.0
        norms: list[tuple[float, float | None]] = []
        for rows in _batches(order, s.batch_size):
            loss, w, norm = self.train_step(rows)
            loss_sum += loss * w
            weight_sum += w
            norms.append(norm)
        head_norms = [h for _, h in norms if h is not None]
        record: dict[str, Any] = {
            "epoch": epoch,
            "train_loss": loss_sum / (weight_sum or 1.0),
            "val_loss": None,
            "val_accuracy": None,
            "val_balanced_accuracy": None,
            "val_predictions": None,
            "lr": self.optimiser.param_groups[0]["lr"],
            "grad_norm_trunk": float(np.mean([t for t, _ in norms])),
            "grad_norm_head": float(np.mean(head_norms)) if head_norms else None,
            **dict.fromkeys(_SPREAD_KEYS),
        }
        if len(val_idx):
            record.update(self.evaluate(val_idx))
        record["seconds"] = time.perf_counter() - start
        return record

    def train_step(
        self, rows: NDArray[np.int64]
    ) -> tuple[float, float, tuple[float, float | None]]:
        """One optimisation step; the batch's loss, its summed class weight and the
        gradient norms of the trunk and of the head."""
        from qdcnn.models.augment import augment_batch

        xb, yb = self.batch(rows)
        xb, yb = xb.to(self.device), yb.to(self.device)
        if self.s.augment:
            xb, yb = augment_batch(
                xb,
                yb,
                self.augment_gen,
                max_shift=float(self.s.max_shift),
                colour=self.s.colour_augment,
            )
        loss = F.cross_entropy(
            self.net(self.t.transform(xb)),
            yb,
            weight=self.weight,
            label_smoothing=self.s.label_smoothing,
        )
        self.optimiser.zero_grad(set_to_none=True)
        loss.backward()
        norm = _gradient_norms(self.net)
        self.optimiser.step()
        if self.scheduler is not None:
            self.scheduler.step()
        self.step += 1
        if self.t.on_step is not None:
            self.t.on_step(self.step, self.total_steps)
        return loss.item(), float(self.weight[yb].sum()), norm

    def evaluate(self, idx: NDArray[np.int64]) -> dict[str, Any]:
        """Validation loss (weighted mean, as in training), accuracy, balanced accuracy,
        predicted-class counts and the head's spreads on samples ``idx``."""
        self.net.eval()
        loss_sum, predicted = 0.0, []
        with torch.inference_mode(), _HeadInputs(self.net) as embeddings:
            for chunk in _batches(idx, max(self.s.batch_size, 64)):
                xb, yb = self.batch(chunk)
                xb, yb = xb.to(self.device), yb.to(self.device)
                logits = self.net(self.t.transform(xb))
                loss_sum += float(
                    F.cross_entropy(
                        logits,
                        yb,
                        weight=self.weight,
                        reduction="sum",
                        label_smoothing=self.s.label_smoothing,
                    )
                )
                predicted.append(logits.argmax(1).cpu())
            spreads = embeddings.spreads()
        y = self.samples.labels[torch.from_numpy(idx)]
        pred = torch.cat(predicted)
        denominator = float(self.weight_cpu[y].sum())
        return {
            "val_loss": loss_sum / (denominator or 1.0),
            "val_accuracy": float((pred == y).float().mean()),
            "val_balanced_accuracy": balanced_accuracy(y.numpy(), pred.numpy()),
            "val_predictions": np.bincount(pred.numpy(), minlength=N_CLASSES).tolist(),
            **spreads,
        }

    def write_checkpoints(
        self, folder: Path, history: list[dict[str, Any]], best_epoch: int, improved: bool
    ) -> None:
        """``best.safetensors`` when the epoch improved, ``last.safetensors`` every epoch."""
        from qdcnn.models.persistence import save_checkpoint, save_network

        meta = {**self.t.checkpoint_meta, "history": history, "best_epoch": best_epoch}
        if improved:
            save_network(folder / "best.safetensors", self.net, meta)
        last = {**meta, "epoch": len(history)}
        save_checkpoint(folder / "last.safetensors", self.net, self.optimiser, last, self.scheduler)


_SPREAD_KEYS = ("angle_std", "angle_min", "angle_max", "feature_std", "feature_min", "feature_max")


def balanced_accuracy(labels: NDArray[np.int64], predicted: NDArray[np.int64]) -> float:
    """The mean over the classes present in ``labels`` of their recall."""
    classes = np.unique(labels)
    return float(np.mean([np.mean(predicted[labels == c] == c) for c in classes]))


def _head_of(network: nn.Module) -> nn.Module | None:
    head = getattr(network, "head", None)
    return head if isinstance(head, nn.Module) else None


def _gradient_norms(network: nn.Module) -> tuple[float, float | None]:
    """L2 norms of the gradient over everything but the ``head``, and over the head."""
    head = _head_of(network)
    in_head = {id(p) for p in head.parameters()} if head is not None else set()
    trunk: list[torch.Tensor] = []
    top: list[torch.Tensor] = []
    for p in network.parameters():
        if p.grad is not None:
            (top if id(p) in in_head else trunk).append(p.grad.detach().float().square().sum())
    trunk_norm = float(torch.stack(trunk).sum().sqrt()) if trunk else 0.0
    if head is None:
        return trunk_norm, None
    return trunk_norm, float(torch.stack(top).sum().sqrt()) if top else 0.0


class _HeadInputs:
    """Collects what a network's ``head`` receives while in use (a forward hook), and the
    spread of the encoded angles and features its ``diagnostics`` gives for them."""

    def __init__(self, network: nn.Module) -> None:
        self.head = _head_of(network)
        self.inputs: list[torch.Tensor] = []
        self.handle: Any = None

    def __enter__(self) -> _HeadInputs:
        if self.head is not None and hasattr(self.head, "diagnostics"):
            self.handle = self.head.register_forward_hook(
                lambda _m, args, _out: self.inputs.append(args[0].detach())
            )
        return self

    def __exit__(self, *_: object) -> None:
        if self.handle is not None:
            self.handle.remove()

    def spreads(self) -> dict[str, float | None]:
        out: dict[str, float | None] = dict.fromkeys(_SPREAD_KEYS)
        if not self.inputs or self.head is None:
            return out
        diagnose = getattr(self.head, "diagnostics")  # noqa: B009 (a Module attribute)
        values = diagnose(torch.cat(self.inputs))
        for key, name in (("angles", "angle"), ("features", "feature")):
            v = values.get(key)
            if v is None or not len(v):
                continue
            v = v.detach().double().cpu()
            std = v.std(0, unbiased=False).mean() if len(v) > 1 else torch.zeros(())
            out[f"{name}_std"], out[f"{name}_min"] = float(std), float(v.min())
            out[f"{name}_max"] = float(v.max())
        return out


def _describe(label: str, record: Mapping[str, Any], epochs: int) -> str:
    text = f"{label} epoch {record['epoch']}/{epochs} loss {record['train_loss']:.3f}"
    if record.get("val_loss") is not None:
        text += f" val {record['val_loss']:.3f} acc {record['val_accuracy']:.2f}"
    return text


@contextmanager
def rich_progress(
    label: str, epochs: int, *, enabled: bool = True
) -> Iterator[tuple[StepCallback, EpochCallback]]:
    """A Rich progress bar on stderr, as the ``(on_step, on_epoch)`` callbacks of :class:`Trainer`.

    Examples
    --------
    >>> with rich_progress("pilotnet", 25, enabled=False) as (on_step, on_epoch):
    ...     on_step(1, 10)
    """
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TaskID,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    task: list[TaskID] = []
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        disable=not enabled,
    ) as bar:

        def on_step(step: int, total: int) -> None:
            if not task:
                task.append(bar.add_task(f"{label} epoch 1/{epochs}", total=total))
            bar.update(task[0], completed=step, total=total)

        def on_epoch(record: Mapping[str, Any], n_epochs: int) -> None:
            if task:
                bar.update(task[0], description=_describe(label, record, n_epochs))

        yield on_step, on_epoch
