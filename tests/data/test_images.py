"""Image reading at the input boundary: header size limits, decoder errors, odd files and names."""

from __future__ import annotations

import os
import struct
import threading
import time
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest

from qdcnn.data import images as image_io
from qdcnn.data.images import (
    MAX_PIXELS,
    display_path,
    header_size,
    list_images,
    read_image,
    read_mask,
    write_image,
)
from qdcnn.errors import InputError


def small_image() -> np.ndarray:
    rng = np.random.default_rng(4)
    return rng.integers(0, 256, (6, 8, 3), dtype=np.uint8)


def png_claiming(width: int, height: int) -> bytes:
    """A valid 8x6 PNG whose IHDR is rewritten to claim ``width x height`` (CRC fixed)."""
    ok, buf = cv2.imencode(".png", small_image())
    assert ok
    data = bytearray(buf.tobytes())
    data[16:24] = struct.pack(">II", width, height)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    return bytes(data)


def jpeg_claiming(width: int, height: int) -> bytes:
    """A valid JPEG whose SOF0 segment is rewritten to claim ``width x height``."""
    ok, buf = cv2.imencode(".jpg", small_image())
    assert ok
    data = bytearray(buf.tobytes())
    sof = data.index(b"\xff\xc0")
    data[sof + 5 : sof + 9] = struct.pack(">HH", height, width)
    return bytes(data)


def no_decoding(monkeypatch: pytest.MonkeyPatch) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the image must not be decoded")

    monkeypatch.setattr(image_io.cv2, "imdecode", refuse)


@pytest.mark.parametrize(
    ("make", "width", "height"),
    [
        (png_claiming, 20_000, 20_000),  # 400 MP: OpenCV would try to allocate 1.2 GB
        (png_claiming, 60_000, 60_000),  # beyond OpenCV's own limit: cv2.error today
        (jpeg_claiming, 65_000, 40_000),
    ],
)
def test_huge_header_is_refused_before_decoding(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, make: object, width: int, height: int
) -> None:
    path = tmp_path / "bomb.png"
    path.write_bytes(make(width, height))  # type: ignore[operator]
    assert path.stat().st_size < 1000
    no_decoding(monkeypatch)
    with pytest.raises(InputError) as info:
        read_image(path)
    assert str(info.value) == f"{path}: image is {width}x{height}, larger than {MAX_PIXELS} pixels"
    with pytest.raises(InputError, match="larger than"):
        read_mask(path)


def test_header_size_reads_every_supported_format() -> None:
    for suffix in (".png", ".jpg", ".bmp", ".tiff", ".webp", ".ppm"):
        ok, buf = cv2.imencode(suffix, small_image())
        assert ok
        assert header_size(buf.tobytes()) == (8, 6), suffix
    ok, buf = cv2.imencode(".pgm", np.zeros((6, 8), np.uint16))
    assert header_size(buf.tobytes()) == (8, 6)
    with pytest.raises(InputError, match="x.gif: not a readable image"):
        header_size(b"GIF89a" + bytes(20), "x.gif")


def test_images_at_the_limit_are_still_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = write_image(tmp_path / "a.png", small_image())
    monkeypatch.setattr(image_io, "MAX_PIXELS", 48)  # exactly 8 x 6
    np.testing.assert_array_equal(read_image(path), small_image())
    monkeypatch.setattr(image_io, "MAX_PIXELS", 47)
    with pytest.raises(InputError, match="image is 8x6, larger than 47 pixels"):
        read_image(path)


def test_decoder_error_becomes_input_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = write_image(tmp_path / "a.png", small_image())

    def failing(*args: object, **kwargs: object) -> None:
        raise cv2.error("OpenCV(5.0) imgcodecs: failed to decode")

    monkeypatch.setattr(image_io.cv2, "imdecode", failing)
    with pytest.raises(InputError) as info:
        read_image(path)
    message = str(info.value)
    assert message.startswith(f"{path}: not a readable image (corrupt or unsupported format)")
    assert "failed to decode" in message and "\n" not in message


def test_truncated_png_is_one_input_error(tmp_path: Path, capfd: pytest.CaptureFixture) -> None:
    _, buf = cv2.imencode(".png", small_image())
    path = tmp_path / "cut.png"
    level = cv2.utils.logging.getLogLevel()
    for keep in (8, 30, 60, len(buf) - 5):
        path.write_bytes(buf.tobytes()[:keep])
        with pytest.raises(InputError, match="cut.png: not a readable image"):
            read_image(path)
    # OpenCV's own "[ WARN ] PNG input buffer is incomplete" line stays off stderr
    assert "WARN" not in capfd.readouterr().err
    assert cv2.utils.logging.getLogLevel() == level


def test_fifo_with_an_image_suffix_never_blocks(tmp_path: Path) -> None:
    fifo = tmp_path / "frame.png"
    os.mkfifo(fifo)
    outcome: list[BaseException | None] = []

    def attempt() -> None:
        try:
            read_image(fifo)
            outcome.append(None)
        except BaseException as exc:  # record whatever happens for the main thread
            outcome.append(exc)

    worker = threading.Thread(target=attempt, daemon=True)
    start = time.monotonic()
    worker.start()
    worker.join(timeout=10)
    if worker.is_alive():  # the old code waits in open(): give it a writer to let it finish
        fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        os.close(fd)
        worker.join(timeout=10)
        pytest.fail("read_image blocked on a FIFO")
    assert time.monotonic() - start < 5
    assert len(outcome) == 1 and isinstance(outcome[0], InputError)
    assert str(outcome[0]) == f"{fifo}: not a regular file (a FIFO), not an image"


def test_device_behind_an_image_name_is_refused(tmp_path: Path) -> None:
    link = tmp_path / "zero.jpg"
    link.symlink_to("/dev/zero")  # reading it would never end
    with pytest.raises(InputError) as info:
        read_image(link)
    assert str(info.value) == f"{link}: not a regular file (a character device), not an image"


def test_folder_and_missing_file(tmp_path: Path) -> None:
    (tmp_path / "dir.png").mkdir()
    with pytest.raises(InputError, match="dir.png: is a directory, not an image file"):
        read_image(tmp_path / "dir.png")
    with pytest.raises(InputError, match="gone.png: file not found"):
        read_image(tmp_path / "gone.png")


def test_file_over_the_byte_limit_is_not_read(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = write_image(tmp_path / "a.png", small_image())
    size = path.stat().st_size
    monkeypatch.setattr(image_io, "MAX_FILE_BYTES", size - 1)
    with pytest.raises(InputError, match=f"file of {size} bytes, larger than {size - 1} bytes"):
        read_image(path)


def test_non_utf8_names_are_read_listed_and_printed(tmp_path: Path) -> None:
    folder = os.fsencode(tmp_path) + b"/caf\xe9"
    os.mkdir(folder)
    good = folder + b"/\xff\xfe.png"
    _, buf = cv2.imencode(".png", small_image()[:, :, ::-1])
    with open(good, "wb") as fh:
        fh.write(buf.tobytes())
    with open(folder + b"/broken\xe9.jpg", "wb") as fh:
        fh.write(b"not a jpeg")
    with open(folder + b"/notes\xe9.txt", "wb") as fh:
        fh.write(b"text")
    np.testing.assert_array_equal(read_image(good), small_image())  # a bytes path
    listing = list_images([folder, folder + b"/missing\xe9.png"])
    assert [p.name for p in listing.images] == [
        os.fsdecode(b"broken\xe9.jpg"),
        os.fsdecode(b"\xff\xfe.png"),
    ]
    np.testing.assert_array_equal(read_image(listing.images[1]), small_image())  # a str path
    assert [p.name for p in listing.skipped] == [os.fsdecode(b"notes\xe9.txt")]
    shown = display_path(folder)
    assert shown.endswith("caf\\xe9")
    with pytest.raises(InputError) as info:
        read_image(listing.images[0])
    # the message can be printed on any terminal and shows the odd bytes
    message = str(info.value)
    message.encode("utf-8")
    assert (
        message == f"{shown}/broken\\xe9.jpg: not a readable image (corrupt or unsupported format)"
    )
    (missing,) = listing.missing
    assert str(missing) == f"{shown}/missing\\xe9.png: file not found"
    str(missing).encode("utf-8")


def test_a_png_with_a_bad_crc_is_one_error_and_libpng_stays_quiet(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    good = write_image(tmp_path / "ok.png", np.zeros((16, 32, 3), np.uint8)).read_bytes()
    flipped = bytearray(good)
    flipped[good.find(b"IDAT") + 8] ^= 0xFF  # first byte of the compressed pixels
    (tmp_path / "crc.png").write_bytes(bytes(flipped))
    (tmp_path / "cut.png").write_bytes(good[:-20])
    with pytest.raises(InputError, match="crc.png: .*PNG chunk 'IDAT' fails its CRC check"):
        read_image(tmp_path / "crc.png")
    with pytest.raises(InputError, match="cut.png: .*ends before its IEND chunk"):
        read_image(tmp_path / "cut.png")
    assert "libpng" not in capfd.readouterr().err
