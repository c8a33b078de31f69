"""Video reading and writing: exact seeking, timestamps, rotation, bad files, odd sizes."""

from __future__ import annotations

import os
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from qdcnn.data import video as video_mod
from qdcnn.data.video import (
    MAX_VIDEO_PIXELS,
    VideoReader,
    VideoWriter,
    concat_mp4,
    video_info,
)
from qdcnn.errors import InputError, ParameterError

av = pytest.importorskip("av")

N, W, H, FPS = 36, 64, 48, 10.0


def pattern(i: int, w: int = W, h: int = H) -> np.ndarray:
    """A frame that changes from frame to frame (moving gradient and a bright block)."""
    y, x = np.mgrid[0:h, 0:w]
    img = np.stack([(x * 4 + i * 7) % 256, (y * 5 + i * 3) % 256, ((x + y) * 2) % 256], axis=2)
    img[(i * 3) % (h - 8) : (i * 3) % (h - 8) + 8, 4:12] = 250
    return img.astype(np.uint8)


def write(path: Path, n: int = N, *, keyframes: int | None = 8, stamps=None, **kw) -> Path:
    with VideoWriter(path, FPS, keyframe_interval=keyframes, **kw) as w:
        for i in range(n):
            w.write(pattern(i), None if stamps is None else float(stamps[i]))
    return path


@pytest.fixture(scope="module")
def clip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write(tmp_path_factory.mktemp("video") / "clip.mp4")


def test_written_video_reads_back_with_its_timestamps(clip: Path) -> None:
    with VideoReader(clip) as reader:
        info = reader.info
        frames = list(reader)
    assert (info.decoder, info.codec, info.width, info.height) == ("pyav", "h264", W, H)
    assert info.frames == info.declared_frames == N and info.fps == pytest.approx(FPS)
    assert info.duration == pytest.approx(N / FPS)
    assert [f.index for f in frames] == list(range(N))
    assert np.allclose([f.timestamp for f in frames], np.arange(N) / FPS, atol=1e-6)
    errors = [np.abs(f.image.astype(int) - pattern(f.index)).mean() for f in frames]
    assert all(f.image.shape == (H, W, 3) and f.image.dtype == np.uint8 for f in frames)
    assert max(errors) < 8.0  # lossy H.264 at crf 23, 4:2:0 chroma on sharp colour edges


def _keyframes(path: Path) -> int:
    with av.open(str(path)) as c:
        return sum(p.is_keyframe for p in c.demux(video=0) if p.size)


@pytest.mark.parametrize("decoder", ["pyav", "opencv"])
def test_seeking_gives_exactly_the_frames_of_sequential_decoding(clip: Path, decoder: str) -> None:
    assert _keyframes(clip) >= 4  # starts inside and at the edges of several GOPs
    with VideoReader(clip, decoder=decoder) as reader:  # type: ignore[arg-type]
        sequential = list(reader)
        assert len(sequential) == N
        for start in (0, 1, 7, 8, 9, 17, 30, N - 1):
            stop = min(start + 6, N)
            part = list(reader.read(start, stop))
            assert [f.index for f in part] == list(range(start, stop))
            for f in part:
                ref = sequential[f.index]
                assert np.array_equal(f.image, ref.image)
                assert f.timestamp == pytest.approx(ref.timestamp, abs=1e-6)


def test_pyav_frames_are_pyavs_own_rgb_conversion(tmp_path: Path) -> None:
    """The reader's one converter per file gives each frame ``to_ndarray(format="rgb24")``."""
    path = tmp_path / "frames.mp4"
    with VideoWriter(path, FPS) as w:
        for i in range(12):
            w.write(pattern(i, 66, 38))
    with av.open(str(path)) as c:
        expected = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    with VideoReader(path, decoder="pyav") as reader:
        frames = list(reader)
    assert len(frames) == len(expected) == 12
    assert all(np.array_equal(f.image, e) for f, e in zip(frames, expected, strict=True))


def test_opencv_and_pyav_decode_the_same_frames(clip: Path) -> None:
    with VideoReader(clip, decoder="pyav") as a, VideoReader(clip, decoder="opencv") as b:
        fa, fb = list(a), list(b)
        assert b.info.decoder == "opencv" and b.info.frames == N
    assert len(fa) == len(fb) == N
    diff = max(np.abs(x.image.astype(int) - y.image).mean() for x, y in zip(fa, fb, strict=True))
    assert diff < 2.0  # same bitstream; the two builds' colour conversions may round apart
    assert np.allclose([f.timestamp for f in fb], [f.timestamp for f in fa], atol=2e-3)


def test_variable_frame_rate_timestamps_come_from_pts_and_survive_seeking(
    tmp_path: Path,
) -> None:
    gaps = np.random.default_rng(3).uniform(0.02, 0.4, N - 1)
    stamps = np.concatenate([[0.0], np.cumsum(gaps)])
    path = write(tmp_path / "vfr.mp4", stamps=stamps)
    with VideoReader(path) as reader:
        got = [f.timestamp for f in reader]
        tail = [f.timestamp for f in reader.read(20, N)]
    assert np.abs(np.array(got) - stamps).max() < 1e-4
    assert np.abs(np.array(tail) - stamps[20:]).max() < 1e-4


def _rotated_clip(path: Path, degrees: int) -> Path:
    with av.open(str(path), "w") as c:
        s = c.add_stream("libx264", rate=10)
        s.width, s.height, s.pix_fmt = W, H, "yuv420p"
        s.set_display_rotation(degrees)
        for i in range(6):
            frame = av.VideoFrame.from_ndarray(pattern(i), format="rgb24")
            frame.pts = i
            for packet in s.encode(frame):
                c.mux(packet)
        for packet in s.encode():
            c.mux(packet)
    return path


@pytest.mark.parametrize("degrees", [90, 180, -90])
def test_rotation_metadata_is_applied(tmp_path: Path, degrees: int) -> None:
    path = _rotated_clip(tmp_path / f"rot{degrees}.mp4", degrees)
    plain = _rotated_clip(tmp_path / "plain.mp4", 0)  # the same bitstream, no display matrix
    with VideoReader(path) as r, VideoReader(plain) as p, VideoReader(path, decoder="opencv") as o:
        turns = (degrees // 90) % 4
        assert p.info.rotation == 0
        assert r.info.rotation == turns * 90 and o.info.rotation == turns * 90
        assert (r.info.width, r.info.height) == ((H, W) if turns % 2 else (W, H))
        for a, b, c in zip(r, p, o, strict=True):
            assert np.array_equal(a.image, np.rot90(b.image, turns))
            assert np.abs(c.image.astype(int) - a.image).mean() < 2.0


def _corrupt(src: Path, dst: Path, at: float = 0.5, size: int = 3000) -> Path:
    data = bytearray(src.read_bytes())
    k = int(len(data) * at)
    data[k : k + size] = np.random.default_rng(1).integers(0, 256, size, dtype=np.uint8).tobytes()
    dst.write_bytes(bytes(data))
    return dst


def test_corrupt_video_decodes_what_it_can_and_reports_the_first_bad_frame(
    clip: Path, tmp_path: Path
) -> None:
    bad = _corrupt(clip, tmp_path / "bad.mp4")
    with VideoReader(clip) as good_reader:
        good = list(good_reader)
    with VideoReader(bad) as reader:
        frames = reader.read()
        got = list(frames)
    first = frames.first_bad_frame
    assert first is not None and 0 < first < N, frames.bad_frames
    assert {f.index for f in got}.isdisjoint(b.index for b in frames.bad_frames)
    assert len(got) + len(frames.bad_frames) == N
    for f in got:
        if f.index < first:
            assert np.array_equal(f.image, good[f.index].image)


def _faststart(src: Path, dst: Path) -> Path:
    with (
        av.open(str(src)) as inp,
        av.open(str(dst), "w", options={"movflags": "+faststart"}) as out,
    ):
        stream = out.add_stream_from_template(inp.streams.video[0])
        for packet in inp.demux(inp.streams.video[0]):
            if packet.dts is not None:
                packet.stream = stream
                out.mux(packet)
    return dst


def test_truncated_video_reports_the_missing_frames(clip: Path, tmp_path: Path) -> None:
    data = clip.read_bytes()
    (tmp_path / "cut.mp4").write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"cut\.mp4: not a readable video"):
        VideoReader(tmp_path / "cut.mp4")  # moov atom at the end: nothing to index
    whole = _faststart(clip, tmp_path / "fast.mp4").read_bytes()
    (tmp_path / "fastcut.mp4").write_bytes(whole[: len(whole) // 2])
    with VideoReader(tmp_path / "fastcut.mp4") as reader:
        assert reader.info.truncated and reader.info.declared_frames == N
        frames = reader.read()
        got = list(frames)
    assert 0 < reader.info.frames < N
    missing_from = min(frames.first_bad_frame or reader.info.frames, reader.info.frames)
    assert 0 < missing_from < N and all(f.index < missing_from for f in got)


def test_files_without_frames_get_one_line_errors(tmp_path: Path) -> None:
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    with pytest.raises(InputError, match=r"empty\.mp4: empty file \(0 bytes\)"):
        VideoReader(empty)
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"this is not a video" * 50)
    with pytest.raises(InputError, match=r"junk\.mp4: not a readable video"):
        VideoReader(junk)
    with av.open(str(tmp_path / "none.mkv"), "w") as c:  # header, a stream, no frames
        s = c.add_stream("ffv1", rate=10)
        s.width, s.height, s.pix_fmt = W, H, "bgr0"
        c.start_encoding()
    with pytest.raises(InputError, match=r"none\.mkv: (the video has no frames|no video stream)"):
        VideoReader(tmp_path / "none.mkv")
    with pytest.raises(InputError, match=r"missing\.mp4: file not found"):
        VideoReader(tmp_path / "missing.mp4")
    with pytest.raises(InputError, match="is a directory"):
        VideoReader(tmp_path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes on this system")
def test_a_fifo_named_like_a_video_is_not_a_regular_file(tmp_path: Path) -> None:
    fifo = tmp_path / "x.mp4"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=r"x\.mp4: not a regular file \(a FIFO; a video file"):
        VideoReader(fifo)


def _raw_clip(path: Path, w: int, h: int, n: int = 3) -> Path:
    with av.open(str(path), "w") as c:
        s = c.add_stream("ffv1", rate=10)
        s.width, s.height, s.pix_fmt = w, h, "bgr0"
        for i in range(n):
            rgb = pattern(i, max(w, 16), max(h, 16))[:h, :w]
            frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(rgb), format="rgb24")
            frame = frame.reformat(format="bgr0")
            frame.pts = i
            for packet in s.encode(frame):
                c.mux(packet)
        for packet in s.encode():
            c.mux(packet)
    return path


def test_tiny_and_huge_frames_are_refused_before_decoding(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.raises(InputError, match=r"one\.mkv: frames are 1x1, smaller than 4x4 pixels"):
        VideoReader(_raw_clip(tmp_path / "one.mkv", 1, 1))
    big = tmp_path / "8k.mp4"
    with av.open(str(big), "w") as c:
        s = c.add_stream("libx264", rate=1)
        s.width, s.height, s.pix_fmt = 7680, 4320, "yuv420p"
        s.options = {"preset": "ultrafast"}
        frame = av.VideoFrame(7680, 4320, "yuv420p")
        for plane in frame.planes:
            plane.update(bytes(plane.buffer_size))
        frame.pts = 0
        for packet in [*s.encode(frame), *s.encode()]:
            c.mux(packet)

    def no_reading(*_: object) -> None:
        raise AssertionError("the file's packets were read before the size check")

    with monkeypatch.context() as m:  # refused from the header: no packet is demuxed or decoded
        m.setattr(video_mod._PyAVBackend, "_scan", no_reading)
        m.setattr(video_mod._PyAVBackend, "_rotation", no_reading)
        with pytest.raises(
            InputError, match=r"8k\.mp4: frames are 7680x4320 \(33177600 pixels\), more"
        ):
            VideoReader(big, decoder="pyav")
    assert 7680 * 4320 > MAX_VIDEO_PIXELS >= 3840 * 2160
    with pytest.raises(InputError, match="more than the limit of 1000 pixels"):
        VideoReader(big.parent / "8k.mp4", max_pixels=1000)


def test_odd_sizes_read_as_they_are_and_are_padded_for_encoding(tmp_path: Path) -> None:
    with VideoReader(_raw_clip(tmp_path / "odd.mkv", 33, 21)) as reader:
        frames = list(reader)
    assert [f.image.shape for f in frames] == [(21, 33, 3)] * 3
    assert np.array_equal(frames[1].image, pattern(1)[:21, :33])  # ffv1 is lossless
    with VideoWriter(tmp_path / "odd.mp4", FPS) as w:
        for f in frames:
            w.write(f.image)
    assert w.result is not None and w.result.padded
    assert (w.result.encoded_width, w.result.encoded_height) == (34, 22)
    info = video_info(tmp_path / "odd.mp4")
    assert (info.width, info.height, info.frames) == (34, 22, 3)


def test_writer_checks_its_input_and_leaves_no_file_on_failure(tmp_path: Path) -> None:
    target = tmp_path / "w.mp4"
    with pytest.raises(InputError, match="frame 1 is 32x32, the video is 64x48"):
        with VideoWriter(target, FPS) as w:
            w.write(pattern(0))
            w.write(np.zeros((32, 32, 3), np.uint8))
    assert not target.exists() and list(tmp_path.iterdir()) == []
    with pytest.raises(ParameterError, match="timestamp=0.0 is invalid: increasing"):
        with VideoWriter(target, FPS) as w:
            w.write(pattern(0), 0.0)
            w.write(pattern(1), 0.0)
    with pytest.raises(InputError, match="no frames to write"):
        VideoWriter(target, FPS).close()
    with pytest.raises(ParameterError, match="a .mp4, .m4v, .mov, .mkv or .avi file"):
        VideoWriter(tmp_path / "w.gif", FPS)
    with pytest.raises(ParameterError, match="fps=0 is invalid"):
        VideoWriter(target, 0)
    with pytest.raises(InputError, match="expected an RGB uint8 array"):
        VideoWriter(target, FPS).write(np.zeros((8, 8), np.uint8))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("encoder", ["libx264", "mpeg4", "opencv"])
def test_every_encoder_writes_a_readable_mp4(tmp_path: Path, encoder: str) -> None:
    path = write(tmp_path / f"{encoder}.mp4", 12, keyframes=None, encoder=encoder)
    with VideoReader(path) as reader:
        frames = list(reader)
    assert len(frames) == 12
    assert max(np.abs(f.image.astype(int) - pattern(f.index)).mean() for f in frames) < 12.0
    in_memory = VideoWriter(None, FPS, encoder=encoder)  # type: ignore[arg-type]
    in_memory.write(pattern(0))
    result = in_memory.close()
    assert in_memory.data and result.frames == 1 and result.path == ""


def test_segments_join_without_re_encoding(tmp_path: Path) -> None:
    segments = []
    for k in range(3):
        w = VideoWriter(None, FPS)
        for i in range(10 * k, 10 * k + 10):
            w.write(pattern(i), (i - 10 * k) / FPS)
        w.close()
        assert w.data is not None
        segments.append((w.data, k * 1.0))
    assert concat_mp4(segments, tmp_path / "joined.mp4") == 30
    with VideoReader(tmp_path / "joined.mp4") as joined:
        frames = list(joined)
    assert np.allclose([f.timestamp for f in frames], np.arange(30) / FPS, atol=1e-4)
    for k, (data, _) in enumerate(segments):
        (tmp_path / f"s{k}.mp4").write_bytes(data)
        with VideoReader(tmp_path / f"s{k}.mp4") as part:
            for f in part:
                assert np.array_equal(f.image, frames[10 * k + f.index].image)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_without_pyav_opencv_decodes_and_encodes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(video_mod, "has_module", lambda name: name != "av")
    assert video_mod.default_decoder() == "opencv" and video_mod.default_encoder() == "opencv"
    path = write(tmp_path / "cv.mp4", 8, keyframes=None)
    with VideoReader(path) as reader:
        frames = list(reader)
        assert reader.info.decoder == "opencv"
    assert len(frames) == 8 and frames[0].image.shape == (H, W, 3)


def test_reader_checks_its_arguments(clip: Path) -> None:
    with VideoReader(clip) as reader:
        with pytest.raises(
            ParameterError, match=r"start=-1 is invalid: a frame index in \[0, 36\]"
        ):
            reader.read(-1)
        with pytest.raises(ParameterError, match=r"stop=40 is invalid"):
            reader.read(0, 40)
        assert list(reader.read(5, 5)) == []
    with pytest.raises(ParameterError, match="decoder='gpu' is invalid"):
        VideoReader(clip, decoder="gpu")  # type: ignore[arg-type]


def test_time_base_of_written_files_is_fine_enough_for_vfr(clip: Path) -> None:
    with av.open(str(clip)) as c:
        assert c.streams.video[0].time_base == Fraction(1, 90_000)
