"""Differentiable, batched quantum simulation in PyTorch (statevector and density matrix).

Runs the circuits of :mod:`qdcnn.quantum.circuits` -- a :class:`CircuitTemplate`, or
any :class:`CircuitBatch` through :meth:`CircuitBatch.as_template` -- on torch tensors,
so gradients flow to every angle, through the noise channels of
:mod:`qdcnn.quantum.noise` too. One to :data:`MAX_QUBITS` qubits; float32 parameters
give complex64 amplitudes and float64 give complex128; CPU or CUDA, following the
parameters' device. The steps follow PennyLane's ``devices/qubit`` split: compile the
gates into steps (:mod:`.program`), apply them (:mod:`.simulate`), measure
(:mod:`.measure`).

torch is the optional ``dnn`` extra; importing this package without it raises
:class:`qdcnn.errors.MissingExtraError`.
"""

from __future__ import annotations

from functools import lru_cache

from qdcnn.quantum.circuits import CircuitTemplate
from qdcnn.quantum.noise import GateNoise
from qdcnn.quantum.torchsim.program import MAX_QUBITS, gate_channels
from qdcnn.quantum.torchsim.simulate import TorchCircuit

__all__ = ["MAX_QUBITS", "TorchCircuit", "compiled", "gate_channels"]


@lru_cache(maxsize=64)
def _cached(template: CircuitTemplate, noise: GateNoise | None) -> TorchCircuit:
    return TorchCircuit(template, noise)


def compiled(template: CircuitTemplate, noise: GateNoise | None = None) -> TorchCircuit:
    """A :class:`TorchCircuit` for ``template`` and ``noise``, cached when both are hashable."""
    try:
        return _cached(template, noise)  # type: ignore[arg-type]  # unhashable: below
    except TypeError:  # an unhashable noise object
        return TorchCircuit(template, noise)
