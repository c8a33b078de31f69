"""Context stacking, side-camera views and augmentation of stacked frames."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.data.labels import direction_labels
from qdcnn.errors import InputError, ParameterError
from qdcnn.models.samples import ExtraView, context_windows, side_camera_views, stack_context


def test_context_windows_repeat_the_first_frame() -> None:
    assert context_windows(5, 1).tolist() == [[0], [1], [2], [3], [4]]
    assert context_windows(4, 3).tolist() == [[0, 0, 0], [0, 0, 1], [0, 1, 2], [1, 2, 3]]
    assert context_windows(0, 2).shape == (0, 2)
    with pytest.raises(ParameterError) as err:
        context_windows(3, 0)
    assert str(err.value) == "context=0 is invalid: an integer >= 1"


def test_stack_context_puts_the_oldest_frame_first() -> None:
    frames = np.zeros((4, 2, 3, 3), np.uint8)
    frames[..., 0] = np.arange(4).reshape(4, 1, 1)  # red channel holds the frame index
    out = stack_context(frames, 3)
    assert out.shape == (4, 2, 3, 9)
    assert out[:, 0, 0, 0::3].tolist() == [[0, 0, 0], [0, 0, 1], [0, 1, 2], [1, 2, 3]]
    assert not out[..., 1::3].any() and not out[..., 2::3].any()
    np.testing.assert_array_equal(stack_context(frames, 1), frames)


def test_side_cameras_get_corrected_steering_labels() -> None:
    frames = np.zeros((5, 4, 4, 3), np.uint8)
    steering = np.array([0.0, -0.1, 0.1, -0.3, 0.3])

    def label_fn(s: np.ndarray) -> np.ndarray:
        return direction_labels(s, window=0, threshold=0.05)

    left, right = side_camera_views(frames, frames + 1, steering, label_fn)
    # left camera: steering + 0.2 -> [0.2, 0.1, 0.3, -0.1, 0.5]
    assert left.labels.tolist() == [2, 2, 2, 0, 2] and left.name == "left camera"
    # right camera: steering - 0.2 -> [-0.2, -0.3, -0.1, -0.5, 0.1]
    assert right.labels.tolist() == [0, 0, 0, 0, 2] and int(right.images[0, 0, 0, 0]) == 1
    left, right = side_camera_views(frames, frames, steering, label_fn, correction=0.0)
    assert left.labels.tolist() == right.labels.tolist() == label_fn(steering).tolist()
    with pytest.raises(InputError) as err:
        side_camera_views(frames[:3], frames, steering, label_fn)
    assert str(err.value) == "left camera: 3 frames for 5 steering values"
    with pytest.raises(InputError) as err:
        side_camera_views(frames, frames, steering, lambda s: s[:2])
    assert str(err.value) == "left camera: label_fn returned shape (2,) for 5 steering values"
    with pytest.raises(ParameterError) as err:
        side_camera_views(frames, frames, steering, label_fn, correction=-0.2)
    assert str(err.value) == "correction=-0.2 is invalid: a finite number in [0, 10]"


def test_augmentation_treats_the_frames_of_a_sample_alike() -> None:
    torch = pytest.importorskip("torch")
    from qdcnn.models.augment import augment_batch

    rng = np.random.default_rng(0)
    k = 3
    frames = torch.from_numpy(rng.integers(0, 256, (6, k, 3, 12, 20), dtype=np.uint8))
    labels = torch.tensor([0, 1, 2, 0, 1, 2])
    kw = {"max_shift": 0.2, "colour": True}
    out, out_labels = augment_batch(
        frames.reshape(6, 3 * k, 12, 20), labels, torch.Generator().manual_seed(5), **kw
    )
    for j in range(k):  # each frame alone, with the same random draws, gets the same change
        alone, alone_labels = augment_batch(
            frames[:, j], labels, torch.Generator().manual_seed(5), **kw
        )
        torch.testing.assert_close(out[:, 3 * j : 3 * j + 3], alone, rtol=0, atol=1e-4)
        assert torch.equal(alone_labels, out_labels)
    assert not torch.equal(out[:, :3], frames[:, 0].float())  # brightness always changes


def test_estimator_stacks_context_at_prediction() -> None:
    pytest.importorskip("torch")
    from qdcnn.models import CNNDirectionClassifier
    from qdcnn.models.networks import build_network

    clf = CNNDirectionClassifier.from_network(
        build_network("pilotnet", 6, seed=0), device="cpu", context=2, batch_size=2
    )
    frames = np.random.default_rng(1).integers(0, 256, (70, 40, 80, 3), dtype=np.uint8)
    base = clf.predict_proba(frames)
    changed = frames.copy()
    changed[65] = 255 - changed[65]  # in the second chunk of 64 frames
    diff = np.abs(clf.predict_proba(changed) - base).max(axis=1)
    assert np.flatnonzero(diff > 0).tolist() == [65, 66]  # the frame and the one after it
    changed = frames.copy()
    changed[63] = 0  # the last frame of the first chunk is context of the second
    diff = np.abs(clf.predict_proba(changed) - base).max(axis=1)
    assert np.flatnonzero(diff > 0).tolist() == [63, 64]
    alone = clf.predict_proba(frames[:1])
    np.testing.assert_allclose(alone, base[:1], atol=1e-6)  # frame 0 is its own context


def test_estimator_trains_with_side_views_and_checks_them() -> None:
    pytest.importorskip("torch")
    from qdcnn.models import CNNDirectionClassifier

    rng = np.random.default_rng(2)
    frames = rng.integers(0, 256, (30, 40, 80, 3), dtype=np.uint8)
    labels = np.arange(30) % 3
    views = [ExtraView(frames[:, :, ::-1].copy(), 2 - labels, "mirror")]
    clf = CNNDirectionClassifier(epochs=1, progress=False, num_threads=1, device="cpu")
    assert len(clf.fit(frames, labels, extra_views=views).history_) == 1
    with pytest.raises(InputError) as err:
        clf.fit(frames, labels, extra_views=[ExtraView(frames[:5], labels[:5], "left camera")])
    assert str(err.value) == (
        "left camera: frames of shape (5, 40, 80, 3), the images are (30, 40, 80, 3)"
    )
    with pytest.raises(InputError) as err:
        clf.fit(frames, labels, extra_views=[ExtraView(frames, labels + 3, "left camera")])
    assert str(err.value) == (
        "left camera labels: values must be 0 (left), 1 (straight) or 2 (right); found 3"
    )
