"""Crop, resize and colour normalisation of frames for the CNN baselines."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
cv2 = pytest.importorskip("cv2")

from qdcnn.models.preprocess import (  # noqa: E402
    PILOTNET_INPUT,
    RESNET50_INPUT,
    ROAD_CROP,
    crop_resize,
    crop_rows,
    normalise,
)


def test_crop_rows_are_relative_to_the_frame_height() -> None:
    assert crop_rows(160, ROAD_CROP) == (60, 135)  # the usual Udacity crop
    assert crop_rows(480, ROAD_CROP) == (180, 405)
    assert crop_rows(1, ROAD_CROP) == (0, 1)  # never empty


def test_crop_removes_sky_and_hood() -> None:
    frames = np.zeros((2, 160, 320, 3), np.uint8)
    frames[:, :60] = (255, 0, 0)  # sky
    frames[:, 60:135] = (0, 200, 0)  # road
    frames[:, 135:] = (0, 0, 255)  # hood
    for spec in (PILOTNET_INPUT, RESNET50_INPUT):
        out = crop_resize(frames, spec)
        assert out.dtype == torch.uint8
        assert tuple(out.shape) == (2, 3, spec.height, spec.width)
        assert torch.equal(out[:, 1], torch.full_like(out[:, 1], 200))
        assert int(out[:, 0].max()) == 0 and int(out[:, 2].max()) == 0


def test_resize_is_opencv_on_the_crop() -> None:
    frames = np.random.default_rng(0).integers(0, 256, (3, 640, 800, 3), dtype=np.uint8)
    crop = frames[1, 240:540]  # rows 240..540 of 640 are the road crop
    out = crop_resize(frames, PILOTNET_INPUT)[1].permute(1, 2, 0).numpy()
    np.testing.assert_array_equal(out, cv2.resize(crop, (200, 66), interpolation=cv2.INTER_AREA))
    out = crop_resize(frames, RESNET50_INPUT)[1].permute(1, 2, 0).numpy()
    # both sides shrink (300 -> 224 rows, 800 -> 224 columns): area interpolation again
    np.testing.assert_array_equal(out, cv2.resize(crop, (224, 224), interpolation=cv2.INTER_AREA))
    small = frames[:, :160, :320]  # a Udacity-size frame: 75 rows grow to 224, bilinear
    out = crop_resize(small, RESNET50_INPUT)[2].permute(1, 2, 0).numpy()
    ref = cv2.resize(small[2, 60:135], (224, 224), interpolation=cv2.INTER_LINEAR)
    np.testing.assert_array_equal(out, ref)


def test_yuv_normalisation_matches_opencv() -> None:
    rgb = np.random.default_rng(1).integers(0, 256, (8, 8, 3), dtype=np.uint8)
    batch = torch.from_numpy(rgb).permute(2, 0, 1)[None]
    ours = normalise(batch, PILOTNET_INPUT)[0].permute(1, 2, 0).numpy()
    ref = cv2.cvtColor(rgb, cv2.COLOR_RGB2YUV).astype(float)
    # PilotNet scaling: Y to [-1, 1], U and V centred on 0 with the same scale
    np.testing.assert_allclose(ours * 127.5 + [127.5, 128, 128], ref, atol=1.0)
    assert np.abs(ours).max() <= 1.0 + 1e-6


def test_imagenet_normalisation() -> None:
    mean = torch.tensor([0.485, 0.456, 0.406]) * 255
    batch = mean.view(1, 3, 1, 1).expand(1, 3, 2, 2)
    torch.testing.assert_close(normalise(batch, RESNET50_INPUT), torch.zeros(1, 3, 2, 2))
    white = normalise(torch.full((1, 3, 1, 1), 255.0), RESNET50_INPUT).flatten()
    torch.testing.assert_close(
        white, (1 - torch.tensor([0.485, 0.456, 0.406])) / torch.tensor([0.229, 0.224, 0.225])
    )
