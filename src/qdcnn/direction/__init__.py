"""The direction domain: from a road frame to left / straight / right.

=====================  ============================================================
``methods``            the direction-method registry (each hybrid with its twin)
``protocol``           contiguous folds with a gap, inner search, pooled scores
``features``           lane features of a dataset (cached by ``feature_cache``)
``lane_data``          the one recipe from a dataset to lane features and labels
``model``              :class:`DirectionModel`: a fitted method with its settings
``builtin``            the built-in direction model (no ``--model``)
``processor``          the per-frame processor the runtime engine is handed
``scores``             accuracy, balanced accuracy, macro-F1; block-bootstrap intervals
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
        "model": ["DirectionModel", "train_direction_model"],
        "builtin": ["default_direction_model", "describe_default_model"],
        "processor": ["LaneDirectionProcessor"],
        "scores": ["Scores", "block_bootstrap", "paired_difference", "score"],
    },
)
