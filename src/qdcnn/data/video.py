"""Reading and writing videos: RGB frames with index and timestamp, exact seeking, mp4 output.

Decoding uses PyAV (the ``video`` extra) when it is installed and OpenCV's FFmpeg backend
(``cv2.VideoCapture``) otherwise; :attr:`VideoInfo.decoder` says which. Frames come as RGB
``uint8`` arrays of shape ``(H, W, 3)`` with their index (presentation order, from 0) and
timestamp in seconds from the first frame, taken from each frame's presentation time stamp
(so variable frame rates are right), rotated as the file's display matrix (or ``rotate`` tag)
says.

Exact seeking (PyAV). Opening a file demuxes it once without decoding (a few milliseconds
per thousand frames) and keeps each frame's presentation time stamp and whether its packet
is a keyframe. Reading from frame ``i`` seeks to the last keyframe at or before frame ``i``
and decodes forward, dropping the frames before ``i``, so a chunk read from the middle gives
the same arrays as decoding the whole file from the start (tested). With OpenCV, seeking
uses ``CAP_PROP_POS_FRAMES``, which is exact for constant-frame-rate files (tested on mp4);
counting frames with OpenCV decodes the whole file once.

Bad input gets one-line :class:`~qdcnn.errors.InputError`: no video stream, no frames,
frames smaller than :data:`_MIN_SIDE` pixels or larger than :data:`MAX_VIDEO_PIXELS` (checked
from the stream header before any frame is decoded). A corrupt or truncated file is decoded
as far as it can be: frames that fail to decode are skipped and listed in
:attr:`FrameReader.bad_frames`, and a file whose header promises more frames than it holds
lists the missing ones too.

Writing (:class:`VideoWriter`): H.264 with libx264 (preset ``ultrafast``: no B-frames, so
segments concatenate by remuxing) through PyAV, else MPEG-4 Part 2 through PyAV, else OpenCV's
``mp4v`` writer. 4:2:0 encoders need even sizes, so odd widths or heights are padded by one
replicated edge pixel and :attr:`VideoWriteResult.padded` says so. The file appears under its
name only when complete (temporary name, then a rename).
"""

from __future__ import annotations

import bisect
import io
import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn._closing import ClosesOnExit, FinishesOnExit
from qdcnn._fileio import temporary_sibling
from qdcnn._optional import has_module, require
from qdcnn._validation import has_shape
from qdcnn.data.images import require_file
from qdcnn.errors import InputError, ParameterError

_VIDEO_SUFFIXES = frozenset({".mp4", ".m4v", ".mov", ".mkv", ".avi", ".webm"})
#: Largest frame decoded: DCI 4K (4096 x 2160); 8K (7680 x 4320) is refused.
MAX_VIDEO_PIXELS = 4096 * 2160
#: Smallest width and height of a frame that is read.
_MIN_SIDE = 4
#: Time base of the files :class:`VideoWriter` writes with H.264 (the MPEG-TS clock).
_H264_TIME_BASE = Fraction(1, 90_000)
#: MPEG-4 Part 2 needs a time base denominator below 2**16: milliseconds.
_MPEG4_TIME_BASE = Fraction(1, 1000)
Decoder = Literal["auto", "pyav", "opencv"]
Encoder = Literal["auto", "libx264", "mpeg4", "opencv"]
_FORMATS = {".mp4": "mp4", ".m4v": "mp4", ".mov": "mov", ".mkv": "matroska", ".avi": "avi"}


@dataclass(frozen=True)
class VideoFrame:
    """One decoded frame.

    Attributes
    ----------
    index : int
        Position in presentation order, from 0.
    timestamp : float
        Seconds since the first frame, from the frame's presentation time stamp.
    image : ndarray of uint8, shape (H, W, 3)
        RGB pixels, rotation applied.
    """

    index: int
    timestamp: float
    image: NDArray[np.uint8]


@dataclass(frozen=True)
class VideoInfo:
    """What a video file holds.

    Attributes
    ----------
    path : str
        The file.
    decoder : {"pyav", "opencv"}
        The library decoding it.
    width, height : int
        Size of the frames as returned (after rotation).
    rotation : int
        Counter-clockwise rotation applied to the decoded pictures (0, 90, 180 or 270).
    frames : int
        Frames that can be read (packets found in the file; for OpenCV, frames decoded).
    declared_frames : int or None
        Frames the container header announces, when it does.
    fps : float or None
        Average frame rate the container reports.
    duration : float or None
        Seconds from the first to the last frame plus one frame time, when known.
    codec : str
        Codec name.
    """

    path: str
    decoder: str
    width: int
    height: int
    rotation: int
    frames: int
    declared_frames: int | None
    fps: float | None
    duration: float | None
    codec: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "path": self.path,
            "decoder": self.decoder,
            "width": self.width,
            "height": self.height,
            "rotation": self.rotation,
            "frames": self.frames,
            "declared_frames": self.declared_frames,
            "fps": self.fps,
            "duration": self.duration,
            "codec": self.codec,
        }

    @property
    def truncated(self) -> bool:
        """The header announces more frames than the file holds."""
        return self.declared_frames is not None and self.declared_frames > self.frames


@dataclass(frozen=True)
class BadFrame:
    """A frame that could not be decoded, and why."""

    index: int
    reason: str


@dataclass(frozen=True)
class VideoIndex:
    """What opening a file learns by reading it through once (presentation time stamps and
    keyframes with PyAV, the frame count with OpenCV); pass it to :class:`VideoReader` to
    open the same file again without that pass (a chunk of a long video)."""

    decoder: str
    frames: int
    pts: tuple[int, ...] = ()
    keyframes: tuple[bool, ...] = ()


def default_decoder() -> str:
    """``"pyav"`` when PyAV is installed, else ``"opencv"``."""
    return "pyav" if has_module("av") else "opencv"


def check_decoder(decoder: str) -> str:
    if decoder not in ("auto", "pyav", "opencv"):
        raise ParameterError("decoder", decoder, "'auto', 'pyav' or 'opencv'")
    return default_decoder() if decoder == "auto" else decoder


def _check_size(path: Path, width: int, height: int, max_pixels: int) -> None:
    if width < _MIN_SIDE or height < _MIN_SIDE:
        raise InputError(
            path, f"frames are {width}x{height}, smaller than {_MIN_SIDE}x{_MIN_SIDE} pixels"
        )
    if width * height > max_pixels:
        raise InputError(
            path,
            f"frames are {width}x{height} ({width * height} pixels), more than the limit of "
            f"{max_pixels} pixels (max_pixels)",
        )


def _check_file(path: Path) -> None:
    if not path.exists():
        raise InputError(path, "file not found")
    if path.is_dir():
        raise InputError(path, "is a directory, not a video file")
    require_file(path, "video file")  # a FIFO or a device is never opened: it could block
    try:
        size = path.stat().st_size
    except OSError as exc:
        raise InputError(path, f"cannot read: {exc.strerror or exc}") from None
    if size == 0:
        raise InputError(path, "empty file (0 bytes)")


def _rotated(image: NDArray[np.uint8], rotation: int) -> NDArray[np.uint8]:
    if rotation == 0:
        return image
    return np.ascontiguousarray(np.rot90(image, rotation // 90))


def _quarter_turns(degrees: float) -> int:
    """A display rotation rounded to a multiple of 90 degrees in [0, 360)."""
    return round(degrees / 90.0) % 4 * 90


def _first_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return text[:200] or type(exc).__name__


class VideoReader(ClosesOnExit):
    """An open video file: its :attr:`info` and frames from any index.

    Parameters
    ----------
    path : path-like
        A video file (mp4, mov, mkv, avi, webm; anything FFmpeg demuxes).
    decoder : {"auto", "pyav", "opencv"}
        ``"auto"`` picks PyAV when installed.
    max_pixels : int
        Refuse frames with more pixels than this (:data:`MAX_VIDEO_PIXELS`).
    threads : int
        Decoder threads (PyAV): 1 decodes on the calling thread, 0 lets FFmpeg choose.

    Raises
    ------
    InputError
        Missing, empty or unreadable file, no video stream, no frames, or frames too small
        or too large.
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        *,
        decoder: Decoder = "auto",
        max_pixels: int = MAX_VIDEO_PIXELS,
        threads: int = 1,
        index: VideoIndex | None = None,
    ) -> None:
        self.path = Path(path)
        self.decoder = check_decoder(decoder)
        if index is not None and index.decoder != self.decoder:
            index = None  # another decoder counts and stamps frames its own way
        if isinstance(threads, bool) or not isinstance(threads, int) or not 0 <= threads <= 64:
            raise ParameterError("threads", threads, "an integer in [0, 64] (0: FFmpeg chooses)")
        self.threads = threads
        self.max_pixels = max_pixels
        _check_file(self.path)
        self._backend: _PyAVBackend | _OpenCVBackend
        if self.decoder == "pyav":
            self._backend = _PyAVBackend(self.path, max_pixels, threads, index)
        else:
            self._backend = _OpenCVBackend(self.path, max_pixels, index)
        self.info = self._backend.info
        if self.info.frames == 0:
            self.close()
            raise InputError(self.path, "the video has no frames")

    def __len__(self) -> int:
        return self.info.frames

    @property
    def index(self) -> VideoIndex:
        """This file's :class:`VideoIndex`, to reopen it quickly."""
        return self._backend.index

    def read(self, start: int = 0, stop: int | None = None) -> FrameReader:
        """Frames ``start`` to ``stop - 1`` (to the end when ``stop`` is None), in order.

        The returned iterator lists the frames it could not decode in ``bad_frames`` once
        it is exhausted.
        """
        n = self.info.frames
        stop = n if stop is None else stop
        if isinstance(start, bool) or not isinstance(start, int) or not 0 <= start <= n:
            raise ParameterError("start", start, f"a frame index in [0, {n}]")
        if isinstance(stop, bool) or not isinstance(stop, int) or not start <= stop <= n:
            raise ParameterError("stop", stop, f"a frame index in [{start}, {n}]")
        return FrameReader(self._backend, start, stop)

    def __iter__(self) -> Iterator[VideoFrame]:
        return iter(self.read())

    def close(self) -> None:
        self._backend.close()


@dataclass
class FrameReader:
    """Iterator over a range of frames; ``bad_frames`` fills in as it goes."""

    backend: _PyAVBackend | _OpenCVBackend
    start: int
    stop: int
    bad_frames: list[BadFrame] = field(default_factory=list)

    def __iter__(self) -> Iterator[VideoFrame]:
        seen = self.start
        for item in self.backend.frames(self.start, self.stop):
            if isinstance(item, BadFrame):
                self.bad_frames.append(item)
            else:
                yield item
            seen = item.index + 1
        info = self.backend.info
        if seen < self.stop:  # the decoder gave up before the end of the range
            reason = "truncated: no data" if info.truncated else "not decoded"
            self.bad_frames.extend(BadFrame(i, reason) for i in range(seen, self.stop))

    @property
    def first_bad_frame(self) -> int | None:
        return min((b.index for b in self.bad_frames), default=None)


class _PyAVBackend:
    """Decoding with PyAV; an index of presentation time stamps gives exact seeking."""

    def __init__(self, path: Path, max_pixels: int, threads: int, index: VideoIndex | None) -> None:
        av = require("av", "decoding videos with PyAV")
        from av.video.reformatter import VideoReformatter

        self._av = av
        self._rgb = VideoReformatter()
        self.path = path
        try:
            self._container = av.open(str(path), metadata_errors="ignore")
        except av.error.EOFError:
            raise InputError(
                path, "the video has no frames (the file ends after its header)"
            ) from None
        except (av.error.FFmpegError, OSError, UnicodeDecodeError) as exc:
            raise InputError(path, f"not a readable video ({_first_line(exc)})") from None
        try:
            if not self._container.streams.video:
                raise InputError(path, "no video stream")
            stream = self._container.streams.video[0]
            self._stream = stream
            ctx = stream.codec_context
            coded_w, coded_h = int(ctx.width), int(ctx.height)
            _check_size(path, coded_w, coded_h, max_pixels)
            ctx.thread_count = threads
            if threads != 1:
                ctx.thread_type = "AUTO"
            if index is None:
                self._pts, self._keyframes = self._scan()
            else:
                self._pts, self._keyframes = list(index.pts), list(index.keyframes)
            self.rotation = self._rotation()
            w, h = (coded_h, coded_w) if self.rotation in (90, 270) else (coded_w, coded_h)
            declared = int(stream.frames) or None
            self._time_base = stream.time_base or Fraction(1, 1)
            rate = stream.average_rate or stream.guessed_rate
            fps = float(rate) if rate else None
            n = len(self._pts)
            self.info = VideoInfo(
                path=str(path),
                decoder="pyav",
                width=w,
                height=h,
                rotation=self.rotation,
                frames=n,
                declared_frames=declared,
                fps=fps,
                duration=self._duration(fps),
                codec=str(ctx.name),
            )
        except BaseException:
            self._container.close()
            raise

    def _scan(self) -> tuple[list[int], list[bool]]:
        """Presentation time stamps of all frames (sorted) and which are keyframes."""
        av = self._av
        entries: list[tuple[int, bool]] = []
        count = 0
        try:
            for packet in self._container.demux(self._stream):
                if packet.size == 0:
                    continue
                ts = packet.pts if packet.pts is not None else packet.dts
                entries.append((count if ts is None else int(ts), bool(packet.is_keyframe)))
                count += 1
        except (av.error.FFmpegError, OSError):
            pass  # a truncated or damaged tail: the frames read so far are the file's frames
        entries.sort()
        self._rewind()
        return [e[0] for e in entries], [e[1] for e in entries]

    def _rotation(self) -> int:
        """Counter-clockwise display rotation: from the first frame's display matrix or the
        ``rotate`` tag (clockwise) of older files."""
        av = self._av
        degrees = 0.0
        try:
            for packet in self._container.demux(self._stream):
                frames = packet.decode()
                if frames:
                    degrees = float(frames[0].rotation or 0)
                    break
        except (av.error.FFmpegError, OSError, ValueError):
            pass
        self._rewind()
        if degrees:
            return _quarter_turns(degrees)
        tag = self._stream.metadata.get("rotate")
        try:
            return _quarter_turns(-float(tag)) if tag is not None else 0
        except ValueError:
            return 0

    def _duration(self, fps: float | None) -> float | None:
        if not self._pts:
            return None
        span = float((self._pts[-1] - self._pts[0]) * self._time_base)
        return span + (1.0 / fps if fps else 0.0)

    def _rewind(self) -> None:
        self._container.seek(0, stream=self._stream, backward=True, any_frame=False)
        self._stream.codec_context.flush_buffers()

    def _seek_to(self, index: int) -> None:
        """Position the demuxer at the last keyframe at or before frame ``index``."""
        key = next((i for i in range(index, -1, -1) if self._keyframes[i]), 0)
        if key == 0:
            self._rewind()
            return
        self._container.seek(self._pts[key], stream=self._stream, backward=True, any_frame=False)
        self._stream.codec_context.flush_buffers()

    def frames(self, start: int, stop: int) -> Iterator[VideoFrame | BadFrame]:
        av = self._av
        if start >= stop:
            return
        first = self._pts[0]
        lo = self._pts[start]
        hi = self._pts[stop] if stop < len(self._pts) else None
        expected = start
        if start == 0:
            self._rewind()
        else:
            self._seek_to(start)
        demux = self._container.demux(self._stream)
        while True:
            try:
                packet = next(demux)
            except StopIteration:
                return
            except (av.error.FFmpegError, OSError) as exc:
                yield BadFrame(expected, f"cannot read: {_first_line(exc)}")
                return
            try:
                decoded = packet.decode()
            except (av.error.FFmpegError, ValueError) as exc:
                bad = self._index_of(packet.pts, expected)
                if bad is not None and start <= bad < stop and bad >= expected:
                    for i in range(expected, bad):
                        yield BadFrame(i, "not decoded")
                    yield BadFrame(bad, f"cannot decode ({_first_line(exc)})")
                    expected = bad + 1
                continue
            for frame in decoded:
                pts = frame.pts
                if pts is None or pts < lo:
                    continue
                if hi is not None and pts >= hi:
                    return
                index = self._index_of(pts, expected)
                if index is None or index < expected:
                    continue
                for i in range(expected, index):
                    yield BadFrame(i, "not decoded")
                expected = index + 1
                if frame.is_corrupt:
                    yield BadFrame(index, "corrupt data (decoded with errors)")
                else:
                    # one converter for the whole file: to_ndarray(format=...) would set
                    # up a new swscale context for every frame (same pixels either way)
                    rgb = self._rgb.reformat(frame, format="rgb24").to_ndarray()
                    image = np.asarray(rgb, dtype=np.uint8)  # (it is uint8: no copy)
                    yield VideoFrame(
                        index,
                        float((pts - first) * self._time_base),
                        _rotated(image, self.rotation),
                    )
                if expected >= stop:
                    return

    @property
    def index(self) -> VideoIndex:
        return VideoIndex("pyav", len(self._pts), tuple(self._pts), tuple(self._keyframes))

    def _index_of(self, pts: int | None, default: int) -> int | None:
        if pts is None:
            return default
        i = bisect.bisect_left(self._pts, pts)
        return i if i < len(self._pts) and self._pts[i] == pts else None

    def close(self) -> None:
        self._container.close()


class _OpenCVBackend:
    """Decoding with OpenCV's FFmpeg backend (no PyAV): rotation applied by OpenCV."""

    def __init__(self, path: Path, max_pixels: int, index: VideoIndex | None) -> None:
        self.path = path
        self._cap = self._open()
        try:
            cap = self._cap
            w = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH))
            h = int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
            if w == 0 or h == 0:
                raise InputError(path, "not a readable video (no video stream found by OpenCV)")
            # OpenCV reports the clockwise angle it turns the pictures by.
            self.rotation = _quarter_turns(-float(cap.get(cv2.CAP_PROP_ORIENTATION_META) or 0))
            _check_size(path, w, h, max_pixels)
            declared = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) or None
            fps = float(cap.get(cv2.CAP_PROP_FPS)) or None
            count = self._count() if index is None else index.frames
            self.info = VideoInfo(
                path=str(path),
                decoder="opencv",
                width=w,
                height=h,
                rotation=self.rotation,
                frames=count,
                declared_frames=declared,
                fps=fps,
                duration=count / fps if fps else None,
                codec=_fourcc(cap.get(cv2.CAP_PROP_FOURCC)),
            )
        except BaseException:
            self._cap.release()
            raise

    def _open(self) -> Any:
        cap = cv2.VideoCapture(str(self.path), cv2.CAP_FFMPEG)
        if not cap.isOpened():
            raise InputError(self.path, "not a readable video (OpenCV cannot open it)")
        return cap

    def _count(self) -> int:
        n = 0
        while self._cap.grab():
            n += 1
        self._cap.set(cv2.CAP_PROP_POS_FRAMES, 0)
        return n

    @property
    def index(self) -> VideoIndex:
        return VideoIndex("opencv", self.info.frames)

    def frames(self, start: int, stop: int) -> Iterator[VideoFrame | BadFrame]:
        cap = self._cap
        cap.set(cv2.CAP_PROP_POS_FRAMES, start)
        for index in range(start, stop):
            ok, bgr = cap.read()
            if not ok or bgr is None:
                yield BadFrame(index, "cannot decode (OpenCV returned no frame)")
                return
            stamp = float(cap.get(cv2.CAP_PROP_POS_MSEC)) / 1000.0
            yield VideoFrame(index, stamp, cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))

    def close(self) -> None:
        self._cap.release()


def _fourcc(value: float) -> str:
    code = int(value)
    return "".join(chr((code >> (8 * i)) & 0xFF) for i in range(4)).strip("\x00 ") or "unknown"


def video_info(path: str | os.PathLike[str], *, decoder: Decoder = "auto") -> VideoInfo:
    """Open ``path``, return its :class:`VideoInfo` and close it."""
    with VideoReader(path, decoder=decoder) as reader:
        return reader.info


def is_video_file(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` has a video suffix (:data:`_VIDEO_SUFFIXES`)."""
    return Path(path).suffix.lower() in _VIDEO_SUFFIXES


# ---------------------------------------------------------------------------- writing


@dataclass(frozen=True)
class VideoWriteResult:
    """A finished video file.

    Attributes
    ----------
    path : str
        The file written (``None`` contents for in-memory writes).
    frames : int
        Frames written.
    encoder : str
        ``"libx264"``, ``"mpeg4"`` or ``"opencv-mp4v"``.
    width, height : int
        Size of the frames given.
    encoded_width, encoded_height : int
        Size in the file (one more where an odd size was padded).
    padded : bool
        An odd width or height was padded by one replicated edge pixel.
    """

    path: str
    frames: int
    encoder: str
    width: int
    height: int
    encoded_width: int
    encoded_height: int
    padded: bool

    def to_dict(self) -> dict[str, Any]:
        return {
            "path": self.path,
            "frames": self.frames,
            "encoder": self.encoder,
            "width": self.width,
            "height": self.height,
            "encoded_width": self.encoded_width,
            "encoded_height": self.encoded_height,
            "padded": self.padded,
        }


def default_encoder() -> str:
    """``"libx264"`` when PyAV has it, else ``"mpeg4"`` (PyAV), else ``"opencv"``."""
    if not has_module("av"):
        return "opencv"
    import av

    return "libx264" if "libx264" in av.codecs_available else "mpeg4"


def check_encoder(encoder: str) -> str:
    if encoder not in ("auto", "libx264", "mpeg4", "opencv"):
        raise ParameterError("encoder", encoder, "'auto', 'libx264', 'mpeg4' or 'opencv'")
    return default_encoder() if encoder == "auto" else encoder


def _check_fps(fps: object) -> float:
    ok = isinstance(fps, int | float) and not isinstance(fps, bool)
    if not ok or not 0.5 <= float(fps) <= 1000.0:  # type: ignore[arg-type]
        raise ParameterError("fps", fps, "a frame rate between 0.5 and 1000")
    return float(fps)  # type: ignore[arg-type]


def _even_padding(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    h, w = image.shape[:2]
    if h % 2 == 0 and w % 2 == 0:
        return image
    padded = cv2.copyMakeBorder(image, 0, h % 2, 0, w % 2, cv2.BORDER_REPLICATE)
    return np.asarray(padded, dtype=np.uint8)


class VideoWriter(FinishesOnExit):
    """Write RGB frames one at a time to an mp4 (or mov, mkv, avi) file, or to bytes.

    Parameters
    ----------
    path : path-like or None
        Target file; its suffix picks the container. ``None`` writes an mp4 in memory
        (:attr:`data` after :meth:`close`; PyAV encoders only).
    fps : float
        Nominal frame rate; frame ``i`` gets time ``i / fps`` unless :meth:`write` is given
        a timestamp.
    encoder : {"auto", "libx264", "mpeg4", "opencv"}
        ``"auto"``: libx264 if available, else mpeg4, else OpenCV's mp4v writer.
    crf : int
        libx264 quality (0 lossless luma .. 51; 23 is x264's default).
    preset : str
        libx264 preset; ``"ultrafast"`` has no B-frames (needed by :func:`concat_mp4`).
    threads : int
        Encoder threads (1: the calling thread; 0: FFmpeg chooses).
    keyframe_interval : int or None
        Frames between keyframes (``None``: the encoder's default, 250 for libx264).

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> with tempfile.TemporaryDirectory() as d:  # doctest: +SKIP
    ...     with VideoWriter(f"{d}/a.mp4", fps=10) as w:
    ...         w.write(np.zeros((160, 320, 3), np.uint8))
    """

    def __init__(
        self,
        path: str | os.PathLike[str] | None,
        fps: float = 10.0,
        *,
        encoder: Encoder = "auto",
        crf: int = 23,
        preset: str = "ultrafast",
        threads: int = 1,
        keyframe_interval: int | None = None,
    ) -> None:
        self.fps = _check_fps(fps)
        if keyframe_interval is not None and (
            isinstance(keyframe_interval, bool)
            or not isinstance(keyframe_interval, int)
            or not 1 <= keyframe_interval <= 100_000
        ):
            raise ParameterError("keyframe_interval", keyframe_interval, "an integer >= 1 or None")
        self.keyframe_interval = keyframe_interval
        self.encoder = check_encoder(encoder)
        if isinstance(crf, bool) or not isinstance(crf, int) or not 0 <= crf <= 51:
            raise ParameterError("crf", crf, "an integer in [0, 51]")
        self.crf, self.preset, self.threads = crf, preset, threads
        self.path = None if path is None else Path(path)
        self._scratch: Path | None = None
        if self.path is None and self.encoder == "opencv":
            # OpenCV writes only files: write one in the temporary folder, read it back
            import tempfile

            fd, name = tempfile.mkstemp(suffix=".mp4", prefix="qdcnn-")
            os.close(fd)
            self._scratch = Path(name)
        if self._scratch is not None:
            self._tmp: Path | None = self._scratch
        elif self.path is not None:
            suffix = self.path.suffix.lower()
            if suffix not in _FORMATS:
                raise ParameterError(
                    "path", str(self.path), "a .mp4, .m4v, .mov, .mkv or .avi file"
                )
            tmp = temporary_sibling(self.path)
            # keep the real suffix last: FFmpeg and OpenCV pick the container from it
            self._tmp = tmp.with_name(tmp.name + suffix)
        else:
            self._tmp = None
        self._buffer: io.BytesIO | None = None
        self.data: bytes | None = None
        self._size: tuple[int, int] | None = None
        self._frames = 0
        self._last_pts: int | None = None
        self._container: Any = None
        self._stream: Any = None
        self._cv_writer: Any = None
        self._av: Any = None
        self.result: VideoWriteResult | None = None

    @property
    def padded(self) -> bool:
        return self._size is not None and (self._size[0] % 2 == 1 or self._size[1] % 2 == 1)

    def _open(self, width: int, height: int) -> None:
        ew, eh = width + width % 2, height + height % 2
        if self._tmp is not None:
            try:
                self._tmp.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise InputError(
                    self._tmp.parent, f"cannot create folder: {exc.strerror}"
                ) from None
        if self.encoder == "opencv":
            assert self._tmp is not None
            fourcc = cv2.VideoWriter_fourcc(*"mp4v")
            writer = cv2.VideoWriter(str(self._tmp), fourcc, self.fps, (ew, eh))
            if not writer.isOpened():
                raise InputError(self.path or "video", "OpenCV cannot write this video file")
            self._cv_writer = writer
            return
        av = require("av", f"writing {self.encoder} video with PyAV")
        self._av = av
        if self.encoder not in av.codecs_available:
            raise ParameterError("encoder", self.encoder, "an encoder this PyAV build has")
        try:
            if self._tmp is None:
                self._buffer = io.BytesIO()
                self._container = av.open(self._buffer, "w", format="mp4")
            else:
                fmt = _FORMATS[self._tmp.suffix.lower()]
                self._container = av.open(str(self._tmp), "w", format=fmt)
        except (av.error.FFmpegError, OSError) as exc:
            raise InputError(self.path or "video", f"cannot write: {_first_line(exc)}") from None
        rate = Fraction(self.fps).limit_denominator(1001)
        stream = self._container.add_stream(self.encoder, rate=rate)
        stream.width, stream.height, stream.pix_fmt = ew, eh, "yuv420p"
        time_base = _H264_TIME_BASE if self.encoder == "libx264" else _MPEG4_TIME_BASE
        stream.time_base = time_base
        stream.codec_context.time_base = time_base
        stream.codec_context.thread_count = self.threads
        if self.keyframe_interval is not None:
            stream.codec_context.gop_size = self.keyframe_interval
        if self.encoder == "libx264":
            stream.options = {"preset": self.preset, "crf": str(self.crf), "tune": "zerolatency"}
        else:
            stream.codec_context.bit_rate = max(200_000, ew * eh * 8)
        self._stream = stream
        self._time_base = time_base

    def write(self, image: NDArray[np.uint8], timestamp: float | None = None) -> None:
        """Append one RGB uint8 frame (all frames must have the first frame's size)."""
        arr = np.asarray(image)
        if arr.dtype != np.uint8 or not has_shape(arr, "H,W,3"):
            raise InputError(
                "image", f"expected an RGB uint8 array (H, W, 3), got {arr.dtype} {arr.shape}"
            )
        h, w = arr.shape[:2]
        if self._size is None:
            if w < 2 or h < 2:
                raise InputError("image", f"frame is {w}x{h}; at least 2x2 pixels to encode")
            self._size = (w, h)
            self._open(w, h)
        elif self._size != (w, h):
            raise InputError(
                "image",
                f"frame {self._frames} is {w}x{h}, the video is {self._size[0]}x{self._size[1]}",
            )
        arr = _even_padding(np.ascontiguousarray(arr))
        t = self._frames / self.fps if timestamp is None else float(timestamp)
        if self._cv_writer is not None:
            self._cv_writer.write(cv2.cvtColor(arr, cv2.COLOR_RGB2BGR))
        else:
            self._encode(arr, t)
        self._frames += 1

    def _encode(self, arr: NDArray[np.uint8], t: float) -> None:
        pts = round(t / self._time_base)
        if self._last_pts is not None and pts <= self._last_pts:
            raise ParameterError("timestamp", t, "increasing from frame to frame")
        self._last_pts = pts
        # OpenCV's BT.601 conversion is faster than the encoder's own (swscale) one; the
        # frame wraps the new array instead of copying it (a tenth of from_ndarray's time)
        yuv = cv2.cvtColor(arr, cv2.COLOR_RGB2YUV_I420)
        frame = self._av.VideoFrame.from_numpy_buffer(yuv, format="yuv420p")
        frame.pts = pts
        frame.time_base = self._time_base
        for packet in self._stream.encode(frame):
            self._container.mux(packet)

    def close(self) -> VideoWriteResult:
        """Flush, close and move the file into place; returns what was written."""
        if self.result is not None:
            return self.result
        if self._size is None:
            self.abort()
            raise InputError(self.path or "video", "no frames to write")
        try:
            if self._cv_writer is not None:
                self._cv_writer.release()
            else:
                for packet in self._stream.encode():
                    self._container.mux(packet)
                self._container.close()
            if self._buffer is not None:
                self.data = self._buffer.getvalue()
            elif self._scratch is not None:
                self.data = self._scratch.read_bytes()
                self._scratch.unlink(missing_ok=True)
            elif self._tmp is not None and self.path is not None:
                with open(self._tmp, "rb+") as fh:
                    os.fsync(fh.fileno())
                os.replace(self._tmp, self.path)
        except OSError as exc:
            self.abort()
            raise InputError(self.path or "video", f"cannot write: {exc.strerror or exc}") from None
        w, h = self._size
        self.result = VideoWriteResult(
            path=str(self.path) if self.path is not None else "",
            frames=self._frames,
            encoder="opencv-mp4v" if self.encoder == "opencv" else self.encoder,
            width=w,
            height=h,
            encoded_width=w + w % 2,
            encoded_height=h + h % 2,
            padded=self.padded,
        )
        return self.result

    def abort(self) -> None:
        """Stop without producing a file (the temporary file is removed)."""
        try:
            if self._cv_writer is not None:
                self._cv_writer.release()
            elif self._container is not None:
                self._container.close()
        except Exception:  # best effort while discarding a failed write
            pass
        if self._tmp is not None:
            self._tmp.unlink(missing_ok=True)
        self._container = self._cv_writer = None


def concat_mp4(
    segments: Sequence[tuple[bytes | Path, float]],
    path: str | os.PathLike[str],
    *,
    atomic: bool = True,
) -> int:
    """Join mp4 segments written by :class:`VideoWriter` into one file without re-encoding.

    Parameters
    ----------
    segments : list of (bytes or Path, float)
        Each segment (an mp4 in memory or a file) and the time in seconds at which it
        starts in the joined video; each segment's own timestamps start at 0. All segments
        need the same encoder settings and size, and no B-frames (libx264 ``ultrafast``).
    path : path-like
        The joined file.
    atomic : bool
        Write to a temporary name and rename when complete (False: write ``path`` itself,
        for callers that already write to a temporary name).

    Returns
    -------
    int
        Frames (packets) written.
    """
    av = require("av", "joining video segments")
    target = Path(path)
    tmp = temporary_sibling(target) if atomic else target
    if atomic:
        tmp = tmp.with_name(tmp.name + target.suffix)
    out = av.open(str(tmp), "w", format=_FORMATS.get(target.suffix.lower(), "mp4"))
    frames = 0
    try:
        out_stream = None
        for segment, start in segments:
            src = av.open(io.BytesIO(segment) if isinstance(segment, bytes) else str(segment))
            try:
                stream = src.streams.video[0]
                if out_stream is None:
                    out_stream = out.add_stream_from_template(stream)
                    out_stream.time_base = stream.time_base
                offset = round(Fraction(start).limit_denominator(10**6) / stream.time_base)
                for packet in src.demux(stream):
                    if packet.dts is None:
                        continue
                    packet.pts = None if packet.pts is None else packet.pts + offset
                    packet.dts = packet.dts + offset
                    packet.stream = out_stream
                    out.mux(packet)
                    frames += 1
            finally:
                src.close()
        out.close()
        if atomic:
            with open(tmp, "rb+") as fh:
                os.fsync(fh.fileno())
            os.replace(tmp, target)
    except BaseException:
        try:
            out.close()
        except Exception:  # already failing: keep the first error
            pass
        tmp.unlink(missing_ok=True)
        raise
    return frames
