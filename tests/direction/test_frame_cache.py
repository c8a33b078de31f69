"""Frames decoded and resized once per recording: hits, invalidation, damaged entries."""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from qdcnn.config import PipelineConfig  # noqa: E402
from qdcnn.data.frames import load_frameset, stack_images  # noqa: E402
from qdcnn.data.synthetic import generate_drive  # noqa: E402
from qdcnn.data.writers import write_udacity  # noqa: E402
from qdcnn.direction.frame_cache import entry_paths, method_inputs, network_frames  # noqa: E402
from qdcnn.direction.methods import TrainingOptions, get_method  # noqa: E402
from qdcnn.errors import InputError  # noqa: E402
from qdcnn.models.networks import input_spec  # noqa: E402
from qdcnn.models.preprocess import PreparedFrames, crop_resize  # noqa: E402

SPEC = input_spec("pilotnet")


@pytest.fixture
def recording(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    rec = tmp_path / "rec"
    write_udacity(generate_drive("track1", 10, seed=2), rec)
    sorted((rec / "IMG").iterdir())[3].write_bytes(b"not a jpeg")  # one unreadable frame
    return rec


def _expected(rec: Path) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The frames decoded and fed to the network without any cache."""
    images, readable, failures = stack_images(load_frameset(f"udacity:{rec}"))
    return (
        crop_resize(images, SPEC).permute(0, 2, 3, 1).numpy(),
        readable,
        [f.file for f in failures],
    )


def test_a_hit_gives_the_arrays_of_the_first_decode(recording: Path) -> None:
    notes: list[str] = []
    frames = load_frameset(f"udacity:{recording}")
    first, readable, failures = network_frames(frames, SPEC, on_note=notes.append)
    assert all(p.exists() for p in entry_paths(frames, SPEC))
    again, readable2, failures2 = network_frames(frames, SPEC, on_note=notes.append)
    assert isinstance(again, np.memmap | PreparedFrames) and not again.flags.writeable
    expected, exp_readable, exp_failures = _expected(recording)
    for images in (first, again):
        assert images.shape == (10, SPEC.height, SPEC.width, 3)
        np.testing.assert_array_equal(np.asarray(images)[exp_readable], expected[exp_readable])
    np.testing.assert_array_equal(readable, exp_readable)
    np.testing.assert_array_equal(readable2, exp_readable)
    assert [f.file for f in failures] == [f.file for f in failures2] == exp_failures
    assert not readable[3] and not notes
    # the network sees the same tensor from the cached frames as from the frames themselves
    assert torch.equal(
        crop_resize(again[readable], SPEC), torch.from_numpy(expected[readable]).permute(0, 3, 1, 2)
    )


def test_a_changed_recording_is_decoded_again(recording: Path) -> None:
    frames = load_frameset(f"udacity:{recording}")
    old_array, _ = entry_paths(frames, SPEC)
    network_frames(frames, SPEC)
    path = sorted((recording / "IMG").iterdir())[5]
    replacement = sorted((recording / "IMG").iterdir())[6].read_bytes()
    path.write_bytes(replacement)  # frame 5 now shows frame 6
    os.utime(path, ns=(path.stat().st_atime_ns, path.stat().st_mtime_ns + 10**9))
    changed = load_frameset(f"udacity:{recording}")
    new_array, _ = entry_paths(changed, SPEC)
    assert new_array != old_array
    images, _, _ = network_frames(changed, SPEC)
    np.testing.assert_array_equal(images[5], images[6])


@pytest.mark.parametrize("damage", ["truncate", "garbage", "record"])
def test_a_damaged_entry_is_rebuilt_with_a_note(recording: Path, damage: str) -> None:
    frames = load_frameset(f"udacity:{recording}")
    good, _, _ = network_frames(frames, SPEC)
    good = np.array(good)
    array_path, record_path = entry_paths(frames, SPEC)
    if damage == "truncate":
        array_path.write_bytes(array_path.read_bytes()[:-1000])
    elif damage == "garbage":
        array_path.write_bytes(b"\x93NUMPY garbage" * 50)
    else:
        record_path.write_text("{not json")
    notes: list[str] = []
    rebuilt, _, _ = network_frames(frames, SPEC, on_note=notes.append)
    assert (
        len(notes) == 1 and str(array_path) in notes[0] and "decoding the frames again" in notes[0]
    )
    np.testing.assert_array_equal(np.asarray(rebuilt), good)
    again, _, _ = network_frames(frames, SPEC, on_note=notes.append)
    assert len(notes) == 1  # the rebuilt entry is whole
    np.testing.assert_array_equal(np.asarray(again), good)


def test_prepared_frames_keep_their_input_and_refuse_another(recording: Path) -> None:
    frames = load_frameset(f"udacity:{recording}")
    images, readable, _ = network_frames(frames, SPEC, use_cache=False)
    subset = images[np.flatnonzero(readable)[:4]]
    assert isinstance(subset, PreparedFrames) and subset.spec == SPEC
    shipped = pickle.loads(pickle.dumps(subset))  # as Dask sends it to a worker
    assert shipped.spec == SPEC and torch.equal(
        crop_resize(shipped, SPEC), crop_resize(subset, SPEC)
    )
    with pytest.raises(InputError, match="prepared for"):
        crop_resize(subset, input_spec("resnet50"))
    assert not any(p.exists() for p in entry_paths(frames, SPEC))


def test_only_network_methods_get_prepared_frames(recording: Path) -> None:
    frames = load_frameset(f"udacity:{recording}")
    cnn, _, _ = method_inputs(
        get_method("dnn-pilotnet"), PipelineConfig(), TrainingOptions(), frames
    )
    assert isinstance(cnn, PreparedFrames) and cnn.spec == SPEC
    hog, _, _ = method_inputs(get_method("hog-logreg"), PipelineConfig(), TrainingOptions(), frames)
    assert not isinstance(hog, PreparedFrames) and hog.shape[1:] == (160, 320, 3)
