"""Dataset specifications, synthetic drives and cached lane features."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from qdcnn.config import GroupingConfig
from qdcnn.data.frames import load_frameset, parse_spec
from qdcnn.data.images import write_image
from qdcnn.data.synthetic import generate_drive
from qdcnn.data.writers import write_udacity
from qdcnn.direction import features as features_module
from qdcnn.direction.features import code_fingerprint, compute_features
from qdcnn.direction.model import default_config
from qdcnn.errors import ParameterError
from qdcnn.pipeline import process_frame


@pytest.mark.parametrize(
    "spec",
    [
        "track1",
        "udacity:",
        "ftp:x",
        "synthetic:track9",
        "synthetic:track1:abc",
        "synthetic:track1:5",
    ],
)
def test_bad_specs(spec: str) -> None:
    with pytest.raises(ParameterError, match="data="):
        load_frameset(spec)


def test_parse_spec() -> None:
    assert parse_spec("carla:/a/b") == ("carla", "/a/b")


def test_synthetic_drive_frameset_has_labels_from_steering() -> None:
    fs = load_frameset("synthetic:track1:40", seed=3)
    assert len(fs) == 40 and fs.image(0).shape == (160, 320, 3)
    assert fs.labels().shape == (40,)
    assert fs.fingerprint() == load_frameset("synthetic:track1:40", seed=3).fingerprint()
    assert fs.fingerprint() != load_frameset("synthetic:track1:40", seed=4).fingerprint()


def test_features_are_cached_and_unreadable_frames_listed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    rec = tmp_path / "rec"
    write_udacity(generate_drive("track1", 12, seed=1), rec)
    frames = sorted((rec / "IMG").iterdir())
    frames[4].write_bytes(b"garbage")  # one corrupt frame
    fs = load_frameset(f"udacity:{rec}")
    cfg = default_config()
    first = compute_features(fs, cfg, ("image-split", "kmeans"))
    assert not first.cached
    assert first.readable.sum() == 11 and not first.readable[4]
    assert [f.file for f in first.failures] == [str(frames[4])]
    assert first.status["kmeans"][4] == "unreadable"
    again = compute_features(fs, cfg, ("image-split", "kmeans"))
    assert again.cached
    for g in ("image-split", "kmeans"):
        np.testing.assert_array_equal(again.features[g], first.features[g])
        np.testing.assert_array_equal(again.status[g], first.status[g])
    assert again.failures == first.failures
    # a changed frame changes the fingerprint, so the cache is not reused
    write_image(frames[4], fs.image(3))
    third = compute_features(load_frameset(f"udacity:{rec}"), cfg, ("image-split", "kmeans"))
    assert not third.cached and third.readable.all()


def test_feature_modes_with_two_column_extras_fill_every_column(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    fs = load_frameset("synthetic:track1:10", seed=2)
    cfg = replace(default_config(), grouping=GroupingConfig.for_features("road-centre"))
    table = compute_features(fs, cfg, ("image-split",))
    feats = table.features["image-split"]
    assert feats.shape == (10, 4)  # two slopes, then the centre line at the far and near rows
    rng = np.random.default_rng(cfg.seed)  # shot-sampled shadow removal draws in frame order
    for i in range(len(fs)):
        direct = process_frame(fs.image(i), cfg, ("image-split",), rng=rng).lanes["image-split"]
        np.testing.assert_array_equal(feats[i], direct.features)
    ok = table.status["image-split"] == "ok"
    assert ok.any() and np.isfinite(feats[ok]).all()


def test_a_code_change_is_a_cache_miss(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    package = tmp_path / "pkg"
    (package / "vision").mkdir(parents=True)
    (package / "vision" / "lanes.py").write_text("THRESHOLD = 50\n")
    before = code_fingerprint(package)
    (package / "vision" / "lanes.py").write_text("THRESHOLD = 51\n")
    code_fingerprint.cache_clear()
    assert code_fingerprint(package) != before
    code_fingerprint.cache_clear()
    # and the features cache obeys it: the same data and settings under other code miss
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    fs = load_frameset("synthetic:track1:10", seed=2)
    assert not compute_features(fs, default_config(), ("image-split",)).cached
    assert compute_features(fs, default_config(), ("image-split",)).cached
    monkeypatch.setattr(features_module, "code_fingerprint", lambda: "other code")
    assert not compute_features(fs, default_config(), ("image-split",)).cached


def test_a_recording_in_row_order_keeps_its_skipped_rows_as_frames(tmp_path: Path) -> None:
    from qdcnn.data.frames import RecordingFrames
    from qdcnn.data.recording import RowError

    names = [f"center_2024_01_01_12_00_00_{ms:03d}.jpg" for ms in range(0, 500, 100)]
    for i, name in enumerate(names):
        write_image(tmp_path / "IMG" / name, np.full((8, 8, 3), 50 * i, np.uint8))
    steering = ["0.1", "abc", "0.2", "", "-0.1"]
    lines = [f"IMG/{n}, , , {s}, 0, 0, 1" for n, s in zip(names, steering, strict=True)]
    (tmp_path / "driving_log.csv").write_text("\n".join(lines) + "\n")
    frames = load_frameset(f"udacity:{tmp_path}")
    assert len(frames) == 3
    ordered = frames.in_recording_order()
    assert isinstance(ordered, RecordingFrames) and len(ordered) == 5
    assert ordered.image(4)[0, 0, 0] == 200  # the fifth row's image, not the third frame's
    with pytest.raises(RowError, match=r"driving_log\.csv:row 2: steering 'abc' is not a number"):
        ordered.image(1)
    assert ordered.timestamps is not None
    assert (
        np.isnan(ordered.timestamps[[1, 3]]).all()
        and np.isfinite(ordered.timestamps[[0, 2, 4]]).all()
    )
    before = ordered.fingerprint()
    (tmp_path / "driving_log.csv").write_text("\n".join(lines).replace("abc", "xyz") + "\n")
    assert load_frameset(f"udacity:{tmp_path}").in_recording_order().fingerprint() != before
    clean = load_frameset("synthetic:track1:10")
    assert clean.in_recording_order() is clean  # nothing skipped: the frames as they are
