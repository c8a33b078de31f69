"""Fuzzing read_image: random and mutated image bytes give an image or one InputError only."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from fuzz_support import fuzz_settings, hang_guard

from qdcnn.data.images import MAX_PIXELS, read_image, read_mask
from qdcnn.errors import InputError

hypothesis = pytest.importorskip("hypothesis")
st = hypothesis.strategies
given = hypothesis.given
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")  # numpy overflow and the like


def _encoded() -> dict[str, bytes]:
    rng = np.random.default_rng(7)
    rgb = rng.integers(0, 256, (9, 11, 3), dtype=np.uint8)
    out = {}
    for suffix in (".png", ".jpg", ".bmp", ".tiff", ".webp", ".ppm"):
        ok, buf = cv2.imencode(suffix, rgb)
        assert ok
        out[suffix] = buf.tobytes()
    ok, buf = cv2.imencode(".pgm", rng.integers(0, 65535, (9, 11), dtype=np.uint16))
    out[".pgm"] = buf.tobytes()
    ok, buf = cv2.imencode(".png", np.dstack([rgb, rgb[:, :, :1]]))  # RGBA
    out["rgba.png"] = buf.tobytes()
    return out


VALID = _encoded()
MAGICS = [b"", b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff", b"BM", b"II*\x00", b"MM\x00*", b"P6\n"]
MAGICS.append(b"RIFF\x00\x00\x00\x00WEBPVP8 ")


def png_with_size(width: int, height: int) -> bytes:
    data = bytearray(VALID[".png"])
    data[16:24] = struct.pack(">II", width, height)
    data[29:33] = struct.pack(">I", zlib.crc32(bytes(data[12:29])))
    return bytes(data)


@st.composite
def mutated(draw: st.DrawFn) -> bytes:
    data = bytearray(VALID[draw(st.sampled_from(sorted(VALID)))])
    for _ in range(draw(st.integers(0, 6))):
        kind = draw(st.sampled_from(["set", "insert", "delete", "truncate", "dims"]))
        pos = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "set" and data:
            data[pos] = draw(st.integers(0, 255))
        elif kind == "insert":
            data[pos:pos] = draw(st.binary(min_size=1, max_size=16))
        elif kind == "delete":
            del data[pos : pos + draw(st.integers(1, 16))]
        elif kind == "truncate":
            del data[pos:]
        elif kind == "dims" and len(data) > pos + 4:
            data[pos : pos + 4] = struct.pack(">I", draw(st.integers(0, 2**32 - 1)))
    return bytes(data)


random_bytes = st.builds(
    lambda magic, tail: magic + tail, st.sampled_from(MAGICS), st.binary(max_size=600)
)
claimed_sizes = st.builds(png_with_size, st.integers(1, 2**31 - 1), st.integers(1, 2**31 - 1))


def check_read(path: Path, data: bytes) -> None:
    path.write_bytes(data)
    with hang_guard():
        try:
            img = read_image(path)
        except InputError as exc:
            message = str(exc)
            assert message.startswith(f"{path}: ") and "\n" not in message
            hypothesis.event("refused: " + exc.reason.split(" (")[0][:40])
            return
    hypothesis.event("decoded")
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[2] == 3
    assert img.shape[0] * img.shape[1] <= MAX_PIXELS
    mask = read_mask(path)
    assert mask.shape == img.shape[:2] and mask.dtype == bool


@pytest.fixture(scope="module")
def target(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz-images") / "frame.png"


@fuzz_settings(500)
@given(data=mutated())
def test_mutated_images(target: Path, data: bytes) -> None:
    check_read(target, data)


@fuzz_settings(200)
@given(data=random_bytes)
def test_random_bytes(target: Path, data: bytes) -> None:
    check_read(target, data)


@fuzz_settings(100)
@given(data=claimed_sizes)
def test_any_claimed_png_size(target: Path, data: bytes) -> None:
    width, height = struct.unpack(">II", data[16:24])
    if width * height <= MAX_PIXELS:
        check_read(target, data)  # decoded (and fails on missing data) or read
        return
    target.write_bytes(data)
    with hang_guard(), pytest.raises(InputError) as info:
        read_image(target)
    assert (
        str(info.value) == f"{target}: image is {width}x{height}, larger than {MAX_PIXELS} pixels"
    )
