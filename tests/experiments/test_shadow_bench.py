"""The shadow benchmark's structure (no timing is asserted: benchmarks are not tests)."""

from __future__ import annotations

from qdcnn.cli.bench import _ratio_line
from qdcnn.experiments.shadow_bench import IBT_TARGETS, bench_shadows, time_in_turns


def test_time_in_turns_calls_every_function_on_every_item_in_turn() -> None:
    calls: list[tuple[str, int]] = []
    fns = {name: (lambda item, name=name: calls.append((name, item))) for name in ("a", "b")}
    timings = time_in_turns(fns, [1, 2, 3], repeats=2)
    assert set(timings) == {"a", "b"}
    assert all(t.repeats == 2 and t.min_s <= t.median_s <= t.max_s for t in timings.values())
    # one untimed warm-up call each, then a and b take turns item by item, the one to
    # go first rotating from item to item
    assert calls[:2] == [("a", 1), ("b", 1)]
    assert calls[2:8] == [("a", 1), ("b", 1), ("b", 2), ("a", 2), ("a", 3), ("b", 3)]
    assert calls[8:14] == [("b", 1), ("a", 1), ("a", 2), ("b", 2), ("b", 3), ("a", 3)]
    assert len(calls) == 2 + 2 * 3 * 2


def test_bench_reports_every_uu_variant_as_a_ratio_to_ibt() -> None:
    result = bench_shadows(((160, 80),), frames=1, repeats=1, aer_blocks=0, include_lbp=False)
    (row,) = result["results"]
    assert set(row["ratios_to_ibt"]) == set(IBT_TARGETS)
    for name, ratio in row["ratios_to_ibt"].items():
        assert ratio == row["seconds"][name] / row["seconds"]["ibt"]
    line = _ratio_line(row)
    assert line.startswith("UU-dagger / IBT, 160x80: exact ")
    assert "1024-shots-calibrated" in line and "(target 1.5x)" in line
