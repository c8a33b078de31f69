"""The chunked, resumable execution engine, handed a frame processor by its caller.

It imports nothing from :mod:`qdcnn.direction` or :mod:`qdcnn.experiments`.

=====================  ============================================================
``engine``             inputs -> chunks -> per-input outputs, resumable
``scheduler``          where chunks run: in process or on a Dask cluster
``resume``             the output folder's manifest of finished work
``timing``             measured timings (never estimates)
``reporting``          the :class:`Reporter` runners report through
=====================  ============================================================
"""

from qdcnn._lazy import attach

__getattr__, __dir__, __all__ = attach(
    __name__,
    {
        "engine": ["FrameOutcome", "FrameProcessor", "RunOptions", "RunResult", "run_inputs"],
        "scheduler": ["Executor", "TaskFailure"],
        "reporting": ["Reporter"],
    },
)
