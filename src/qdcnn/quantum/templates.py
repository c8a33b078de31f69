"""Circuit templates of the quantum layers, written once for every backend.

Each function returns a :class:`~qdcnn.quantum.circuits.CircuitTemplate`: the NumPy
simulators, Qiskit and the exporters use ``template.bind(inputs, weights)``; the
PyTorch simulator and the ``torch.nn`` layers of :mod:`qdcnn.models.quantum_layers`
evaluate the same template on tensors.

* :func:`head_template`: angle encoding ``RY(x_i)`` on qubit ``i`` (PennyLane's
  ``AngleEmbedding(rotation="Y")``), then ``L`` layers of PennyLane's
  ``StronglyEntanglingLayers`` (``Rot`` on every qubit, then ``CX(i, (i + r) mod n)``
  with ``r = (l mod (n - 1)) + 1``), optionally re-uploading the encoding before
  every layer. :func:`head_circuit` and :func:`head_readout` are its inspection side.
* :func:`random_layers_template`: ``RY`` encoding then PennyLane's ``RandomLayers``
  (the quanvolution of Henderson et al. 2019), drawn with PennyLane's own sampling.
* :func:`uu_fidelity_template`: the paper's UU-dagger test on one qubit per feature.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn._validation import check_choice
from qdcnn.errors import ParameterError
from qdcnn.quantum.circuits import (
    CircuitBatch,
    CircuitTemplate,
    TemplateBuilder,
    check_num_qubits,
    cnot_ring,
)
from qdcnn.quantum.noise import NoiseSpec
from qdcnn.quantum.simulator import probabilities as numpy_probabilities


def _positive(name: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise ParameterError(name, value, "a positive integer")
    return int(value)


def entangler_ranges(num_qubits: int, num_layers: int) -> tuple[int, ...]:
    """PennyLane's default ``StronglyEntanglingLayers`` ranges: ``(l mod (n - 1)) + 1``.

    One qubit has no entangler; its ranges are 0 (PennyLane's convention).
    """
    if num_qubits == 1:
        return (0,) * num_layers
    return tuple((layer % (num_qubits - 1)) + 1 for layer in range(num_layers))


#: The head's two-qubit gates: PennyLane's default ``CX`` or ``CZ`` (its ``imprimitive``).
ENTANGLERS = ("cx", "cz")


def head_template(
    num_qubits: int,
    num_layers: int,
    *,
    reupload: bool = False,
    entangle: bool = True,
    entangler: str = "cx",
) -> CircuitTemplate:
    """The quantum head's circuit; inputs ``x`` (``n``), weights ``(L, n, 3)`` flattened.

    Weight slot ``n + 3 (l n + i) + k`` is angle ``k`` (``phi, theta, omega``) of the
    ``Rot`` on qubit ``i`` in layer ``l``: PennyLane's weight shape, row-major. With
    ``reupload=False`` this is exactly ``AngleEmbedding(x, rotation="Y")`` followed by
    ``StronglyEntanglingLayers(weights)``. ``entangle=False`` leaves out every CNOT: the
    state stays a product state (the head's no-entanglement ablation). ``entangler="cz"``
    puts ``CZ`` on the CNOT ring's pairs (``imprimitive=qml.CZ``): ``CZ`` is diagonal, so
    with layer angles at zero the read-out ``<Z_i>`` is the encoding's, as without
    entanglement, and the layers' angles decide how much the entanglement acts; a ring of
    ``CX`` rewrites every ``Z_i`` into a parity of several qubits whatever the angles.

    Examples
    --------
    >>> t = head_template(2, 1)
    >>> [(g.name, g.qubits, g.slots) for g in t.gates]  # doctest: +NORMALIZE_WHITESPACE
    [('ry', (0,), (0,)), ('ry', (1,), (1,)), ('rot', (0,), (2, 3, 4)),
     ('rot', (1,), (5, 6, 7)), ('cx', (0, 1), ()), ('cx', (1, 0), ())]
    """
    n = check_num_qubits(num_qubits)
    layers = _positive("num_layers", num_layers)
    entangler = check_choice("entangler", entangler, ENTANGLERS)
    b = TemplateBuilder(n, num_inputs=n, num_weights=3 * layers * n)
    for layer, r in enumerate(entangler_ranges(n, layers)):
        if layer == 0 or reupload:
            for q in range(n):
                b.ry(q, q)
        for q in range(n):
            b.rot(q, n + 3 * (layer * n + q))
        if n > 1 and entangle:
            b.ring(r, entangler)
    name = "qdcnn_head" + ("_reupload" if reupload else "")
    name += ("_cz" if entangler == "cz" else "") if entangle else "_product"
    return b.build(name)


def _head_shapes(
    x: ArrayLike, weights: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``x`` as ``(B, n)`` and ``weights`` as ``(L, n, 3)``, checked against each other."""
    xa = np.atleast_2d(np.asarray(x, dtype=np.float64))
    if xa.ndim != 2 or xa.shape[1] < 1:
        raise ParameterError("x", f"shape {np.shape(x)}", "(n,) or (B, n) angles")
    n = xa.shape[1]
    w = np.asarray(weights, dtype=np.float64)
    if w.size == 0 or w.size % (3 * n):
        raise ParameterError("weights", f"shape {w.shape}", f"(L, {n}, 3) or L * {3 * n} values")
    return xa, w.reshape(-1, n, 3)


def head_circuit(
    x: ArrayLike,
    weights: ArrayLike,
    *,
    reupload: bool = False,
    entangle: bool = True,
    entangler: str = "cx",
) -> CircuitBatch:
    """The head's circuits for encoded angles ``x`` ``(B, n)`` and ``weights`` ``(L, n, 3)``.

    ``weights`` may also be flat, ``L x n x 3`` in that order. The result draws with
    :func:`qdcnn.quantum.export.draw_text` and exports with
    :func:`qdcnn.quantum.export.write_qasm3` (``index`` picks the sample).
    """
    xa, w = _head_shapes(x, weights)
    template = head_template(
        xa.shape[1], w.shape[0], reupload=reupload, entangle=entangle, entangler=entangler
    )
    return template.bind(xa, w.ravel())


def head_readout(
    x: ArrayLike,
    weights: ArrayLike,
    *,
    reupload: bool = False,
    noise: NoiseSpec | None = None,
    entangler: str = "cx",
) -> dict[str, NDArray[np.float64]]:
    """Exact read-out of the head's circuits with the NumPy simulator.

    Returns
    -------
    dict
        ``probabilities`` ``(B, 2**n)`` (index = basis state, qubit 0 the least
        significant bit, as in Qiskit) and ``expectations`` ``(B, n)``, ``<Z_i>`` per qubit.
    """
    circuits = head_circuit(x, weights, reupload=reupload, entangler=entangler)
    probs = numpy_probabilities(circuits, noise)
    return {"probabilities": probs, "expectations": z_expectations(probs)}


def z_expectations(probs: NDArray[np.float64]) -> NDArray[np.float64]:
    """``<Z_q>`` per qubit from probabilities ``(B, 2**n)`` (qubit 0 = LSB)."""
    n = int(np.log2(probs.shape[-1]))
    idx = np.arange(2**n)[:, None]
    signs = 1.0 - 2.0 * ((idx >> np.arange(n)[None, :]) & 1)
    return np.asarray(probs @ signs, dtype=np.float64)


ROTATIONS = ("rx", "ry", "rz")


def random_layer_gates(
    num_qubits: int,
    num_layers: int,
    num_rotations: int,
    *,
    seed: int = 42,
    ratio_imprim: float = 0.3,
) -> list[tuple[str, tuple[int, ...], int | None]]:
    """The gates of PennyLane's ``RandomLayers``: ``(name, qubits, weight index or None)``.

    Draws exactly as ``qml.RandomLayers(weights, wires=range(n), ratio_imprim,
    seed=seed)`` with weights of shape ``(num_layers, num_rotations)``: per layer, while
    rotations remain, a CNOT on two random qubits with probability ``ratio_imprim``,
    otherwise a random RX/RY/RZ on a random qubit taking the next weight.
    """
    n = check_num_qubits(num_qubits)
    layers, rotations = (
        _positive("num_layers", num_layers),
        _positive("num_rotations", num_rotations),
    )
    if not 0.0 <= ratio_imprim < 1.0:
        raise ParameterError("ratio_imprim", ratio_imprim, "a probability in [0, 1)")
    rng = np.random.default_rng(seed)
    gates: list[tuple[str, tuple[int, ...], int | None]] = []
    for layer in range(layers):
        i = 0
        while i < rotations:
            if rng.random() > ratio_imprim:
                name = str(rng.choice(ROTATIONS))
                wire = int(rng.choice(n, size=1, replace=False)[0])
                gates.append((name, (wire,), layer * rotations + i))
                i += 1
            elif n > 1:
                pair = rng.choice(n, size=2, replace=False)
                gates.append(("cx", (int(pair[0]), int(pair[1])), None))
    return gates


def random_layers_template(
    num_qubits: int = 4,
    num_layers: int = 1,
    num_rotations: int | None = None,
    *,
    seed: int = 42,
    ratio_imprim: float = 0.3,
) -> CircuitTemplate:
    """``RY(input_i)`` on qubit ``i``, then :func:`random_layer_gates` on the weights.

    The quanvolution circuit of PennyLane's demo uses ``input_i = pi x_i``, four qubits,
    one layer of four rotations (``num_rotations`` defaults to ``num_qubits``).
    """
    n = check_num_qubits(num_qubits)
    rotations = n if num_rotations is None else num_rotations
    gates = random_layer_gates(n, num_layers, rotations, seed=seed, ratio_imprim=ratio_imprim)
    b = TemplateBuilder(n, num_inputs=n, num_weights=num_layers * rotations)
    for q in range(n):
        b.ry(q, q)
    for name, qubits, w in gates:
        b.add(name, qubits, () if w is None else (n + w,))
    return b.build(f"random_layers_seed{seed}")


def uu_fidelity_template(num_features: int = 1) -> CircuitTemplate:
    """The UU-dagger test on one qubit per feature: ``RY(theta_c)`` then ``RY(-theta_x)``.

    Inputs are the negated test angles ``-theta_x`` (one per feature), weights the
    centroid angles; ``P(0...0) = prod_f cos^2((theta_c,f - theta_x,f) / 2)``, the
    fidelity of the two product states (paper Alg. 1 for one feature).
    """
    n = check_num_qubits(num_features)
    b = TemplateBuilder(n, num_inputs=n, num_weights=n)
    for q in range(n):
        b.ry(q, n + q)
    for q in range(n):
        b.ry(q, q)
    return b.build("uu_dagger")


__all__ = [
    "ROTATIONS",
    "cnot_ring",
    "entangler_ranges",
    "head_circuit",
    "head_readout",
    "head_template",
    "random_layer_gates",
    "random_layers_template",
    "uu_fidelity_template",
    "z_expectations",
]
