"""The application layer: one runner per command, each a spec in and a result out.

The command line only renders results; Python callers get the same results. The library
they run lives below: :mod:`qdcnn.direction` (methods, protocol, models) and
:mod:`qdcnn.runtime` (the resumable engine, scheduler and reporter).

=====================  ============================================================
``evaluate``           ``qdcnn evaluate``
``train_direction``    ``qdcnn train-direction``
``detect_lanes``       ``qdcnn detect-lanes``
``score``              ``qdcnn score`` (a direction model on labelled data)
``shadow_batch``       ``qdcnn detect-shadows``, ``score-shadows``, ``train-shadows``
``synth``              ``qdcnn synth``
``run``                ``qdcnn run`` (videos, folders, recordings; resumable, Dask)
``noise``              ``qdcnn noise-sweep``
``circuit``            ``qdcnn circuit``
``reproduce``          ``qdcnn reproduce`` (and ``qdcnn demo``)
``shadow_bench``       ``qdcnn bench shadows``
``pipeline_bench``     ``qdcnn bench pipeline``
=====================  ============================================================
"""

from qdcnn._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "train_direction": ["TrainDirectionSpec", "train_direction"],
        "evaluate": ["EvaluationSpec", "run_evaluation", "evaluate_features", "evaluate_frames"],
        "detect_lanes": ["DetectLanesSpec", "detect_lanes"],
        "score": ["ScoreSpec", "run_score"],
        "shadow_batch": [
            "ShadowDetectionSpec",
            "run_shadow_detection",
            "ShadowTrainingSpec",
            "train_shadows",
            "score_folders",
        ],
        "synth": ["SynthSpec", "run_synth"],
        "run": ["RunSpec", "run"],
        "noise.runner": ["NoiseSweepSpec", "run_noise_sweep"],
        "circuit": ["CircuitSpec", "inspect_circuit"],
        "reproduce": ["ReproduceSpec", "run_reproduce"],
    },
)
