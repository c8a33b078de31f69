"""Noise sweeps (the paper's Fig. 7): accuracy and shadow BER against noise strength.

The package is split by concern:

- :mod:`~qdcnn.experiments.noise.options`: parsing strengths, channels, methods, groupings.
- :mod:`~qdcnn.experiments.noise.direction`: direction methods of the registry under noise.
- :mod:`~qdcnn.experiments.noise.shadow`: the UU-dagger shadow detector under noise.
- :mod:`~qdcnn.experiments.noise.results`: rows, results, tables.
- :mod:`~qdcnn.experiments.noise.plot`: the figures.
- :mod:`~qdcnn.experiments.noise.runner`: :func:`run_noise_sweep`, what ``qdcnn noise-sweep``
  calls.

Noise acts after every gate on every qubit the gate touches (:mod:`qdcnn.quantum.noise`),
which equals a Qiskit Aer ``NoiseModel`` with that error on those gates.
"""

from qdcnn.experiments.noise.direction import (
    FRAMES,
    SweepTarget,
    direction_sweep,
    fit_direction_model,
    predict_folds,
    sweep_targets,
)
from qdcnn.experiments.noise.options import (
    DIRECTION_METHODS,
    MAX_STRENGTHS,
    METHODS,
    PAPER_STRENGTHS,
    PHASE_DAMPING_FORMS,
    SHADOW_METHOD,
    SHADOW_THRESHOLD_CHOICES,
    check_grid,
    check_phase_damping_form,
    direction_methods,
    parse_channels,
    parse_groupings,
    parse_methods,
    parse_shadow_thresholds,
    parse_strengths,
    phase_damping_form,
)
from qdcnn.experiments.noise.results import (
    CHANNEL_SHORT_NAMES,
    NoiseSweepResult,
    SweepRow,
    SweepTable,
)
from qdcnn.experiments.noise.runner import NoiseSweepRun, NoiseSweepSpec, run_noise_sweep
from qdcnn.experiments.noise.shadow import (
    MAX_SHADOW_FRAMES,
    shadow_sweep,
    split_train_test,
    synthetic_shadow_set,
)

__all__ = [
    "CHANNEL_SHORT_NAMES",
    "DIRECTION_METHODS",
    "FRAMES",
    "MAX_SHADOW_FRAMES",
    "MAX_STRENGTHS",
    "METHODS",
    "PAPER_STRENGTHS",
    "PHASE_DAMPING_FORMS",
    "SHADOW_METHOD",
    "SHADOW_THRESHOLD_CHOICES",
    "NoiseSweepResult",
    "NoiseSweepRun",
    "NoiseSweepSpec",
    "SweepRow",
    "SweepTable",
    "SweepTarget",
    "check_grid",
    "check_phase_damping_form",
    "direction_methods",
    "direction_sweep",
    "fit_direction_model",
    "parse_channels",
    "parse_groupings",
    "parse_methods",
    "parse_shadow_thresholds",
    "parse_strengths",
    "phase_damping_form",
    "predict_folds",
    "run_noise_sweep",
    "shadow_sweep",
    "split_train_test",
    "sweep_targets",
    "synthetic_shadow_set",
]
