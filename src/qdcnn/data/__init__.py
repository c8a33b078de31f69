"""Data: image input and output, recordings, labels, splits, videos and synthetic drives.

=================  =================================================================
``frames``         :class:`FrameSet` and :func:`load_frameset` (``udacity:``, ``carla:``,
                   ``synthetic:`` specs, ``@unit=,threshold=`` suffixes), :func:`stack_images`
``images``         reading and writing images and masks, with one-line errors
``udacity``        Udacity ``driving_log.csv`` + ``IMG/`` recordings
``carla``          CARLA-style image folders with steering labels
``labels``         direction labels from smoothed steering, steering units
``splits``         :class:`ContiguousKFold`, the one splitter, and validation splits
``shadow_set``     shadow sets of ``images/`` + ``masks/``
``synthetic``      the road-scene generator with exact ground truth
``writers``        the real layouts (Udacity, shadow set, CARLA, video), streamed
``video``          video files in and out (PyAV or OpenCV's FFmpeg)
=================  =================================================================
"""

from qdcnn._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "frames": [
            "FrameSet",
            "DataSpec",
            "load_frameset",
            "parse_spec",
            "parse_data_spec",
            "resolve_quantile_threshold",
            "stack_images",
        ],
        "images": ["read_image", "read_mask", "write_image", "write_mask", "list_images"],
        "udacity": ["load_udacity"],
        "carla": ["load_carla"],
        "labels": [
            "DIRECTIONS",
            "Quantile",
            "direction_labels",
            "label_directions",
            "class_balance",
        ],
        "splits": ["ContiguousKFold", "validation_split"],
        "shadow_set": ["load_shadow_set"],
        "synthetic": [
            "PRESETS",
            "generate_scene",
            "generate_scenes",
            "generate_drive",
            "iter_drive",
        ],
        "writers": [
            "write_udacity",
            "write_shadow_set",
            "write_carla",
            "write_video",
            "write_layouts",
        ],
        "video": ["VideoReader", "VideoWriter"],
        "recording": ["Recording"],
    },
)
