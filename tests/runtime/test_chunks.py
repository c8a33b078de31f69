"""One chunk processed: the trailing majority vote and the csv header."""

from __future__ import annotations

from video_fakes import HalvesProcessor

from qdcnn.runtime.chunks import csv_header, majority_vote


def test_majority_vote_prefers_the_most_recent_of_tied_decisions() -> None:
    assert majority_vote(["left", "left", "right"]) == "left"
    assert majority_vote(["left", "right"]) == "right"
    assert majority_vote(["right", "left", None]) == "left"
    assert majority_vote([None, None]) is None


def test_the_header_is_fixed_with_the_raw_decision_always() -> None:
    assert csv_header(HalvesProcessor()) == [
        "frame", "timestamp", "direction", "direction_raw", "p_left", "p_straight", "p_right",
        "shadow_fraction", "lane_status", "status", "note",
    ]  # fmt: skip
