"""The demo report's sections run on tiny synthetic sets and write their figures."""

from __future__ import annotations

from pathlib import Path

from qdcnn.experiments.direction_model import default_config
from qdcnn.experiments.report import direction_section, named_options_config, shadow_section


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
    assert len(section.data) == 27  # 3 presets x (6 methods + 3 UU methods with named options)
    for result in section.data.values():
        assert 0 <= result["accuracy"] <= 1 and result["n"] == 120
    named = [k for k in section.data if k.endswith("/named-options")]
    assert len(named) == 9 and all("-uu/" in k for k in named)
    assert "accuracy (named options)" in section.body
    assert (tmp_path / "lanes.png").stat().st_size > 0


def test_named_options_leave_the_paper_defaults_alone() -> None:
    paper = default_config()
    named = named_options_config(paper)
    assert (named.lanes.edge_channels, named.lanes.remove_shadows) == ("rgb", False)
    assert named.grouping.features == "road-centre"
    assert (paper.lanes.edge_channels, paper.lanes.remove_shadows) == ("grey", True)
    assert paper.grouping.features == "slopes" and named.lanes.canny_low == paper.lanes.canny_low
