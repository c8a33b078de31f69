"""The demo report's sections run on tiny synthetic sets and write their figures."""

from __future__ import annotations

from pathlib import Path

from qdcnn.experiments.report import direction_section, shadow_section


def test_shadow_section_scores_every_detector(tmp_path: Path) -> None:
    section = shadow_section(tmp_path, n_test=2, n_train=3, seed=0, say=lambda _m: None)
    scores = section.data["scores"]
    assert {"ibt", "cbs", "lbp", "uu-chroma"} <= set(scores)
    assert sum(name.startswith("uu ") for name in scores) == 3
    for s in scores.values():
        assert 0 <= s["ber"] <= 100 and s["n"] == 2 and s["ms_per_frame"] > 0
    assert (tmp_path / "shadows.png").stat().st_size > 0
    assert section.data["multi_model"]["centroids"]


def test_direction_section_runs_the_six_methods_on_three_presets(tmp_path: Path) -> None:
    section = direction_section(tmp_path, n_frames=120, seed=0, say=lambda _m: None)
    assert len(section.data) == 18
    for result in section.data.values():
        assert 0 <= result["accuracy"] <= 1 and result["n"] == 120
    assert (tmp_path / "lanes.png").stat().st_size > 0
