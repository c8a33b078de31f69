"""The paper's printed values, as data: the numbers a reproduction is compared against.

Every value is copied from ``shared/paper/qdcnn-paper.tex`` (tables and the text of
Sec. III) and NOTES section 8; nothing here is computed. Keys are the names qdcnn uses:
dataset labels ``track1``, ``track2``, ``carla`` and the registered method names of
:mod:`qdcnn.direction.methods` (the paper's DNN is ``dnn-resnet50``).

Where the paper's text and its table disagree, the table is kept and the text's value is
listed in :data:`TEXT_DISAGREES` (Table I vs Sec. III-C and III-D).

Examples
--------
>>> ACCURACY["track1"]["image-split-uu"], ACCURACY["carla"]["spectral-vqc"]
(0.7, 0.6)
>>> TIMING_SECONDS["qdcnn"]["kind"]
'estimate'
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "ACCURACY",
    "CNN_TRAINING",
    "COMPARISON",
    "DATASET_LABELS",
    "DATASET_TITLES",
    "NOISE_POINTS",
    "NOISE_TEXT",
    "TABLE_OF_LABEL",
    "TEXT_DISAGREES",
    "TIMING_SECONDS",
    "paper_accuracy",
]

#: Dataset labels of the paper, in its order.
DATASET_LABELS: tuple[str, ...] = ("track1", "track2", "carla")
#: How the paper names them.
DATASET_TITLES: dict[str, str] = {
    "track1": "Track 1",
    "track2": "Track 2",
    "carla": "CARLA",
}
#: The accuracy table of each dataset: Table I (Track 1 and 2), Table III (CARLA).
TABLE_OF_LABEL: dict[str, str] = {"track1": "Table I", "track2": "Table I", "carla": "Table III"}

#: Direction accuracy, Table I (tab:my_labl) and Table III (tab:my_label_carla).
ACCURACY: dict[str, dict[str, float]] = {
    "track1": {
        "dnn-resnet50": 0.57,
        "image-split-uu": 0.70,
        "image-split-vqc": 0.33,
        "kmeans-vqc": 0.36,
        "spectral-vqc": 0.40,
        "kmeans-uu": 0.36,
        "spectral-uu": 0.40,
    },
    "track2": {
        "dnn-resnet50": 0.70,
        "image-split-uu": 0.40,
        "image-split-vqc": 0.60,
        "kmeans-vqc": 0.50,
        "spectral-vqc": 0.50,
        "kmeans-uu": 0.36,
        "spectral-uu": 0.33,
    },
    "carla": {
        "spectral-vqc": 0.60,
        "image-split-vqc": 0.41,
        "kmeans-vqc": 0.50,
        "image-split-uu": 0.23,
        "kmeans-uu": 0.20,
        "spectral-uu": 0.20,
    },
}

#: The DNN (ResNet-50) training of Fig. 5 as the text of Sec. III-C and III-D states it.
CNN_TRAINING: dict[str, dict[str, float]] = {
    "track1": {"epochs": 25, "final_train_accuracy": 0.38, "final_val_accuracy": 0.58},
    "track2": {
        "epochs": 25,
        "first_train_loss": 1.1598,
        "first_train_accuracy": 0.55,
        "first_val_loss": 0.1094,
        "first_val_accuracy": 0.705,
        "final_train_loss": 0.7930,
        "final_train_accuracy": 0.58,
        "final_val_loss": 0.0473,
        "final_val_accuracy": 0.70,
    },
}

#: (dataset, method) -> the value the paper's text gives where it differs from its table.
TEXT_DISAGREES: dict[tuple[str, str], float] = {
    ("track1", "spectral-uu"): 0.33,  # Sec. III-C: "spectral clustering-UU ... 0.33"
    ("track2", "kmeans-uu"): 0.33,  # Sec. III-D: "k-means-UU and spectral ... 0.33 and 0.36"
    ("track2", "spectral-uu"): 0.36,
}

#: Table II (comparison): other papers' methods on "similar datasets", in percent.
COMPARISON: tuple[dict[str, Any], ...] = (
    {"algorithm": "DQN-PF [REDA2024104630]", "percent": 88.62, "ours": False},
    {"algorithm": "RL-MOHH [REDA2024104630]", "percent": 80.0, "ours": False},
    {"algorithm": "UU\u2020 (the paper's)", "percent": 70.56, "ours": True},
    {"algorithm": "Novel CNN based model [abc]", "percent": 99.56, "ours": False},
)

#: Table IV (tabfortimecomp): seconds per frame for shadow detection. The QDCNN value is
#: not a measurement: 224,676 elements x 1000 runs x 2 gates x ~11 ps (NOTES 4).
TIMING_SECONDS: dict[str, dict[str, Any]] = {
    "ibt": {"seconds": 0.03, "kind": "measured (by the paper, hardware not stated)"},
    "cbs": {"seconds": 1.47, "kind": "measured (by the paper, hardware not stated)"},
    "lbp": {"seconds": 2.05, "kind": "measured (by the paper, hardware not stated)"},
    "qdcnn": {"seconds": 0.0049352, "kind": "estimate"},
}

#: Fig. 7 points the paper's text gives with their noise strength (Sec. III, "Effect of
#: Noise Models"): (dataset, classifier kind, channel, p, accuracy).
NOISE_POINTS: tuple[tuple[str, str, str, float, float], ...] = (
    ("track1", "uu", "amplitude-damping", 0.22, 0.766),
    ("track2", "uu", "amplitude-damping", 0.0, 0.466),
    ("track1", "vqc", "amplitude-damping", 0.11, 0.433),
    ("track1", "vqc", "phase-damping", 0.78, 0.433),
    ("track1", "vqc", "bit-flip", 0.55, 0.466),
    ("track2", "vqc", "amplitude-damping", 0.22, 0.666),
    ("track2", "vqc", "phase-damping", 0.88, 0.666),
    ("carla", "vqc", "amplitude-damping", 0.88, 0.7),
)

#: The rest of the paper's Fig. 7 text, which gives values without a strength.
NOISE_TEXT: dict[tuple[str, str], str] = {
    ("track1", "uu"): "phase damping 0.633, depolarizing 0.733 (stable); bit flip drops to "
    "0.2, bit-phase flip to 0.233",
    ("track2", "uu"): "amplitude damping 0.466 falling to 0.233; bit flip and bit-phase flip "
    "drop to 0.166",
    ("carla", "uu"): "0.233 under most channels; peaks 0.4 (amplitude damping), 0.433 (bit flip)",
    ("track1", "vqc"): "peaks 0.433 (amplitude damping p=0.11, phase damping p=0.78); bit flip "
    "peaks 0.466 at p=0.55",
    ("track2", "vqc"): "peaks 0.666 (amplitude damping p=0.22, phase damping p=0.88); 0.5-0.6 "
    "under the other channels",
    ("carla", "vqc"): "peaks 0.7 (amplitude damping p=0.88); phase damping 0.533-0.666 (peak "
    "0.633); depolarizing peak 0.666; bit flip and bit-phase flip 0.566-0.633",
}


def paper_accuracy(label: str, method: str) -> float | None:
    """The paper's accuracy of ``method`` on dataset ``label`` (``None`` if it reports none).

    Examples
    --------
    >>> paper_accuracy("track2", "dnn-resnet50"), paper_accuracy("carla", "dnn-pilotnet")
    (0.7, None)
    """
    return ACCURACY.get(label, {}).get(method)
