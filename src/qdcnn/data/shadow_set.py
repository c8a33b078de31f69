"""Shadow sets on disk: ``DIR/images/<stem>.*`` with ``DIR/masks/<stem>.*`` binary masks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from qdcnn.batch import Failure, run_batch
from qdcnn.data.images import IMAGE_SUFFIXES, read_image, read_mask, require_folder
from qdcnn.errors import InputError

__all__ = ["index_by_stem", "load_shadow_set", "require_shadow_set"]


def index_by_stem(folder: Path) -> dict[str, Path]:
    """Image files of ``folder`` by file stem, in name order."""
    return {
        p.stem: p
        for p in sorted(folder.iterdir())
        if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES
    }


def require_shadow_set(folder: Path) -> tuple[Path, Path]:
    """The ``images/`` and ``masks/`` folders of a shadow set, or an :class:`InputError`."""
    require_folder(folder, "shadow set folder")
    images_dir, masks_dir = folder / "images", folder / "masks"
    for d in (images_dir, masks_dir):
        if not d.is_dir():
            raise InputError(d, "folder not found (a shadow set has images/ and masks/)")
    return images_dir, masks_dir


def load_shadow_set(
    folder: Path,
) -> tuple[list[NDArray[np.uint8]], list[NDArray[np.bool_]], list[Failure]]:
    """Images and masks of a shadow set laid out as ``images/<stem>.*`` and ``masks/<stem>.*``.

    Pairs with an unreadable image or mask, or a missing mask, are failures; the
    others are returned.
    """
    images_dir, masks_dir = require_shadow_set(folder)
    masks = index_by_stem(masks_dir)
    images, truth = [], []

    def work(path: Path) -> tuple[NDArray[np.uint8], NDArray[np.bool_]]:
        mask_file = masks.get(path.stem)
        if mask_file is None:
            raise InputError(path, f"no mask {path.stem}.* in {masks_dir}")
        image, mask = read_image(path), read_mask(mask_file)
        if mask.shape != image.shape[:2]:
            raise InputError(
                mask_file, f"mask is {mask.shape[::-1]}, image is {image.shape[1::-1]}"
            )
        return image, mask

    failures = []
    for outcome in run_batch(list(index_by_stem(images_dir).values()), work):
        if outcome.result is not None:
            images.append(outcome.result[0])
            truth.append(outcome.result[1])
        elif outcome.failure is not None:
            failures.append(outcome.failure)
    if not images:
        raise InputError(folder, "no usable image/mask pairs")
    return images, truth, failures
