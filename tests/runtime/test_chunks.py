"""One chunk processed: the trailing majority vote and the csv header."""

from __future__ import annotations

from video_fakes import HalvesProcessor

from qdcnn.runtime.chunks import csv_header, majority_vote


def test_majority_vote_prefers_the_most_recent_of_tied_decisions() -> None:
    assert majority_vote(["left", "left", "right"]) == "left"
    assert majority_vote(["left", "right"]) == "right"
    assert majority_vote(["right", "left", None]) == "left"
    assert majority_vote([None, None]) is None


def test_the_header_has_raw_decisions_only_when_smoothing() -> None:
    assert csv_header(HalvesProcessor(), 1) == [
        "frame", "timestamp", "direction", "p_left", "p_straight", "p_right",
        "shadow_fraction", "lane_status",
    ]  # fmt: skip
    assert csv_header(HalvesProcessor(), 3)[3] == "direction_raw"
