"""Transfer training of a hybrid network: the standard two-stage recipe for a dressed head.

Stage 1 trains the classical network: for ``qdcnn-head`` PilotNet itself, trained as
the ``dnn-pilotnet`` method trains it (:class:`ClassicalStage`); for the other hybrids
their trunk with a linear head, trained with the hybrid's settings. Stage 2 puts the
hybrid's own head (quantum, its twin or an ablation) on that trunk and trains the head
alone, the trunk frozen, at ten times the learning rate. Stage 3 fine-tunes everything at
a tenth of the learning rate (Mari et al. 2020, "Transfer learning in hybrid
classical-quantum neural networks"; PennyLane's quantum transfer learning demo trains
stage 2 only).

The stage-1 trunk depends on the training frames, the seed and the settings, not on the
head, so it is kept in memory (:func:`cached_trunk`): a hybrid, its twin and the ablations
trained on the same fold with the same seed share one classical training, and with
PilotNet as stage 1 that training is the ``dnn-pilotnet`` run of the same fold and seed.
Given a folder (``evaluate`` gives one inside its cache), trunks are also kept there as
safetensors files, so a resumed run and other processes (Dask workers) find them too.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from qdcnn._fileio import write_cache_entry
from qdcnn._optional import require
from qdcnn.errors import ParameterError
from qdcnn.models.trainer import MAX_LR, FrameSamples, Trainer, TrainResult, TrainSettings

require("torch", "transfer training")
import torch  # noqa: E402
from torch import nn  # noqa: E402

#: ``build(head, seed)``: a fresh hybrid network with head ``head`` (``"linear"`` in stage 1).
HybridBuilder = Callable[[str, int], nn.Module]
#: Parts of a hybrid network that stage 2 freezes and stage 3 fine-tunes.
TRUNK_PARTS: tuple[str, str] = ("front", "trunk")
#: key -> (stage-1 trunk, epochs stage 1 ran)
_TRUNKS: dict[str, tuple[dict[str, torch.Tensor], int]] = {}
_MAX_CACHED = 32
#: Stage 2 trains the new head alone at this multiple of the learning rate (new layers on
#: a frozen trunk learn at a higher rate than the fine-tuning; at the trunk's rate a dressed
#: head's few dozen parameters barely move in its quarter of the epochs:
#: ``docs/hybrid-collapse.md``).
HEAD_STAGE_LR_FACTOR = 10.0


@dataclass(frozen=True)
class ClassicalStage:
    """Stage 1 as the training of another (classical) network whose trunk the hybrid takes.

    Attributes
    ----------
    build : callable
        ``build(seed)``: a fresh classical network.
    settings : TrainSettings
        Its own training settings (those its own method trains with).
    trunk_of : callable
        ``trunk_of(network)``: its trunk under the hybrid's names (:func:`trunk_state`'s).
    """

    build: Callable[[int], nn.Module]
    settings: TrainSettings
    trunk_of: Callable[[nn.Module], dict[str, torch.Tensor]]


def stage_epochs(epochs: int) -> tuple[int, int]:
    """Epochs of the head stage and of the fine-tuning stage after ``epochs`` classical ones
    (those stage 1 ran, early stopping included).

    A quarter each (at least one): the head stage runs the trunk forward only, so the
    three stages cost about 1.3 times the classical training alone.
    """
    quarter = max(1, epochs // 4)
    return quarter, quarter


def trunk_state(network: nn.Module) -> dict[str, torch.Tensor]:
    """The state of ``network``'s front and trunk (copies, on the CPU), by their names."""
    out: dict[str, torch.Tensor] = {}
    for part in TRUNK_PARTS:
        module = getattr(network, part, None)
        if isinstance(module, nn.Module):
            for key, value in module.state_dict().items():
                out[f"{part}.{key}"] = value.detach().cpu().clone()
    return out


def load_trunk(network: nn.Module, state: dict[str, torch.Tensor]) -> None:
    """Copy a :func:`trunk_state` into ``network`` (names and shapes must match)."""
    mine = trunk_state(network)
    if set(mine) != set(state) or any(mine[k].shape != state[k].shape for k in mine):
        raise ParameterError("trunk", "another network's trunk", "a trunk of this network")
    network.load_state_dict(state, strict=False)


def freeze_trunk(network: nn.Module, frozen: bool) -> None:
    """Stop (or restart) gradients to ``network``'s front and trunk."""
    for part in TRUNK_PARTS:
        module = getattr(network, part, None)
        if isinstance(module, nn.Module):
            for p in module.parameters():
                p.requires_grad_(not frozen)


def data_key(samples: FrameSamples, settings: TrainSettings, what: str) -> str:
    """A digest of the training samples, the settings and ``what`` (the network without
    its head): the key of a cached trunk."""
    h = hashlib.blake2b(digest_size=16)
    for tensor in (samples.pool, samples.windows, samples.labels):
        h.update(np.ascontiguousarray(tensor.cpu().numpy()).tobytes())
    how = replace(settings, num_threads=None, checkpoint_dir=None)  # where it ran: not the key
    h.update(repr((how, what)).encode())
    return h.hexdigest()


def cached_trunk(key: str, folder: str | Path | None = None) -> dict[str, torch.Tensor] | None:
    """The stage-1 trunk kept under ``key``, if any."""
    kept = _kept(key, folder)
    return None if kept is None else kept[0]


def cached_epochs(key: str, folder: str | Path | None = None) -> int | None:
    """How many epochs the stage 1 of the trunk kept under ``key`` ran, if kept."""
    kept = _kept(key, folder)
    return None if kept is None else kept[1]


def keep_trunk(
    key: str, state: dict[str, torch.Tensor], epochs: int, folder: str | Path | None = None
) -> None:
    """Keep a stage-1 trunk and the epochs it took (the oldest goes beyond
    :data:`_MAX_CACHED`), and write it to ``folder`` when given."""
    _remember(key, (state, epochs))
    if folder is not None:
        from safetensors.torch import save

        data = save({k: v.contiguous() for k, v in state.items()}, {"epochs": str(epochs)})
        write_cache_entry(_trunk_file(folder, key), data)  # unwritable: kept in memory only


def _remember(key: str, kept: tuple[dict[str, torch.Tensor], int]) -> None:
    if len(_TRUNKS) >= _MAX_CACHED:
        _TRUNKS.pop(next(iter(_TRUNKS)))
    _TRUNKS[key] = kept


def _kept(key: str, folder: str | Path | None) -> tuple[dict[str, torch.Tensor], int] | None:
    """The trunk kept under ``key``: in memory, else in ``folder`` (then remembered). An
    unreadable file counts as absent: the trunk is trained again and the file rewritten."""
    if key in _TRUNKS or folder is None:
        return _TRUNKS.get(key)
    from safetensors import SafetensorError, safe_open

    try:
        with safe_open(str(_trunk_file(folder, key)), framework="pt") as f:
            state = {k: f.get_tensor(k) for k in f.keys()}
            kept = state, int((f.metadata() or {}).get("epochs", ""))
    except (OSError, ValueError, SafetensorError):  # absent, unreadable or damaged
        return None
    _remember(key, kept)
    return kept


def _trunk_file(folder: str | Path, key: str) -> Path:
    return Path(folder) / f"{key}.safetensors"


def fit_transfer(
    trainer: Trainer,
    build: HybridBuilder,
    head: str,
    samples: FrameSamples,
    *,
    trunk: dict[str, torch.Tensor] | None = None,
    cache_key: str | None = None,
    fit_kw: dict[str, Any] | None = None,
    classical: ClassicalStage | None = None,
    folder: str | Path | None = None,
) -> tuple[TrainResult, dict[str, torch.Tensor]]:
    """Run the three stages (stage 1 skipped when ``trunk`` is given or cached).

    Parameters
    ----------
    trainer : Trainer
        Its settings are stage 1's; stage 2 runs :func:`stage_epochs`' first count (of the
        epochs stage 1 ran, early stopping included) at :data:`HEAD_STAGE_LR_FACTOR` times
        the rate, stage 3 the second count at a tenth of it.
    build : callable
        ``build(head, seed)``, a fresh hybrid network.
    head : str
        The head of the trained network.
    trunk : dict or None
        A trunk to start from (``train-direction --from``).
    cache_key : str or None
        Where stage 1's trunk is kept and looked up (:func:`data_key`).
    fit_kw : dict or None
        Further arguments of :meth:`Trainer.fit` (extra samples).
    classical : ClassicalStage or None
        Stage 1 as another network's own training; by default the hybrid with a linear
        head, trained with ``trainer``'s settings.
    folder : path or None
        Where trunks are also kept on disk (:func:`keep_trunk`).

    Returns
    -------
    (TrainResult, dict)
        The result, whose history holds every stage (each record's ``stage``), and the trunk.
    """
    s = trainer.settings.checked(min_batch_size=trainer.min_batch_size)
    kw = dict(fit_kw or {})
    records: list[dict[str, Any]] = []
    restarts: list[dict[str, Any]] = []
    ran = s.epochs  # a trunk from a file: the epochs asked for
    kept = _kept(cache_key, folder) if trunk is None and cache_key is not None else None
    if kept is not None:
        trunk, ran = kept
    if trunk is None:
        first = _classical_stage(trainer, build, classical, samples, kw)
        trunk, ran = _trunk_of(first.network, classical), len(first.history)
        records += _staged(first, "classical")
        restarts += [{**r, "stage": "classical"} for r in first.restarts]
        if cache_key is not None:
            keep_trunk(cache_key, trunk, ran, folder)
    head_epochs, tune_epochs = stage_epochs(ran)

    def with_trunk(seed: int) -> nn.Module:
        network = build(head, seed)
        load_trunk(network, trunk)
        freeze_trunk(network, True)
        return network

    head_lr = min(s.lr * HEAD_STAGE_LR_FACTOR, MAX_LR)
    head_settings = replace(s, epochs=head_epochs, patience=0, lr=head_lr)
    second = _stage(trainer, head_settings, "head", with_trunk(s.seed), samples, kw, with_trunk)
    restarts += [{**r, "stage": "head"} for r in second.restarts]
    freeze_trunk(second.network, False)
    tune = replace(s, epochs=tune_epochs, lr=s.lr / 10, seed=second.seed, patience=0)
    third = _stage(trainer, tune, "finetune", second.network, samples, kw, None)
    offset = len(records) + len(second.history)
    result = replace(
        third,
        history=records + _staged(second, "head") + _staged(third, "finetune"),
        best_epoch=offset + third.best_epoch,
        restarts=restarts,
    )
    return result, trunk


def _classical_stage(
    trainer: Trainer,
    build: HybridBuilder,
    classical: ClassicalStage | None,
    samples: FrameSamples,
    kw: dict[str, Any],
) -> TrainResult:
    rebuild: Callable[[int], nn.Module]
    if classical is None:
        s, rebuild = trainer.settings, partial(build, "linear")
    else:
        s, rebuild = classical.settings, classical.build
    return _stage(trainer, s, "classical", rebuild(s.seed), samples, kw, rebuild)


def _trunk_of(network: nn.Module, classical: ClassicalStage | None) -> dict[str, torch.Tensor]:
    return trunk_state(network) if classical is None else classical.trunk_of(network)


def _stage(
    trainer: Trainer,
    settings: TrainSettings,
    name: str,
    network: nn.Module,
    samples: FrameSamples,
    kw: dict[str, Any],
    rebuild: Callable[[int], nn.Module] | None,
) -> TrainResult:
    if name != "finetune":  # only the last stage's network is the model's
        settings = replace(settings, checkpoint_dir=None)
    stage = Trainer(
        settings,
        transform=trainer.transform,
        on_step=trainer.on_step,
        on_epoch=trainer.on_epoch,
        checkpoint_meta={**trainer.checkpoint_meta, "stage": name},
        min_batch_size=trainer.min_batch_size,
    )
    return stage.fit(network, samples, rebuild=rebuild, **kw)


def _staged(result: TrainResult, stage: str) -> list[dict[str, Any]]:
    return [{**record, "stage": stage} for record in result.history]
