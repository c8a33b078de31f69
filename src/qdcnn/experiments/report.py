"""The ``qdcnn demo`` report, now :func:`qdcnn.experiments.reproduce.run_reproduce`.

``qdcnn demo`` is ``qdcnn reproduce --quick`` on the synthetic presets: one code path.
:func:`run_demo` stays importable for existing callers.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from qdcnn.experiments.reproduce import (
    ReproduceSpec,
    StageReporter,
    named_options_config,
    run_reproduce,
)
from qdcnn.runtime.reporting import Reporter

__all__ = ["named_options_config", "run_demo"]


class _Say(StageReporter):
    def __init__(self, say: Callable[[str], None]) -> None:
        self.say = say

    def stage(self, index: int, total: int, title: str) -> None:
        self.say(f"[{index}/{total}] {title}")


def run_demo(
    out_dir: Path,
    *,
    quick: bool = True,
    seed: int = 0,
    say: Callable[[str], None] | None = None,
    force: bool = False,
) -> dict[str, Any]:
    """``reproduce`` on the synthetic presets; the paths written and each section's status."""
    reporter: Reporter = Reporter() if say is None else _Say(say)
    spec = ReproduceSpec(Path(out_dir), quick=quick, seed=seed, force=force)
    return run_reproduce(spec, reporter).to_dict()
