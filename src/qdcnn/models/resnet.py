"""ResNet-50 in plain PyTorch, with torchvision's module and parameter names.

The names match ``torchvision.models.resnet50`` exactly (``conv1``, ``bn1``,
``layer1.0.downsample.0``, ..., ``fc``), so a torchvision-format ImageNet
``state_dict`` loads with :func:`qdcnn.models.weights.load_weights` without
torchvision being installed. The stride of a downsampling bottleneck sits on its
3x3 convolution (torchvision's "ResNet V1.5").

References
----------
.. [1] K. He, X. Zhang, S. Ren and J. Sun, "Deep Residual Learning for Image
       Recognition", CVPR 2016.
"""

from __future__ import annotations

from qdcnn._optional import require

require("torch", "the ResNet-50 model")
import torch  # noqa: E402
from torch import nn  # noqa: E402

_RESNET50_LAYERS: tuple[int, int, int, int] = (3, 4, 6, 3)


class _Bottleneck(nn.Module):
    """1x1 reduce, 3x3 (carrying the stride), 1x1 expand by 4, plus the shortcut."""

    expansion = 4

    def __init__(
        self, inplanes: int, planes: int, stride: int = 1, downsample: nn.Module | None = None
    ) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(inplanes, planes, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(planes)
        self.conv2 = nn.Conv2d(planes, planes, 3, stride=stride, padding=1, bias=False)
        self.bn2 = nn.BatchNorm2d(planes)
        self.conv3 = nn.Conv2d(planes, planes * self.expansion, 1, bias=False)
        self.bn3 = nn.BatchNorm2d(planes * self.expansion)
        self.relu = nn.ReLU(inplace=True)
        self.downsample = downsample

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Residual block output."""
        identity = x if self.downsample is None else self.downsample(x)
        out = self.relu(self.bn1(self.conv1(x)))
        out = self.relu(self.bn2(self.conv2(out)))
        out = self.bn3(self.conv3(out))
        result: torch.Tensor = self.relu(out + identity)
        return result


class ResNet(nn.Module):
    """Bottleneck ResNet [1]_ laid out as torchvision's ``ResNet``.

    Parameters
    ----------
    layers : 4 ints
        Bottleneck blocks per stage; ``(3, 4, 6, 3)`` is ResNet-50.
    num_classes : int
        Outputs of the final ``fc`` layer.
    in_channels : int
        Input planes of ``conv1``: 3, or 3K for K frames stacked along channels.
    """

    def __init__(
        self,
        layers: tuple[int, int, int, int] = _RESNET50_LAYERS,
        num_classes: int = 1000,
        in_channels: int = 3,
    ) -> None:
        super().__init__()
        self.inplanes = 64
        self.conv1 = nn.Conv2d(in_channels, 64, 7, stride=2, padding=3, bias=False)
        self.bn1 = nn.BatchNorm2d(64)
        self.relu = nn.ReLU(inplace=True)
        self.maxpool = nn.MaxPool2d(kernel_size=3, stride=2, padding=1)
        self.layer1 = self._make_layer(64, layers[0])
        self.layer2 = self._make_layer(128, layers[1], stride=2)
        self.layer3 = self._make_layer(256, layers[2], stride=2)
        self.layer4 = self._make_layer(512, layers[3], stride=2)
        self.avgpool = nn.AdaptiveAvgPool2d((1, 1))
        self.fc = nn.Linear(512 * _Bottleneck.expansion, num_classes)
        for m in self.modules():  # torchvision's initialisation
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
            elif isinstance(m, nn.BatchNorm2d):
                nn.init.constant_(m.weight, 1)
                nn.init.constant_(m.bias, 0)

    def _make_layer(self, planes: int, blocks: int, stride: int = 1) -> nn.Sequential:
        downsample = None
        if stride != 1 or self.inplanes != planes * _Bottleneck.expansion:
            downsample = nn.Sequential(
                nn.Conv2d(
                    self.inplanes, planes * _Bottleneck.expansion, 1, stride=stride, bias=False
                ),
                nn.BatchNorm2d(planes * _Bottleneck.expansion),
            )
        stage = [_Bottleneck(self.inplanes, planes, stride, downsample)]
        self.inplanes = planes * _Bottleneck.expansion
        stage += [_Bottleneck(self.inplanes, planes) for _ in range(1, blocks)]
        return nn.Sequential(*stage)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Logits ``(B, num_classes)`` for a ``(B, in_channels, H, W)`` batch (H, W >= 32)."""
        x = self.maxpool(self.relu(self.bn1(self.conv1(x))))
        x = self.layer4(self.layer3(self.layer2(self.layer1(x))))
        out: torch.Tensor = self.fc(torch.flatten(self.avgpool(x), 1))
        return out


def resnet50(num_classes: int = 1000, in_channels: int = 3) -> ResNet:
    """ResNet-50 with randomly initialised weights (25,557,032 parameters for 1000 classes).

    Examples
    --------
    >>> model = resnet50(num_classes=3)
    >>> tuple(model.state_dict()["layer4.2.bn3.running_var"].shape)
    (2048,)
    """
    return ResNet(_RESNET50_LAYERS, num_classes=num_classes, in_channels=in_channels)
