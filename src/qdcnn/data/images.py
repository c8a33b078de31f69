"""Reading and writing images and masks, with one-line errors for bad files.

Every image qdcnn works on is an RGB ``uint8`` array of shape ``(H, W, 3)``;
masks are ``bool`` arrays of shape ``(H, W)``. Readers normalise what real
files hold: greyscale is replicated to three channels, alpha is dropped,
16-bit and float images are scaled to 8 bits.
"""

from __future__ import annotations

import io
import os
import stat
import warnings
import zlib
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn._fileio import atomic_write_bytes
from qdcnn._validation import has_shape
from qdcnn.errors import InputError

IMAGE_SUFFIXES = frozenset(
    {".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".ppm", ".pgm"}
)
#: Largest image accepted, in pixels (width x height), checked from the file header before
#: decoding: a road frame this large is almost surely a mistake or a decompression bomb.
MAX_PIXELS = 100_000_000
#: Largest image file read into memory (a 100-megapixel 16-bit RGB TIFF is 600 MB).
MAX_FILE_BYTES = 2**30
MASK_LEVEL = 128  # masks are binarised at this 8-bit level (shadow if >= 128)
#: Pillow header parsers of the formats qdcnn reads (Pillow's PPM parser covers PGM).
_HEADER_FORMATS = ("PNG", "JPEG", "BMP", "TIFF", "WEBP", "PPM")
_UNREADABLE = "not a readable image (corrupt or unsupported format)"

PathArg = str | bytes | os.PathLike[str] | os.PathLike[bytes]


def _as_path(path: PathArg) -> Path:
    """``path`` as a :class:`~pathlib.Path`; ``bytes`` names are decoded as the OS does.

    Names that are not valid UTF-8 keep their bytes (as surrogate escapes), so the
    file can still be opened; :func:`display_path` prints them readably.
    """
    return Path(os.fsdecode(path))


def display_path(path: PathArg) -> str:
    """``path`` as printable text: bytes that are not UTF-8 are written as ``\\xNN``.

    A file name that is not valid UTF-8 would otherwise make printing an error
    message fail (``UnicodeEncodeError``) on a UTF-8 terminal.

    Examples
    --------
    >>> display_path(b"IMG/caf\\xe9.png")
    'IMG/caf\\\\xe9.png'
    """
    return os.fsencode(path).decode("utf-8", "backslashreplace")


def is_regular_file(path: PathArg) -> bool:
    """Whether ``path`` is a regular file; ``False`` for any path the OS cannot look up.

    Unlike :meth:`pathlib.Path.is_file`, a name too long for the file system or
    holding a NUL byte gives ``False`` instead of an exception.
    """
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def require_file(path: PathArg, what: str = "file") -> Path:
    """``path`` if it is a regular file this process may read, else an :class:`InputError`.

    The message names the path and says what is wrong: not found (or a broken symbolic
    link), a folder or a FIFO where ``what`` is needed, or no permission to read.
    """
    p = _as_path(path)
    mode = _existing_mode(p, what)
    if stat.S_ISDIR(mode):
        raise InputError(display_path(p), f"is a folder (a {what} is expected)")
    if not stat.S_ISREG(mode):
        raise InputError(
            display_path(p), f"not a regular file ({_file_type(mode)}; a {what} is expected)"
        )
    return _readable(p, os.R_OK)


def require_folder(path: PathArg, what: str = "folder") -> Path:
    """``path`` if it is a folder this process may list, else an :class:`InputError`."""
    p = _as_path(path)
    if not stat.S_ISDIR(_existing_mode(p, what)):
        raise InputError(display_path(p), f"is not a folder (a {what} is expected)")
    return _readable(p, os.R_OK | os.X_OK)


def require_file_or_folder(path: PathArg, what: str) -> Path:
    """``path`` if it is a readable regular file or a listable folder."""
    p = _as_path(path)
    mode = _existing_mode(p, what)
    if stat.S_ISDIR(mode):
        return require_folder(p, what)
    return require_file(p, what)


def _existing_mode(p: Path, what: str) -> int:
    try:
        return os.stat(p).st_mode
    except FileNotFoundError:
        broken = " (a broken symbolic link)" if p.is_symlink() else ""
        raise InputError(display_path(p), f"{what} not found{broken}") from None
    except (OSError, ValueError) as exc:
        reason = getattr(exc, "strerror", None) or exc
        raise InputError(display_path(p), f"cannot read: {reason}") from None


def _readable(p: Path, mode: int) -> Path:
    if not os.access(p, mode):
        raise InputError(display_path(p), "cannot read: permission denied")
    return p


def _read_bytes(path: Path) -> bytes:
    """The file's bytes; only regular files are opened, so a FIFO or a device never blocks."""
    shown = display_path(path)
    try:
        info = os.stat(path)
    except FileNotFoundError:
        broken = " (a broken symbolic link)" if path.is_symlink() else ""
        raise InputError(shown, f"file not found{broken}") from None
    except OSError as exc:
        raise InputError(shown, f"cannot read: {exc.strerror or exc}") from None
    if stat.S_ISDIR(info.st_mode):
        raise InputError(shown, "is a directory, not an image file")
    if not stat.S_ISREG(info.st_mode):
        raise InputError(shown, _not_regular(info.st_mode))
    try:
        # O_NONBLOCK: if the path was swapped for a FIFO after the check, open does not wait
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except PermissionError:
        raise InputError(shown, "cannot read: permission denied") from None
    except OSError as exc:
        raise InputError(shown, f"cannot read: {exc.strerror or exc}") from None
    with os.fdopen(fd, "rb") as fh:
        info = os.fstat(fh.fileno())
        if not stat.S_ISREG(info.st_mode):
            raise InputError(
                shown, f"not a regular file ({_file_type(info.st_mode)}), not an image"
            )
        if info.st_size > MAX_FILE_BYTES:
            raise InputError(
                shown, f"file of {info.st_size} bytes, larger than {MAX_FILE_BYTES} bytes"
            )
        try:
            data = fh.read(MAX_FILE_BYTES + 1)
        except OSError as exc:
            raise InputError(shown, f"cannot read: {exc.strerror or exc}") from None
    if not data:
        raise InputError(shown, "empty file (0 bytes)")
    if len(data) > MAX_FILE_BYTES:
        raise InputError(shown, f"file larger than {MAX_FILE_BYTES} bytes")
    return data


def _not_regular(mode: int) -> str:
    return f"not a regular file ({_file_type(mode)}), not an image"


def _file_type(mode: int) -> str:
    kinds = (
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    )
    return next((name for test, name in kinds if test(mode)), "not a plain file")


def header_size(data: bytes, source: str = "<bytes>") -> tuple[int, int]:
    """Width and height an image file's header declares, read without decoding pixels.

    Uses Pillow's header parsers for the formats qdcnn reads (PNG, JPEG, BMP, TIFF,
    WebP, PPM/PGM), called directly so that no pixel data is touched.

    Raises
    ------
    InputError
        No parser recognises the header (naming ``source``).
    """
    from PIL import Image

    Image.init()
    prefix = data[:16]
    for fmt in _HEADER_FORMATS:
        factory, accept = Image.OPEN[fmt]
        if accept is not None and not accept(prefix):
            continue
        try:
            with warnings.catch_warnings():  # e.g. "Corrupt EXIF data": the decoder decides
                warnings.simplefilter("ignore")
                with factory(io.BytesIO(data), "") as im:
                    width, height = im.size
        except Exception:  # Pillow's parsers raise many types on bad headers: not this format
            continue
        return int(width), int(height)
    raise InputError(source, _UNREADABLE)


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def check_png_chunks(data: bytes, source: str = "<bytes>") -> None:
    """Refuse a PNG whose chunks are cut short or fail their CRC, before libpng sees it.

    libpng prints its own ``libpng error:`` lines on stderr for such files (OpenCV's log
    level does not reach them); checked here, the file gets qdcnn's one-line error only.
    Other formats pass unchecked.

    Raises
    ------
    InputError
        A truncated chunk or a CRC mismatch (naming ``source`` and the chunk).
    """
    if not data.startswith(_PNG_SIGNATURE):
        return
    pos = len(_PNG_SIGNATURE)
    while pos + 12 <= len(data):
        length = int.from_bytes(data[pos : pos + 4], "big")
        end = pos + 8 + length
        if end + 4 > len(data):
            break
        kind = data[pos + 4 : pos + 8]
        if zlib.crc32(data[pos + 4 : end]) != int.from_bytes(data[end : end + 4], "big"):
            name = kind.decode("latin-1")
            raise InputError(source, f"{_UNREADABLE}: PNG chunk {name!r} fails its CRC check")
        if kind == b"IEND":
            return
        pos = end + 4
    raise InputError(source, f"{_UNREADABLE}: PNG data ends before its IEND chunk")


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
    raise InputError(display_path(path), f"unsupported pixel type {img.dtype}")


@contextmanager
def _opencv_quiet() -> Iterator[None]:
    """Silence OpenCV's own warnings (a truncated PNG's ``[ WARN ]`` line on stderr): the
    failure becomes qdcnn's one-line error instead. The caller's log level is restored."""
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    try:
        yield
    finally:
        cv2.utils.logging.setLogLevel(level)


def _decode(path: Path) -> NDArray[np.generic]:
    data = _read_bytes(path)
    shown = display_path(path)
    width, height = header_size(data, shown)
    check_png_chunks(data, shown)
    if width * height > MAX_PIXELS:
        raise InputError(shown, f"image is {width}x{height}, larger than {MAX_PIXELS} pixels")
    try:
        with _opencv_quiet():
            img = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    except cv2.error as exc:
        reason = " ".join(str(exc).split())[-160:]
        raise InputError(shown, f"{_UNREADABLE}: decoder error ({reason})") from None
    if img is None:
        raise InputError(shown, _UNREADABLE)
    if not has_shape(img, "H,W|H,W,C") or img.shape[0] == 0 or img.shape[1] == 0:
        raise InputError(shown, f"image has an unusable shape {img.shape}")
    if img.shape[0] * img.shape[1] > MAX_PIXELS:
        raise InputError(
            shown, f"image is {img.shape[1]}x{img.shape[0]}, larger than {MAX_PIXELS} pixels"
        )
    return img


def read_image(path: PathArg) -> NDArray[np.uint8]:
    """Read an image file as RGB ``uint8`` of shape ``(H, W, 3)``.

    Parameters
    ----------
    path : str, bytes or path-like
        A PNG, JPEG, BMP, TIFF, WebP or PPM/PGM file (OpenCV decodes it). ``bytes``
        names that are not UTF-8 are accepted.

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
        The image in RGB channel order.

    Raises
    ------
    InputError
        Missing, empty, unreadable, corrupt or oversized files, and paths that are
        not regular files (folders, FIFOs, devices), naming the file.

    Notes
    -----
    Only regular files are opened (a FIFO or device with an image suffix is refused
    without waiting on it). The image size is read from the file header first and
    an image over :data:`MAX_PIXELS` pixels is refused without decoding it; decoder
    errors become :class:`InputError`.
    """
    p = _as_path(path)
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
    raise InputError(display_path(p), f"unsupported number of channels ({channels})")


def read_mask(path: PathArg) -> NDArray[np.bool_]:
    """Read a ground-truth mask as ``bool`` of shape ``(H, W)``, binarised at 128.

    Colour masks are converted to grey first; 16-bit masks are scaled to 8 bits.
    Files are checked as in :func:`read_image`.
    """
    p = _as_path(path)
    img = _to_uint8(_decode(p), p)
    if img.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if img.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        img = cv2.cvtColor(img, code) if img.shape[2] in (3, 4) else img[:, :, 0]
    return np.asarray(img >= MASK_LEVEL)


def encode_image(image: NDArray[np.uint8], suffix: str = ".png") -> bytes:
    """The bytes of an RGB (or greyscale, or boolean) image file of type ``suffix``."""
    arr = np.asarray(image)
    if arr.dtype == np.bool_:
        arr = arr.astype(np.uint8) * 255
    if arr.ndim == 3:
        arr = cv2.cvtColor(arr, cv2.COLOR_RGB2BGR)
    try:
        ok, buf = cv2.imencode(suffix or ".png", arr)
    except cv2.error:
        ok = False
    if not ok:
        raise InputError(f"*{suffix}", "cannot encode an image of this file type")
    return bytes(buf.tobytes())


def encode_mask(mask: NDArray[np.bool_]) -> bytes:
    """The bytes of a single-channel 0/255 PNG of ``mask``."""
    return encode_image(np.asarray(mask, dtype=bool).astype(np.uint8) * 255, ".png")


def write_image(path: str | os.PathLike[str], image: NDArray[np.uint8]) -> Path:
    """Write an RGB (or greyscale) ``uint8`` image; the suffix picks the format.

    The file is written atomically (:func:`qdcnn._fileio.atomic_write_bytes`): a reader
    never sees half an image, and a symbolic link at ``path`` is replaced, never followed.
    """
    p = Path(path)
    try:
        data = encode_image(image, p.suffix or ".png")
    except InputError:
        raise InputError(p, "cannot encode image for this file type") from None
    return atomic_write_bytes(p, data)


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
        Given paths that do not exist or cannot be read, and given files that are not
        image files.
    """

    images: list[Path] = field(default_factory=list)
    skipped: list[Path] = field(default_factory=list)
    missing: list[InputError] = field(default_factory=list)


def list_images(paths: Iterable[PathArg], recursive: bool = False) -> ImageListing:
    """Expand files and folders into the image files to process.

    Folders contribute their files with an image suffix (sorted by name); other
    files in them go to ``skipped``. A path given explicitly must be a readable
    regular file with an image suffix or a folder this process may list, or it is
    reported in ``missing``. Names that are not
    UTF-8 (``bytes`` paths, or such files inside a folder) are listed like any
    other; messages show their odd bytes as ``\\xNN``.
    """
    out = ImageListing()
    for raw in paths:
        p = _as_path(raw)
        try:
            if p.is_dir():
                _add_folder(out, require_folder(p), recursive)
            else:
                out.images.append(_named_image(p))
        except InputError as exc:
            out.missing.append(exc)
    return out


def list_named_images(paths: Sequence[PathArg]) -> ImageListing:
    """:func:`list_images`, for a run that must not start on a mistyped or unusable path.

    Raises
    ------
    InputError
        The first named path that is missing, unreadable or not an image file or folder,
        or no image files at all under ``paths``.
    """
    listing = list_images(paths)
    if listing.missing:
        raise listing.missing[0]
    if not listing.images:
        raise InputError(", ".join(map(display_path, paths)), "no image files found")
    return listing


def _add_folder(out: ImageListing, folder: Path, recursive: bool) -> None:
    try:
        children: Sequence[Path] = sorted(folder.rglob("*") if recursive else folder.iterdir())
    except OSError as exc:
        raise InputError(display_path(folder), f"cannot list: {exc.strerror or exc}") from None
    for child in children:
        if child.is_dir():
            continue
        is_image = child.suffix.lower() in IMAGE_SUFFIXES
        (out.images if is_image else out.skipped).append(child)


def _named_image(p: Path) -> Path:
    """A path given explicitly: an existing, readable file with an image suffix."""
    if p.exists() and p.suffix.lower() not in IMAGE_SUFFIXES:
        suffix = display_path(p.suffix) if p.suffix else "none"
        raise InputError(display_path(p), f"not an image file (suffix {suffix!r})")
    return require_file(p, "file")
