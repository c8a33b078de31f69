"""The hybrid QDCNN methods through the registry: evaluation, files, noise."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")
cv2 = pytest.importorskip("cv2")

from qdcnn.config import PipelineConfig  # noqa: E402
from qdcnn.direction.methods import (  # noqa: E402
    HYBRID_RECIPE,
    TrainingOptions,
    balanced_note,
    get_method,
    staged_note,
    standardise_note,
    with_head,
)
from qdcnn.direction.model import DirectionModel, train_direction_model  # noqa: E402
from qdcnn.errors import ParameterError  # noqa: E402
from qdcnn.experiments.evaluate import (  # noqa: E402
    EvaluationSpec,
    evaluate_frames,
    fold_store,
    run_evaluation,
)
from qdcnn.experiments.noise.direction import direction_sweep  # noqa: E402
from qdcnn.models.pilotnet import FrameStandardisation  # noqa: E402
from qdcnn.runtime.reporting import Collector  # noqa: E402

OPTIONS = TrainingOptions(
    epochs=6, threads=1, params={"lr_schedule": "constant", "val_fraction": 0.0}
)


def lean_frames(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Frames with one bright line leaning left (0), upright (1) or right (2), in blocks."""
    rng = np.random.default_rng(seed)
    labels = np.repeat(np.arange(n // 10) % 3, 10).astype(np.int64)
    images = np.empty((len(labels), 40, 80, 3), np.uint8)
    for i, label in enumerate(labels):
        img = (60 + rng.integers(0, 20, (40, 80, 3))).astype(np.uint8)
        x0 = 40 + rng.uniform(-6, 6)
        lean = (-1, 0, 1)[label] * rng.uniform(0.6, 1.0) * 40
        cv2.line(img, (int(x0), 39), (int(x0 + lean), 0), (240, 240, 240), 3)
        images[i] = img
    return images, labels


class _Frames:
    """An in-memory FrameSet stand-in for evaluate_frames."""

    def __init__(self, images: np.ndarray) -> None:
        self.images, self.name, self.spec, self.problems = images, "toy", "toy", []
        self.sources = [f"toy:{i}" for i in range(len(images))]

    def __len__(self) -> int:
        return len(self.images)

    def image(self, i: int) -> np.ndarray:
        return self.images[i]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("method", "epochs"),
    [("qdcnn-head", 6), ("qdcnn-head-classical", 6), ("qdcnn-uuconv", 15), ("qdcnn-quanv", 15)],
)
def test_hybrids_learn_under_the_shared_folds(method: str, epochs: int) -> None:
    images, labels = lean_frames(120)
    options = TrainingOptions(epochs=epochs, threads=1, params=dict(OPTIONS.params))
    res, failures = evaluate_frames(
        method,
        _Frames(images),  # type: ignore[arg-type]
        labels,
        config=PipelineConfig(seed=1),
        options=options,
        folds=3,
        gap=2,
    )
    assert not failures and res.method == method
    assert res.accuracy > res.majority_baseline + 0.2


def test_with_head_picks_twins() -> None:
    assert with_head("qdcnn-head", "classical") == "qdcnn-head-classical"
    assert with_head("qdcnn-quanv,kmeans-uu", "quantum") == "qdcnn-quanv,kmeans-uu"
    assert get_method("qdcnn-head").quantum and not get_method("qdcnn-head-classical").quantum
    with pytest.raises(ParameterError, match="head='twin' is invalid"):
        with_head("qdcnn-head", "twin")


@pytest.fixture(scope="module")
def trained() -> tuple[DirectionModel, np.ndarray, np.ndarray]:
    images, labels = lean_frames(60, seed=2)
    model = train_direction_model(
        "qdcnn-head", images, labels, PipelineConfig(seed=0), "toy", inner_folds=0, options=OPTIONS
    )
    return model, images, labels


def test_a_hybrid_model_file_round_trips(trained, tmp_path: Path) -> None:
    model, images, _ = trained
    back = DirectionModel.load(model.save(tmp_path / "hybrid.safetensors"))
    np.testing.assert_allclose(back.predict_proba(images), model.predict_proba(images), atol=1e-9)
    head = back.estimator.model_.head
    np.testing.assert_array_equal(
        head.weights.detach(), model.estimator.model_.head.weights.detach()
    )


def test_noise_reaches_the_quantum_head_and_only_it(trained) -> None:
    model, images, _ = trained
    clean = model.estimator.predict_proba(images)
    full = model.estimator.predict_proba(images, noise="depolarizing:1.0")
    # fully depolarised: <Z_i> = 0 for every frame, so every frame gets the same probabilities
    # (to float32 rounding, which the read-out gain scales)
    np.testing.assert_allclose(full, np.broadcast_to(full[0], full.shape), atol=1e-6)
    assert np.abs(full - clean).max() > 1e-3
    np.testing.assert_allclose(model.estimator.predict_proba(images), clean, atol=0)  # restored
    pilot = train_direction_model(
        "dnn-pilotnet", images, np.repeat([0, 1, 2], 20), PipelineConfig(), "toy", inner_folds=0,
        options=TrainingOptions(epochs=1, threads=1, params={"val_fraction": 0.0}),
    )  # fmt: skip
    with pytest.raises(ParameterError, match="this network has no quantum layer"):
        pilot.estimator.predict(images, noise="bit-flip:0.1")


def test_device_noise_runs_the_head_on_the_numpy_simulator(trained) -> None:
    pytest.importorskip("qiskit_ibm_runtime")
    model, images, _ = trained
    clean = model.estimator.predict_proba(images[:6])
    device = model.estimator.predict_proba(images[:6], noise="device:FakeMelbourneV2,route:swap")
    assert np.all(np.isfinite(device)) and 1e-6 < np.abs(device - clean).max() < 0.5


@pytest.mark.slow
def test_the_noise_sweep_runs_a_hybrid() -> None:
    images, labels = lean_frames(90, seed=3)
    rows = direction_sweep(
        {"frames": images},
        labels,
        methods=["qdcnn-head"],
        channels=["depolarizing"],
        strengths=[0.0, 1.0],
        folds=3,
        gap=2,
        inner_folds=0,
        training=OPTIONS,
    )
    by_p = {r.p: r.accuracy for r in rows}
    assert by_p[0.0] > 0.6 and by_p[1.0] <= 0.5  # fully depolarised, the head sees nothing


def test_head_ablations_are_methods_derived_from_the_table() -> None:
    from qdcnn.direction.methods import HYBRID_RECIPE
    from qdcnn.models.hybrid import build_hybrid, trainable_parameters
    from qdcnn.models.specs import HEAD_ABLATIONS, HYBRID_NETWORKS

    names = [name for h in HYBRID_NETWORKS for name, _ in h.ablations]
    assert names == [f"qdcnn-head-{a.suffix}" for a in HEAD_ABLATIONS]
    for name, ablation in HYBRID_NETWORKS[0].ablations:
        method = get_method(name)
        estimator, grid = method.estimator(PipelineConfig(), OPTIONS)
        assert method.kind == "hybrid-ablation" and grid == {}
        assert estimator.network_params == {"head": ablation.head}
        assert estimator.arch == "qdcnn-head" and method.quantum == (ablation.head != "linear")
        assert all(getattr(estimator, k) == v for k, v in HYBRID_RECIPE.items())
    twin = get_method("qdcnn-head-classical").estimator(PipelineConfig(), OPTIONS)[0]
    assert all(getattr(twin, k) == v for k, v in HYBRID_RECIPE.items())  # the same training
    counts = {
        h: trainable_parameters(build_hybrid("qdcnn-head", head=h)) for h in ("quantum", "fixed")
    }
    assert counts["quantum"] - counts["fixed"] == 2 * 4 * 3  # the circuit's angles do not train


def test_transfer_and_from_are_for_hybrids_only(tmp_path: Path) -> None:
    pilotnet, lines = get_method("dnn-pilotnet"), get_method("lines-logreg")
    hybrid = get_method("qdcnn-head-noent")
    for options in (TrainingOptions(transfer=True), TrainingOptions(from_model=tmp_path)):
        what = "--transfer" if options.transfer else "--from"
        estimator = hybrid.estimator(PipelineConfig(), options)[0]
        assert estimator.transfer == options.transfer
        plain = pilotnet.estimator(PipelineConfig(), options)[0]
        assert not plain.transfer and plain.trunk_from is None
        note = staged_note([pilotnet, hybrid, lines], options)
        assert note == f"{what} applies to the hybrids; dnn-pilotnet, lines-logreg train as usual"
        assert staged_note([hybrid], options) is None
        assert (
            staged_note([hybrid, pilotnet], options)
            == f"{what} applies to the hybrids; dnn-pilotnet trains as usual"
        )
        with pytest.raises(ParameterError, match=f"{what}=.*unset: dnn-pilotnet is not a hybrid"):
            staged_note([pilotnet], options)
        with pytest.raises(ParameterError, match="none of dnn-pilotnet, lines-logreg is a hybrid"):
            staged_note([pilotnet, lines], options)
    assert staged_note([pilotnet], TrainingOptions()) is None


def test_cached_folds_tell_transfer_and_trunk_files_apart(tmp_path: Path) -> None:
    def key(name: str, options: TrainingOptions) -> str:
        return fold_store(get_method(name), PipelineConfig(), options, {}, "data", True).key

    trunk = tmp_path / "trunk.safetensors"
    trunk.write_bytes(b"one")
    plain, staged = TrainingOptions(), TrainingOptions(transfer=True)
    started = TrainingOptions(from_model=trunk)
    assert len({key("qdcnn-head", o) for o in (plain, staged, started)}) == 3
    assert key("dnn-pilotnet", plain) == key("dnn-pilotnet", staged) == key("dnn-pilotnet", started)
    before = key("qdcnn-head", started)
    trunk.write_bytes(b"two")  # another trunk under the same name
    assert key("qdcnn-head", started) != before


def test_evaluate_says_transfer_leaves_other_methods_as_they_are() -> None:
    def spec(methods: str) -> EvaluationSpec:
        options = replace(OPTIONS, epochs=1, transfer=True)
        return EvaluationSpec(
            "synthetic:track1:100", methods, folds=2, inner_folds=0, training=options
        )

    with pytest.raises(ParameterError, match="unset: lines-logreg is not a hybrid method"):
        run_evaluation(spec("lines-logreg"), Collector())
    collected = Collector()
    result = run_evaluation(spec("lines-logreg,qdcnn-head"), collected)
    note = "--transfer applies to the hybrids; lines-logreg trains as usual"
    assert note in collected.notes and note in result.notes
    assert [r.method for r in result.results] == ["lines-logreg", "qdcnn-head"]


def test_transfer_stage_one_is_the_pilotnet_run_of_the_same_frames(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from qdcnn.models import transfer

    monkeypatch.setattr(transfer, "_TRUNKS", {})
    images, labels = lean_frames(60, seed=4)
    options = replace(OPTIONS, epochs=3, transfer=True)
    pilot = get_method("dnn-pilotnet").estimator(PipelineConfig(), options)[0]
    hybrid = get_method("qdcnn-head").estimator(PipelineConfig(), options)[0]
    assert hybrid.classical_recipe == {"class_weight": None, "select": "loss", "restarts": 0}
    hybrid.fit(images, labels)  # nothing kept yet: stage 1 trains PilotNet
    assert [r["stage"] for r in hybrid.history_] == ["classical"] * 3 + ["head", "finetune"]
    (by_hybrid,) = transfer._TRUNKS.values()
    monkeypatch.setattr(transfer, "_TRUNKS", {})
    pilot.fit(images, labels)  # dnn-pilotnet's own run keeps its trunk
    (by_pilotnet,) = transfer._TRUNKS.values()
    assert by_pilotnet[1] == len(pilot.history_) == 3
    assert all(torch.equal(by_hybrid[0][k], v) for k, v in by_pilotnet[0].items())
    twin = get_method("qdcnn-head-classical").estimator(PipelineConfig(), options)[0]
    assert [r["stage"] for r in twin.fit(images, labels).history_] == ["head", "finetune"]


def test_stage_one_trains_with_the_classical_methods_params() -> None:
    options = replace(OPTIONS, transfer=True, params={"class_weight": "balanced"})
    hybrid = get_method("qdcnn-head").estimator(PipelineConfig(), options)[0]
    assert hybrid.classical_recipe == {"class_weight": "balanced", "select": "loss", "restarts": 0}
    hybrid.set_params(classical_recipe={"colour": "red"})
    with pytest.raises(ParameterError, match="classical_recipe=.*a mapping of training param"):
        hybrid.fit(*lean_frames(30))


def test_balanced_trains_pilotnet_and_stage_one_with_the_hybrid_recipe() -> None:
    balanced = TrainingOptions(balanced=True, transfer=True)
    pilot = get_method("dnn-pilotnet").estimator(PipelineConfig(), balanced)[0]
    assert {k: pilot.get_params()[k] for k in HYBRID_RECIPE} == dict(HYBRID_RECIPE)
    hybrid = get_method("qdcnn-head").estimator(PipelineConfig(), balanced)[0]
    assert hybrid.classical_recipe == dict(HYBRID_RECIPE)
    plain = get_method("dnn-pilotnet").estimator(PipelineConfig(), TrainingOptions())[0]
    assert (plain.class_weight, plain.select, plain.restarts) == (None, "loss", 0)
    mine = replace(balanced, params={"restarts": 0})  # params still win
    assert get_method("dnn-pilotnet").estimator(PipelineConfig(), mine)[0].restarts == 0
    assert get_method("qdcnn-head").estimator(PipelineConfig(), mine)[0].classical_recipe == {
        **HYBRID_RECIPE,
        "restarts": 0,
    }


def test_balanced_is_for_cnns_and_pilotnet_as_stage_one() -> None:
    pilotnet, lines = get_method("dnn-pilotnet"), get_method("lines-logreg")
    hog, hybrid = get_method("hog-logreg"), get_method("qdcnn-head-linear")
    options, staged = TrainingOptions(balanced=True), TrainingOptions(balanced=True, transfer=True)
    assert balanced_note([pilotnet, hybrid], staged) is None
    assert balanced_note([pilotnet, hybrid], options) == (
        "--balanced applies to the CNNs and to the hybrids' PilotNet stage 1; "
        "qdcnn-head-linear trains as usual"
    )
    assert balanced_note([pilotnet, lines, hog], options) == (
        "--balanced applies to the CNNs and to the hybrids' PilotNet stage 1; "
        "lines-logreg, hog-logreg train as usual"
    )
    refused = "--balanced=.*unset: {} is not a CNN or a hybrid with PilotNet as stage 1"
    for method, opts in ((hog, options), (hybrid, options), (get_method("qdcnn-quanv"), staged)):
        with pytest.raises(ParameterError, match=refused.format(method.name)):
            balanced_note([method], opts)  # the hybrid recipe already, or another stage 1
    assert balanced_note([hog], TrainingOptions()) is None
    with pytest.raises(ParameterError, match="balanced='yes'"):
        TrainingOptions(balanced="yes")  # type: ignore[arg-type]


def test_cached_folds_tell_balanced_runs_apart() -> None:
    def key(name: str, options: TrainingOptions) -> str:
        return fold_store(get_method(name), PipelineConfig(), options, {}, "data", True).key

    plain, balanced = TrainingOptions(), TrainingOptions(balanced=True)
    assert key("dnn-pilotnet", plain) != key("dnn-pilotnet", balanced)
    recipe = TrainingOptions(params=HYBRID_RECIPE)  # the same training: the same results
    assert key("dnn-pilotnet", recipe) == key("dnn-pilotnet", balanced)
    for name in ("qdcnn-head", "qdcnn-head-fixed"):
        assert key(name, plain) == key(name, balanced)  # trains with the recipe already
        staged = replace(plain, transfer=True)
        assert key(name, staged) != key(name, replace(staged, balanced=True))  # its stage 1
    assert key("hog-logreg", plain) == key("hog-logreg", balanced)


@pytest.mark.parametrize("flag", ["balanced", "standardise_frames"])
def test_stage_one_under_a_flag_is_that_flags_pilotnet_run(
    monkeypatch: pytest.MonkeyPatch, flag: str
) -> None:
    from qdcnn.models import transfer

    monkeypatch.setattr(transfer, "_TRUNKS", {})
    images, labels = lean_frames(60, seed=4)
    options = replace(OPTIONS, epochs=2, transfer=True, **{flag: True})
    get_method("dnn-pilotnet").estimator(PipelineConfig(), options)[0].fit(images, labels)
    hybrid = get_method("qdcnn-head").estimator(PipelineConfig(), options)[0]
    assert [r["stage"] for r in hybrid.fit(images, labels).history_] == ["head", "finetune"]
    plain = get_method("qdcnn-head").estimator(PipelineConfig(), replace(options, **{flag: False}))
    stages = [r["stage"] for r in plain[0].fit(images, labels).history_]
    assert stages[0] == "classical"  # that PilotNet's trunk is not the plain one's
    standardised = isinstance(hybrid.model_.front, FrameStandardisation)
    assert standardised == (flag == "standardise_frames")


def test_a_resumed_transfer_evaluation_reads_its_trunks_from_the_cache(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from qdcnn.direction.features import code_fingerprint
    from qdcnn.experiments.evaluate import with_trunk_cache
    from qdcnn.models import transfer

    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path))
    monkeypatch.setattr(transfer, "_TRUNKS", {})
    options = replace(OPTIONS, epochs=2, transfer=True)

    def spec(methods: str, **kw: Any) -> EvaluationSpec:
        return EvaluationSpec("synthetic:track1:100", methods, folds=2, inner_folds=0, **kw)

    folder = tmp_path / "trunks" / code_fingerprint()
    assert with_trunk_cache(spec("qdcnn-head", training=options)).training.trunk_cache == folder
    for kw in ({"training": OPTIONS}, {"training": options, "use_cache": False}):
        assert with_trunk_cache(spec("qdcnn-head", **kw)).training.trunk_cache is None
    run_evaluation(spec("dnn-pilotnet,qdcnn-head", training=options), Collector())
    assert len(list(folder.glob("*.safetensors"))) == 2  # one trunk per fold
    monkeypatch.setattr(transfer, "_TRUNKS", {})  # a new process
    stage_ones: list[str] = []
    run_stage = transfer._classical_stage
    monkeypatch.setattr(
        transfer, "_classical_stage", lambda *a: stage_ones.append("ran") or run_stage(*a)
    )
    run_evaluation(spec("dnn-pilotnet,qdcnn-head-linear", training=options), Collector())
    assert stage_ones == []


def test_standardise_frames_reaches_pilotnet_the_hybrid_its_twin_and_ablations() -> None:
    options = TrainingOptions(standardise_frames=True, transfer=True)
    for name in ("dnn-pilotnet", "qdcnn-head", "qdcnn-head-classical", "qdcnn-head-fixed"):
        estimator = get_method(name).estimator(PipelineConfig(), options)[0]
        assert estimator.network_params["standardise_frames"] is True
    hybrid = get_method("qdcnn-head-classical").estimator(PipelineConfig(), options)[0]
    assert hybrid.network_params == {"head": "classical", "standardise_frames": True}
    assert hybrid._classical_estimator("pilotnet").network_params == {"standardise_frames": True}
    plain = get_method("dnn-pilotnet").estimator(PipelineConfig(), TrainingOptions())[0]
    assert plain.network_params is None
    quanv = get_method("qdcnn-quanv").estimator(PipelineConfig(), options)[0]
    assert quanv.network_params == {"head": "quantum"}  # its front reads raw YUV: as usual


def test_edge_frames_reach_the_same_networks_and_are_told_apart_in_the_cache() -> None:
    options = TrainingOptions(edge_frames=True, transfer=True)
    for name in ("dnn-pilotnet", "qdcnn-head", "qdcnn-head-classical", "qdcnn-head-fixed"):
        estimator = get_method(name).estimator(PipelineConfig(), options)[0]
        assert estimator.network_params.get("edge_frames") is True
        assert "standardise_frames" not in estimator.network_params
    hybrid = get_method("qdcnn-head").estimator(PipelineConfig(), options)[0]
    assert hybrid._classical_estimator("pilotnet").network_params == {"edge_frames": True}
    methods = [get_method("dnn-pilotnet"), get_method("lines-logreg")]
    assert standardise_note(methods, options) == (
        "--edge-frames applies to the PilotNet and qdcnn-head networks; "
        "lines-logreg trains as usual"
    )

    def key(name: str, options: TrainingOptions) -> str:
        return fold_store(get_method(name), PipelineConfig(), options, {}, "data", True).key

    standardised = TrainingOptions(standardise_frames=True)
    edges = TrainingOptions(edge_frames=True)
    both = TrainingOptions(standardise_frames=True, edge_frames=True)
    for name in ("dnn-pilotnet", "qdcnn-head"):
        keys = {key(name, o) for o in (TrainingOptions(), standardised, edges, both)}
        assert len(keys) == 4
    assert key("hog-logreg", TrainingOptions()) == key("hog-logreg", edges)
    hybrid = get_method("qdcnn-head").estimator(PipelineConfig(), replace(both, transfer=True))[0]
    stage_one = hybrid._classical_estimator("pilotnet").network_params
    assert stage_one == {"standardise_frames": True, "edge_frames": True}
    assert hybrid.network_params == {
        "head": "quantum",
        "standardise_frames": True,
        "edge_frames": True,
    }
    assert standardise_note(methods, both) == (
        "--standardise-frames --edge-frames applies to the PilotNet and qdcnn-head networks; "
        "lines-logreg trains as usual"
    )


def test_standardise_frames_says_what_trains_as_usual_and_is_refused_where_it_does_nothing() -> (
    None
):
    methods = [get_method(n) for n in ("dnn-pilotnet", "qdcnn-head-fixed", "lines-logreg")]
    options = TrainingOptions(standardise_frames=True)
    assert standardise_note(methods[:2], options) is None
    assert standardise_note(methods, options) == (
        "--standardise-frames applies to the PilotNet and qdcnn-head networks; "
        "lines-logreg trains as usual"
    )
    for names in (["qdcnn-quanv"], ["dnn-resnet50", "hog-logreg"]):
        with pytest.raises(ParameterError) as err:
            standardise_note([get_method(n) for n in names], options)
        said = f"{names[0]} is not" if len(names) == 1 else f"none of {', '.join(names)} is"
        assert str(err.value) == (
            f"--standardise-frames='set' is invalid: unset: {said} PilotNet or a qdcnn-head network"
        )
    assert standardise_note(methods[2:], TrainingOptions()) is None
    with pytest.raises(ParameterError, match="standardise_frames=1"):
        TrainingOptions(standardise_frames=1)  # type: ignore[arg-type]


def test_cached_folds_tell_standardised_runs_apart() -> None:
    def key(name: str, options: TrainingOptions) -> str:
        return fold_store(get_method(name), PipelineConfig(), options, {}, "data", True).key

    on = TrainingOptions(standardise_frames=True)
    for name in ("dnn-pilotnet", "qdcnn-head", "qdcnn-head-linear"):
        assert key(name, TrainingOptions()) != key(name, on)
    for name in ("hog-logreg", "qdcnn-quanv"):
        assert key(name, TrainingOptions()) == key(name, on)  # trains as usual


def test_a_standardised_network_decides_alike_in_shade() -> None:
    images, labels = lean_frames(60, seed=5)
    options = replace(OPTIONS, epochs=3, standardise_frames=True)
    model = get_method("dnn-pilotnet").estimator(PipelineConfig(), options)[0].fit(images, labels)
    shaded = (images * 0.6).astype(np.uint8)
    np.testing.assert_allclose(model.predict_proba(shaded), model.predict_proba(images), atol=0.03)
    plain = get_method("dnn-pilotnet").estimator(
        PipelineConfig(), replace(options, standardise_frames=False)
    )[0]
    plain.fit(images, labels)
    assert np.abs(plain.predict_proba(shaded) - plain.predict_proba(images)).max() > 0.03


def test_a_saved_standardised_pilotnet_loads_standardised(tmp_path: Path) -> None:
    images, labels = lean_frames(60, seed=6)
    options = replace(OPTIONS, epochs=2, standardise_frames=True)
    model = train_direction_model(
        "dnn-pilotnet", images, labels, PipelineConfig(), "toy", options=options
    )
    loaded = DirectionModel.load(model.save(tmp_path / "std.safetensors"))
    assert isinstance(loaded.estimator.model_.standardise, FrameStandardisation)
    np.testing.assert_array_equal(
        loaded.estimator.predict_proba(images), model.estimator.predict_proba(images)
    )
