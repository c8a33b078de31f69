"""Moved to :mod:`qdcnn.data.frames`; this name stays for existing imports."""

from qdcnn.data.frames import DEFAULT_SYNTHETIC_FRAMES, FrameSet, load_frameset, parse_spec

__all__ = ["DEFAULT_SYNTHETIC_FRAMES", "FrameSet", "load_frameset", "parse_spec"]
