"""Training samples of the CNN direction classifiers, in NumPy (no torch needed).

- :func:`context_windows`: which frames make up each sample when K consecutive
  frames are stacked along channels (``context=K``);
- :class:`ExtraView` and :func:`side_camera_views`: further camera views of the
  same frames (Udacity's left and right cameras) with corrected labels, added to
  the training samples of the frames they accompany, never to validation;
- :func:`split_train_val`: the contiguous validation blocks, fenced by gaps,
  that early stopping judges on;
- :func:`class_weights`: scikit-learn's balanced class weights.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from qdcnn._validation import check_float, check_int
from qdcnn.data.labels import DIRECTIONS, LEFT, RIGHT
from qdcnn.errors import InputError

N_CLASSES = len(DIRECTIONS)
#: Steering added to the left camera's frames and taken from the right camera's (the
#: usual Udacity-simulator value, in the recording's steering unit).
_SIDE_CAMERA_CORRECTION = 0.2


def context_windows(n: int, context: int) -> NDArray[np.int64]:
    """Frame indices of each of ``n`` samples that stack ``context`` consecutive frames.

    Sample ``i`` is frames ``i - K + 1, ..., i`` (oldest first); before the first
    frame, frame 0 repeats.

    Examples
    --------
    >>> context_windows(4, 3).tolist()
    [[0, 0, 0], [0, 0, 1], [0, 1, 2], [1, 2, 3]]
    """
    check_int("context", context, 1)
    lags = np.arange(context - 1, -1, -1, dtype=np.int64)
    return np.maximum(np.arange(n, dtype=np.int64)[:, None] - lags[None, :], 0)


def stack_context(images: NDArray[np.uint8], context: int) -> NDArray[np.uint8]:
    """Stack each frame with the ``context - 1`` before it along the colour axis.

    Parameters
    ----------
    images : (N, H, W, 3) uint8 ndarray
        Frames in recording order.
    context : int
        Frames per sample, K.

    Returns
    -------
    (N, H, W, 3K) uint8 ndarray
        Channels ``3j .. 3j + 2`` of sample ``i`` are frame ``max(i - K + 1 + j, 0)``.
    """
    windows = context_windows(len(images), context)
    stacked = images[windows]  # (N, K, H, W, 3)
    n, k, h, w, c = stacked.shape
    return np.ascontiguousarray(stacked.transpose(0, 2, 3, 1, 4).reshape(n, h, w, k * c))


@dataclass(frozen=True)
class ExtraView:
    """Another view of every training frame, with its own labels (a side camera).

    Frame ``i`` of ``images`` was taken at the same time as frame ``i`` of the
    images it accompanies; it trains only when that frame trains (never when the
    frame validates), with ``labels[i]``.

    Attributes
    ----------
    images : (N, H, W, 3) uint8 ndarray
    labels : (N,) int64 ndarray
        0 = left, 1 = straight, 2 = right.
    name : str
        For messages (``"left camera"``).
    """

    images: NDArray[np.uint8]
    labels: NDArray[np.int64]
    name: str = "extra view"


def side_camera_views(
    left: NDArray[np.uint8],
    right: NDArray[np.uint8],
    steering: ArrayLike,
    label_fn: Callable[[NDArray[np.float64]], ArrayLike],
    *,
    correction: float = _SIDE_CAMERA_CORRECTION,
) -> tuple[ExtraView, ExtraView]:
    """Left and right camera frames as extra training views with corrected labels.

    A side camera sees the road as if the car had drifted to that side, so the
    steering that brings it back is the recorded one plus ``correction`` for the
    left camera and minus it for the right camera (steering positive to the right,
    as Udacity's). The direction labels are recomputed from the corrected steering
    by ``label_fn`` (for example :func:`qdcnn.data.labels.direction_labels` with
    the recording's timestamps), exactly as for the centre camera.

    Parameters
    ----------
    left, right : (N, H, W, 3) uint8 ndarray
        Side-camera frames, aligned with the centre frames.
    steering : (N,) array
        Recorded steering of the centre frames.
    label_fn : callable
        Steering ``(N,)`` to labels ``(N,)``.
    correction : float
        Steering correction, in the recording's steering unit (default 0.2).

    Examples
    --------
    >>> frames = np.zeros((3, 4, 4, 3), np.uint8)
    >>> to_label = lambda s: np.digitize(s, [-0.1, 0.1])
    >>> left, right = side_camera_views(frames, frames, [0.0, -0.15, 0.15], to_label)
    >>> left.labels.tolist(), right.labels.tolist()
    ([2, 1, 2], [0, 0, 1])
    """
    correction = check_float("correction", correction, 0.0, 10.0)
    steer = np.asarray(steering, dtype=np.float64)
    views = []
    for name, images, sign in (("left camera", left, 1.0), ("right camera", right, -1.0)):
        if len(images) != len(steer):
            raise InputError(name, f"{len(images)} frames for {len(steer)} steering values")
        labels = np.asarray(label_fn(steer + sign * correction))
        if labels.shape != steer.shape:
            raise InputError(
                name, f"label_fn returned shape {labels.shape} for {len(steer)} steering values"
            )
        views.append(ExtraView(images, labels.astype(np.int64), name))
    return views[0], views[1]


def class_weights(labels: NDArray[np.int64], *, mirrored: bool = False) -> NDArray[np.float64]:
    """Balanced class weights ``n / (k * n_c)`` (scikit-learn's rule); 0 for absent classes.

    Parameters
    ----------
    labels : (N,) int ndarray
        Training labels, 0 = left, 1 = straight, 2 = right.
    mirrored : bool
        Count left and right as the flip augmentation sees them: each half of
        ``n_left + n_right``, so frames flipped into a rare class are not over-weighted.

    Examples
    --------
    >>> class_weights(np.array([0, 1, 1, 1]))
    array([2.        , 0.66666667, 0.        ])
    >>> class_weights(np.array([0, 1, 1, 1]), mirrored=True)
    array([2.66666667, 0.44444444, 2.66666667])
    """
    counts = np.bincount(labels, minlength=N_CLASSES).astype(np.float64)
    if mirrored:
        counts[LEFT] = counts[RIGHT] = (counts[LEFT] + counts[RIGHT]) / 2
    present = counts > 0
    weights = np.zeros(N_CLASSES)
    weights[present] = len(labels) / (present.sum() * counts[present])
    return weights


def split_train_val(
    n: int, val_fraction: float, *, blocks: int = 1, gap: int = 0
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Training and validation frames for early stopping (see :func:`validation_split`).

    :func:`qdcnn.data.splits.validation_split`: ``val_fraction`` of the frames validate
    as ``blocks`` contiguous blocks of the one splitter the evaluation protocol uses
    (:class:`qdcnn.data.splits.ContiguousKFold`), fenced by ``gap`` frames on each side.
    """
    from qdcnn.data.splits import validation_split

    return validation_split(n, val_fraction, blocks=blocks, gap=gap)
