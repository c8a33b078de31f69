"""Vision stage: shadow detectors and removal, lane preprocessing, grouping, metrics.

=====================  ============================================================
``shadows``            the block-wise UU-dagger shadow detector and its model file
``detectors``          every shadow detector behind one function and one registry
``baselines``          the classical detectors (IBT, CBS, LBP)
``shadow_training``    training the UU-dagger centroid (propagation algorithm)
``removal``            replacing shadow pixels with road pixels
``lanes``              smoothing, Canny, ROI and Hough segments
``camera``             horizon, vanishing point and hood of a recording (``--lanes auto``)
``marks``              white and yellow lane-mark evidence
``grouping``           segments into two lines (image-split, k-means, spectral)
``tracking``           lines smoothed across frames
``overlays``           pictures of what the stages found
``metrics``            balanced error rate and friends
=====================  ============================================================
"""

from qdcnn._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "shadows": ["detect_shadows_uu", "ShadowModel"],
        "detectors": ["detect_shadows", "SHADOW_DETECTORS"],
        "baselines": ["detect_ibt", "detect_cbs", "detect_lbp"],
        "shadow_training": ["train_shadow_model", "train_multi_shadow_model"],
        "removal": ["remove_shadows"],
        "lanes": ["detect_segments"],
        "camera": ["estimate_camera", "CameraGeometry"],
        "marks": ["marking_mask"],
        "grouping": ["group_segments", "LaneFeatures"],
        "tracking": ["LaneTracker"],
        "overlays": ["draw_lane_overlay", "draw_shadow_overlay"],
        "metrics": ["shadow_scores", "confusion_counts"],
    },
)
