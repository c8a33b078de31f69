"""The video processor: a batch of frames gets what each frame gets alone."""

from __future__ import annotations

import numpy as np
import pytest

from qdcnn.data.synthetic import generate_drive
from qdcnn.direction.processor import LaneDirectionProcessor
from qdcnn.errors import QdcnnError


def _same(a: object, b: object) -> bool:
    fields = ("direction", "probabilities", "shadow_fraction", "lane_status")
    return all(getattr(a, f) == getattr(b, f) for f in fields)


@pytest.mark.parametrize("method", ["image-split-uu", "image-split-vqc"])
def test_a_batch_gives_every_frame_its_own_outcome(method: str) -> None:
    processor = LaneDirectionProcessor.train(method, data="synthetic:track1:80")
    images = [s.image for s in generate_drive("track2", 64, seed=3)][::2]
    indices = list(range(100, 132))
    alone = [processor.process(image, i) for image, i in zip(images, indices, strict=True)]
    batch = processor.process_batch(images, indices)
    assert all(_same(a, b) for a, b in zip(alone, batch, strict=True))
    # the frames' outcomes differ, so a batch that mixed them up would show
    assert len({a.probabilities for a in alone}) > len(alone) // 2
    first, *_ = batch
    assert not isinstance(first, QdcnnError)
    np.testing.assert_array_equal(first.drawing[0], alone[0].drawing[0])  # the segments


def test_without_probabilities_a_batch_gives_the_labels_alone() -> None:
    trained = LaneDirectionProcessor.train("image-split-uu", data="synthetic:track1:80")
    processor = LaneDirectionProcessor(trained.model, seed=4, probabilities=False)
    images = [s.image for s in generate_drive("track1", 12, seed=9)]
    alone = [processor.process(image, i) for i, image in enumerate(images)]
    batch = processor.process_batch(images, list(range(12)))
    assert all(_same(a, b) for a, b in zip(alone, batch, strict=True))
    assert all(not isinstance(b, QdcnnError) and b.probabilities is None for b in batch)


def test_a_frame_that_cannot_be_processed_gets_its_error_and_the_others_their_outcome() -> None:
    processor = LaneDirectionProcessor.train("image-split-uu", data="synthetic:track1:80")
    images = [s.image for s in generate_drive("track1", 4, seed=1)]
    bad = np.zeros((8, 8, 4), np.uint8)  # four channels: not an RGB frame
    batch = processor.process_batch([images[0], bad, *images[1:]], [0, 1, 2, 3, 4])
    assert isinstance(batch[1], QdcnnError)
    with pytest.raises(QdcnnError):
        processor.process(bad, 1)
    good = [b for i, b in enumerate(batch) if i != 1]
    alone = [processor.process(image, i) for i, image in zip([0, 2, 3, 4], images, strict=True)]
    assert all(_same(a, b) for a, b in zip(alone, good, strict=True))
