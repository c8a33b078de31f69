"""Grouping of Hough segments into two lines and the paper's 2-slope feature vector."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np
import pytest

from conftest import shared_recording
from qdcnn.config import GroupingConfig, LaneConfig
from qdcnn.data.images import list_images, read_image
from qdcnn.errors import InputError, ParameterError
from qdcnn.vision.grouping import (
    EXTRA_FEATURES,
    FAR_ROW,
    GROUPINGS,
    LEFT_OUT,
    NEAR_PART,
    NEAR_ROW,
    feature_names,
    fit_line,
    group_segments,
    mode_columns,
    pair_status,
    segment_descriptors,
)
from qdcnn.vision.lanes import detect_segments
from qdcnn.vision.roi import roi_rows

H, W = 160, 320
UDACITY = LaneConfig.udacity()
SHAPE = (H, W)

# (x_bottom, y_bottom, x_top, y_top) of the two drawn lines, left line first
PAIRS = {
    "straight": [(60, 159, 140, 72), (260, 159, 180, 72)],
    "left-leaning": [(130, 159, 40, 72), (300, 159, 180, 72)],
    "right-leaning": [(20, 159, 140, 72), (190, 159, 280, 72)],
}


#: Drawn pairs that cannot be a road: lines crossing at y = 97 (inside the ROI, rows 67 to
#: 159), and the two lines leaning the wrong way (they converge downwards)
NOT_A_ROAD = {
    "crossed": [(60, 159, 200, 72), (260, 159, 120, 72)],
    "wrong-side": [(100, 159, 40, 72), (220, 159, 280, 72)],
}


def road(lines: list[tuple[int, int, int, int]]) -> np.ndarray:
    """Grey road (90) with bright (230) straight lane lines, 3 px wide (RGB, 320x160)."""
    img = np.full((H, W, 3), 90, np.uint8)
    for x1, y1, x2, y2 in lines:
        cv2.line(img, (x1, y1), (x2, y2), (230, 230, 230), 3)
    return img


def lane_features(image: np.ndarray, config: LaneConfig, method: str = "image-split", **kw):
    """Hough segments of ``image`` grouped: the lane stage of ``process_frame``."""
    return group_segments(detect_segments(image, config), image.shape, method, **kw)


def drawn_slopes(lines: list[tuple[int, int, int, int]]) -> np.ndarray:
    return np.array([(x1 - x2) / (y1 - y2) for x1, y1, x2, y2 in lines])


@pytest.mark.parametrize("method", GROUPINGS)
@pytest.mark.parametrize("pair", PAIRS)
def test_recovered_slopes_match_drawn_lines(method: str, pair: str) -> None:
    lines = PAIRS[pair]
    result = lane_features(road(lines), UDACITY, method)
    assert result.status == "ok"
    assert result.features.shape == (2,)
    np.testing.assert_allclose(result.features, drawn_slopes(lines), rtol=0.03, atol=0.03)
    assert result.method == method
    assert result.feature_names == ("slope_left", "slope_right")


def test_slope_signs_on_a_straight_road() -> None:
    left, right = lane_features(road(PAIRS["straight"]), UDACITY).features
    assert left < 0 < right  # dx/dy with y pointing down


@pytest.mark.parametrize("method", ["kmeans", "spectral"])
def test_clustering_follows_a_line_across_the_midline(method: str) -> None:
    # the right line reaches x = 120 at the top: image-split puts its top piece on the left
    lines = [(10, 159, 60, 72), (310, 159, 120, 72)]
    img = road(lines)
    segments = detect_segments(img, UDACITY)
    clustered = group_segments(segments, SHAPE, method)
    np.testing.assert_allclose(clustered.features, drawn_slopes(lines), rtol=0.03, atol=0.03)
    split = group_segments(segments, SHAPE, "image-split")
    crossing = (segments[:, 0] + segments[:, 2]) / 2 < (W - 1) / 2
    crossing &= clustered.labels == 1
    assert crossing.any()
    assert (split.labels[crossing] == 0).all()


@pytest.mark.parametrize("method", GROUPINGS)
def test_group_order_is_left_first_whatever_the_segment_order(method: str) -> None:
    segments = detect_segments(road(PAIRS["straight"]), UDACITY)
    forward = group_segments(segments, SHAPE, method)
    backward = group_segments(segments[::-1].copy(), SHAPE, method)
    np.testing.assert_allclose(backward.features, forward.features, rtol=1e-12)
    np.testing.assert_array_equal(backward.labels, forward.labels[::-1])
    mid_x = (segments[:, 0] + segments[:, 2]) / 2
    assert mid_x[forward.labels == 0].mean() < mid_x[forward.labels == 1].mean()


@pytest.mark.parametrize("method", ["kmeans", "spectral"])
def test_clustering_is_deterministic_for_a_seed(method: str) -> None:
    rng = np.random.default_rng(7)
    segments = rng.uniform(0, 150, (30, 4)) * [2, 1, 2, 1]  # no structure: the seed matters
    a = group_segments(segments, SHAPE, method, seed=5)
    b = group_segments(segments, SHAPE, method, seed=5)
    np.testing.assert_array_equal(a.labels, b.labels)
    np.testing.assert_array_equal(a.features, b.features)


@pytest.mark.parametrize("method", GROUPINGS)
def test_no_segments_gives_no_lines(method: str) -> None:
    result = group_segments(np.empty((0, 4)), SHAPE, method)
    assert result.status == "no-lines"
    assert result.n_segments == 0
    assert result.labels.shape == (0,) and result.labels.dtype == np.int64
    assert np.isnan(result.features).all()
    assert result.lines == [None, None]


@pytest.mark.parametrize("method", GROUPINGS)
def test_blank_frame_gives_no_lines(method: str) -> None:
    result = lane_features(np.full((H, W, 3), 90, np.uint8), UDACITY, method)
    assert result.status == "no-lines"


@pytest.mark.parametrize("method", GROUPINGS)
@pytest.mark.parametrize("side", ["left", "right"])
def test_single_drawn_line_gives_one_line_on_its_side(method: str, side: str) -> None:
    line = PAIRS["straight"][0 if side == "left" else 1]
    result = lane_features(road([line]), UDACITY, method)
    assert result.status == "one-line"
    slot = 0 if side == "left" else 1
    np.testing.assert_allclose(result.features[slot], drawn_slopes([line])[0], atol=0.03)
    assert np.isnan(result.features[1 - slot])
    assert (result.labels == slot).all()


@pytest.mark.parametrize("method", ["kmeans", "spectral"])
def test_without_merging_clustering_always_gives_two_slopes(method: str) -> None:
    line = PAIRS["straight"][0]
    result = lane_features(road([line]), UDACITY, method, merge_tolerance=None)
    assert result.status == "ok"  # the stripe's pieces, split in two clusters
    np.testing.assert_allclose(result.features, drawn_slopes([line, line]), atol=0.2)


def test_merge_keeps_two_separate_lines() -> None:
    # parallel lines 40 px apart along x, slope -0.75: 32 px apart, so one line between
    # them leaves an RMS distance of 16 px = 0.05 W
    segments = np.array([[100.0, 70, 40, 150], [140, 70, 80, 150]])
    for tolerance in (0.03, 0.045):
        kept = group_segments(segments, SHAPE, "kmeans", merge_tolerance=tolerance)
        assert kept.status == "ok"
    merged = group_segments(segments, SHAPE, "kmeans", merge_tolerance=0.055)
    assert merged.status == "one-line"
    np.testing.assert_allclose(merged.features[0], -0.75)
    assert merged.labels.tolist() == [0, 0]


@pytest.mark.parametrize("method", GROUPINGS)
def test_one_and_two_segments(method: str) -> None:
    one = group_segments(np.array([[100.0, 70, 40, 150]]), SHAPE, method)
    assert one.status == "one-line"
    np.testing.assert_allclose(one.features[0], -0.75)
    two = group_segments(np.array([[100.0, 70, 40, 150], [220, 70, 280, 150]]), SHAPE, method)
    assert two.status == "ok"
    np.testing.assert_allclose(two.features, [-0.75, 0.75])
    assert two.labels.tolist() == [0, 1]


@pytest.mark.parametrize("method", GROUPINGS)
def test_identical_segments_give_one_line(method: str) -> None:
    segments = np.tile([[220.0, 70, 280, 150]], (6, 1))
    result = group_segments(segments, SHAPE, method)
    assert result.status == "one-line"
    assert np.isnan(result.features[0])
    np.testing.assert_allclose(result.features[1], 0.75)


def test_all_segments_on_one_side_with_image_split() -> None:
    segments = np.array([[20.0, 80, 10, 150], [120, 80, 90, 150]])
    result = group_segments(segments, SHAPE, "image-split")
    assert result.status == "one-line"
    assert result.lines[1] is None
    assert result.labels.tolist() == [0, 0]


@pytest.mark.parametrize("method", GROUPINGS)
def test_horizontal_segments_have_no_line(method: str) -> None:
    segments = np.array([[10.0, 100, 60, 100], [250, 90, 300, 90]])
    result = group_segments(segments, SHAPE, method)
    assert result.status == "no-lines"
    assert result.n_segments == 2


def test_fit_line_matches_weighted_polyfit() -> None:
    rng = np.random.default_rng(11)
    segments = rng.uniform(0, 150, (9, 4))
    x = np.r_[segments[:, 0], segments[:, 2]]
    y = np.r_[segments[:, 1], segments[:, 3]]
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    # polyfit's w multiplies the residuals, so sqrt(length) weighs squares by length
    reference = np.polyfit(y, x, 1, w=np.sqrt(np.r_[length, length]))
    np.testing.assert_allclose(fit_line(segments), reference, rtol=1e-9)


def test_fit_line_of_collinear_segments_is_exact() -> None:
    a, b = -0.4, 200.0
    ys = np.array([[70.0, 90], [100, 140], [145, 159]])
    segments = np.column_stack([a * ys[:, 0] + b, ys[:, 0], a * ys[:, 1] + b, ys[:, 1]])
    np.testing.assert_allclose(fit_line(segments), (a, b), rtol=1e-12)
    assert fit_line(np.empty((0, 4))) is None


def test_descriptor_ignores_endpoint_order() -> None:
    seg = np.array([[10.0, 20, 40, 80], [300, 150, 250, 60]])
    np.testing.assert_allclose(
        segment_descriptors(seg, W), segment_descriptors(seg[:, [2, 3, 0, 1]], W)
    )
    vertical, horizontal = np.array([[5.0, 0, 5, 9], [0.0, 5, 9, 5]])
    d = segment_descriptors(np.array([vertical, horizontal]), W)
    np.testing.assert_allclose(d[:, 1:], [[0.5, 0.0], [-0.5, 0.0]], atol=1e-12)


def test_extra_features_are_appended_after_the_slopes() -> None:
    # left line x = -0.75 y + 152.5, right line x = 0.75 y + 160
    segments = np.array([[100.0, 70, 40, 150], [220, 80, 280, 160]])
    result = group_segments(
        segments, SHAPE, extra_features=("intercepts", "angles", "vanishing-point-offset")
    )
    left, right = result.lines
    assert left is not None and right is not None
    assert result.feature_names == (
        "slope_left",
        "slope_right",
        "intercept_left",
        "intercept_right",
        "angle_left",
        "angle_right",
        "vanishing_point_offset",
    )
    y_cross = (right[1] - left[1]) / (left[0] - right[0])
    expected = [
        left[0],
        right[0],
        (left[0] * 159 + left[1]) / 319,
        (right[0] * 159 + right[1]) / 319,
        np.arctan(left[0]),
        np.arctan(right[0]),
        (left[0] * y_cross + left[1]) / 319 - 0.5,
    ]
    np.testing.assert_allclose(result.features, expected, rtol=1e-12)
    np.testing.assert_allclose(result.features[:2], [-0.75, 0.75])
    plain = group_segments(segments, SHAPE)
    np.testing.assert_array_equal(plain.features, result.features[:2])


def rel(x: float) -> float:
    return x / (W - 1) - 0.5


def test_far_offsets_and_road_centre_known_answers() -> None:
    # left line x = -0.75 y + 152.5, right line x = 0.75 y + 160
    segments = np.array([[100.0, 70, 40, 150], [220, 80, 280, 160]])
    result = group_segments(segments, SHAPE, extra_features=("far-offsets", "road-centre"))
    assert result.feature_names[2:] == ("far_left", "far_right", "centre_far", "centre_near")
    far, near = FAR_ROW * (H - 1), NEAR_ROW * (H - 1)
    left_far, right_far = -0.75 * far + 152.5, 0.75 * far + 160
    left_near, right_near = -0.75 * near + 152.5, 0.75 * near + 160
    expected = [
        rel(left_far),
        rel(right_far),
        rel((left_far + right_far) / 2),
        rel((left_near + right_near) / 2),
    ]
    np.testing.assert_allclose(result.features[2:], expected, rtol=1e-9, atol=1e-12)


def test_near_vanishing_point_uses_only_the_near_segments() -> None:
    # a road bending right: the near parts (lower end at the bottom row) head for x = 200,
    # the far parts (lower end at y = 100, above NEAR_PART) for x = 120, both at y = 40
    assert 100 < NEAR_PART * (H - 1) <= 159

    def on(x_bottom: float, y_bottom: float, x_vp: float, y: float) -> float:
        return x_vp + (x_bottom - x_vp) * (y - 40) / (y_bottom - 40)

    segments = np.array(
        [
            [on(60, 159, 200, 120), 120, 60, 159],
            [on(330, 159, 200, 120), 120, 330, 159],
            [on(20, 100, 120, 60), 60, 20, 100],
            [on(250, 100, 120, 60), 60, 250, 100],
        ]
    )
    result = group_segments(
        segments, SHAPE, extra_features=("vanishing-point-offset", "near-vanishing-point-offset")
    )
    assert result.status == "ok"
    np.testing.assert_allclose(result.features[3], rel(200.0), atol=1e-9)
    assert abs(result.features[2] - result.features[3]) > 0.1  # whole lines: elsewhere


def test_near_vanishing_point_is_nan_without_near_segments_on_both_sides() -> None:
    segments = np.array([[100.0, 60, 80, 100], [220, 60, 240, 100], [80, 130, 60, 159]])
    result = group_segments(segments, SHAPE, extra_features=("near-vanishing-point-offset",))
    assert result.status == "ok" and np.isnan(result.features[2])


def drawn_x(line: tuple[int, int, int, int], row: float) -> float:
    x1, y1, x2, y2 = line
    return x1 + (x2 - x1) * (row * (H - 1) - y1) / (y2 - y1)


def drawn_crossing(lines: list[tuple[int, int, int, int]]) -> float:
    (a, b), (c, d) = [
        ((x2 - x1) / (y2 - y1), x1 - (x2 - x1) / (y2 - y1) * y1) for x1, y1, x2, y2 in lines
    ]
    return a * (d - b) / (a - c) + b


@pytest.mark.parametrize("method", GROUPINGS)
@pytest.mark.parametrize("pair", PAIRS)
def test_new_extras_match_drawn_lines(method: str, pair: str) -> None:
    lines = PAIRS[pair]
    extras = ("far-offsets", "road-centre", "near-vanishing-point-offset")
    result = lane_features(road(lines), UDACITY, method, extra_features=extras)
    far = [drawn_x(line, FAR_ROW) for line in lines]
    near = [drawn_x(line, NEAR_ROW) for line in lines]
    expected = [rel(far[0]), rel(far[1]), rel(sum(far) / 2), rel(sum(near) / 2)]
    # 0.01 of the width is 3 px: the fitted lines follow the stripes' borders
    np.testing.assert_allclose(result.features[2:6], expected, atol=0.01)
    # straight lines: the near parts meet where the whole lines do (up to 2 widths away)
    np.testing.assert_allclose(result.features[6], rel(drawn_crossing(lines)), rtol=0.05, atol=0.01)


def test_feature_modes_name_columns_of_their_extras() -> None:
    assert set(EXTRA_FEATURES) == set(GroupingConfig.EXTRAS)
    for mode, (columns, extras) in GroupingConfig.FEATURE_MODES.items():
        cfg = GroupingConfig.for_features(mode, extra_features=("angles",))
        assert cfg.features == mode and cfg.extra_features[0] == "angles"
        i, j = mode_columns(mode, cfg.extra_features)
        names = feature_names(cfg.extra_features)
        assert (names[i], names[j]) == columns
        assert set(extras) <= set(cfg.extra_features)
    assert mode_columns("slopes") == (0, 1)
    assert mode_columns("far-offsets", ("angles", "far-offsets")) == (4, 5)


def test_middle_line_is_the_average_of_the_two_lines() -> None:
    result = group_segments(np.array([[100.0, 70, 40, 150], [220, 70, 280, 150]]), SHAPE)
    left, right = result.lines
    assert left is not None and right is not None and result.middle_line is not None
    np.testing.assert_allclose(result.middle_line, np.add(left, right) / 2)


def test_unknown_method_or_extra_raises_parameter_error() -> None:
    seg = np.array([[100.0, 70, 40, 150]])
    with pytest.raises(ParameterError, match=r"^method='dbscan' is invalid"):
        group_segments(seg, SHAPE, "dbscan")
    with pytest.raises(ParameterError, match=r"^extra_features='curvature' is invalid"):
        group_segments(seg, SHAPE, extra_features=("curvature",))
    with pytest.raises(ParameterError, match=r"^grouping.features='angles' is invalid"):
        GroupingConfig(features="angles")
    with pytest.raises(ParameterError, match=r"^grouping.extra_features=\(\) is invalid: to incl"):
        GroupingConfig(features="road-centre")
    with pytest.raises(ParameterError, match=r"^features='x' is invalid"):
        mode_columns("x")
    with pytest.raises(ParameterError, match=r"^extra_features=\(\) is invalid: to include"):
        mode_columns("far-offsets")
    with pytest.raises(ParameterError, match=r"^extra_features='angles' is invalid"):
        group_segments(seg, SHAPE, extra_features="angles")
    with pytest.raises(TypeError, match="method"):  # the grouping is the method's, not a setting
        GroupingConfig(method="knn")  # type: ignore[call-arg]
    with pytest.raises(ParameterError, match=r"^merge_tolerance=2.0 is invalid"):
        group_segments(seg, SHAPE, merge_tolerance=2.0)
    with pytest.raises(ParameterError, match=r"^grouping.merge_tolerance=-1 is invalid"):
        GroupingConfig(merge_tolerance=-1)
    with pytest.raises(ParameterError, match=r"^grouping.extra_features='x' is invalid"):
        GroupingConfig(extra_features=("x",))
    assert feature_names(("intercepts",))[2:] == ("intercept_left", "intercept_right")


def test_bad_segments_raise_input_error() -> None:
    with pytest.raises(InputError, match=r"^segments: expected a finite \(N, 4\) array"):
        group_segments(np.zeros((3, 3)), SHAPE)
    with pytest.raises(InputError, match=r"^segments: expected a finite"):
        group_segments(np.array([[np.nan, 0, 1, 1]]), SHAPE)


_NOT_A_ROAD = ("crossed", "wrong-side")  # pair_status flags on real frames


@pytest.mark.realdata
@pytest.mark.parametrize("recording", ["udacity-lake-track", "udacity-mountain-track"])
def test_real_frames_extract_without_error(
    recording: str, record_property: Callable[[str, object], None]
) -> None:
    root = shared_recording(recording)
    paths = list_images([root / "IMG"]).images[:50]
    images = [read_image(p) for p in paths]
    assert len(images) == 50
    for method in GROUPINGS:
        results = [lane_features(image, UDACITY, method) for image in images]
        features = np.vstack([r.features for r in results])
        statuses = [r.status for r in results]
        assert features.shape == (50, 2)
        counts = {s: statuses.count(s) for s in ("ok", "one-line", "no-lines", *_NOT_A_ROAD)}
        assert sum(counts.values()) == 50
        record_property(f"{recording}/{method}", counts)
        print(recording, method, counts)
        ok = np.array(statuses) == "ok"
        assert np.isfinite(features[ok]).all()
        assert np.isnan(features[np.array(statuses) == "no-lines"]).all()
        # the road edges are visible in most frames (measured: 72-98 % "ok")
        assert counts["ok"] >= 25


def test_inner_lines_keep_each_sides_own_lane_border() -> None:
    # left side: the car's lane border and, further out, the other lane's far border;
    # right side: the lane border and a kerb beyond it
    inner_left, outer_left = (110, 72, 40, 159), (70, 72, -60, 159)
    inner_right, kerb = (210, 72, 280, 159), (250, 72, 380, 159)
    segments = np.array([inner_left, outer_left, inner_right, kerb], dtype=np.float64)
    segments = np.vstack([segments, np.add(segments, [1, 0, 1, 0])])  # each line seen twice
    plain = group_segments(segments, SHAPE, "image-split")
    inner = group_segments(segments, SHAPE, "image-split", inner_lines=True)
    wanted = drawn_slopes([inner_left[2:] + inner_left[:2], inner_right[2:] + inner_right[:2]])
    np.testing.assert_allclose(inner.features, wanted, atol=0.02)
    assert not np.allclose(plain.features, wanted, atol=0.05)
    assert set(inner.labels.tolist()) == {0, 1, LEFT_OUT}
    assert (inner.labels[[1, 3, 5, 7]] == LEFT_OUT).all()
    # a car's outline on the right leaning down-left is no right border, however inner
    car = np.array([[200.0, 120, 170, 150]])
    with_car = group_segments(np.vstack([segments, car]), SHAPE, "image-split", inner_lines=True)
    assert with_car.labels[-1] == LEFT_OUT
    np.testing.assert_allclose(with_car.features, wanted, atol=0.02)


def test_inner_lines_keep_a_double_centre_line_as_one_line() -> None:
    # two stripes 4 px apart are one marking; a faint short segment inside is not a line
    a, b = (120, 72, 40, 159), (124, 72, 44, 159)
    stub = (140, 150, 136, 159)
    segments = np.array([a, b, stub, (210, 72, 280, 159)], dtype=np.float64)
    result = group_segments(segments, SHAPE, "image-split", inner_lines=True)
    assert result.labels.tolist() == [0, 0, LEFT_OUT, 1]


def test_pair_status_known_answers() -> None:
    rows = (67.0, 159.0)
    assert pair_status([(-1.0, 220.0), (1.0, 100.0)], rows) == "ok"  # meet at y = 60
    assert pair_status([(-1.0, 220.0), (1.0, 20.0)], rows) == "crossed"  # meet at y = 100
    assert pair_status([(0.5, 0.0), (-0.5, 300.0)], rows) == "wrong-side"  # lean the wrong way
    assert pair_status([(0.0, 250.0), (0.0, 50.0)], rows) == "wrong-side"  # left right of right
    assert pair_status([(0.2, 10.0), (0.3, 200.0)], rows) == "ok"  # a bend: both lean one way
    assert pair_status([None, (0.3, 200.0)], rows) == "one-line"
    assert pair_status([None, None], rows) == "no-lines"


@pytest.mark.parametrize("method", GROUPINGS)
@pytest.mark.parametrize("pair", NOT_A_ROAD)
def test_a_pair_that_cannot_be_a_road_is_flagged_and_keeps_its_slopes(
    method: str, pair: str
) -> None:
    lines = NOT_A_ROAD[pair]
    result = lane_features(road(lines), UDACITY, method, roi_rows=roi_rows(UDACITY.roi))
    assert result.status == pair
    np.testing.assert_allclose(result.features, drawn_slopes(lines), rtol=0.03, atol=0.03)


@pytest.mark.parametrize("method", GROUPINGS)
def test_a_normal_road_in_the_roi_is_ok(method: str) -> None:
    result = lane_features(
        road(PAIRS["straight"]), UDACITY, method, roi_rows=roi_rows(UDACITY.roi)
    )
    assert result.status == "ok"


def test_lines_crossing_above_the_roi_are_not_crossed() -> None:
    # the crossed pair meets at y = 97: below a region that ends at row 80 they are apart
    lines = [(-1.609, 315.8), (1.609, 4.2)]  # x = a y + b of NOT_A_ROAD["crossed"]
    assert pair_status(lines, (100.0, 159.0)) == "ok"
    assert pair_status(lines, (67.0, 159.0)) == "crossed"
