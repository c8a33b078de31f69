"""PilotNet layer sizes (Bojarski et al. 2016, Fig. 4)."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from qdcnn.errors import ParameterError  # noqa: E402
from qdcnn.models.pilotnet import FrameStandardisation, PilotNet  # noqa: E402


def test_layers_and_output_shape() -> None:
    model = PilotNet().eval()
    x = torch.zeros((2, 3, 66, 200))
    assert tuple(model.features(x).shape) == (2, 64, 1, 18)
    assert tuple(model(x).shape) == (2, 3)
    convs = [m for m in model.features if isinstance(m, torch.nn.Conv2d)]
    assert [(c.out_channels, c.kernel_size, c.stride) for c in convs] == [
        (24, (5, 5), (2, 2)), (36, (5, 5), (2, 2)), (48, (5, 5), (2, 2)),
        (64, (3, 3), (1, 1)), (64, (3, 3), (1, 1)),
    ]  # fmt: skip
    dense = [m.out_features for m in model.classifier if isinstance(m, torch.nn.Linear)]
    assert dense == [100, 50, 10, 3]
    # convolutions 1824 + 21636 + 43248 + 27712 + 36928, dense 115300 + 5050 + 510 + 33
    assert sum(p.numel() for p in model.parameters()) == 252_241


def _yuv_frames(seed: int, n: int = 2, k: int = 1) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return torch.rand((n, 3 * k, 66, 200), generator=g) * 2 - 1


def test_frame_standardisation_ignores_brightness_contrast_and_colour_cast() -> None:
    std = FrameStandardisation()
    x = _yuv_frames(0, k=2)
    cast = torch.tensor([0.0, 0.1, -0.05]).repeat(2).view(1, 6, 1, 1)
    for changed in (x * 0.4 - 0.3, x * 0.4 + cast):
        torch.testing.assert_close(std(changed), std(x), atol=0.06, rtol=0.06)  # eps: 0.02
    out = std(x).reshape(2, 2, 3, -1)
    torch.testing.assert_close(out.mean(-1), torch.zeros(2, 2, 3), atol=1e-5, rtol=0)
    y_spread = out[:, :, 0].std(-1)
    assert torch.all((y_spread > 0.45) & (y_spread < 0.5))  # 0.5 sd / (sd + eps)


def test_frame_standardisation_keeps_each_frame_of_a_stack_apart() -> None:
    x = _yuv_frames(1, n=1, k=2)
    scaled = x.clone()
    scaled[:, 3:] = scaled[:, 3:] * 0.5  # only the second frame is darker
    out, again = FrameStandardisation()(x), FrameStandardisation()(scaled)
    torch.testing.assert_close(out[:, :3], again[:, :3])
    each = torch.cat([FrameStandardisation()(x[:, :3]), FrameStandardisation()(x[:, 3:])], 1)
    torch.testing.assert_close(out, each)  # a stack is its frames, each on its own


def test_standardising_pilotnet_has_the_same_weights_and_answers_the_standardised_frame() -> None:
    torch.manual_seed(0)
    plain, standardised = PilotNet().eval(), PilotNet(standardise_frames=True).eval()
    assert plain.state_dict().keys() == standardised.state_dict().keys()
    standardised.load_state_dict(plain.state_dict())
    x = _yuv_frames(2)
    torch.testing.assert_close(standardised(x), plain(FrameStandardisation()(x)))
    torch.testing.assert_close(standardised(0.5 * x), standardised(x), atol=0.01, rtol=0.01)


def test_standardise_frames_takes_only_a_bool() -> None:
    with pytest.raises(ParameterError, match="standardise_frames=1 is invalid: True or False"):
        PilotNet(standardise_frames=1)  # type: ignore[arg-type]
