"""The chunked, resumable execution engine, handed a frame processor by its caller.

It imports nothing from :mod:`qdcnn.direction` or :mod:`qdcnn.experiments`.

=====================  ============================================================
``engine``             the run: inputs -> chunks -> per-input outputs, resumable
``inputs``             video files, image folders and frame sources, by name
``chunks``             one chunk processed: rows, timings, overlay segment
``assembly``           chunk files, then an input's final files
``manifest``           the output folder's layout and manifest of finished work
``scheduler``          where chunks run: in process or on a Dask cluster
``timing``             measured timings (never estimates)
``reporting``          the :class:`Reporter` runners report through
=====================  ============================================================
"""

from qdcnn._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "chunks": ["FrameOutcome", "FrameProcessor"],
        "engine": ["RunOptions", "RunResult", "run_inputs"],
        "manifest": ["ResumableBatch"],
        "scheduler": ["Executor", "TaskFailure"],
        "reporting": ["Reporter"],
    },
)
