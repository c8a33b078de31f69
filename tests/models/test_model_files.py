"""CNN model files (JSON header + safetensors): round trips, and one-line errors for bad files."""

from __future__ import annotations

import json
import pickle
import re
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("safetensors")

from qdcnn.errors import InputError  # noqa: E402
from qdcnn.models import CNNDirectionClassifier  # noqa: E402
from qdcnn.models.networks import build_network  # noqa: E402
from qdcnn.models.persistence import (  # noqa: E402
    MODEL_FORMAT_VERSION,
    MODEL_KIND,
    load_checkpoint,
    save_checkpoint,
)
from qdcnn.models.pilotnet import FramesAndEdges, FrameStandardisation  # noqa: E402
from qdcnn.persistence import load_model, save_model  # noqa: E402

FRAMES = np.random.default_rng(0).integers(0, 256, (7, 40, 80, 3), dtype=np.uint8)


def untrained(context: int = 1, **params: Any) -> CNNDirectionClassifier:
    network = build_network("pilotnet", 3 * context, seed=1)
    return CNNDirectionClassifier.from_network(
        network, "pilotnet", device="cpu", num_threads=1, context=context, **params
    )


@pytest.fixture(scope="module")
def saved(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("files") / "pilotnet.safetensors"
    untrained().save(path)
    return path


def load_error(path: Path) -> str:
    with pytest.raises(InputError) as err:
        CNNDirectionClassifier.load(path)
    message = str(err.value)
    assert "\n" not in message
    return message


def rewrite(
    source: Path, target: Path, *, meta: dict[str, Any] | None = None, arrays: Any = None
) -> Path:
    """``source`` with its header meta updated by ``meta`` and/or other arrays."""
    header, stored = load_model(source, MODEL_KIND, {MODEL_FORMAT_VERSION})
    new_meta = {**header.meta, **(meta or {})}
    save_model(
        target, MODEL_KIND, MODEL_FORMAT_VERSION, new_meta, stored if arrays is None else arrays
    )
    return target


def test_round_trip_gives_identical_predictions(tmp_path: Path) -> None:
    clf = untrained(context=2, tta=True)
    path = clf.save(tmp_path / "ctx2.safetensors")
    loaded = CNNDirectionClassifier.load(path)
    np.testing.assert_array_equal(loaded.predict_proba(FRAMES), clf.predict_proba(FRAMES))
    assert loaded.get_params() == clf.get_params()
    assert loaded.input_spec_ == clf.input_spec_ and loaded.context_ == 2
    header, arrays = load_model(path, MODEL_KIND, {2})
    assert header.meta["architecture"] == "pilotnet"
    assert header.meta["class_names"] == ["left", "straight", "right"]
    assert header.meta["input_spec"] == {
        "crop": [0.375, 0.84375],
        "height": 66,
        "width": 200,
        "colour": "yuv",
    }
    assert header.meta["in_channels"] == 6
    state = clf.model_.state_dict()
    assert set(arrays) == set(state)
    assert all(np.array_equal(arrays[k], v.numpy()) for k, v in state.items())


def test_load_keeps_the_saved_input_spec(saved: Path, tmp_path: Path) -> None:
    spec = {"crop": [0.25, 0.75], "height": 66, "width": 200, "colour": "yuv"}
    path = rewrite(saved, tmp_path / "spec.safetensors", meta={"input_spec": spec})
    assert CNNDirectionClassifier.load(path).input_spec_.crop == (0.25, 0.75)


def test_corrupt_and_truncated_files(saved: Path, tmp_path: Path) -> None:
    noise = tmp_path / "noise.safetensors"
    noise.write_bytes(b"qdcnn" + np.random.default_rng(0).bytes(4096))
    assert re.fullmatch(
        re.escape(f"{noise}: not a readable qdcnn model file (") + r".+\)", load_error(noise)
    )
    cut = tmp_path / "cut.safetensors"
    cut.write_bytes(saved.read_bytes()[: saved.stat().st_size // 2])
    assert re.fullmatch(
        re.escape(f"{cut}: not a readable qdcnn model file (") + r".*not fully covered\)",
        load_error(cut),
    )
    empty = tmp_path / "empty.safetensors"
    empty.touch()
    assert load_error(empty) == f"{empty}: empty file (0 bytes)"


def test_old_torch_and_pickle_files_are_refused_unread(tmp_path: Path) -> None:
    refusal = (
        "a pickle-based file (an older qdcnn model or a torch file); it is never loaded "
        "because unpickling can run code: retrain the model with this qdcnn version"
    )
    old = tmp_path / "old.pt"
    torch.save({"format": "qdcnn-cnn-direction-classifier/1", "state_dict": {}}, old)
    assert load_error(old) == f"{old}: {refusal}"
    raw = tmp_path / "raw.pkl"
    raw.write_bytes(pickle.dumps({"state_dict": {}}))
    assert load_error(raw) == f"{raw}: {refusal}"


def test_weights_of_another_architecture(saved: Path, tmp_path: Path) -> None:
    resnet = {k: v.numpy() for k, v in build_network("resnet50", seed=0).state_dict().items()}
    path = rewrite(saved, tmp_path / "resnet-arrays.safetensors", arrays=resnet)
    assert load_error(path) == (
        f"{path}: not a qdcnn pilotnet state_dict: missing 18 keys such as features.0.weight; "
        "unexpected 320 keys such as bn1.bias"
    )


def test_headers_that_lie(saved: Path, tmp_path: Path) -> None:
    # the qdcnn header claims two stacked frames; the arrays are a one-frame network
    path = rewrite(
        saved,
        tmp_path / "context.safetensors",
        meta={"params": {**_params(saved), "context": 2}, "in_channels": 6, "context": 2},
    )
    assert load_error(path) == (
        f"{path}: not a qdcnn pilotnet state_dict: 1 tensor with the wrong shape, "
        "such as features.0.weight (24, 3, 5, 5) instead of (24, 6, 5, 5)"
    )
    path = rewrite(saved, tmp_path / "channels.safetensors", meta={"in_channels": 9})
    assert load_error(path) == f"{path}: header in_channels 9 but context 1 (3 per frame)"
    path = rewrite(saved, tmp_path / "arch.safetensors", meta={"architecture": "vgg"})
    assert load_error(path) == (
        f"{path}: architecture 'vgg' is not a known network ('pilotnet', 'resnet50', "
        "'qdcnn-head', 'qdcnn-uuconv', 'qdcnn-quanv')"
    )
    path = rewrite(saved, tmp_path / "params.safetensors", meta={"architecture": "resnet50"})
    assert (
        load_error(path) == f"{path}: header architecture 'resnet50' but settings arch 'pilotnet'"
    )
    path = rewrite(
        saved, tmp_path / "bad.safetensors", meta={"params": {**_params(saved), "epochs": 0}}
    )
    assert load_error(path) == (
        f"{path}: saved settings are invalid: epochs=0 is invalid: an integer in [1, 100000]"
    )
    path = rewrite(saved, tmp_path / "classes.safetensors", meta={"class_names": ["a", "b"]})
    assert load_error(path) == (
        f"{path}: class names ['a', 'b'] are not ['left', 'straight', 'right']"
    )
    path = rewrite(saved, tmp_path / "best.safetensors", meta={"best_epoch": 3})
    assert load_error(path) == f"{path}: header best_epoch 3 is not an epoch of its history"


def test_safetensors_header_that_lies_about_a_shape(saved: Path, tmp_path: Path) -> None:
    data = saved.read_bytes()
    (n,) = struct.unpack("<Q", data[:8])

    def with_shape(shape: list[int], name: str) -> Path:
        header = json.loads(data[8 : 8 + n])
        header["features.0.weight"]["shape"] = shape
        text = json.dumps(header, separators=(",", ":")).encode()
        path = tmp_path / name
        path.write_bytes(data[:8] + text.ljust(n) + data[8 + n :])
        return path

    fewer = with_shape([24, 3, 5, 4], "fewer.safetensors")  # does not cover its bytes
    assert re.fullmatch(
        re.escape(f"{fewer}: not a readable qdcnn model file (") + r".*offset.*\)",
        load_error(fewer),
    )
    permuted = with_shape([5, 24, 3, 5], "permuted.safetensors")  # same bytes, wrong layout
    assert load_error(permuted) == (
        f"{permuted}: not a qdcnn pilotnet state_dict: 1 tensor with the wrong shape, "
        "such as features.0.weight (5, 24, 3, 5) instead of (24, 3, 5, 5)"
    )


def test_non_finite_and_mistyped_weights(saved: Path, tmp_path: Path) -> None:
    _, arrays = load_model(saved, MODEL_KIND, {2})
    nan = dict(arrays)
    nan["classifier.2.bias"] = np.full_like(arrays["classifier.2.bias"], np.nan)
    path = rewrite(saved, tmp_path / "nan.safetensors", arrays=nan)
    assert (
        load_error(path) == f"{path}: weights contain NaN or infinite values (in classifier.2.bias)"
    )
    half = {k: v.astype(np.float16) for k, v in arrays.items()}
    path = rewrite(saved, tmp_path / "half.safetensors", arrays=half)
    assert load_error(path) == (
        f"{path}: array classifier.2.bias is torch.float16, the network expects torch.float32"
    )


def test_a_checkpoint_restores_the_optimiser_and_scheduler(tmp_path: Path) -> None:
    torch.manual_seed(0)
    network = torch.nn.Sequential(torch.nn.Linear(4, 8), torch.nn.ReLU(), torch.nn.Linear(8, 3))
    optimiser = torch.optim.AdamW(network.parameters(), lr=0.01, betas=(0.8, 0.99))
    scheduler = torch.optim.lr_scheduler.CosineAnnealingLR(optimiser, T_max=10)
    for _ in range(3):
        loss = network(torch.randn(5, 4)).logsumexp(1).mean()
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        scheduler.step()
    path = save_checkpoint(
        tmp_path / "last.safetensors", network, optimiser, {"epoch": 3}, scheduler
    )
    twin = torch.nn.Sequential(torch.nn.Linear(4, 8), torch.nn.ReLU(), torch.nn.Linear(8, 3))
    twin_opt = torch.optim.AdamW(twin.parameters(), lr=0.5)
    twin_sched = torch.optim.lr_scheduler.CosineAnnealingLR(twin_opt, T_max=99)
    meta = load_checkpoint(path, twin, twin_opt, twin_sched)
    assert meta["epoch"] == 3
    assert all(
        torch.equal(a, b) for a, b in zip(network.parameters(), twin.parameters(), strict=True)
    )
    saved, restored = optimiser.state_dict(), twin_opt.state_dict()
    assert restored["param_groups"] == saved["param_groups"]
    for index, entry in saved["state"].items():
        assert all(torch.equal(v, restored["state"][index][k]) for k, v in entry.items())
    assert twin_sched.state_dict() == scheduler.state_dict()
    # the next step of the restored pair is the next step of the original
    x = torch.randn(5, 4)
    for net, opt in ((network, optimiser), (twin, twin_opt)):
        opt.zero_grad()
        net(x).logsumexp(1).mean().backward()
        opt.step()
    assert all(
        torch.equal(a, b) for a, b in zip(network.parameters(), twin.parameters(), strict=True)
    )
    sgd = torch.optim.SGD(twin.parameters(), lr=0.1)
    with pytest.raises(InputError) as err:
        load_checkpoint(path, twin, sgd)
    assert str(err.value) == f"{path}: optimiser state of 'AdamW', not 'SGD'"


def _params(path: Path) -> dict[str, Any]:
    header, _ = load_model(path, MODEL_KIND, {MODEL_FORMAT_VERSION})
    return dict(header.meta["params"])


def test_non_finite_history_values_are_stored_as_null(tmp_path: Path) -> None:
    clf = untrained()
    clf.history_ = [{"epoch": 1, "train_loss": float("nan"), "val_loss": float("inf")}]
    clf.best_epoch_ = 1
    loaded = CNNDirectionClassifier.load(clf.save(tmp_path / "nan.safetensors"))
    assert loaded.history_ == [{"epoch": 1, "train_loss": None, "val_loss": None}]


# ------------------------------------------ hybrid files across the dressed heads (issue 20)


def hybrid(**params: Any) -> CNNDirectionClassifier:
    kw = {"head": "quantum", **params.pop("network_params", {})}
    network = build_network("qdcnn-head", seed=2, **kw)
    return CNNDirectionClassifier.from_network(
        network,
        "qdcnn-head",
        device="cpu",
        num_threads=1,
        network_params={"head": "quantum"},
        **params,
    )


def test_a_hybrid_saved_before_the_dressed_heads_loads_as_it_was(tmp_path: Path) -> None:
    old = hybrid(network_params={"dressed": False})
    meta, arrays = old.fitted_state()
    del meta["head_format"]  # what files written before the dressed heads hold
    save_model(tmp_path / "old.safetensors", MODEL_KIND, MODEL_FORMAT_VERSION, meta, arrays)
    loaded = CNNDirectionClassifier.load(tmp_path / "old.safetensors")
    assert not loaded.model_.head.dressed and loaded.model_.head.readout_gain == 10.0
    np.testing.assert_array_equal(loaded.predict_proba(FRAMES), old.predict_proba(FRAMES))
    new = hybrid()
    new.save(tmp_path / "new.safetensors")
    again = CNNDirectionClassifier.load(tmp_path / "new.safetensors")
    assert again.model_.head.dressed
    np.testing.assert_array_equal(again.predict_proba(FRAMES), new.predict_proba(FRAMES))
    assert again.restarts_ == [] and again.seed_ == 0
    assert again.model_.head.entangler == "cz"


def test_a_dressed_hybrid_of_head_format_2_loads_with_its_cx_ring(tmp_path: Path) -> None:
    old = hybrid(network_params={"entangler": "cx"})
    meta, arrays = old.fitted_state()
    meta["head_format"] = 2  # what dressed hybrids saved before the CZ ring hold
    save_model(tmp_path / "v2.safetensors", MODEL_KIND, MODEL_FORMAT_VERSION, meta, arrays)
    loaded = CNNDirectionClassifier.load(tmp_path / "v2.safetensors")
    assert loaded.model_.head.entangler == "cx"
    np.testing.assert_array_equal(loaded.predict_proba(FRAMES), old.predict_proba(FRAMES))
    as_cz = hybrid()
    as_cz.model_.load_state_dict(old.model_.state_dict())
    assert not np.allclose(as_cz.predict_proba(FRAMES), old.predict_proba(FRAMES))


def test_hybrid_head_format_and_restarts_are_checked(tmp_path: Path) -> None:
    source = hybrid().save(tmp_path / "new.safetensors")
    bad = rewrite(source, tmp_path / "future.safetensors", meta={"head_format": 4})
    assert "head_format 4 is not one this qdcnn reads" in load_error(bad)
    # an undressed network under a dressed header: the arrays do not fit
    old = hybrid(network_params={"dressed": False}).save(tmp_path / "old.safetensors")
    header, stored = load_model(old, MODEL_KIND, {MODEL_FORMAT_VERSION})
    save_model(tmp_path / "lie.safetensors", MODEL_KIND, MODEL_FORMAT_VERSION, header.meta, stored)
    assert "missing 3 keys such as head.input_scale" in load_error(tmp_path / "lie.safetensors")
    for field, value in (("restarts", {"seed": 1}), ("seed_used", -1)):
        wrong = rewrite(source, tmp_path / f"{field}.safetensors", meta={field: value})
        assert field in load_error(wrong)


def test_a_trunk_from_another_network_is_refused_in_one_line(tmp_path: Path) -> None:
    source = hybrid().save(tmp_path / "head.safetensors")
    pilot = untrained().save(tmp_path / "pilotnet.safetensors")
    trunk = CNNDirectionClassifier("qdcnn-head", trunk_from=source).read_trunk()
    assert set(trunk) == {k for k in hybrid().model_.state_dict() if k.startswith("trunk.")}
    two = rewrite(source, tmp_path / "two.safetensors", meta={"class_names": ["left", "right"]})
    cases = [
        (("qdcnn-uuconv", {}), source, "its architecture is 'qdcnn-head'"),
        (("qdcnn-head", {"context": 2}), source, "its frames per input (context) is 1"),
        (("qdcnn-head", {"crop": (0.2, 0.9)}), source, "its input is"),
        (("qdcnn-head", {}), pilot, "its architecture is 'pilotnet'"),
        (
            ("qdcnn-head", {}),
            two,
            "--from: its classes is ['left', 'right'], this network's "
            "['left', 'straight', 'right']",
        ),
    ]
    for (arch, params), path, message in cases:
        with pytest.raises(InputError) as err:
            CNNDirectionClassifier(arch, trunk_from=path, **params).read_trunk()
        assert message in str(err.value) and "\n" not in str(err.value)


def test_a_trunk_must_match_the_frame_standardisation(tmp_path: Path) -> None:
    kw = {"head": "quantum", "standardise_frames": True}
    network = build_network("qdcnn-head", seed=2, **kw)
    standardised = CNNDirectionClassifier.from_network(
        network, "qdcnn-head", device="cpu", num_threads=1, network_params=kw
    ).save(tmp_path / "standardised.safetensors")
    plain = hybrid().save(tmp_path / "plain.safetensors")
    same = CNNDirectionClassifier("qdcnn-head", trunk_from=standardised, network_params=kw)
    assert set(same.read_trunk()) == {k for k in network.state_dict() if k.startswith("trunk.")}
    cases = [
        (
            standardised,
            {"head": "quantum"},
            "its frame front is 'standardised', this network's 'none'",
        ),
        (plain, kw, "its frame front is 'none', this network's 'standardised'"),
        (
            standardised,
            {"head": "quantum", "edge_frames": True},
            "its frame front is 'standardised', this network's 'edges'",
        ),
        (
            standardised,
            {**kw, "edge_frames": True},
            "its frame front is 'standardised', this network's 'standardised+edges'",
        ),
    ]
    for path, params, message in cases:
        with pytest.raises(InputError, match=re.escape(f"--from: {message}")):
            CNNDirectionClassifier(
                "qdcnn-head", trunk_from=path, network_params=params
            ).read_trunk()
    loaded = CNNDirectionClassifier.load(standardised)
    assert loaded.network_params == kw and isinstance(loaded.model_.front, FrameStandardisation)


def test_a_network_with_both_fronts_saves_loads_and_answers_alike(tmp_path: Path) -> None:
    kw = {"head": "quantum", "standardise_frames": True, "edge_frames": True}
    network = build_network("qdcnn-head", seed=3, **kw)
    assert network.trunk[0][0].in_channels == 6
    saved = CNNDirectionClassifier.from_network(
        network, "qdcnn-head", device="cpu", num_threads=1, network_params=kw
    )
    path = saved.save(tmp_path / "both.safetensors")
    loaded = CNNDirectionClassifier.load(path)
    assert loaded.network_params == kw and isinstance(loaded.model_.front, FramesAndEdges)
    frames = np.random.default_rng(0).integers(0, 256, (4, 160, 320, 3), dtype=np.uint8)
    np.testing.assert_allclose(loaded.predict_proba(frames), saved.predict_proba(frames))
    trunk = CNNDirectionClassifier("qdcnn-head", trunk_from=path, network_params=kw).read_trunk()
    assert trunk["trunk.0.0.weight"].shape[1] == 6
    fronts = {k: True for k in ("standardise_frames", "edge_frames")}
    two_frames = build_network("pilotnet", in_channels=6, seed=0, **fronts)
    stacked = build_network("qdcnn-head", in_channels=6, seed=0, head="quantum", **fronts)
    assert two_frames.features[0].weight.shape == stacked.trunk[0][0].weight.shape == (24, 12, 5, 5)
