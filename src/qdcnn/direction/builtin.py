"""The built-in direction models: what ``run``, ``detect-lanes`` and ``score`` use without
``--model``.

With torch installed (the ``dnn`` extra) it is the built-in QDCNN model
(:func:`builtin_qdcnn_model`): a ``qdcnn-head`` hybrid shipped inside the package as
:data:`QDCNN_FILE`, made by ``benchmarks/train_builtin.py`` (trained on the four
recordings of ``../shared/data`` and three synthetic presets; its header says what it was
trained on and its leave-one-recording-out scores). Its SHA-256 is :data:`QDCNN_SHA256`;
a missing or altered file is an error, never a silent fallback to the lane model.

Without torch, or when a lane ``--method`` or lane options are asked for, it is the
built-in lane model: :data:`DEFAULT_METHOD` trained on :data:`DEFAULT_TRAINING_DATA`, all three
synthetic presets (clear track1, hilly track2 with shadows, rain). The method is the one
of the registry's lane methods that generalised best in
``benchmarks/default_model_study.py``: trained on two presets and tested on the third,
and trained on all three and tested on the recordings of ``../shared/data``.

The first use trains it (about a minute: 900 synthetic frames through the lane pipeline)
and scores it with the evaluation protocol (contiguous folds with a gap over the three
presets in a row); the model file goes to ``$QDCNN_CACHE/models`` (default
``~/.cache/qdcnn/models``) under a key of the method, the data, the seed, the settings
and the code, and later uses read it back. A cached file that no longer reads is
trained again.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from qdcnn import __version__
from qdcnn._optional import has_torch
from qdcnn.config import PipelineConfig
from qdcnn.direction.features import cache_dir, code_fingerprint
from qdcnn.direction.methods import DirectionMethod, get_method
from qdcnn.direction.model import DirectionModel, train_direction_model
from qdcnn.direction.protocol import cross_validate, majority_baseline, pooled_accuracy
from qdcnn.errors import InputError, ParameterError
from qdcnn.runtime.reporting import Reporter

__all__ = [
    "DEFAULT_METHOD",
    "DEFAULT_TRAINING_DATA",
    "QDCNN_FILE",
    "QDCNN_SHA256",
    "builtin_model",
    "builtin_qdcnn_model",
    "default_direction_model",
    "default_model_path",
    "describe_default_model",
    "direction_model",
    "uses_builtin_qdcnn",
]

#: The lane method of the built-in model (``benchmarks/default_model_study.py``).
DEFAULT_METHOD = "image-split-uu"
#: What the built-in model is trained on: 300 frames of each synthetic preset.
DEFAULT_TRAINING_DATA = ("synthetic:track1:300", "synthetic:track2:300", "synthetic:rain:300")
#: The protocol that scores it (that of ``qdcnn evaluate``).
SCORE_FOLDS, SCORE_GAP = 5, 5
#: The built-in QDCNN model, shipped with the package (``benchmarks/train_builtin.py``).
QDCNN_FILE = Path(__file__).with_name("builtin_models") / "qdcnn-head.safetensors"
#: The SHA-256 of :data:`QDCNN_FILE`: a file with another digest is refused at load.
QDCNN_SHA256 = "8d92c66b3c871cb32cf85fc2c38f25426483bc58f666ce37872072c00a1c2987"


def builtin_qdcnn_model(path: Path | None = None, sha256: str | None = None) -> DirectionModel:
    """The built-in QDCNN model, read from ``path`` (default :data:`QDCNN_FILE`) after
    checking its SHA-256 against ``sha256`` (default :data:`QDCNN_SHA256`).

    Raises
    ------
    InputError
        The file is missing, unreadable, or its SHA-256 is not ``sha256`` (altered or
        truncated): one line naming the file; nothing else is tried instead.
    """
    path = QDCNN_FILE if path is None else path
    sha256 = QDCNN_SHA256 if sha256 is None else sha256
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(
            path, "the built-in QDCNN model file is missing (reinstall qdcnn, or give --model)"
        ) from None
    except OSError as exc:
        raise InputError(
            path, f"the built-in QDCNN model file cannot be read ({exc.strerror or exc})"
        ) from None
    digest = hashlib.sha256(data).hexdigest()
    if digest != sha256:
        raise InputError(
            path,
            f"the built-in QDCNN model file is altered: its SHA-256 is {digest[:16]}..., "
            f"the package's is {sha256[:16]}... (reinstall qdcnn, or give --model)",
        )
    return DirectionModel.load(path)


def uses_builtin_qdcnn(method: str | None, seed: int, config: PipelineConfig | None) -> bool:
    """Whether :func:`builtin_model` gives the QDCNN model for these arguments: no lane
    ``method`` asked for, torch installed and the default lane settings."""
    default = config is None or config == PipelineConfig(seed=seed)
    return method is None and default and has_torch()


def builtin_model(
    method: str | None,
    seed: int,
    config: PipelineConfig | None = None,
    reporter: Reporter | None = None,
) -> tuple[DirectionModel, str]:
    """The built-in model and one line naming it.

    ``method`` ``None`` with torch installed and the default lane settings (``config``
    ``None`` or ``PipelineConfig(seed=seed)``): the built-in QDCNN model. Otherwise the
    built-in lane model of ``method`` (default :data:`DEFAULT_METHOD`) trained with
    ``config`` (:func:`default_direction_model`).
    """
    config = config or PipelineConfig(seed=seed)
    if uses_builtin_qdcnn(method, seed, config):
        model = builtin_qdcnn_model()
        return model, describe_default_model(model)
    model = default_direction_model(
        method or DEFAULT_METHOD, seed, data=DEFAULT_TRAINING_DATA, config=config, reporter=reporter
    )
    why = "" if method is not None or has_torch() else " (torch is not installed)"
    return model, f"{describe_default_model(model)}{why}"


def default_model_path(
    method: str = DEFAULT_METHOD,
    seed: int = 0,
    data: Sequence[str] = DEFAULT_TRAINING_DATA,
    config: PipelineConfig | None = None,
) -> Path:
    """Where the cached model of ``method`` trained on ``data`` with ``seed`` (and the
    pipeline ``config``, default ``PipelineConfig(seed=seed)``) lives."""
    payload = json.dumps(
        {
            "method": method,
            "data": list(data),
            "seed": seed,
            "config": (config or PipelineConfig(seed=seed)).to_dict(),
            "version": __version__,
            "code": code_fingerprint(),
        },
        sort_keys=True,
    )
    key = hashlib.sha256(payload.encode()).hexdigest()[:20]
    return cache_dir() / "models" / f"default-{method}-{key}.qdcnn"


def default_direction_model(
    method: str = DEFAULT_METHOD,
    seed: int = 0,
    *,
    data: str | Sequence[str] = DEFAULT_TRAINING_DATA,
    use_cache: bool = True,
    config: PipelineConfig | None = None,
    reporter: Reporter | None = None,
) -> DirectionModel:
    """Lane method ``method`` trained on ``data`` (dataset specs), read from the cache if there.

    ``config`` is the pipeline it is trained with (default ``PipelineConfig(seed=seed)``);
    ``reporter`` is told the training's progress (a minute when nothing is cached). A cache
    that cannot be written (``$QDCNN_CACHE`` read-only, full, or not a folder) does not stop
    the work: the model is used as trained, and ``reporter`` gets a note that it was not kept.

    Raises
    ------
    InputError
        ``method`` is an image method (those need a trained model file).
    """
    info = get_method(method)
    if info.inputs != "lanes" or info.grouping is None:
        raise InputError(method, "needs a trained model file (--model) for image methods")
    specs = (data,) if isinstance(data, str) else tuple(data)
    config = config or PipelineConfig(seed=seed)
    path = default_model_path(info.name, seed, specs, config)
    if use_cache and path.is_file():
        try:
            return DirectionModel.load(path)
        except InputError:
            pass  # an unreadable cache entry (an interrupted disk, an older format): retrain
    report = reporter or Reporter()
    model = _train_and_score(info, specs, seed, config, report)
    if use_cache:
        try:
            model.save(path)
        except InputError as exc:  # the cache only saves time: go on with the model in hand
            report.note(
                f"the built-in model is not kept in the cache ({exc}); it is trained again "
                "next time (set QDCNN_CACHE to a writable folder)"
            )
    return model


def direction_model(
    path: Path | None,
    method: str | None,
    seed: int,
    config: PipelineConfig,
    note: Callable[[str], None],
    reporter: Reporter | None = None,
) -> tuple[DirectionModel, str]:
    """The model file at ``path``, or (``path`` None) the built-in model
    (:func:`builtin_model`: the QDCNN model, or the lane model of ``method`` trained with
    ``config``, its progress told to ``reporter``) named in a ``note``; and one line
    naming the model that decides.

    Raises
    ------
    ParameterError
        ``path`` is given with a ``config`` other than the default one: a model file
        carries the pipeline settings it was trained with.
    """
    if path is not None:
        if config != PipelineConfig(seed=seed):
            raise ParameterError(
                "model",
                str(path),
                "a model file carries the lane settings it was trained with; give either "
                "--model or lane options other than the defaults, not both",
            )
        model = DirectionModel.load(path)
        return model, f"{model.method} from {path}"
    model, name = builtin_model(method, seed, config, reporter)
    note(f"no --model: model: {name}")
    return model, name


def describe_default_model(model: DirectionModel) -> str:
    """One line: which built-in model, what it was trained on and how it scores."""
    builtin = model.summary.get("builtin")
    if isinstance(builtin, dict):
        names = ", ".join(builtin.get("training", {}).get("recordings", {})) or model.trained_on
        networks = int(getattr(model.estimator, "ensemble", 1))
        mean = f", the mean of {networks} networks" if networks > 1 else ""
        return f"built-in {model.method}{mean} (trained on {names}; sha256 {QDCNN_SHA256[:12]})"
    cv = model.summary.get("cross_validation", {})
    score = (
        f"; {cv['folds']}-fold contiguous CV accuracy {cv['accuracy']:.3f} "
        f"(majority class {cv['majority_baseline']:.3f})"
        if cv
        else ""
    )
    return f"built-in lane model {model.method} trained on {model.trained_on}{score}"


def _train_and_score(
    info: DirectionMethod,
    specs: tuple[str, ...],
    seed: int,
    config: PipelineConfig,
    report: Reporter,
) -> DirectionModel:
    from qdcnn.direction.lane_data import load_lane_data

    assert info.grouping is not None
    with report.progress(len(specs) + 2, f"built-in model {info.name}: train, score") as step:
        parts = []
        for spec in specs:
            parts.append(load_lane_data(spec, config, (info.grouping,), seed=seed))
            step()
        x = np.concatenate([p.features(info.grouping) for p in parts])
        y = np.concatenate([p.y for p in parts])
        model = train_direction_model(info, x, y, config, " + ".join(specs))
        step()
        cv = cross_validate(lambda: info.estimator(config), x, y, folds=SCORE_FOLDS, gap=SCORE_GAP)
        step()
    model.summary["cross_validation"] = {
        "folds": SCORE_FOLDS,
        "gap": SCORE_GAP,
        "accuracy": pooled_accuracy(y, cv.splits, cv.predictions),
        "majority_baseline": majority_baseline(y, cv.splits),
    }
    return model
