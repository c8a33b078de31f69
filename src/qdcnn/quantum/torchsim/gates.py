"""The gates of :mod:`qdcnn.quantum.gates` as batched, differentiable torch matrices.

Same names, angles and conventions (Qiskit's ``RY``, ``RX``, ``RZ``, ``P``;
PennyLane's ``Rot``); the tests check every gate of
:data:`qdcnn.quantum.circuits.GATE_NAMES` against its NumPy matrix. Angles have
shape ``S + (count,)`` (``count`` = :data:`qdcnn.quantum.gates.ANGLE_COUNT`) and the
result ``S + (2, 2)``. Real gates (``ry``, ``h``, ``x``, ``z``) stay real, so a circuit
made only of them is simulated in real arithmetic.
"""

from __future__ import annotations

from collections.abc import Callable

from qdcnn._optional import require
from qdcnn.quantum import gates as np_gates

require("torch", "the PyTorch quantum simulator")
import torch  # noqa: E402

from qdcnn.quantum.torchsim._constants import cached_constant  # noqa: E402

_REAL_GATES = frozenset({"ry", "h", "x", "z"})

# (phi, theta, omega) -> ((phi + omega) / 2, theta / 2, (phi - omega) / 2)
_ROT_HALVES = ((0.5, 0.0, 0.5), (0.0, 0.5, 0.0), (0.5, 0.0, -0.5))


def complex_dtype(real: torch.dtype) -> torch.dtype:
    """``complex64`` for ``float32`` parameters, ``complex128`` for ``float64``."""
    return torch.complex64 if real == torch.float32 else torch.complex128


def _square(entries: list[torch.Tensor]) -> torch.Tensor:
    m = torch.stack(entries, dim=-1)
    return m.reshape(*m.shape[:-1], 2, 2)


def _ry(a: torch.Tensor) -> torch.Tensor:
    half = a[..., 0] * 0.5
    c, s = torch.cos(half), torch.sin(half)
    return _square([c, -s, s, c])


def _rx(a: torch.Tensor) -> torch.Tensor:
    half = a[..., 0] * 0.5
    c, s = torch.cos(half), torch.sin(half)
    zero = torch.zeros_like(c)
    return torch.complex(_square([c, zero, zero, c]), _square([zero, -s, -s, zero]))


def _rz(a: torch.Tensor) -> torch.Tensor:
    half = a[..., 0] * 0.5
    c, s = torch.cos(half), torch.sin(half)
    zero = torch.zeros_like(c)
    return torch.complex(_square([c, zero, zero, c]), _square([-s, zero, zero, s]))


def _phase(a: torch.Tensor) -> torch.Tensor:
    t = a[..., 0]
    c, s = torch.cos(t), torch.sin(t)
    zero, one = torch.zeros_like(c), torch.ones_like(c)
    return torch.complex(_square([one, zero, zero, c]), _square([zero, zero, zero, s]))


@cached_constant(16)
def _rot_tables(dtype: torch.dtype, device: torch.device) -> tuple[torch.Tensor, torch.Tensor]:
    halves = torch.tensor(_ROT_HALVES, dtype=dtype, device=device)
    # entries as signed products: re = (c ca, -s cb, s cb, c ca), im = (-c sa, -s sb, -s sb, c sa)
    signs = torch.tensor([[1, -1, 1, 1], [-1, -1, -1, 1]], dtype=dtype, device=device)
    return halves, signs


# index into [cos a, cos h, cos b, sin a, sin h, sin b] (a, h, b = the three half angles)
_ROT_LEFT = (1, 4, 4, 1, 1, 4, 4, 1)  # c, s, s, c, c, s, s, c
_ROT_RIGHT = (0, 2, 2, 0, 3, 5, 5, 3)  # ca, cb, cb, ca, sa, sb, sb, sa


def _rot(a: torch.Tensor) -> torch.Tensor:
    # one matmul gives the three half-angle combinations, one cos and one sin their
    # trigonometry; two gathers and two products give all eight real entries
    halves, signs = _rot_tables(a.dtype, a.device)
    h = a @ halves
    trig = torch.cat([torch.cos(h), torch.sin(h)], dim=-1)
    left, right = _gather(trig, _ROT_LEFT), _gather(trig, _ROT_RIGHT)
    parts = (left * right).view(*a.shape[:-1], 2, 4) * signs
    return torch.complex(parts[..., 0, :], parts[..., 1, :]).view(*a.shape[:-1], 2, 2)


def _gather(t: torch.Tensor, index: tuple[int, ...]) -> torch.Tensor:
    return t.index_select(-1, _index(index, t.device))


@cached_constant(16)
def _index(index: tuple[int, ...], device: torch.device) -> torch.Tensor:
    return torch.tensor(index, dtype=torch.long, device=device)


PARAMETRIC: dict[str, Callable[[torch.Tensor], torch.Tensor]] = {
    "ry": _ry,
    "rx": _rx,
    "rz": _rz,
    "p": _phase,
    "rot": _rot,
}


def gate_matrices(name: str, angles: torch.Tensor | None, like: torch.Tensor) -> torch.Tensor:
    """Matrices of one-qubit gate ``name``, shape ``S + (2, 2)``.

    Parameters
    ----------
    name : str
        A one-qubit gate name.
    angles : Tensor or None
        ``S + (count,)`` angles for a parametric gate; ``None`` for a constant one.
    like : Tensor
        Gives the real dtype and the device (and, for a constant gate, ``S`` is ``(1,)``).
    """
    if name in PARAMETRIC:
        assert angles is not None
        return PARAMETRIC[name](angles)
    m = np_gates.CONSTANT[name]
    dtype = like.dtype if name in _REAL_GATES else complex_dtype(like.dtype)
    return torch.as_tensor(m, dtype=dtype, device=like.device)[None]
