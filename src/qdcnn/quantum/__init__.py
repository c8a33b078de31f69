"""Quantum stage: batched circuits and simulators, noise, and the quantum classifiers.

=================  ================================================================
``circuits``       batched circuits and templates in one gate vocabulary
``simulator``      exact NumPy statevector and density-matrix simulation
``torchsim``       the differentiable PyTorch simulator (the ``dnn`` extra)
``execute``        one entry point: NumPy or Aer, exact or with shots
``noise``          the Kraus channels and the noise protocol
``noise_text``     noise models from their text form (``parse_noise``)
``device``         a real device's calibrated noise (offline fake backends)
``uu_dagger``      the paper's UU-dagger fidelity test
``direction``      the UU-dagger direction rule as a scikit-learn classifier
``vqc``            the paper's 2-qubit VQC as a scikit-learn classifier
``templates``      the hybrid head's circuit and other templates
``export``         drawing and OpenQASM 3
=================  ================================================================
"""

from qdcnn._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "circuits": ["CircuitBatch", "CircuitBuilder", "uu_dagger_circuit", "vqc_circuit"],
        "simulator": ["statevector", "density_matrix", "probabilities"],
        "execute": ["run_probabilities"],
        "noise": ["NoiseSpec", "CHANNELS", "PAPER_CHANNELS"],
        "noise_text": ["parse_noise"],
        "device": ["DeviceNoise"],
        "uu_dagger": ["fidelity"],
        "direction": ["UUDirectionClassifier"],
        "vqc": ["VQCClassifier"],
        "templates": ["head_circuit", "head_readout"],
        "export": ["draw_text", "write_qasm3"],
    },
)
