"""PilotNet layer sizes (Bojarski et al. 2016, Fig. 4)."""

from __future__ import annotations

from pathlib import Path

import pytest

torch = pytest.importorskip("torch")

from qdcnn.errors import ParameterError  # noqa: E402
from qdcnn.models.pilotnet import (  # noqa: E402
    EdgeFrames,
    FramesAndEdges,
    FrameStandardisation,
    PilotNet,
)


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


def test_edge_frames_ignore_brightness_contrast_and_colour() -> None:
    edges = EdgeFrames()
    x = _yuv_frames(3, k=2)
    recoloured = x.clone()
    recoloured[:, [1, 2, 4, 5]] = -recoloured[:, [1, 2, 4, 5]]
    for changed in (x * 0.4 - 0.3, recoloured):
        torch.testing.assert_close(edges(changed), edges(x), atol=0.03, rtol=0.03)  # eps 0.01
    out = edges(x).reshape(2, 2, 3, 66, 200)
    size = out[:, :, 2]
    torch.testing.assert_close(size, out[:, :, :2].square().sum(2).sqrt(), atol=1e-4, rtol=0)
    means = size.mean(dim=(-1, -2))
    assert torch.all((means > 0.49) & (means < 0.5))  # mean / (2 mean + eps)


def test_edge_frames_find_a_vertical_edge_and_nothing_on_a_flat_frame() -> None:
    x = torch.zeros((1, 3, 66, 200))
    x[:, 0, :, 100:] = 0.8  # Y steps up at column 100; U and V flat
    out = EdgeFrames()(x)[0]
    assert torch.all(out[0, :, 99:101] > 0.5) and torch.all(out[1].abs() < 1e-3)
    assert torch.all(out[:, :, :99].abs() < 1e-3) and torch.all(out[:, :, 101:].abs() < 1e-3)
    assert torch.all(EdgeFrames()(torch.full((2, 6, 66, 200), 0.3)).abs() < 1e-3)


def test_both_fronts_give_each_frame_its_standardised_planes_then_its_edges() -> None:
    x = _yuv_frames(4, k=2)
    out = FramesAndEdges()(x)
    assert out.shape == (2, 12, 66, 200)
    std, edges = FrameStandardisation()(x), EdgeFrames()(x)
    for k in range(2):
        torch.testing.assert_close(out[:, 6 * k : 6 * k + 3], std[:, 3 * k : 3 * k + 3])
        torch.testing.assert_close(out[:, 6 * k + 3 : 6 * k + 6], edges[:, 3 * k : 3 * k + 3])
    net = PilotNet(in_channels=6, standardise_frames=True, edge_frames=True).eval()
    assert isinstance(net.standardise, FramesAndEdges) and net.features[0].in_channels == 12
    assert tuple(net(x).shape) == (2, 3)
    with pytest.raises(ParameterError, match="edge_frames"):
        PilotNet(edge_frames="yes")  # type: ignore[arg-type]
    edge_only = PilotNet(edge_frames=True)
    assert isinstance(edge_only.standardise, EdgeFrames)
    assert edge_only.state_dict().keys() == PilotNet().state_dict().keys()


def test_a_weights_file_is_refused_with_the_edge_front(tmp_path: Path) -> None:
    from qdcnn.models.networks import build_network

    path = tmp_path / "pilotnet.pt"
    torch.save(PilotNet().state_dict(), path)
    assert build_network("pilotnet", weights=path, standardise_frames=True) is not None
    for kw in ({"edge_frames": True}, {"edge_frames": True, "standardise_frames": True}):
        with pytest.raises(ParameterError, match="no weights file with edge_frames"):
            build_network("pilotnet", weights=path, **kw)
