"""Random circuits that use every gate of the vocabulary (a helper module, not a test)."""

from __future__ import annotations

import numpy as np

from qdcnn.quantum.circuits import GATE_NAMES, CircuitBatch, CircuitBuilder

ANGLE_GATES = ("ry", "rx", "rz", "p")


def random_all_gates_circuit(
    rng: np.random.Generator, num_qubits: int, batch: int, n_gates: int = 30
) -> CircuitBatch:
    """``n_gates`` random gates, then one of every gate kind so that none is missing.

    Angles are per circuit or shared at random; ``cx``/``cz`` act on random ordered pairs.
    """
    b = CircuitBuilder(num_qubits, batch)
    names = sorted(GATE_NAMES) if num_qubits > 1 else sorted(GATE_NAMES - {"cx", "cz"})
    kinds = list(rng.choice(names, n_gates)) + names
    for kind in kinds:
        q = int(rng.integers(num_qubits))
        shape = (batch,) if rng.random() < 0.6 else ()
        if kind in ANGLE_GATES:
            b.add(str(kind), (q,), rng.uniform(-2 * np.pi, 2 * np.pi, shape))
        elif kind == "rot":
            b.add("rot", (q,), rng.uniform(-2 * np.pi, 2 * np.pi, (*shape, 3)))
        elif kind in ("cx", "cz"):
            a, c = rng.choice(num_qubits, 2, replace=False)
            b.add(str(kind), (int(a), int(c)))
        else:
            b.add(str(kind), (q,))
    return b.build("all_gates")
