"""Feature cache entries: round trip, concurrent writers, bad entries named, removed, recomputed."""

from __future__ import annotations

import io
import os
import subprocess
import sys
import textwrap
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from qdcnn.batch import Failure
from qdcnn.data.frames import load_frameset
from qdcnn.direction.feature_cache import (
    CachedFeatures,
    FeatureCacheWarning,
    entry_path,
    evict,
    read_entry,
    write_entry,
)
from qdcnn.direction.features import compute_features
from qdcnn.direction.model import default_config

GROUPINGS = ("image-split", "kmeans")
SRC = Path(__file__).resolve().parents[2] / "src"


def entry() -> CachedFeatures:
    """Five frames, two feature columns; frame 1 is unreadable."""
    readable = np.array([True, False, True, True, True])
    status = np.array(["ok", "unreadable", "one-line", "no-lines", "ok"])
    feats = np.random.default_rng(0).normal(size=(5, 2))
    feats[1] = np.nan
    return CachedFeatures(
        {g: feats + i for i, g in enumerate(GROUPINGS)},
        {g: status.copy() for g in GROUPINGS},
        readable,
        [Failure("IMG/b.jpg", "IMG/b.jpg: not a readable image (corrupt or unsupported format)")],
        0.0123,
    )


def same(a: CachedFeatures, b: CachedFeatures) -> None:
    for g in GROUPINGS:
        np.testing.assert_array_equal(a.features[g], b.features[g])
        np.testing.assert_array_equal(a.status[g], b.status[g])
    np.testing.assert_array_equal(a.readable, b.readable)
    assert a.failures == b.failures and a.seconds_per_frame == b.seconds_per_frame


def test_round_trip_leaves_no_temporary(tmp_path: Path) -> None:
    path = entry_path(tmp_path / "cache", "abc")
    assert read_entry(path, GROUPINGS, 5, 2) is None  # a miss, silently
    assert write_entry(path, entry(), GROUPINGS)
    got = read_entry(path, GROUPINGS, 5, 2)
    assert got is not None
    same(got, entry())
    assert [p.name for p in path.parent.iterdir()] == ["features-abc.npz"]


def npz_bytes(**arrays: np.ndarray) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


def good_arrays() -> dict[str, np.ndarray]:
    with np.load(io.BytesIO(_written())) as data:
        return {name: data[name] for name in data.files}


def _written() -> bytes:
    buffer = io.BytesIO()
    e = entry()
    arrays = {
        "readable": e.readable,
        "seconds": np.array(e.seconds_per_frame),
        "failures": np.array(['{"file": "IMG/b.jpg", "error": "bad"}']),
    }
    for g in GROUPINGS:
        arrays[f"features/{g}"] = e.features[g]
        arrays[f"status/{g}"] = e.status[g]
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


def changed(**replace: np.ndarray | None) -> bytes:
    arrays = good_arrays()
    for name, value in replace.items():
        name = name.replace("__", "/")
        if value is None:
            arrays.pop(name)
        else:
            arrays[name] = value
    return npz_bytes(**arrays)


def _npy_bytes() -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, np.zeros(3))
    return buffer.getvalue()


BAD_ENTRIES = {
    "garbage": (b"this is not a cache entry", "is unreadable (ValueError"),
    "truncated": (_written()[:300], "is unreadable (BadZipFile"),
    "empty": (b"", "is unreadable ("),
    "npy": (_npy_bytes(), "is not an .npz archive"),
    "pickled": (
        npz_bytes(**{**good_arrays(), "failures": np.array([{"file": 1}], dtype=object)}),
        "is unreadable (ValueError: Object arrays cannot be loaded when allow_pickle=False",
    ),
    "missing key": (changed(seconds=None), "has other arrays (missing ['seconds'], unexpected []"),
    "extra key": (changed(extra=np.zeros(1)), "unexpected ['extra']"),
    "short": (changed(readable=np.ones(4, bool)), "array 'readable' is bool (4,), expected"),
    "wrong dtype": (
        changed(features__kmeans=np.zeros((5, 2), np.int64)),
        "array 'features/kmeans' is int64 (5, 2), expected kind 'f' (5, 2)",
    ),
    "odd status": (
        changed(status__kmeans=np.array(["ok", "unreadable", "ok", "what", "ok"])),
        "status/kmeans holds unknown values ['what']",
    ),
    "status vs readable": (
        changed(readable=np.ones(5, bool)),
        "status/image-split does not match 'readable'",
    ),
    "negative seconds": (changed(seconds=np.array(-1.0)), "seconds per frame is -1.0"),
    "failure count": (changed(failures=np.array([], dtype=str)), "lists 0 failures for 1 frames"),
    "failure record": (
        changed(failures=np.array(['{"file": "x"}'])),
        "a failure record is not {'file': str, 'error': str}",
    ),
}


@pytest.mark.parametrize("case", list(BAD_ENTRIES))
def test_bad_entry_is_named_removed_and_missed(tmp_path: Path, case: str) -> None:
    data, reason = BAD_ENTRIES[case]
    path = entry_path(tmp_path, "k")
    path.write_bytes(data)
    seen: list[tuple[Path, str]] = []
    assert read_entry(path, GROUPINGS, 5, 2, on_bad=lambda p, r: seen.append((p, r))) is None
    assert len(seen) == 1 and seen[0][0] == path
    assert reason in seen[0][1], seen[0][1]
    assert seen[0][1].endswith("; removed, the features are computed again")
    assert not path.exists()


def test_bad_entry_warning_names_the_file(tmp_path: Path) -> None:
    path = entry_path(tmp_path, "k")
    path.write_bytes(b"garbage")
    with pytest.warns(FeatureCacheWarning) as record:
        assert read_entry(path, GROUPINGS, 5, 2) is None
    (warning,) = record
    text = str(warning.message)
    assert text.startswith(f"{path}: feature cache entry is unreadable") and "\n" not in text


def test_evict_keeps_an_entry_replaced_meanwhile(tmp_path: Path) -> None:
    path = entry_path(tmp_path, "k")
    path.write_bytes(b"bad")
    seen = os.stat(path)
    write_entry(path, entry(), GROUPINGS)  # another process replaces it
    assert not evict(path, seen)
    assert read_entry(path, GROUPINGS, 5, 2) is not None
    assert evict(path) and not path.exists()


def test_unwritable_cache_is_reported_not_fatal(tmp_path: Path) -> None:
    blocker = tmp_path / "cache"
    blocker.write_text("a file where the cache folder should be")
    path = entry_path(blocker, "k")
    with pytest.warns(FeatureCacheWarning, match="feature cache entry not written"):
        assert not write_entry(path, entry(), GROUPINGS)


def test_compute_features_recomputes_a_corrupt_entry(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    fs = load_frameset("synthetic:track1:10", seed=2)
    cfg = default_config()
    first = compute_features(fs, cfg, ("image-split",))
    (path,) = (tmp_path / "cache").iterdir()
    good = path.read_bytes()
    for damaged in (good[: len(good) // 2], b"\x00" * 64, b"PK\x03\x04garbage"):
        path.write_bytes(damaged)
        with pytest.warns(FeatureCacheWarning, match=f"{path}: feature cache entry"):
            again = compute_features(fs, cfg, ("image-split",))
        assert not again.cached  # recomputed, and the same features
        np.testing.assert_array_equal(again.features["image-split"], first.features["image-split"])
        assert compute_features(fs, cfg, ("image-split",)).cached  # a good entry again


WRITER = textwrap.dedent(
    """
    import sys
    import warnings
    from pathlib import Path

    import numpy as np

    from qdcnn.batch import Failure
    from qdcnn.direction.feature_cache import CachedFeatures, read_entry, write_entry

    path, seed, rounds = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3])
    n, groupings = 2000, ("image-split", "kmeans", "spectral")
    rng = np.random.default_rng(seed)
    readable = np.ones(n, bool)
    readable[::7] = False
    status = np.where(readable, "ok", "unreadable")
    failures = [Failure(f"f{i}", "bad") for i in np.flatnonzero(~readable)]
    warnings.simplefilter("error")  # a bad entry read back would fail this process
    for _ in range(rounds):
        feats = {g: rng.normal(size=(n, 2)) for g in groupings}
        write_entry(path, CachedFeatures(feats, {g: status for g in groupings}, readable,
                                         failures, 0.5), groupings)
        got = read_entry(path, groupings, n, 2)
        assert got is not None, "entry vanished or was bad"
    print("ok")
    """
)


def test_two_processes_writing_one_key_never_crash_or_corrupt(tmp_path: Path) -> None:
    path = entry_path(tmp_path / "cache", "same-key")
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", WRITER, str(path), str(seed), "20"],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
            text=True,
        )
        for seed in (1, 2)
    ]
    for proc in procs:
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0, err[-2000:]
        assert out.strip() == "ok"
    assert [p.name for p in path.parent.iterdir()] == [path.name]  # no temporaries left
    assert read_entry(path, ("image-split", "kmeans", "spectral"), 2000, 2) is not None
    with zipfile.ZipFile(path) as archive:
        assert archive.testzip() is None


def test_auto_lanes_estimate_the_camera_and_say_what_they_chose(tmp_path, monkeypatch) -> None:
    from qdcnn.config import LaneConfig, PipelineConfig
    from qdcnn.data.frames import load_frameset
    from qdcnn.direction.features import compute_features

    monkeypatch.setenv("QDCNN_CACHE", str(tmp_path / "cache"))
    frames = load_frameset("synthetic:dashcam:60", seed=2)
    cfg = PipelineConfig(lanes=LaneConfig.auto())
    table = compute_features(frames, cfg, ("image-split",))
    assert table.camera is not None and "horizon" in str(table.camera)
    assert table.readable.all()
    again = compute_features(frames, cfg, ("image-split",))
    assert again.cached and again.camera == table.camera
    tracked = replace(cfg, grouping=replace(cfg.grouping, track="ema"))
    smooth = compute_features(frames, tracked, ("image-split",))
    assert not np.array_equal(
        smooth.features["image-split"], table.features["image-split"], equal_nan=True
    )
