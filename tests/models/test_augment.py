"""Seeded flip / brightness / shadow augmentation with label swapping."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from qdcnn.models.augment import (  # noqa: E402
    SHADOW_DARKNESS,
    augment_batch,
    randomise_colour,
    shadow_masks,
    shift_columns,
)


def half_bright_batch(n: int) -> torch.Tensor:
    x = torch.zeros((n, 3, 12, 20))
    x[..., :10] = 200.0  # bright left half, black right half: a flip is visible
    return x


def test_flip_swaps_left_and_right_only() -> None:
    n = 64
    labels = torch.arange(n) % 3
    out, new = augment_batch(half_bright_batch(n), labels, torch.Generator().manual_seed(0))
    flipped = out[..., 10:].amax(dim=(1, 2, 3)) > 0
    assert 10 < int(flipped.sum()) < n - 10  # about half are flipped
    expected = torch.where(flipped, 2 - labels, labels)  # 0 <-> 2, 1 stays
    assert torch.equal(new, expected)


def test_brightness_and_shadow_scale_a_flat_frame() -> None:
    x = torch.full((40, 3, 16, 24), 100.0)
    out, _ = augment_batch(x, torch.ones(40, dtype=torch.long), torch.Generator().manual_seed(1))
    assert out.min() >= 0 and out.max() <= 255
    shaded = 0
    for frame in out:
        levels = torch.unique(frame)
        assert len(levels) in (1, 2)  # lit, and possibly one shadow level
        if len(levels) == 2:
            shaded += 1
            ratio = float(levels[0] / levels[1])
            assert SHADOW_DARKNESS[0] - 1e-4 <= ratio <= SHADOW_DARKNESS[1] + 1e-4
    assert 5 < shaded < 35


def test_shadows_are_convex_quadrilaterals() -> None:
    masks = shadow_masks(20, 30, 40, torch.Generator().manual_seed(2)).numpy()
    for mask in masks:
        for row in mask:
            cols = np.flatnonzero(row)
            if len(cols):
                assert cols[-1] - cols[0] + 1 == len(cols)  # one run per row


def test_same_generator_seed_same_augmentation() -> None:
    x = torch.rand((6, 3, 8, 8)) * 255
    y = torch.tensor([0, 1, 2, 0, 1, 2])
    a = augment_batch(x, y, torch.Generator().manual_seed(5))
    b = augment_batch(x, y, torch.Generator().manual_seed(5))
    assert torch.equal(a[0], b[0]) and torch.equal(a[1], b[1])


def test_shift_columns_moves_frames_and_repeats_the_edge() -> None:
    x = torch.arange(5.0).view(1, 1, 1, 5).repeat(3, 2, 2, 1)
    out = shift_columns(x, torch.tensor([2, 0, -1]))
    assert out[0, 1, 1].tolist() == [0, 0, 0, 1, 2]  # right by 2, column 0 repeated
    assert torch.equal(out[1], x[1])
    assert out[2, 0, 0].tolist() == [1, 2, 3, 4, 4]  # left by 1, last column repeated


def test_shift_is_bounded_keeps_labels_and_is_off_by_default() -> None:
    n, w = 64, 40
    x = torch.zeros((n, 3, 4, w))
    x[..., w // 2] = 200.0  # one bright column in the middle
    labels = torch.arange(n) % 3
    plain = augment_batch(x, labels, torch.Generator().manual_seed(7))
    unshifted = augment_batch(x, labels, torch.Generator().manual_seed(7), max_shift=0.0)
    assert torch.equal(plain[0], unshifted[0]) and torch.equal(plain[1], unshifted[1])
    out, new = augment_batch(x, labels, torch.Generator().manual_seed(7), max_shift=0.1)
    assert torch.equal(new, plain[1])  # same flips, labels untouched by shifts
    column = out[:, 0, 0].argmax(dim=1)  # where the bright column went
    offsets = (column - w // 2).abs()  # a flip moves the middle column by at most 1
    assert int(offsets.max()) <= round(0.1 * w) + 1
    assert int((offsets >= 2).sum()) > n // 4  # most frames did move


def flat_colour_batch(n: int) -> torch.Tensor:
    """Frames of three flat, distinct channel levels (R 40, G 120, B 220) and one
    brighter pixel, so the channel order and the contrast can be read back."""
    x = torch.empty((n, 3, 6, 8))
    x[:, 0], x[:, 1], x[:, 2] = 40.0, 120.0, 220.0
    x[:, :, 0, 0] += 10.0
    return x


def test_colour_permutes_channels_scales_contrast_and_greys() -> None:
    n = 600
    x = flat_colour_batch(n)
    out = randomise_colour(x, torch.Generator().manual_seed(2))
    grey = (out[:, 0] == out[:, 1]).all(dim=(1, 2)) & (out[:, 1] == out[:, 2]).all(dim=(1, 2))
    assert 0.15 < grey.float().mean() < 0.25
    # a grey frame is the BT.601 luma of its own RGB (contrast keeps the mean)
    luma = 0.299 * 40.0 + 0.587 * 120.0 + 0.114 * 220.0 + 10.0 / 48.0
    torch.testing.assert_close(out[grey].mean(dim=(1, 2, 3)), torch.full((int(grey.sum()),), luma))
    colour = out[~grey]
    # contrast about the frame's mean keeps the mean and scales every deviation alike
    torch.testing.assert_close(colour.mean(dim=(1, 2, 3)), x[~grey].mean(dim=(1, 2, 3)))
    order = colour[:, :, 1, 1].argsort(dim=1)  # which input channel each output holds
    orders = {tuple(o.tolist()) for o in order}
    assert len(orders) == 6  # every permutation occurs
    identity = (order == torch.arange(3)).all(dim=1).float().mean()
    assert 0.5 < identity < 0.67  # kept with 1/2 + 1/2 * 1/6
    spread = colour[:, :, 0, 0] - colour[:, :, 1, 1]  # the bright pixel's offset, scaled
    factor = spread / 10.0
    assert factor.min() >= 0.6 - 1e-5 and factor.max() <= 1.4 + 1e-5
    assert factor.std() > 0.1


def test_colour_keeps_labels_and_the_other_draws() -> None:
    labels = torch.arange(40) % 3
    x = half_bright_batch(40)
    plain, plain_labels = augment_batch(x, labels, torch.Generator().manual_seed(4))
    coloured, coloured_labels = augment_batch(
        x, labels, torch.Generator().manual_seed(4), colour=True
    )
    assert torch.equal(plain_labels, coloured_labels)
    assert not torch.equal(plain, coloured)

    # colour changes no frame's left-right layout: the same frames are flipped
    def flipped(out: torch.Tensor) -> torch.Tensor:
        return out[..., 10:].mean(dim=(1, 2, 3)) > out[..., :10].mean(dim=(1, 2, 3))

    assert torch.equal(flipped(plain), flipped(coloured))
