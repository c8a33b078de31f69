"""evaluate_frames: the CNN row under the quantum methods' folds, with bad frames listed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
cv2 = pytest.importorskip("cv2")

from qdcnn.config import PipelineConfig  # noqa: E402
from qdcnn.data.frames import FrameSet, stack_images  # noqa: E402
from qdcnn.direction.methods import TrainingOptions  # noqa: E402
from qdcnn.direction.protocol import ContiguousKFold  # noqa: E402
from qdcnn.experiments.evaluate import evaluate_frames  # noqa: E402


def lean_frame(label: int, rng: np.random.Generator, h: int = 40, w: int = 80) -> np.ndarray:
    """A dark frame with one bright line leaning left (0), upright (1) or right (2)."""
    img = (60 + rng.integers(0, 20, (h, w, 3))).astype(np.uint8)
    x0 = w / 2 + rng.uniform(-6, 6)
    lean = (-1, 0, 1)[label] * rng.uniform(0.6, 1.0) * w / 2
    cv2.line(img, (int(x0), h - 1), (int(x0 + lean), 0), (240, 240, 240), 3)
    return img


def recording(tmp_path: Path, n: int, bad: dict[int, str]) -> tuple[FrameSet, np.ndarray]:
    """``n`` frames on disk in blocks of one label; ``bad`` replaces frames by broken files."""
    rng = np.random.default_rng(0)
    labels = np.repeat(np.arange(n // 10) % 3, 10).astype(np.int64)
    paths = []
    for i, label in enumerate(labels):
        p = tmp_path / f"f{i:03d}.png"
        if bad.get(i) == "corrupt":
            p.write_bytes(b"not a png")
        elif bad.get(i) == "size":
            cv2.imwrite(str(p), np.zeros((20, 20, 3), np.uint8))
        else:
            cv2.imwrite(str(p), lean_frame(int(label), rng)[:, :, ::-1])
        paths.append(p)
    frames = FrameSet(
        name="toy",
        spec=f"udacity:{tmp_path}",
        steering=np.array([-0.5, 0.0, 0.5])[labels],
        timestamps=None,
        sources=[str(p) for p in paths],
        paths=paths,
    )
    return frames, labels


def test_load_images_lists_corrupt_and_odd_sized_frames(tmp_path: Path) -> None:
    frames, _ = recording(tmp_path, 10, {3: "corrupt", 7: "size"})
    stack, readable, failures = stack_images(frames)
    assert stack.shape == (10, 40, 80, 3)
    assert readable.tolist() == [i not in (3, 7) for i in range(10)]
    assert [Path(f.file).name for f in failures] == ["f003.png", "f007.png"]
    assert "frame size (20, 20, 3) differs from the first frame's (40, 80, 3)" in failures[1].error
    assert not stack[3].any() and not stack[7].any()


def test_cnn_row_uses_the_same_folds_and_learns(tmp_path: Path) -> None:
    frames, labels = recording(tmp_path, 120, {5: "corrupt"})
    options = TrainingOptions(
        epochs=6, threads=1, params={"lr_schedule": "constant", "val_fraction": 0.0}
    )
    res, failures = evaluate_frames(
        "dnn-pilotnet",
        frames,
        labels,
        config=PipelineConfig(seed=1),
        options=options,
        folds=3,
        gap=2,
    )
    assert res.method == "dnn-pilotnet" and res.dataset == "toy"
    assert [Path(f.file).name for f in failures] == ["f005.png"]
    assert res.extra["epochs_run"] == [6, 6, 6]
    assert res.extra["settings"]["lr_schedule"] == "constant"
    assert res.extra["settings"]["num_threads"] == 1
    # 119 readable frames: test blocks are the quantum methods' contiguous folds
    assert len(list(ContiguousKFold(3, 2).split(range(119)))) == 3
    assert int(np.sum(res.confusion)) == 119
    # blocks of one label: the majority of the training part is a poor guess
    assert res.accuracy > res.majority_baseline + 0.2
    assert res.accuracy > 0.7
