"""The direction-method registry: every left / straight / right method, declared once.

A :class:`DirectionMethod` names a method, says what it reads (``"lanes"``: the lane
features of one grouping; ``"frames"``: the RGB frames themselves), how to build its
estimator and hyperparameter grid from a :class:`~qdcnn.config.PipelineConfig`, and what
it needs (torch, a GPU). Every command (``evaluate``, ``train-direction``,
``detect-lanes``, ``noise-sweep``, ``run``), the demo and the benchmarks read this table,
so a new method is one :func:`register` call plus its estimator (any scikit-learn
classifier of 0 = left, 1 = straight, 2 = right).

Examples
--------
>>> get_method("kmeans-uu").grouping, get_method("kmeans-uu").kind
('kmeans', 'uu')
>>> [m for m in method_names() if m.startswith("image-split")]
['image-split-uu', 'image-split-vqc']
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, Literal

from sklearn.base import BaseEstimator

from qdcnn.config import PipelineConfig
from qdcnn.errors import ParameterError
from qdcnn.models.specs import HEADS, HYBRID_NETWORKS, HybridNetwork, hybrid_of
from qdcnn.vision.grouping import GROUPINGS

__all__ = [
    "GROUPINGS",
    "DirectionMethod",
    "TrainingOptions",
    "check_fit_settings",
    "check_inner_search",
    "get_method",
    "method_names",
    "register",
    "select_methods",
    "unregister",
    "with_head",
]

_Grid = dict[str, list[Any]]


@dataclass(frozen=True)
class TrainingOptions:
    """Settings of image-based methods (CNNs, hybrids); lane methods ignore them.

    Attributes
    ----------
    epochs : int
        Maximum training epochs (the paper: 25).
    weights : path or None
        Initial weights file (ImageNet ResNet-50 state dict), never downloaded.
    threads : int or None
        torch CPU threads (default: the CPUs this process may use).
    progress : bool
        Show training progress on stderr.
    context : int
        Frames stacked as one input (the frame and the ``context - 1`` before it).
    params : mapping
        Further estimator parameters (for studies).
    transfer : bool
        Train hybrid networks in stages (:mod:`qdcnn.models.transfer`).
    from_model : path or None
        A saved network of the same architecture whose trunk a hybrid starts from
        (``train-direction --from``).
    trunk_cache : path or None
        Where transfer's stage-1 trunks are also kept on disk (``evaluate`` with its cache
        on sets it); changes no result.
    balanced : bool
        Train the classical CNNs (and so the hybrids' stage 1) with the hybrids'
        :data:`HYBRID_RECIPE` (``--balanced``); ``params`` still win where they overlap.
    standardise_frames : bool
        PilotNet and ``qdcnn-head`` (its twin and ablations too) put each frame on its own
        scale first (:class:`~qdcnn.models.pilotnet.FrameStandardisation`,
        ``--standardise-frames``); the other methods train as usual
        (:func:`standardise_note`).
    edge_frames : bool
        The same networks see each frame's edges
        (:class:`~qdcnn.models.pilotnet.EdgeFrames`, ``--edge-frames``): only them, or with
        ``standardise_frames`` both (six planes a frame).

    ``transfer`` and ``from_model`` change only the hybrids' estimators; other methods
    ignore them (:func:`staged_note` says which, and refuses them without a hybrid).
    """

    epochs: int = 25
    weights: Path | None = None
    threads: int | None = None
    progress: bool = False
    context: int = 1
    params: Mapping[str, Any] = field(default_factory=dict)
    transfer: bool = False
    from_model: Path | None = None
    balanced: bool = False
    trunk_cache: Path | None = None
    standardise_frames: bool = False
    edge_frames: bool = False

    def __post_init__(self) -> None:
        from qdcnn._validation import check_bool, check_int

        check_int("epochs", self.epochs, 1, 10_000)
        if self.threads is not None:
            check_int("threads", self.threads, 1, 1024)
        check_int("context", self.context, 1, 64)
        check_bool("balanced", self.balanced)
        check_bool("standardise_frames", self.standardise_frames)
        check_bool("edge_frames", self.edge_frames)
        if self.trunk_cache is not None and not isinstance(self.trunk_cache, str | Path):
            raise ParameterError("trunk_cache", self.trunk_cache, "a folder path or None")


def check_fit_settings(gap: int, inner_folds: int, training: TrainingOptions) -> None:
    """Check what fitting a method on recorded frames takes: the ``gap`` of frames left out
    around test folds, the ``inner_folds`` of the hyper-parameter search (0: none) and that
    the initial weights file, if any, exists."""
    from qdcnn._validation import check_int
    from qdcnn.data.images import require_file

    check_int("gap", gap, 0, 10_000)
    if inner_folds != 0:
        check_int("inner_folds", inner_folds, 2, 100)
    if training.weights is not None:
        require_file(training.weights, "weights file")
    if training.from_model is not None:
        require_file(training.from_model, "--from model file")


def check_inner_search(
    n: int, inner_folds: int, gap: int, *, frames_from: str | None = None
) -> None:
    """Refuse an inner search that cannot run on ``n`` training frames.

    :func:`~qdcnn.direction.protocol.fit_with_search` fits without a search when an
    inner block (``n // inner_folds`` frames) is not longer than the ``gap``; asked for
    explicitly, that would silently ignore ``--inner-folds`` and ``--gap``.
    ``frames_from`` names the option that set ``n`` (``"--folds 2"`` in evaluate).

    Raises
    ------
    OptionConflict
        Naming ``--inner-folds``, ``--gap`` (and ``frames_from``) with the block length.
    """
    from qdcnn.errors import OptionConflict

    if inner_folds == 0:
        return
    block = n // inner_folds
    if block > gap:
        return
    where = f"{n} training frames" + (f" ({frames_from})" if frames_from else "")
    raise OptionConflict(
        f"--inner-folds {inner_folds}",
        f"--gap {gap}",
        f"on {where} an inner block has {block} frames, not more than the gap, so no "
        "hyperparameter search would run (fewer inner folds, a smaller gap, or "
        "--inner-folds 0 for none)",
    )


_Builder = Callable[[PipelineConfig, TrainingOptions], tuple[BaseEstimator, _Grid]]


@dataclass(frozen=True)
class DirectionMethod:
    """One direction method.

    Attributes
    ----------
    name : str
        Its name on the command line and in results.
    inputs : {"lanes", "frames"}
        Lane features of ``grouping``, or the frames.
    build : callable
        ``build(config, options) -> (estimator, grid)``: a fresh unfitted estimator and the
        hyperparameter grid the inner contiguous CV chooses from (may be empty).
    kind : str
        Classifier family (``"uu"``, ``"vqc"``, ``"cnn"``, ...): noise sweeps group by it.
    grouping : str or None
        Lane grouping for ``inputs="lanes"``.
    needs_torch : bool
        Needs the ``dnn`` extra.
    needs_gpu : bool
        Too slow without a GPU: ``all`` leaves it out on a CPU-only machine (it still runs
        when named).
    quantum : bool
        Has a simulated quantum circuit (noise sweeps apply to it).
    summary : str
        One line for listings and reports.
    """

    name: str
    inputs: Literal["lanes", "frames"]
    build: _Builder
    kind: str
    grouping: str | None = None
    needs_torch: bool = False
    needs_gpu: bool = False
    quantum: bool = False
    summary: str = ""

    def __post_init__(self) -> None:
        if self.inputs not in ("lanes", "frames"):
            raise ParameterError("inputs", self.inputs, "'lanes' or 'frames'")
        if (self.inputs == "lanes") != (self.grouping is not None):
            raise ParameterError(
                "grouping", self.grouping, "a grouping exactly when inputs='lanes'"
            )

    def estimator(
        self, config: PipelineConfig, options: TrainingOptions | None = None
    ) -> tuple[BaseEstimator, _Grid]:
        """A fresh estimator of this method and its grid (see :attr:`build`)."""
        return self.build(config, options or TrainingOptions())


_REGISTRY: dict[str, DirectionMethod] = {}


def register(method: DirectionMethod, *, replace: bool = False) -> DirectionMethod:
    """Add ``method`` to the registry (``replace`` allows redefining a name)."""
    if method.name in _REGISTRY and not replace:
        raise ParameterError("method", method.name, "a name not registered yet")
    if method.name == "all":
        raise ParameterError("method", method.name, "a name other than 'all'")
    _REGISTRY[method.name] = method
    return method


def unregister(name: str) -> None:
    """Remove a method (for plug-ins and tests)."""
    _REGISTRY.pop(name, None)


def method_names(*, inputs: str | None = None) -> tuple[str, ...]:
    """Registered names in registration order, optionally of one input kind."""
    return tuple(n for n, m in _REGISTRY.items() if inputs is None or m.inputs == inputs)


def get_method(name: str) -> DirectionMethod:
    """The registered method ``name``; a :class:`ParameterError` lists the others."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ParameterError("method", name, "one of " + ", ".join(_REGISTRY)) from None


def select_methods(
    names: str | Sequence[str], *, has_torch: bool, has_gpu: bool
) -> tuple[list[DirectionMethod], list[str]]:
    """Methods for ``names`` (``"all"``, one name or a comma list) and notes on what was left out.

    ``all`` leaves out methods that need torch when it is missing, and methods marked
    ``needs_gpu`` when there is no GPU; each omission gets a note. A method named
    explicitly is always returned (its estimator reports a missing extra itself).
    """
    items = names.split(",") if isinstance(names, str) else list(names)
    wanted = [n.strip() for n in items if n.strip()]
    if not wanted:
        raise ParameterError("method", names, "a method name, a comma list or 'all'")
    chosen: list[DirectionMethod] = []
    notes: list[str] = []
    for name in wanted:
        if name != "all":
            method = get_method(name)
            if method not in chosen:
                chosen.append(method)
            continue
        for method in _REGISTRY.values():
            if method in chosen:
                continue
            if method.needs_torch and not has_torch:
                notes.append(
                    f"skipping {method.name}: torch is not installed (pip install 'qdcnn[dnn]')"
                )
            elif method.needs_gpu and not has_gpu:
                notes.append(
                    f"skipping {method.name}: no GPU, and its training takes tens of core-hours "
                    f"on a CPU (ask for it alone: --method {method.name})"
                )
            else:
                chosen.append(method)
    return chosen, notes


# ---------------------------------------------------------------- the paper's methods


def _lane_columns(config: PipelineConfig) -> tuple[int, int] | None:
    from qdcnn.vision.grouping import mode_columns

    grouping = config.grouping
    if grouping.features == "slopes" and not grouping.extra_features:
        return None
    return mode_columns(grouping.features, grouping.extra_features)


def _build_uu(config: PipelineConfig, options: TrainingOptions) -> tuple[BaseEstimator, _Grid]:
    """The paper's UU-dagger rule on the two lane inputs; the grid is the angle map."""
    from qdcnn.quantum.direction import UUDirectionClassifier

    estimator = UUDirectionClassifier(
        straight_margin=config.direction.straight_margin,
        shots=config.direction.shots,
        seed=config.seed,
        feature_columns=_lane_columns(config),
    )
    return estimator, {"angle_map": ["arctan", "minmax"]}


def _build_vqc(config: PipelineConfig, options: TrainingOptions) -> tuple[BaseEstimator, _Grid]:
    """The paper's 2-qubit VQC; the grid is the interpret map.

    The named feature modes (not the paper's) add the angle span (1 or 0.5) and the feature
    map's repetitions (1 or the configured value) to the grid and train from 3 starts
    (``restarts=3``): on the paper's full span the ZZ map's phase reaches ``2 pi^2``, and
    from one start COBYLA often ends worse than the majority class.
    """
    from qdcnn.quantum.vqc import VQCClassifier

    paper = config.grouping.features == "slopes"
    estimator = VQCClassifier(
        feature_map_reps=config.vqc.feature_map_reps,
        ansatz_reps=config.vqc.ansatz_reps,
        maxiter=config.vqc.maxiter,
        loss=config.vqc.loss,
        shots=config.vqc.shots,
        seed=config.seed,
        feature_columns=_lane_columns(config),
        restarts=1 if paper else 3,
    )
    grid: _Grid = {"interpret": ["min2", "mod3"]}
    if not paper:
        grid["angle_span"] = [1.0, 0.5]
        grid["feature_map_reps"] = sorted({config.vqc.feature_map_reps, 1})
    return estimator, grid


#: How the hybrids, their twins and ablations train (issue 20): class-balanced loss, the
#: epoch of the best validation balanced accuracy, and up to two restarts with the next
#: seed when the validation predictions are all one class.
HYBRID_RECIPE: Mapping[str, Any] = {
    "class_weight": "balanced",
    "select": "balanced_accuracy",
    "restarts": 2,
}
#: Method kinds of the hybrid family (``transfer`` and ``--from`` apply to them).
HYBRID_KINDS: tuple[str, ...] = ("hybrid", "hybrid-twin", "hybrid-ablation")


def cnn_params(options: TrainingOptions) -> dict[str, Any]:
    """The estimator parameters ``options`` set for every CNN: the hybrid recipe with
    ``balanced``, then ``params``."""
    return {**(HYBRID_RECIPE if options.balanced else {}), **options.params}


def classical_recipe(options: TrainingOptions) -> dict[str, Any]:
    """What the classical method (``dnn-pilotnet``) trains with where the hybrid recipe
    differs: the estimator's defaults, or what ``options`` set (:func:`cnn_params`).
    Transfer's stage 1 then trains exactly as that method does, and shares its trunk."""
    import inspect

    from qdcnn.models.training import CNNDirectionClassifier

    defaults = inspect.signature(CNNDirectionClassifier).parameters
    params = cnn_params(options)
    return {k: params.get(k, defaults[k].default) for k in HYBRID_RECIPE}


def _cnn_builder(arch: str, network_params: Mapping[str, Any] | None = None) -> _Builder:
    hybrid = network_params is not None

    def build(config: PipelineConfig, options: TrainingOptions) -> tuple[BaseEstimator, _Grid]:
        from qdcnn.models.training import CNNDirectionClassifier

        staged: dict[str, Any] = {}
        if hybrid:
            from_model = None if options.from_model is None else str(options.from_model)
            staged = {
                **HYBRID_RECIPE,
                "transfer": options.transfer,
                "trunk_from": from_model,
                "classical_recipe": classical_recipe(options),
            }
        estimator = CNNDirectionClassifier(
            arch,
            epochs=options.epochs,
            weights=options.weights,
            seed=config.seed,
            progress=options.progress,
            num_threads=options.threads,
            trunk_cache=options.trunk_cache,
            context=options.context,
            network_params=_network_params(arch, network_params, options),
            **{**staged, **cnn_params(options)},
        )
        return estimator, {}

    return build


#: The networks that take ``standardise_frames`` and ``edge_frames`` (PilotNet's layers
#: on raw YUV).
STANDARDISING_NETWORKS = ("pilotnet", "qdcnn-head")
#: The frame fronts a :class:`TrainingOptions` can ask of those networks (its field names,
#: which are also the networks' keyword arguments).
FRAME_FRONTS = ("standardise_frames", "edge_frames")


def _network_params(
    arch: str, network_params: Mapping[str, Any] | None, options: TrainingOptions
) -> dict[str, Any] | None:
    """The registered ``network_params``, with ``standardise_frames`` or ``edge_frames``
    when ``options`` ask."""
    fronts = {k: True for k in FRAME_FRONTS if getattr(options, k)}
    if not (fronts and arch in STANDARDISING_NETWORKS):
        return None if network_params is None else dict(network_params)
    return {**(network_params or {}), **fronts}


def staged_note(methods: Sequence[DirectionMethod], options: TrainingOptions) -> str | None:
    """What ``--transfer`` / ``--from`` do to ``methods``: they apply to the hybrids, the
    other methods train as usual (a note says which). Without a hybrid they are refused.
    """
    if not (options.transfer or options.from_model is not None):
        return None
    what = "--transfer" if options.transfer else "--from"
    nouns = ("hybrids", "a hybrid method")
    return _applies_note(what, methods, lambda m: m.kind in HYBRID_KINDS, nouns)


def balanced_note(methods: Sequence[DirectionMethod], options: TrainingOptions) -> str | None:
    """What ``--balanced`` does to ``methods``: it applies to the classical CNNs and, under
    ``--transfer``, to the stage 1 of hybrids whose stage 1 is one (the others train as
    usual; a note says which). Where it changes nothing it is refused."""
    if not options.balanced:
        return None
    nouns = (
        "CNNs and to the hybrids' PilotNet stage 1",
        "a CNN or a hybrid with PilotNet as stage 1 under --transfer",
    )
    return _applies_note("--balanced", methods, partial(balanced_applies, options=options), nouns)


def balanced_applies(method: DirectionMethod, options: TrainingOptions) -> bool:
    """Whether ``--balanced`` changes how ``method`` trains: a classical CNN, or a hybrid
    whose transfer stage 1 is a classical network's own training (the hybrids' own
    training has the recipe already)."""
    if method.kind == "cnn":
        return True
    return method.kind in HYBRID_KINDS and options.transfer and _stage_one(method) is not None


def _stage_one(method: DirectionMethod) -> str | None:
    """The classical network whose training is ``method``'s transfer stage 1, if any."""
    family = _hybrid_family(method)
    return None if family is None else family.classical


def _hybrid_family(method: DirectionMethod) -> HybridNetwork | None:
    """The hybrid ``method`` is (its own, its twin or one of its ablations), if any."""
    for h in HYBRID_NETWORKS:
        if method.name in (h.name, h.twin, *(name for name, _ in h.ablations)):
            return h
    return None


def standardise_note(methods: Sequence[DirectionMethod], options: TrainingOptions) -> str | None:
    """What ``--standardise-frames`` (or ``--edge-frames``) does to ``methods``: it applies
    to PilotNet and to ``qdcnn-head`` with its twin and ablations; the others train as
    usual (a note says which). Where it changes nothing it is refused."""
    if not (options.standardise_frames or options.edge_frames):
        return None
    flags = (
        ("--standardise-frames", options.standardise_frames),
        ("--edge-frames", options.edge_frames),
    )
    what = " ".join(flag for flag, on in flags if on)
    nouns = ("PilotNet and qdcnn-head networks", "PilotNet or a qdcnn-head network")
    return _applies_note(what, methods, standardise_applies, nouns)


def standardise_applies(method: DirectionMethod) -> bool:
    """Whether ``--standardise-frames`` (or ``--edge-frames``) changes ``method``'s network."""
    return _network_of(method) in STANDARDISING_NETWORKS


def _network_of(method: DirectionMethod) -> str | None:
    """The registered network ``method`` trains, if it trains one."""
    if method.name == "dnn-pilotnet":
        return "pilotnet"
    family = _hybrid_family(method)
    return None if family is None else family.name


def option_notes(methods: Sequence[DirectionMethod], options: TrainingOptions) -> list[str]:
    """The notes of ``--transfer`` / ``--from``, ``--balanced`` and the frame fronts
    for ``methods``; an option that changes none of them is refused (:class:`ParameterError`)."""
    notes = (
        staged_note(methods, options),
        balanced_note(methods, options),
        standardise_note(methods, options),
        ensemble_note(methods, options),
    )
    return [n for n in notes if n]


def ensemble_note(methods: Sequence[DirectionMethod], options: TrainingOptions) -> str | None:
    """What ``--ensemble K`` does to ``methods``: it applies to the CNNs and the hybrids
    (their twins and ablations too); the others train as usual (a note says which). Where it
    changes nothing it is refused."""
    networks = int(options.params.get("ensemble", 1))
    if networks <= 1:
        return None
    nouns = ("CNNs and hybrids", "a CNN or a hybrid")
    return _applies_note(f"--ensemble {networks}", methods, ensemble_applies, nouns)


def ensemble_applies(method: DirectionMethod) -> bool:
    """Whether ``method`` trains networks (a CNN or a hybrid), so an ensemble of them."""
    return method.kind == "cnn" or method.kind in HYBRID_KINDS


def _applies_note(
    what: str,
    methods: Sequence[DirectionMethod],
    applies: Callable[[DirectionMethod], bool],
    nouns: tuple[str, str],
) -> str | None:
    """The note (or, when it applies to none, the refusal) of option ``what``."""
    others = [m.name for m in methods if not applies(m)]
    if len(others) == len(methods):
        said = f"{others[0]} is not" if len(others) == 1 else f"none of {', '.join(others)} is"
        raise ParameterError(what, "set", f"unset: {said} {nouns[1]}")
    if not others:
        return None
    verb = "trains" if len(others) == 1 else "train"
    return f"{what} applies to the {nouns[0]}; {', '.join(others)} {verb} as usual"


def with_head(names: str, head: str) -> str:
    """``names`` (a comma list) with the hybrids given the ``head`` asked for.

    ``head`` is ``"quantum"`` (the names as given, twins included), ``"classical"`` (each
    hybrid replaced by its classical twin) or ``"both"`` (each hybrid and its twin);
    other methods pass through.

    Examples
    --------
    >>> with_head("qdcnn-head,dnn-pilotnet", "both")
    'qdcnn-head,qdcnn-head-classical,dnn-pilotnet'
    >>> with_head("qdcnn-head-classical", "quantum")
    'qdcnn-head-classical'
    """
    if head not in (*HEADS, "both"):
        raise ParameterError("head", head, "'quantum', 'classical' or 'both'")
    out: list[str] = []
    for name in (n.strip() for n in names.split(",") if n.strip()):
        hybrid = hybrid_of(name)
        if head == "quantum" or hybrid is None:
            out.append(name)
            continue
        if head == "both":
            out.append(hybrid.name)
        out.append(hybrid.twin)
    return ",".join(dict.fromkeys(out))


_CLASSIFIERS: dict[str, tuple[_Builder, str]] = {
    "uu": (_build_uu, "the paper's UU-dagger rule on two lane inputs"),
    "vqc": (_build_vqc, "the paper's 2-qubit VQC (ZZ feature map + RealAmplitudes, COBYLA)"),
}
for _kind, (_build, _what) in _CLASSIFIERS.items():
    for _grouping in GROUPINGS:
        register(
            DirectionMethod(
                f"{_grouping}-{_kind}",
                "lanes",
                _build,
                _kind,
                grouping=_grouping,
                quantum=True,
                summary=f"{_what}, {_grouping} grouping",
            )
        )
register(
    DirectionMethod(
        "dnn-pilotnet",
        "frames",
        _cnn_builder("pilotnet"),
        "cnn",
        needs_torch=True,
        summary="PilotNet CNN (Bojarski et al. 2016), classical baseline",
    )
)
for _hybrid in HYBRID_NETWORKS:
    register(
        DirectionMethod(
            _hybrid.name,
            "frames",
            _cnn_builder(_hybrid.name, {"head": "quantum"}),
            "hybrid",
            needs_torch=True,
            quantum=True,
            summary=_hybrid.summary,
        )
    )
    register(
        DirectionMethod(
            _hybrid.twin,
            "frames",
            _cnn_builder(_hybrid.name, {"head": "classical"}),
            "hybrid-twin",
            needs_torch=True,
            summary=f"{_hybrid.summary}: its classical twin (an MLP head of the same parameter "
            "count)",
        )
    )
    for _name, _ablation in _hybrid.ablations:
        register(
            DirectionMethod(
                _name,
                "frames",
                _cnn_builder(_hybrid.name, {"head": _ablation.head}),
                "hybrid-ablation",
                needs_torch=True,
                quantum=_ablation.head != "linear",
                summary=f"{_hybrid.summary}: ablation, {_ablation.summary}",
            )
        )
register(
    DirectionMethod(
        "dnn-resnet50",
        "frames",
        _cnn_builder("resnet50"),
        "cnn",
        needs_torch=True,
        needs_gpu=True,
        summary="ResNet-50 CNN (the paper's DNN, 25 epochs), classical baseline",
    )
)


# ---------------------------------------------------------------- classical references


def _reference_builder(name: str) -> _Builder:
    def build(config: PipelineConfig, options: TrainingOptions) -> tuple[BaseEstimator, _Grid]:
        from qdcnn.direction import references

        estimator = getattr(references, name)()
        return estimator, {"C": list(references.C_GRID)}

    return build


register(
    DirectionMethod(
        "lines-logreg",
        "lanes",
        _reference_builder("LinesLogisticClassifier"),
        "logreg",
        grouping="image-split",
        summary="logistic regression on the fitted lines' features (classical reference)",
    )
)
register(
    DirectionMethod(
        "hog-logreg",
        "frames",
        _reference_builder("HOGLogisticClassifier"),
        "logreg",
        summary="logistic regression on the HOG of the road band (classical reference)",
    )
)
