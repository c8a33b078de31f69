"""The benchmarks' timing records: what they claim about the fold cache."""

from __future__ import annotations

import json
import sys
from pathlib import Path

BENCHMARKS = Path(__file__).parents[1] / "benchmarks"


def test_a_timing_record_states_the_cache_only_when_it_is_known(tmp_path: Path) -> None:
    sys.path.insert(0, str(BENCHMARKS))
    try:
        from cross_recording import _record
    finally:
        sys.path.remove(str(BENCHMARKS))
    path = tmp_path / "timing.json"
    _record(path, "own", ["dnn-pilotnet"], 2, True, 12.34, 20.0, load=False)
    _record(path, "shared", ["dnn-pilotnet"], 2, None, 5.0, 9.0, load=False, commit="abc")
    timing = json.loads(path.read_text(encoding="utf-8"))
    assert timing["own"]["cold_cache"] is True and timing["own"]["wall_seconds"] == 12.3
    assert "cold_cache" not in timing["shared"] and timing["shared"]["commit"] == "abc"
