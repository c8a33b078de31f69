"""Noise models from their text form, as the command line and saved settings write them.

``"CHANNEL:P[,readout:E]"`` is a :class:`~qdcnn.quantum.noise.NoiseSpec`;
``"device:NAME[,...]"`` is a device's calibrated noise,
:class:`~qdcnn.quantum.device.DeviceNoise`. This module sits above both, so that
:mod:`qdcnn.quantum.noise` does not import :mod:`qdcnn.quantum.device` (which builds on it).
"""

from __future__ import annotations

from qdcnn.errors import ParameterError
from qdcnn.quantum.device import parse_device_noise
from qdcnn.quantum.noise import NoiseSpec, check_channel


def parse_noise(text: str) -> NoiseSpec:
    """Parse ``"CHANNEL:P"`` (optionally ``",readout:E"``) into a :class:`NoiseSpec`.

    ``"device:NAME"`` (options ``,layout:0-1-2``, ``,route:swap``,
    ``,readout:asymmetric|symmetric|none``) gives the calibrated noise of an offline IBM
    fake backend, a :class:`qdcnn.quantum.device.DeviceNoise` (a ``NoiseSpec`` subclass,
    accepted wherever a ``NoiseSpec`` is); see :func:`qdcnn.quantum.device.parse_device_noise`.

    Examples
    --------
    >>> parse_noise("bit-flip:0.1")
    NoiseSpec(channel='bit-flip', p=0.1, readout=0.0)
    """
    if any(part.strip().partition(":")[0] == "device" for part in text.split(",")):
        return parse_device_noise(text)
    channel: str | None = None
    p = 0.0
    readout = 0.0
    for part in filter(None, (t.strip() for t in text.split(","))):
        name, sep, value = part.partition(":")
        if not sep:
            raise ParameterError("noise", text, "CHANNEL:P, e.g. depolarizing:0.1")
        try:
            v = float(value)
        except ValueError:
            raise ParameterError("noise", text, f"a number after '{name}:'") from None
        if name == "readout":
            readout = v
        else:
            channel, p = check_channel(name), v
    return NoiseSpec(channel, p, readout)
