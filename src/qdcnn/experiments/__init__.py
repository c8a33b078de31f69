"""The application layer: one runner per command, the method registry, the protocol.

Every runner takes a spec object and returns a result object; the command line only
renders them, and Python callers get the same results.

=====================  ============================================================
``methods``            the direction-method registry
``protocol``           contiguous folds with a gap, inner search, pooled scores
``lane_data``          the one recipe from a dataset to lane features and labels
``evaluate``           ``qdcnn evaluate``
``direction_model``    ``qdcnn train-direction`` and the model file
``detect_lanes``       ``qdcnn detect-lanes``
``default_model``      the built-in direction model (no ``--model``)
``shadow_batch``       ``qdcnn detect-shadows``, ``score-shadows``, ``train-shadows``
``synth``              ``qdcnn synth``
``run``                ``qdcnn run`` (videos, folders, recordings; resumable, Dask)
``noise``              ``qdcnn noise-sweep``
``circuit``            ``qdcnn circuit``
``reproduce``          ``qdcnn reproduce`` (and ``qdcnn demo``)
``reporting``          the :class:`Reporter` runners report through
=====================  ============================================================
"""

from qdcnn._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "methods": [
            "DirectionMethod",
            "TrainingOptions",
            "get_method",
            "method_names",
            "register",
            "select_methods",
        ],
        "protocol": ["cross_validate", "fit_with_search", "pooled_accuracy", "majority_baseline"],
        "lane_data": ["LaneData", "load_lane_data"],
        "evaluate": ["EvaluationSpec", "run_evaluation", "evaluate_features", "evaluate_frames"],
        "direction_model": ["DirectionModel", "TrainDirectionSpec", "train_direction"],
        "detect_lanes": ["DetectLanesSpec", "detect_lanes"],
        "default_model": ["default_direction_model", "describe_default_model"],
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
        "reporting": ["Reporter"],
    },
)
