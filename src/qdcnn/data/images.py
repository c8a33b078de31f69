"""Reading and writing images and masks, with one-line errors for bad files.

Every image qdcnn works on is an RGB ``uint8`` array of shape ``(H, W, 3)``;
masks are ``bool`` arrays of shape ``(H, W)``. Readers normalise what real
files hold: greyscale is replicated to three channels, alpha is dropped,
16-bit and float images are scaled to 8 bits.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.errors import InputError

IMAGE_SUFFIXES = frozenset(
    {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm"}
)
MAX_PIXELS = 2**27  # 134 megapixels: beyond this a road frame is almost surely a mistake
MASK_LEVEL = 128  # masks are binarised at this 8-bit level (shadow if >= 128)


def _read_bytes(path: Path) -> NDArray[np.uint8]:
    if not path.exists():
        raise InputError(path, "file not found")
    if path.is_dir():
        raise InputError(path, "is a directory, not an image file")
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except PermissionError:
        raise InputError(path, "cannot read: permission denied") from None
    except OSError as exc:
        raise InputError(path, f"cannot read: {exc.strerror or exc}") from None
    if data.size == 0:
        raise InputError(path, "empty file (0 bytes)")
    return data


def _to_uint8(img: NDArray[np.generic], path: Path) -> NDArray[np.uint8]:
    if img.dtype == np.uint8:
        return img  # type: ignore[return-value]
    if img.dtype == np.uint16:
        return (img.astype(np.uint32) * 255 // 65535).astype(np.uint8)
    if img.dtype in (np.float32, np.float64):
        f = np.nan_to_num(img.astype(np.float64), nan=0.0)
        scale = 255.0 if f.max(initial=0.0) <= 1.0 else 1.0
        return np.clip(f * scale + 0.5, 0, 255).astype(np.uint8)
    if img.dtype in (np.int8, np.int16, np.int32):
        return np.clip(img, 0, 255).astype(np.uint8)
    raise InputError(path, f"unsupported pixel type {img.dtype}")


def _decode(path: Path) -> NDArray[np.generic]:
    data = _read_bytes(path)
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise InputError(path, "not a readable image (corrupt or unsupported format)")
    if img.ndim not in (2, 3) or img.shape[0] == 0 or img.shape[1] == 0:
        raise InputError(path, f"image has an unusable shape {img.shape}")
    if img.shape[0] * img.shape[1] > MAX_PIXELS:
        raise InputError(
            path, f"image is {img.shape[1]}x{img.shape[0]}, larger than {MAX_PIXELS} pixels"
        )
    return img


def read_image(path: str | os.PathLike[str]) -> NDArray[np.uint8]:
    """Read an image file as RGB ``uint8`` of shape ``(H, W, 3)``.

    Parameters
    ----------
    path : str or path-like
        Any format OpenCV decodes (PNG, JPEG, BMP, TIFF, WebP, PPM/PGM).

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
        The image in RGB channel order.

    Raises
    ------
    InputError
        Missing, empty, unreadable, corrupt or oversized files, naming the file.
    """
    p = Path(path)
    img = _to_uint8(_decode(p), p)
    if img.ndim == 2:
        return np.ascontiguousarray(np.repeat(img[:, :, None], 3, axis=2))
    channels = img.shape[2]
    if channels == 1:
        return np.ascontiguousarray(np.repeat(img, 3, axis=2))
    if channels == 3:
        return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    if channels == 4:
        return cv2.cvtColor(img, cv2.COLOR_BGRA2RGB)
    raise InputError(p, f"unsupported number of channels ({channels})")


def read_mask(path: str | os.PathLike[str]) -> NDArray[np.bool_]:
    """Read a ground-truth mask as ``bool`` of shape ``(H, W)``, binarised at 128.

    Colour masks are converted to grey first; 16-bit masks are scaled to 8 bits.
    """
    p = Path(path)
    img = _to_uint8(_decode(p), p)
    if img.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        img = cv2.cvtColor(img, code) if img.shape[2] in (3, 4) else img[:, :, 0]
    return np.asarray(img >= MASK_LEVEL)


def write_image(path: str | os.PathLike[str], image: NDArray[np.uint8]) -> Path:
    """Write an RGB (or greyscale) ``uint8`` image; the suffix picks the format."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    arr = np.asarray(image)
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8) * 255
    if arr.ndim == 3:
        arr = cv2.cvtColor(arr, cv2.COLOR_RGB2BGR)
    ok, buf = cv2.imencode(p.suffix or ".png", arr)
    if not ok:
        raise InputError(p, "cannot encode image for this file type")
    buf.tofile(p)
    return p


def write_mask(path: str | os.PathLike[str], mask: NDArray[np.bool_]) -> Path:
    """Write a mask as a single-channel PNG with values 0 and 255."""
    return write_image(path, (np.asarray(mask, dtype=bool).astype(np.uint8) * 255))


@dataclass
class ImageListing:
    """Image files found under some paths, and what was passed over.

    Attributes
    ----------
    images : list of Path
        Files to process, in the order given (folders expanded and sorted).
    skipped : list of Path
        Files inside given folders that do not have an image suffix.
    missing : list of InputError
        Given paths that do not exist, or given files that are not image files.
    """

    images: list[Path] = field(default_factory=list)
    skipped: list[Path] = field(default_factory=list)
    missing: list[InputError] = field(default_factory=list)


def list_images(paths: Iterable[str | os.PathLike[str]], recursive: bool = False) -> ImageListing:
    """Expand files and folders into the image files to process.

    Folders contribute their files with an image suffix (sorted by name); other
    files in them go to ``skipped``. A path given explicitly must exist and
    carry an image suffix, or it is reported in ``missing``.
    """
    out = ImageListing()
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            children: Sequence[Path] = sorted(p.rglob("*") if recursive else p.iterdir())
            for child in children:
                if child.is_dir():
                    continue
                is_image = child.suffix.lower() in IMAGE_SUFFIXES
                (out.images if is_image else out.skipped).append(child)
        elif not p.exists():
            out.missing.append(InputError(p, "file not found"))
        elif p.suffix.lower() not in IMAGE_SUFFIXES:
            out.missing.append(InputError(p, f"not an image file (suffix {p.suffix or 'none'!r})"))
        else:
            out.images.append(p)
    return out
