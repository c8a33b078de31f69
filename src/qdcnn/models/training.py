"""The CNN direction classifier users call: an estimator over network, trainer and model file.

:class:`CNNDirectionClassifier` maps RGB frames to 0 = left, 1 = straight,
2 = right. It composes three parts, as qiskit-machine-learning's
``TrainableModel`` composes its network, optimiser and serialisation mixin:

- the network, from the registry of :mod:`qdcnn.models.networks`
  (PilotNet, ResNet-50, and any network registered there);
- the training loop, :class:`qdcnn.models.trainer.Trainer`;
- the model file, :mod:`qdcnn.models.persistence` (JSON header + safetensors).

Parameters are stored as given in ``__init__`` (scikit-learn's convention, so
``clone`` never fails) and validated by ``fit``. This module imports without
torch; torch is loaded when a model is built.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Mapping, Sequence
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from sklearn.base import BaseEstimator, ClassifierMixin, clone
from sklearn.utils.validation import check_is_fitted

from qdcnn._optional import require
from qdcnn._validation import check_bool, check_choice, check_input_shape, check_int, has_shape
from qdcnn.data.labels import DIRECTIONS, LEFT, RIGHT, STRAIGHT
from qdcnn.errors import InputError, ParameterError
from qdcnn.models.ensemble import MAX_ENSEMBLE, joined_arrays, member_seed, split_arrays
from qdcnn.models.networks import (
    NETWORKS,
    NetworkEntry,
    input_spec,
    network_entry,
)
from qdcnn.models.samples import (
    N_CLASSES,
    ExtraView,
    class_weights,
    context_windows,
    split_train_val,
)
from qdcnn.models.specs import classical_network, network_label
from qdcnn.quantum.noise import GateNoise, is_noise

if TYPE_CHECKING:
    import torch
    from torch import nn

    from qdcnn.models.specs import InputSpec
    from qdcnn.models.trainer import FrameSamples, TrainSettings

__all__ = [
    "ARCHS",
    "CNNDirectionClassifier",
    "class_weights",
    "inference_fps",
    "input_spec",
    "split_train_val",
]

#: Networks a classifier can train (the registry's names when this module was imported).
ARCHS: tuple[str, ...] = tuple(NETWORKS)
#: Network parameters of a hybrid's head (left out when transfer's stage 1 builds a linear head).
_HEAD_OPTIONS = (
    "head",
    "n_qubits",
    "n_layers",
    "reupload",
    "shots",
    "noise",
    "readout_gain",
    "dressed",
    "entangler",
)
#: Version of the hybrid heads in a model file's header (``head_format``): 3 is the dressed
#: head with a ``CZ`` ring, 2 the dressed head with a ``CX`` ring; files without the field
#: hold the original (undressed) heads.
HEAD_FORMAT = 3
#: Network parameters each older ``head_format`` implies.
_OLDER_HEAD_FORMATS: dict[int | None, dict[str, Any]] = {
    None: {"dressed": False},
    2: {"entangler": "cx"},
}
_MAX_CONTEXT = 64
#: Fields of the trainer's settings that say where and how a run goes, not how it
#: trains (``classical_recipe`` may set every other field).
_RUN_FIELDS = frozenset({"seed", "device", "num_threads", "checkpoint_dir"})


def _torch(purpose: str) -> Any:
    return require("torch", purpose)


def _as_images(
    images: ArrayLike | Sequence[NDArray[np.uint8]], source: str = "images"
) -> NDArray[np.uint8]:
    if isinstance(images, np.ndarray):
        arr = images
    else:
        try:
            arr = np.stack([np.asarray(im) for im in images])  # type: ignore[union-attr]
        except (TypeError, ValueError):
            raise InputError(
                source, "expected a uint8 array (N, H, W, 3) or a list of equal-size frames"
            ) from None
    if arr.dtype != np.uint8 or not has_shape(arr, "N,H,W,3") or 0 in arr.shape:
        raise InputError(
            source,
            f"expected a non-empty uint8 RGB array of shape (N, H, W, 3), "
            f"got {arr.dtype} of shape {arr.shape}",
        )
    return arr


def _as_labels(labels: ArrayLike, n: int, source: str = "labels") -> NDArray[np.int64]:
    y = np.asarray(labels)
    check_input_shape(source, y, str(n), f"{n} labels (one per image)")
    if y.dtype.kind == "f" and np.all(np.isfinite(y)) and np.all(y == np.round(y)):
        y = y.astype(np.int64)
    if y.dtype.kind not in "iu" or np.any((y < 0) | (y >= N_CLASSES)):
        bad = y[0] if y.dtype.kind not in "iu" else y[(y < 0) | (y >= N_CLASSES)][0]
        raise InputError(
            source, f"values must be 0 (left), 1 (straight) or 2 (right); found {bad.item()!r}"
        )
    return y.astype(np.int64)


def _check_crop(crop: object) -> None:
    ok = crop is None or (
        isinstance(crop, tuple | list)
        and len(crop) == 2
        and all(isinstance(c, int | float) and not isinstance(c, bool) for c in crop)
        and 0.0 <= crop[0] < crop[1] <= 1.0
    )
    if not ok:
        raise ParameterError("crop", crop, "(top, bottom) with 0 <= top < bottom <= 1")


def _check_network_params(value: object) -> None:
    ok = value is None or (
        isinstance(value, Mapping)
        and all(isinstance(k, str) for k in value)
        and all(_is_plain(v) for v in value.values())
    )
    if not ok:
        raise ParameterError(
            "network_params", value, "None or a dict of str to plain values (numbers, strings)"
        )


def _is_plain(value: object) -> bool:
    """A JSON value that survives a model file unchanged (so ``load`` rebuilds the network)."""
    if value is None or isinstance(value, bool | int | str):
        return True
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, list):
        return all(_is_plain(v) for v in value)
    if isinstance(value, Mapping):
        return all(isinstance(k, str) and _is_plain(v) for k, v in value.items())
    return False


def _plain_params(params: dict[str, Any]) -> dict[str, Any]:
    def plain(v: Any) -> Any:
        if isinstance(v, Path):
            return str(v)
        if isinstance(v, tuple):
            return list(v)
        if is_noise(v):  # a noise model: by its label
            return None if v.is_ideal else v.label()
        return v

    return {k: plain(v) for k, v in params.items()}


def _as_noise(name: str, value: object) -> GateNoise | None:
    """``value`` as a noise model: ``None``, a noise object, or its text (parsed)."""
    if value is None or is_noise(value):
        return value
    if isinstance(value, str):
        from qdcnn.quantum.noise_text import parse_noise

        return parse_noise(value)
    raise ParameterError(name, value, "None, a noise model or its text (depolarizing:0.1)")


def _set_quantum_noise(network: Any, noise: GateNoise | None, name: str) -> None:
    """Put ``noise`` on every quantum layer of ``network``; refuse noise without one."""
    layers = [m for m in network.modules() if hasattr(m, "set_noise")]
    if noise is not None and not layers:
        raise ParameterError(name, noise.label(), "None: this network has no quantum layer")
    for layer in layers:
        layer.set_noise(noise)


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

    The network comes from the registry of :mod:`qdcnn.models.networks`, the
    training loop is :class:`qdcnn.models.trainer.Trainer` and the model file is
    :mod:`qdcnn.models.persistence`'s (JSON header + safetensors, never pickle).
    Parameters are stored as given and checked by :meth:`fit`.

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
    arch : {"pilotnet", "resnet50"} or another registered network
        PilotNet (Bojarski et al. 2016, 66x200 YUV input) or ResNet-50 (He et
        al. 2016, 224x224 ImageNet-normalised input; the paper's baseline); any
        name in :data:`qdcnn.models.networks.NETWORKS`.
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
    colour_augment : bool
        Also randomise colours (:func:`qdcnn.models.augment.randomise_colour`: channel
        order, contrast, grey frames), so the network decides by shapes that other roads
        share. Only with ``augment``.
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
    select : {"loss", "balanced_accuracy"}
        The epoch kept (and early stopping's measure): the lowest validation loss, or
        the highest validation balanced accuracy (ties: the lower loss).
    restarts : int
        Start a run again with the next seed (at most this many times) when its
        validation predictions are all one class (:meth:`Trainer.fit
        <qdcnn.models.trainer.Trainer.fit>`); ``restarts_`` says what happened.
    transfer : bool
        Hybrid networks only: train in stages (:mod:`qdcnn.models.transfer`): the
        classical network (``qdcnn-head``: PilotNet, with ``classical_recipe``; the other
        hybrids: their trunk with a linear head) for ``epochs`` epochs, then the network's
        own head on the frozen trunk, then everything at a tenth of ``lr``.
    classical_recipe : mapping or None
        Hybrid networks with a classical network only: the training parameters of its
        own training that differ from this estimator's (such as ``class_weight``).
        Stage 1 trains with them, so it is the classical method's training of the same
        frames and seed, and a trunk that training kept is reused.
    trunk_from : path or None
        Hybrid networks only: a saved network of the same architecture, input size and
        context (a model file of this class or of ``train-direction``) whose trunk
        replaces stage 1 of the transfer recipe.
    tta : bool
        Test-time flip averaging: the probabilities of a frame and of its mirror
        image (left and right swapped) are averaged. Doubles inference cost.
    weights : path or None
        Initial weights from a local file: a ``state_dict`` as a PyTorch file
        (read with ``torch.load(weights_only=True)``, which runs no code) or as
        safetensors (a saved classifier qualifies). For ResNet-50 a
        torchvision-format ImageNet ``state_dict`` whose ``fc`` layer is replaced
        by a 3-class head; for PilotNet a complete PilotNet ``state_dict``. With
        ``context > 1`` RGB first-layer kernels are inflated to the stacked
        frames. Never downloaded.
    device : str
        ``"auto"`` (CUDA, then Apple MPS, then CPU) or a torch device string.
    seed : int
        Seeds initialisation, dropout, shuffling and augmentation; the same seed
        gives identical predictions on the same device and thread count.
    trunk_cache : path or None
        A folder where transfer's stage-1 trunks are also kept (and looked up), so a
        resumed run or another process does not train them again
        (:func:`qdcnn.models.transfer.keep_trunk`); it changes no result.
    checkpoint_dir : path or None
        When set, ``last.safetensors`` (network, AdamW state, scheduler state,
        history: :func:`qdcnn.models.persistence.load_checkpoint`) is written
        after each epoch and ``best.safetensors`` (loadable with :meth:`load`)
        whenever validation improves.
    progress : bool
        Show a Rich progress bar on stderr while fitting.
    num_threads : int or None
        CPU threads torch uses during ``fit``/``predict`` (default: the CPUs this
        process may run on); restored afterwards.
    crop : (float, float) or None
        Rows kept, as fractions of the frame height; default ``(0.375, 0.84375)``
        (rows 60..135 of a 160-row Udacity frame).
    context : int
        Frames per input, K: frame ``i`` is fed with frames ``i - K + 1 .. i`` of
        the array given to :meth:`fit` or :meth:`predict` stacked along channels
        (the first frames repeat frame 0), so pass whole recordings in order. The
        network gets ``3K`` input channels; augmentation flips, brightens, shades
        and shifts the K frames of a sample alike.
    network_params : dict or None
        Further keyword arguments of the network's factory
        (:func:`qdcnn.models.networks.build_network`), such as ``{"dropout": 0.5}``
        for PilotNet; plain JSON values, kept in saved files.
    ensemble : int
        Networks trained, network ``k`` with seed ``seed + 1000 k`` exactly as a
        one-network classifier of that seed; the probabilities are their mean and the
        decision its most probable class (:mod:`qdcnn.models.ensemble`); 1: one network.

    Attributes
    ----------
    model_ : torch.nn.Module
        The trained network (in eval mode).
    input_spec_ : InputSpec
        The preprocessing the network was trained with (kept in saved files).
    history_ : list of dict
        Per epoch, as :attr:`TrainResult.history <qdcnn.models.trainer.TrainResult>`
        says: losses, accuracies, predicted-class counts, gradient norms, the head's
        spreads, ``lr`` and ``seconds`` (with ``transfer``, each record's ``stage``).
    restarts_ : list of dict
        Runs given up because they predicted one class (their seed); empty when none.
    seed_ : int
        The seed of the run kept.
    best_epoch_ : int
        The epoch whose weights were kept (1-based).
    classes_ : ndarray
        ``[0, 1, 2]``.
    members_ : list of CNNDirectionClassifier
        With ``ensemble > 1``: the one-network classifiers averaged (the attributes above
        are the first one's).

    Examples
    --------
    >>> clf = CNNDirectionClassifier("pilotnet", epochs=1, progress=False)
    >>> clf.get_params()["arch"]
    'pilotnet'
    >>> CNNDirectionClassifier(epochs=0).get_params()["epochs"]  # checked by fit, not here
    0
    """

    def __init__(
        self,
        arch: str = "pilotnet",
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
        colour_augment: bool = False,
        class_weight: Literal["balanced"] | None = None,
        label_smoothing: float = 0.1,
        lr_schedule: Literal["constant", "cosine"] = "cosine",
        select: Literal["loss", "balanced_accuracy"] = "loss",
        restarts: int = 0,
        transfer: bool = False,
        trunk_from: str | Path | None = None,
        classical_recipe: Mapping[str, Any] | None = None,
        tta: bool = False,
        weights: str | Path | None = None,
        device: str = "auto",
        seed: int = 0,
        checkpoint_dir: str | Path | None = None,
        trunk_cache: str | Path | None = None,
        progress: bool = True,
        num_threads: int | None = None,
        crop: tuple[float, float] | None = None,
        context: int = 1,
        network_params: Mapping[str, Any] | None = None,
        noise: GateNoise | str | None = None,
        train_noise: GateNoise | str | None = None,
        ensemble: int = 1,
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
        self.colour_augment = colour_augment
        self.class_weight = class_weight
        self.label_smoothing = label_smoothing
        self.lr_schedule = lr_schedule
        self.select = select
        self.restarts = restarts
        self.transfer = transfer
        self.trunk_from = trunk_from
        self.classical_recipe = classical_recipe
        self.tta = tta
        self.weights = weights
        self.device = device
        self.seed = seed
        self.checkpoint_dir = checkpoint_dir
        self.trunk_cache = trunk_cache
        self.progress = progress
        self.num_threads = num_threads
        self.crop = crop
        self.context = context
        self.network_params = network_params
        self.noise = noise
        self.train_noise = train_noise
        self.ensemble = ensemble

    # ----------------------------------------------------------------- checks
    def _checked(self) -> tuple[NetworkEntry, TrainSettings]:
        """Validate every parameter; the network entry and the trainer's settings."""
        from qdcnn.models.trainer import TrainSettings

        entry = network_entry(self.arch)
        settings = TrainSettings(
            epochs=self.epochs,
            batch_size=self.batch_size,
            lr=self.lr,
            weight_decay=self.weight_decay,
            val_fraction=self.val_fraction,
            val_blocks=self.val_blocks,
            val_gap=self.val_gap,
            patience=self.patience,
            augment=self.augment,
            max_shift=self.max_shift,
            colour_augment=self.colour_augment,
            class_weight=self.class_weight,
            label_smoothing=self.label_smoothing,
            lr_schedule=self.lr_schedule,
            select=self.select,
            restarts=self.restarts,
            seed=self.seed,
            device=self.device,
            num_threads=self.num_threads,
            checkpoint_dir=self.checkpoint_dir,
        ).checked(min_batch_size=entry.min_batch_size)
        check_bool("tta", self.tta)
        check_bool("progress", self.progress)
        self._check_staged()
        if self.weights is not None and not isinstance(self.weights, str | os.PathLike):
            raise ParameterError("weights", self.weights, "a weights file path or None")
        if self.trunk_cache is not None and not isinstance(self.trunk_cache, str | os.PathLike):
            raise ParameterError("trunk_cache", self.trunk_cache, "a folder path or None")
        _check_crop(self.crop)
        check_int("context", self.context, 1, _MAX_CONTEXT)
        _check_network_params(self.network_params)
        _as_noise("noise", self.noise)
        _as_noise("train_noise", self.train_noise)
        check_int("ensemble", self.ensemble, 1, MAX_ENSEMBLE)
        return entry, settings

    def _check_staged(self) -> None:
        """``transfer`` and ``trunk_from`` need a hybrid network."""
        check_bool("transfer", self.transfer)
        if self.trunk_from is not None and not isinstance(self.trunk_from, str | os.PathLike):
            raise ParameterError("trunk_from", self.trunk_from, "a model file path or None")
        from dataclasses import fields

        from qdcnn.models.trainer import TrainSettings

        training = {f.name for f in fields(TrainSettings)} - _RUN_FIELDS
        recipe = self.classical_recipe
        if recipe is not None and not (isinstance(recipe, Mapping) and set(recipe) <= training):
            raise ParameterError(
                "classical_recipe", recipe, "None or a mapping of training parameters"
            )
        staged = self.transfer or self.trunk_from is not None
        if staged and not _is_hybrid(self.arch):
            what = "transfer" if self.transfer else "trunk_from"
            raise ParameterError(
                what, getattr(self, what), f"unset: {self.arch} is not a hybrid network"
            )

    def _network_kw(self) -> dict[str, Any]:
        return dict(self.network_params or {})

    def _trunk_network_kw(self) -> dict[str, Any]:
        """The network parameters that are not the head's."""
        return {k: v for k, v in self._network_kw().items() if k not in _HEAD_OPTIONS}

    def _front(self) -> str:
        """What the network does to each frame first (:func:`_front_of`)."""
        return _front_of(self._network_kw())

    def _label(self) -> str:
        """The network's name on the progress bar; a hybrid's classical twin says so."""
        return network_label(self.arch, self._network_kw().get("head"))

    def _threads(self) -> int:
        from qdcnn.models.trainer import default_threads

        return self.num_threads if self.num_threads is not None else default_threads()

    def _set_fitted(
        self,
        network: nn.Module,
        spec: InputSpec,
        history: list[dict[str, Any]],
        best_epoch: int,
        restarts: Sequence[dict[str, Any]] = (),
        seed: int | None = None,
    ) -> None:
        from qdcnn.models.trainer import place, resolve_device

        self.__dict__.pop("members_", None)  # a refit or a loaded network: no old networks
        self.device_ = resolve_device(self.device)
        self.model_ = place(network, self.device_).eval()
        self.input_spec_ = spec
        self.context_ = int(self.context)
        self.history_ = history
        self.best_epoch_ = best_epoch
        self.restarts_ = list(restarts)
        self.seed_ = int(self.seed if seed is None else seed)
        self.classes_ = np.arange(N_CLASSES)

    # -------------------------------------------------------------- training
    def fit(
        self,
        images: ArrayLike | Sequence[NDArray[np.uint8]],
        labels: ArrayLike,
        *,
        extra_views: Sequence[ExtraView] = (),
    ) -> CNNDirectionClassifier:
        """Train on frames in recording order.

        Parameters
        ----------
        images : (N, H, W, 3) uint8 array or sequence of equal-size frames
            RGB frames in the order they were recorded.
        labels : (N,) int array
            0 = left, 1 = straight, 2 = right.
        extra_views : sequence of ExtraView
            Further views of the same frames with their own labels, such as the
            left and right cameras with corrected steering
            (:func:`qdcnn.models.samples.side_camera_views`). The view of frame
            ``i`` trains only when frame ``i`` trains: never when it validates.

        Returns
        -------
        self

        Raises
        ------
        ParameterError
            An invalid parameter (they are checked here, not in ``__init__``).
        InputError
            Images, labels or views of the wrong type or shape, or a bad weights file.
        """
        entry, settings = self._checked()
        _torch("training a CNN direction classifier")
        if self.ensemble > 1:
            return self._fit_members(images, labels, extra_views)
        from qdcnn.models.preprocess import crop_resize, normalise
        from qdcnn.models.trainer import FrameSamples, Trainer, resolve_device, rich_progress

        x = _as_images(images)
        y = _as_labels(labels, len(x))
        views = [_as_view(v, x.shape) for v in extra_views]
        resolve_device(self.device)  # fail before the work
        spec = input_spec(self.arch, self.crop)
        k = int(self.context)
        trunk = None if self.trunk_from is None else self.read_trunk()
        # first: a bad weights file fails fast
        network = self._build(self._head(), self.seed)
        samples = FrameSamples.sequence(crop_resize(x, spec), y, k)
        extra, extra_of = _extra_samples(views, spec, k)
        with rich_progress(self._label(), settings.epochs, enabled=self.progress) as callbacks:
            trainer = Trainer(
                settings,
                transform=partial(normalise, spec=spec),
                on_step=callbacks[0],
                on_epoch=callbacks[1],
                checkpoint_meta=self._meta(spec, k),
                min_batch_size=entry.min_batch_size,
            )
            fit_kw: dict[str, Any] = {"extra": extra, "extra_of": extra_of}
            if self.transfer or trunk is not None:
                result = self._fit_staged(trainer, samples, trunk, fit_kw)
            else:
                rebuild = partial(self._build, self._head())
                result = trainer.fit(
                    network, samples, extra=extra, extra_of=extra_of, rebuild=rebuild
                )
                if extra is None:
                    self._keep_classical_trunk(samples, settings, result)
        self._set_fitted(
            result.network, spec, result.history, result.best_epoch, result.restarts, result.seed
        )
        _set_quantum_noise(self.model_, _as_noise("noise", self.noise), "noise")
        return self

    def _fit_members(
        self,
        images: ArrayLike | Sequence[NDArray[np.uint8]],
        labels: ArrayLike,
        extra_views: Sequence[ExtraView],
    ) -> CNNDirectionClassifier:
        """The ensemble: one network per seed, each trained as ``ensemble=1`` would."""
        members = [
            self._member(k).fit(images, labels, extra_views=extra_views)
            for k in range(self.ensemble)
        ]
        self._adopt(members)
        return self

    def _member(self, k: int) -> CNNDirectionClassifier:
        """Network ``k`` of the ensemble: its seed, its checkpoints in their own folder."""
        seed = member_seed(self.seed, k)
        member: CNNDirectionClassifier = clone(self).set_params(ensemble=1, seed=seed)
        if self.checkpoint_dir is not None:  # only ensembles have members
            member.set_params(checkpoint_dir=Path(self.checkpoint_dir) / f"network{k}")
        return member

    def _adopt(self, members: list[CNNDirectionClassifier]) -> None:
        """Take the first member's fitted attributes and keep all members to average."""
        first = members[0]
        self._set_fitted(
            first.model_,
            first.input_spec_,
            first.history_,
            first.best_epoch_,
            first.restarts_,
            first.seed_,
        )
        self.members_ = members

    def _averaged(self) -> list[CNNDirectionClassifier]:
        """The networks (one-network classifiers) a fitted ensemble averages; empty for one."""
        members: list[CNNDirectionClassifier] = getattr(self, "members_", [])
        return members if len(members) > 1 else []

    def _head(self) -> str | None:
        head = self._network_kw().get("head")
        return head if isinstance(head, str) else None

    def _build(self, head: str | None, seed: int) -> nn.Module:
        """A fresh network of this estimator (with another ``head`` for transfer's stage 1)."""
        from qdcnn.models.networks import build_network

        kw = self._network_kw()
        if head is not None and head != kw.get("head", "quantum"):
            kw = {**self._trunk_network_kw(), "head": head}
        network = build_network(
            self.arch, 3 * int(self.context), weights=self.weights, seed=seed, **kw
        )
        _set_quantum_noise(network, _as_noise("train_noise", self.train_noise), "train_noise")
        return network

    def _fit_staged(
        self, trainer: Any, samples: FrameSamples, trunk: Any, fit_kw: dict[str, Any]
    ) -> Any:
        """:func:`qdcnn.models.transfer.fit_transfer` with this estimator's networks."""
        from qdcnn.models.transfer import fit_transfer

        head = self._head() or "quantum"
        first, classical = self, None
        arch = classical_network(self.arch)
        if arch is not None:
            first = self._classical_estimator(arch)
            classical = first._classical_stage()
        settings = trainer.settings if classical is None else classical.settings
        key = None if fit_kw.get("extra") is not None else first._trunk_key(samples, settings)
        result, _ = fit_transfer(
            trainer,
            self._build,
            head,
            samples,
            trunk=trunk,
            cache_key=key,
            fit_kw=fit_kw,
            classical=classical,
            folder=self.trunk_cache,
        )
        return result

    def _trunk_key(self, samples: FrameSamples, settings: TrainSettings) -> str:
        """Where a trunk trained by this estimator on ``samples`` is cached."""
        from qdcnn.models.transfer import data_key

        common = self._trunk_network_kw()
        what = repr((self.arch, int(self.context), self.weights, sorted(common.items())))
        return data_key(samples, settings, what)

    def _classical_estimator(self, arch: str) -> CNNDirectionClassifier:
        """The classical network ``arch`` with this estimator's settings and its
        ``classical_recipe``: the estimator its own method would build."""
        params = {**self.get_params(deep=False), **dict(self.classical_recipe or {})}
        params.update(
            arch=arch,
            network_params=self._trunk_network_kw() or None,
            transfer=False,
            trunk_from=None,
            classical_recipe=None,
            noise=None,
            train_noise=None,
        )
        return CNNDirectionClassifier(**params)

    def _classical_stage(self) -> Any:
        """Stage 1 of a transfer as this (classical) estimator's own training."""
        from qdcnn.models.hybrid import CLASSICAL_TRUNKS
        from qdcnn.models.transfer import ClassicalStage

        settings = self._checked()[1]
        return ClassicalStage(partial(self._build, None), settings, CLASSICAL_TRUNKS[self.arch])

    def _keep_classical_trunk(
        self, samples: FrameSamples, settings: TrainSettings, result: Any
    ) -> None:
        """Keep the trunk of a trained classical network that a hybrid's transfer recipe
        starts from (``dnn-pilotnet`` for ``qdcnn-head``), for the hybrids of that fold."""
        from qdcnn.models.hybrid import CLASSICAL_TRUNKS
        from qdcnn.models.transfer import keep_trunk

        if self.arch not in CLASSICAL_TRUNKS:
            return

        trunk = CLASSICAL_TRUNKS[self.arch](result.network)
        keep_trunk(self._trunk_key(samples, settings), trunk, len(result.history), self.trunk_cache)

    def read_trunk(self) -> dict[str, Any]:
        """The front and trunk weights of the ``trunk_from`` network, checked against this
        estimator's architecture, input size, context and classes.

        Raises
        ------
        InputError
            Another architecture, input spec, frame context or class set (one line).
        """
        torch = _torch("reading a trunk")
        from qdcnn.models.persistence import read_saved_network, spec_from_meta

        path = self.trunk_from
        assert path is not None
        meta, arrays = read_saved_network(path)
        spec = input_spec(self.arch, self.crop)
        checks = (
            ("architecture", meta.get("architecture"), self.arch),
            ("input", spec_from_meta(meta.get("input_spec"), path), spec),
            ("frames per input (context)", meta.get("context", 1), int(self.context)),
            ("classes", meta.get("class_names"), list(DIRECTIONS)),
            ("frame front", _saved_front(meta), self._front()),
        )
        for what, theirs, ours in checks:
            if theirs != ours:
                raise InputError(path, f"--from: its {what} is {theirs!r}, this network's {ours!r}")
        parts = ("front.", "trunk.")
        return {k: torch.from_numpy(np.array(v)) for k, v in arrays.items() if k.startswith(parts)}

    # -------------------------------------------------------------- inference
    def predict_proba(
        self, images: ArrayLike | Sequence[NDArray[np.uint8]], noise: GateNoise | str | None = None
    ) -> NDArray[np.float64]:
        """Class probabilities ``(N, 3)`` for left, straight, right.

        ``noise`` (a :class:`~qdcnn.quantum.noise.NoiseSpec`, a device noise or its text,
        e.g. ``"depolarizing:0.1"``) overrides the estimator's ``noise`` for this call; it
        needs a network with a quantum layer (the hybrids).
        """
        check_is_fitted(self, "model_")
        members = self._averaged()
        if members:
            return np.mean([m.predict_proba(images, noise) for m in members], axis=0)
        if noise is not None:
            previous = _as_noise("noise", self.noise)
            _set_quantum_noise(self.model_, _as_noise("noise", noise), "noise")
            try:
                return self.predict_proba(images)
            finally:
                _set_quantum_noise(self.model_, previous, "noise")
        torch = _torch("CNN inference")
        from qdcnn.models.trainer import torch_session

        x = _as_images(images)
        out = np.empty((len(x), N_CLASSES), dtype=np.float64)
        step = max(int(self.batch_size), 64)
        self.model_.eval()
        with torch_session(self._threads(), None, self.device_), torch.inference_mode():
            for start in range(0, len(x), step):
                xb = self._inputs(x, start, min(start + step, len(x)))
                proba = torch.softmax(self.model_(xb).float(), 1)
                if self.tta:
                    mirrored = torch.softmax(self.model_(xb.flip(-1)).float(), 1)
                    proba = (proba + mirrored[:, [RIGHT, STRAIGHT, LEFT]]) / 2
                out[start : start + step] = proba.cpu().numpy()
        return out

    def _inputs(self, x: NDArray[np.uint8], start: int, stop: int) -> torch.Tensor:
        """Network input of frames ``start .. stop - 1``, with their context frames."""
        from qdcnn.models.preprocess import crop_resize, normalise

        k = self.context_
        first = max(start - k + 1, 0)
        pool = crop_resize(x[first:stop], self.input_spec_)
        windows = context_windows(stop, k)[start:] - first
        stacked = pool[windows]  # (B, K, 3, h, w)
        b, _, c, h, w = stacked.shape
        return normalise(stacked.reshape(b, k * c, h, w).to(self.device_), self.input_spec_)

    def predict(
        self, images: ArrayLike | Sequence[NDArray[np.uint8]], noise: GateNoise | str | None = None
    ) -> NDArray[np.int64]:
        """Direction per frame: 0 = left, 1 = straight, 2 = right (``noise``: see
        :meth:`predict_proba`), the most probable class."""
        return self.predict_with_proba(images, noise)[0]

    def predict_with_proba(
        self, images: ArrayLike | Sequence[NDArray[np.uint8]], noise: GateNoise | str | None = None
    ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """:meth:`predict` and :meth:`predict_proba` from one pass of each network."""
        proba = self.predict_proba(images, noise)
        return np.argmax(proba, axis=1).astype(np.int64), proba

    def score(
        self,
        images: ArrayLike | Sequence[NDArray[np.uint8]],
        labels: ArrayLike,
        sample_weight: ArrayLike | None = None,
    ) -> float:
        """Accuracy of :meth:`predict` against ``labels``."""
        x = _as_images(images)
        y = _as_labels(labels, len(x))
        hits = (self.predict(x) == y).astype(np.float64)
        if sample_weight is None:
            return float(hits.mean())
        return float(np.average(hits, weights=np.asarray(sample_weight, dtype=np.float64)))

    # --------------------------------------------------- building and files
    @classmethod
    def from_network(
        cls, network: nn.Module, arch: str = "pilotnet", **params: Any
    ) -> CNNDirectionClassifier:
        """A classifier ready for inference with a given network (trained or not).

        Parameters
        ----------
        network : nn.Module
            Maps ``arch``'s preprocessed frames ``(B, 3 * context, H, W)`` to logits
            ``(B, 3)``, for example :func:`qdcnn.models.networks.build_network`'s.
        arch : str
            The registered network whose input spec (crop, size, colour) applies.
        **params
            Further constructor parameters (``device``, ``tta``, ``context``, ...).

        Raises
        ------
        ParameterError
            An invalid parameter.

        Examples
        --------
        >>> from qdcnn.models.networks import build_network
        >>> net = build_network("pilotnet", seed=0)  # doctest: +SKIP
        >>> clf = CNNDirectionClassifier.from_network(net, device="cpu")  # doctest: +SKIP
        """
        clf = cls(arch, **params)
        clf._checked()
        clf._set_fitted(network, input_spec(arch, clf.crop), [], 0)
        return clf

    def _meta(self, spec: InputSpec, context: int) -> dict[str, Any]:
        """Header fields of a model file, except ``history`` and ``best_epoch``."""
        from qdcnn.models.persistence import spec_to_meta

        meta = {
            "architecture": self.arch,
            "params": {**_plain_params(self.get_params()), "context": context},
            "class_names": list(DIRECTIONS),
            "input_spec": spec_to_meta(spec),
            "context": context,
            "in_channels": 3 * context,
        }
        if _is_hybrid(self.arch):
            meta["head_format"] = HEAD_FORMAT
        return meta

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the trained network, its settings and history to ``path`` (safetensors + header).

        Returns
        -------
        Path
            The file written (atomically: never half-written).
        """
        from qdcnn.models.persistence import save_network

        if self._averaged():
            raise ParameterError(
                "ensemble",
                self.ensemble,
                "1 for a network file (save the ensemble as a direction model)",
            )
        return save_network(path, self.model_, self._fitted_meta())

    def fitted_state(self) -> tuple[dict[str, Any], dict[str, NDArray[Any]]]:
        """Header fields and weight arrays for a direction model file (:mod:`qdcnn.persistence`)."""
        from qdcnn.models.persistence import state_arrays

        members = self._averaged()
        if not members:
            return self._fitted_meta(), state_arrays(self.model_)
        meta = {**self._fitted_meta(), "members": [m._fitted_meta() for m in members[1:]]}
        return meta, joined_arrays([state_arrays(m.model_) for m in members])

    def _fitted_meta(self) -> dict[str, Any]:
        """The header of a model file: settings, input spec, history and best epoch."""
        check_is_fitted(self, "model_")
        from qdcnn.models.persistence import json_safe

        return {
            **self._meta(self.input_spec_, self.context_),
            "history": json_safe(self.history_),
            "best_epoch": self.best_epoch_,
            "restarts": json_safe(self.restarts_),
            "seed_used": self.seed_,
        }

    def load_fitted_state(
        self, meta: dict[str, Any], arrays: dict[str, NDArray[Any]], source: str | os.PathLike[str]
    ) -> None:
        """Rebuild the network from :meth:`fitted_state`'s output (names and shapes checked)."""
        if not isinstance(meta, dict) or meta.get("architecture") != self.arch:
            raise InputError(source, f"the weights are not those of a {self.arch!r} network")
        self._checked()
        metas = [meta, *_member_metas(meta, self.ensemble, source)]
        if self.ensemble == 1:
            self._restore(meta, arrays, source)
            return
        members = [self._member(k) for k in range(len(metas))]
        for member, part, arrays_of in zip(
            members, metas, split_arrays(arrays, self.ensemble, source), strict=True
        ):
            member._restore(part, arrays_of, source)
        self._adopt(members)

    @classmethod
    def load(
        cls, path: str | os.PathLike[str], *, device: str | None = None
    ) -> CNNDirectionClassifier:
        """Read a classifier written by :meth:`save` (or a ``best.safetensors`` checkpoint).

        Parameters
        ----------
        path : str or path-like
            The file.
        device : str or None
            Override the saved device setting (for example ``"cpu"``).

        Raises
        ------
        InputError
            The file is missing, empty, corrupt or truncated, pickle-based (an
            older ``.pt`` model: never unpickled), not a CNN direction classifier,
            or its header and weights disagree (architecture, names, shapes).
        """
        _torch("loading a CNN direction classifier")
        from qdcnn.models.persistence import read_network_file

        meta, arrays = read_network_file(path)
        clf = _classifier_from_meta(cls, meta, path, device)
        clf._restore(meta, arrays, path)
        return clf

    def _restore(
        self, meta: dict[str, Any], arrays: dict[str, NDArray[Any]], source: str | os.PathLike[str]
    ) -> None:
        """Rebuild the trained network from a model file's header and arrays (settings checked)."""
        _torch("loading a CNN direction classifier")
        from qdcnn.models.networks import build_network
        from qdcnn.models.persistence import history_from_meta, load_state_arrays, spec_from_meta

        spec = spec_from_meta(meta.get("input_spec"), source)
        kw = {**_saved_head_format(meta, self.arch, source), **self._network_kw()}
        try:
            network = build_network(self.arch, 3 * int(self.context), seed=0, **kw)
        except ParameterError as exc:
            raise InputError(source, f"saved settings are invalid: {exc}") from None
        load_state_arrays(network, arrays, source, name=f"qdcnn {self.arch}")
        restarts, seed = _restarts_from_meta(meta, source)
        self._set_fitted(network, spec, *history_from_meta(meta, source), restarts, seed)


def _member_metas(
    meta: dict[str, Any], networks: int, source: str | os.PathLike[str]
) -> list[dict[str, Any]]:
    """The headers of an ensemble file's networks after the first."""
    members = meta.get("members", [])
    if not isinstance(members, list) or len(members) != networks - 1:
        held = len(members) + 1 if isinstance(members, list) else 1
        noun = "network" if held == 1 else "networks"
        raise InputError(source, f"holds {held} {noun}, its settings say ensemble={networks}")
    if not all(isinstance(m, dict) for m in members):
        raise InputError(source, "header field 'members' is not a list of objects")
    return members


def _front_of(network_params: dict[str, Any]) -> str:
    """``"standardised"``, ``"edges"``, ``"standardised+edges"`` or ``"none"``: what a
    network with these parameters does to each frame before its trunk."""
    on = [
        name
        for key, name in (("standardise_frames", "standardised"), ("edge_frames", "edges"))
        if network_params.get(key) is True
    ]
    return "+".join(on) or "none"


def _saved_front(meta: dict[str, Any]) -> str:
    """:func:`_front_of` a model file's network."""
    params = meta.get("params")
    network = params.get("network_params") if isinstance(params, dict) else None
    return _front_of(network) if isinstance(network, dict) else "none"


def _classifier_from_meta(
    cls: type[CNNDirectionClassifier],
    meta: dict[str, Any],
    path: str | os.PathLike[str],
    device: str | None,
) -> CNNDirectionClassifier:
    """The estimator a file's header describes, its architecture and settings checked."""
    arch = meta.get("architecture")
    if not isinstance(arch, str) or arch not in NETWORKS:
        known = ", ".join(map(repr, NETWORKS))
        raise InputError(path, f"architecture {arch!r} is not a known network ({known})")
    if meta.get("class_names") != list(DIRECTIONS):
        raise InputError(
            path, f"class names {meta.get('class_names')!r} are not {list(DIRECTIONS)!r}"
        )
    params = meta.get("params")
    if not isinstance(params, dict):
        raise InputError(path, "header field 'params' is missing or not an object")
    params = dict(params)
    if isinstance(params.get("crop"), list):
        params["crop"] = tuple(params["crop"])
    if device is not None:
        params["device"] = device
    try:
        clf = cls(**params)
        clf._checked()
    except (TypeError, ParameterError) as exc:
        raise InputError(path, f"saved settings are invalid: {exc}") from None
    if clf.arch != arch:
        raise InputError(path, f"header architecture {arch!r} but settings arch {clf.arch!r}")
    in_channels = meta.get("in_channels", 3 * clf.context)
    if in_channels != 3 * clf.context:
        raise InputError(
            path, f"header in_channels {in_channels!r} but context {clf.context} (3 per frame)"
        )
    return clf


def _saved_head_format(meta: dict[str, Any], arch: str, source: object) -> dict[str, Any]:
    """Network parameters a file's ``head_format`` implies: a hybrid saved before the
    dressed heads (no field) is rebuilt with ``dressed=False``, one of format 2 with a
    ``CX`` ring; other values are refused."""
    if not _is_hybrid(arch):
        return {}
    found = meta.get("head_format")
    if found == HEAD_FORMAT:
        return {}
    if (found is None or type(found) is int) and found in _OLDER_HEAD_FORMATS:
        return dict(_OLDER_HEAD_FORMATS[found])
    readable = ", ".join(str(v) for v in (HEAD_FORMAT, *_OLDER_HEAD_FORMATS) if v is not None)
    raise InputError(
        str(source),
        f"header head_format {found!r} is not one this qdcnn reads "
        f"({readable}, or none for the original heads)",
    )


def _restarts_from_meta(
    meta: dict[str, Any], source: object
) -> tuple[list[dict[str, Any]], int | None]:
    """The restarts and the seed used a header stores (absent in older files), checked."""
    restarts = meta.get("restarts", [])
    seed = meta.get("seed_used")
    if not isinstance(restarts, list) or not all(isinstance(r, dict) for r in restarts):
        raise InputError(str(source), "header field 'restarts' is not a list of records")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or seed < 0):
        raise InputError(str(source), f"header seed_used {seed!r} is not a seed")
    return restarts, seed


def _is_hybrid(arch: str) -> bool:
    from qdcnn.models.specs import hybrid_of

    hybrid = hybrid_of(arch)
    return hybrid is not None and hybrid.name == arch


def _as_view(view: object, shape: tuple[int, ...]) -> ExtraView:
    if not isinstance(view, ExtraView):
        raise InputError("extra_views", f"expected ExtraView items, got {type(view).__name__}")
    images = _as_images(view.images, view.name)
    if images.shape != shape:
        raise InputError(view.name, f"frames of shape {images.shape}, the images are {shape}")
    return ExtraView(images, _as_labels(view.labels, shape[0], f"{view.name} labels"), view.name)


def _extra_samples(
    views: list[ExtraView], spec: InputSpec, context: int
) -> tuple[FrameSamples | None, NDArray[np.int64] | None]:
    """All views as one set of extra samples, and the frame each accompanies."""
    if not views:
        return None, None
    torch = _torch("training a CNN direction classifier")
    from qdcnn.models.preprocess import crop_resize
    from qdcnn.models.trainer import FrameSamples

    n = len(views[0].labels)
    windows = context_windows(n, context)
    pool = torch.cat([crop_resize(v.images, spec) for v in views])
    all_windows = np.concatenate([windows + i * n for i in range(len(views))])
    labels = np.concatenate([v.labels for v in views])
    extra = FrameSamples(pool, torch.from_numpy(all_windows), torch.from_numpy(labels))
    return extra, np.tile(np.arange(n, dtype=np.int64), len(views))


def inference_fps(
    arch: str = "pilotnet",
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
    from qdcnn.models.networks import build_network

    check_int("n", n, 1, 10**7)
    check_choice("clock", clock, ("wall", "cpu"))
    if len(size) != 2 or min(size) < 1:
        raise ParameterError("size", size, "(height, width) with positive integers")
    clf = CNNDirectionClassifier.from_network(
        build_network(arch, seed=seed),
        arch,
        batch_size=batch_size,
        device="cpu",
        num_threads=num_threads,
        seed=seed,
        progress=False,
        tta=tta,
    )
    timer = time.perf_counter if clock == "wall" else time.process_time
    frames = np.random.default_rng(seed).integers(0, 256, (n, *size, 3), dtype=np.uint8)
    clf.predict(frames[: min(n, batch_size)])
    start = timer()
    clf.predict(frames)
    return n / (timer() - start)
