"""One entry point for every shadow detector: UU-dagger (intensity, chromaticity) and classical."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from qdcnn.config import ShadowConfig
from qdcnn.errors import ParameterError
from qdcnn.quantum.noise import NoiseSpec
from qdcnn.vision.baselines import detect_cbs, detect_ibt, detect_lbp
from qdcnn.vision.shadows import ShadowModel, detect_shadows_uu

#: The shadow-detector registry: name -> what it is (command line and results use the names).
SHADOW_DETECTORS: dict[str, str] = {
    "uu": "the paper's UU-dagger fidelity test on block intensity (quantum)",
    "uu-chroma": "the UU-dagger fidelity test on block chromaticity (quantum)",
    "ibt": "intensity-based thresholding (classical baseline)",
    "cbs": "chromaticity-based shadow detection (classical baseline)",
    "lbp": "local binary pattern texture detector (classical baseline)",
}
#: The names, in registry order.
_SHADOW_METHODS: tuple[str, ...] = tuple(SHADOW_DETECTORS)
#: The detectors with a simulated quantum circuit.
QUANTUM_DETECTORS = frozenset({"uu", "uu-chroma"})


def check_method(method: str) -> str:
    """Return ``method`` if it is a known shadow detector, else raise :class:`ParameterError`."""
    if method not in _SHADOW_METHODS:
        raise ParameterError("method", method, "one of " + ", ".join(SHADOW_DETECTORS))
    return method


def detect_shadows(
    image: NDArray[np.uint8],
    method: str = "uu",
    config: ShadowConfig | None = None,
    *,
    model: ShadowModel | None = None,
    backend: str = "numpy",
    noise: NoiseSpec | None = None,
    rng: int | np.random.Generator | None = None,
) -> NDArray[np.bool_]:
    """Shadow mask of ``image`` (input size) by ``method``.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3)
        RGB image.
    method : {"uu", "uu-chroma", "ibt", "cbs", "lbp"}
        UU-dagger on intensity or chromaticity (:func:`~qdcnn.vision.shadows.detect_shadows_uu`),
        or a classical baseline (:mod:`qdcnn.vision.baselines`).
    config : ShadowConfig, optional
        Settings of the UU-dagger detectors (ignored by the baselines).
    model, backend, noise, rng
        Passed to the UU-dagger detector.
    """
    check_method(method)
    if method in QUANTUM_DETECTORS:
        cfg = config or ShadowConfig()
        if method == "uu-chroma":
            cfg = replace(cfg, feature="chromaticity")
        elif model is None:
            cfg = replace(cfg, feature="intensity")
        return detect_shadows_uu(
            image, cfg, model=model, backend=backend, noise=noise, rng=rng
        ).mask
    if method == "ibt":
        return detect_ibt(image)
    if method == "cbs":
        return detect_cbs(image)
    return detect_lbp(image)
