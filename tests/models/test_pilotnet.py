"""PilotNet layer sizes (Bojarski et al. 2016, Fig. 4)."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")

from qdcnn.models.pilotnet import PilotNet  # noqa: E402


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
