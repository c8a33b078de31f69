"""Synthetic road scenes: determinism, geometry, labels and exact ground truth."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from qdcnn.data.labels import LEFT, RIGHT, STRAIGHT
from qdcnn.data.synthetic import (
    LABEL_THRESHOLD,
    PRESETS,
    RoadScene,
    direction_of,
    drive_curvature,
    generate_drive,
    generate_scene,
    generate_scenes,
)
from qdcnn.data.synthetic_world import STYLES
from qdcnn.errors import ParameterError


@pytest.fixture(scope="module")
def track2_scenes() -> list[RoadScene]:
    return generate_scenes("track2", 24, seed=21)


@pytest.fixture(scope="module")
def track1_scenes() -> list[RoadScene]:
    return generate_scenes("track1", 24, seed=22)


def _same(a: RoadScene, b: RoadScene) -> bool:
    return (
        np.array_equal(a.image, b.image)
        and np.array_equal(a.shadow_mask, b.shadow_mask)
        and np.array_equal(a.road_mask, b.road_mask)
        and all(np.array_equal(p, q) for p, q in zip(a.lane_lines, b.lane_lines, strict=True))
        and (a.steering, a.curvature, a.direction) == (b.steering, b.curvature, b.direction)
    )


@pytest.mark.parametrize("preset", PRESETS)
def test_same_seed_gives_identical_scene_and_other_seeds_differ(preset: str) -> None:
    a = generate_scene(preset, seed=7)
    assert _same(a, generate_scene(preset, seed=7))
    b = generate_scene(preset, seed=8)
    assert np.abs(a.image.astype(int) - b.image).mean() > 5


@pytest.mark.parametrize("size", [(320, 160), (64, 48), (1280, 720), (17, 23)])
def test_any_size_gives_consistent_shapes_and_types(size: tuple[int, int]) -> None:
    w, h = size
    s = generate_scene("track2", seed=3, width=w, height=h)
    assert s.image.shape == (h, w, 3) and s.image.dtype == np.uint8
    assert s.shadow_mask.shape == (h, w) and s.shadow_mask.dtype == np.bool_
    assert s.road_mask.shape == (h, w) and s.road_mask.dtype == np.bool_
    assert len(s.lane_lines) == 2
    for line in s.lane_lines:
        assert line.ndim == 2 and line.shape[1] == 2 and line.dtype == np.float64
        assert ((line[:, 0] >= 0) & (line[:, 0] <= w - 1)).all()
        assert ((line[:, 1] >= 0) & (line[:, 1] <= h - 1)).all()
    assert s.road_mask.any()


def test_scene_content_does_not_depend_on_the_frame_size() -> None:
    small = generate_scene("track2", seed=11, width=320, height=160)
    large = generate_scene("track2", seed=11, width=640, height=320)
    assert (small.steering, small.direction) == (large.steering, large.direction)
    down = cv2.resize(large.road_mask.astype(np.uint8), (320, 160), interpolation=cv2.INTER_AREA)
    assert np.mean((down > 0) == small.road_mask) > 0.97


@pytest.mark.parametrize("preset", PRESETS)
@pytest.mark.parametrize("direction", [LEFT, STRAIGHT, RIGHT])
def test_direction_steering_and_curvature_agree(preset: str, direction: int) -> None:
    for seed in range(3):
        s = generate_scene(preset, seed=seed, direction=direction)
        assert s.direction == direction
        assert direction_of(s.steering) == direction
        if direction == STRAIGHT:
            assert abs(s.steering) <= 0.02
        else:
            assert 0.15 <= abs(s.steering) <= 0.8
            assert np.sign(s.steering) == (1 if direction == RIGHT else -1)
            assert np.sign(s.curvature) == np.sign(s.steering)
            assert abs(s.steering) > 2 * LABEL_THRESHOLD


def test_direction_of_uses_the_label_threshold() -> None:
    assert [direction_of(v) for v in (-0.3, -0.05, 0.0, 0.05, 0.06)] == [0, 1, 1, 1, 2]


def _lean(line: np.ndarray, height: int) -> float:
    """dx/dy of a straight line fitted to the lower part (the lane ROI) of a marking."""
    part = line[line[:, 1] >= 0.45 * height]
    return float(np.polyfit(part[:, 1], part[:, 0], 1)[0])


@pytest.mark.parametrize("preset", ["track1", "track2", "rain"])  # the car mid-road
def test_fitted_lane_line_slopes_tell_the_direction(preset: str) -> None:
    # A bend makes both boundaries lean towards it: the summed dx/dy of the two fitted
    # lines is positive (lines lean left going up) for left bends, near 0 when straight.
    correct, total = 0, 0
    for s in generate_scenes(preset, 18, seed=4):
        left, right = (_lean(line, 160) for line in s.lane_lines)
        assert left < 0 < right  # left boundary runs up-right, right boundary up-left
        lean = left + right
        guess = LEFT if lean > 0.8 else RIGHT if lean < -0.8 else STRAIGHT
        correct += guess == s.direction
        total += 1
    assert correct / total >= 0.85


def test_lane_lines_are_painted_on_the_road() -> None:
    s = generate_scene("track1", seed=5, direction=STRAIGHT)
    grey = s.image.astype(float).mean(axis=2)
    near = [line[line[:, 1] > 90] for line in s.lane_lines]
    for pts in near:
        assert len(pts) > 10
        x, y = np.round(pts[:, 0]).astype(int), np.round(pts[:, 1]).astype(int)
        assert s.road_mask[y, x].mean() > 0.9  # markings lie on the drivable surface
        assert grey[y, x].mean() > grey[s.road_mask].mean() + 20  # and are brighter than it
    # the two boundaries enclose the straight road and meet towards the horizon
    left, right = s.lane_lines
    gap_near = np.interp(130, right[:, 1][::-1], right[:, 0][::-1]) - np.interp(
        130, left[:, 1][::-1], left[:, 0][::-1]
    )
    gap_far = np.interp(75, right[:, 1][::-1], right[:, 0][::-1]) - np.interp(
        75, left[:, 1][::-1], left[:, 0][::-1]
    )
    assert gap_near > 3 * gap_far > 0


def test_road_mask_narrows_towards_the_horizon() -> None:
    s = generate_scene("rain", seed=2, direction=STRAIGHT)
    widths = s.road_mask.sum(axis=1)
    assert widths[130] > widths[100] > widths[75] > 0
    assert not s.road_mask[:40].any()  # sky
    assert s.road_mask[150, 150:170].all()  # straight ahead of the car


def test_shadows_are_darker_and_bluer_than_the_same_road_lit(
    track2_scenes: list[RoadScene],
) -> None:
    shadow_sum = lit_sum = 0.0
    shadow_n = lit_n = 0
    blue_shift = []
    for s in track2_scenes:
        img = s.image.astype(float)
        grey = img.mean(axis=2)
        for r in range(s.image.shape[0]):  # compare within rows: same depth, same haze
            sh = s.shadow_mask[r] & s.road_mask[r]
            lit = ~s.shadow_mask[r] & s.road_mask[r]
            if sh.sum() >= 5 and lit.sum() >= 5:
                shadow_sum += grey[r, sh].sum()
                shadow_n += int(sh.sum())
                lit_sum += grey[r, lit].sum()
                lit_n += int(lit.sum())
                chroma = img[r, :, 2] / (img[r].sum(axis=1) + 1e-9)
                blue_shift.append(chroma[sh].mean() - chroma[lit].mean())
    assert shadow_n > 1000
    assert shadow_sum / shadow_n < 0.7 * (lit_sum / lit_n)
    assert np.median(blue_shift) > 0.005  # skylight tint: blue is darkened least


def test_track2_has_shadow_in_most_frames_and_track1_in_few(
    track2_scenes: list[RoadScene], track1_scenes: list[RoadScene]
) -> None:
    frac2 = np.array([s.shadow_mask.mean() for s in track2_scenes])
    assert (frac2 > 0.02).mean() >= 0.8
    assert 0.05 <= np.median(frac2) <= 0.4
    assert frac2.max() < 0.6
    frac1 = np.array([s.shadow_mask.mean() for s in track1_scenes])
    assert (frac1 == 0).mean() >= 0.3
    assert np.median(frac1) < 0.02


def test_shadow_mask_is_on_visible_ground_only(track2_scenes: list[RoadScene]) -> None:
    for s in track2_scenes[:8]:
        assert not s.shadow_mask[: int(0.3 * 160)].any()  # never in the sky
        assert not s.shadow_mask[159, 150:170].any()  # never on the car hood
        assert not s.road_mask[159, 150:170].any()


def test_track2_has_dark_non_shadow_decoys(track2_scenes: list[RoadScene]) -> None:
    # Tar patches and dark bushes: some clearly dark pixels are not shadow.
    dark_not_shadow = 0
    for s in track2_scenes:
        grey = s.image.astype(float).mean(axis=2)
        lit_ground = ~s.shadow_mask
        lit_ground[:80] = False
        dark_not_shadow += int((lit_ground & (grey < 60)).sum())
    assert dark_not_shadow > 200


def test_generate_scenes_balances_classes_and_scenes_regenerate() -> None:
    scenes = generate_scenes("track1", 9, seed=3, width=96, height=48)
    dirs = [s.direction for s in scenes]
    assert sorted(dirs[:3]) == [0, 1, 2]
    assert dirs[3:6] == dirs[:3] and dirs[6:] == dirs[:3]
    assert len({s.seed for s in scenes}) == 9
    again = generate_scene(
        "track1", seed=scenes[4].seed, width=96, height=48, direction=scenes[4].direction
    )
    assert _same(again, scenes[4])
    assert generate_scenes("track1", 0) == []


def test_drive_curvature_is_made_of_long_segments_and_ramps() -> None:
    rng = np.random.default_rng(5)
    curv, kinds = drive_curvature(rng, STYLES["track2"], 600)
    change = np.flatnonzero(np.diff(kinds)) + 1
    runs = np.diff(np.concatenate([[0], change, [600]]))
    assert (runs[:-1] >= 25).all()  # every finished segment lasts 25 frames or more
    assert len(runs) >= 6
    steering = 20.0 * curv
    assert np.abs(np.diff(steering)).max() < 0.25  # ramps, not jumps
    for start, run in zip(np.concatenate([[0], change])[:-1], runs[:-1], strict=True):
        plateau = steering[start + run - 25 : start + run]  # a segment ends on its plateau
        assert np.ptp(plateau) == 0
        if kinds[start] == STRAIGHT:
            assert plateau[0] == 0
        else:
            assert 0.3 <= abs(plateau[0]) <= 0.8
            assert np.sign(plateau[0]) == (1 if kinds[start] == RIGHT else -1)


@pytest.fixture(scope="module")
def drive() -> list[RoadScene]:
    return generate_drive("track1", 160, seed=2, width=160, height=80)


def test_drive_labels_from_smoothed_steering_match_except_near_transitions(
    drive: list[RoadScene],
) -> None:
    steering = np.array([s.steering for s in drive])
    smooth = np.convolve(np.pad(steering, 5, mode="edge"), np.ones(11) / 11, "valid")
    labels = np.array([direction_of(v) for v in smooth])
    curvature = np.array([s.curvature for s in drive])
    kind = np.where(curvature > 1e-9, RIGHT, np.where(curvature < -1e-9, LEFT, STRAIGHT))
    # frames whose +-8 neighbourhood lies in one segment kind
    steady = np.array([len(set(kind[max(0, i - 8) : i + 9])) == 1 for i in range(len(kind))])
    assert steady.mean() > 0.5
    assert (labels[steady] == kind[steady]).all()
    assert set(labels) == {LEFT, STRAIGHT, RIGHT} or len(set(kind)) < 3
    straight = np.abs(steering[curvature == 0])
    assert (straight <= 0.02).all()
    assert [s.frame for s in drive] == list(range(160))


def test_drive_frames_look_like_video(drive: list[RoadScene]) -> None:
    imgs = [s.image.astype(float) for s in drive]
    step = np.mean([np.abs(imgs[i] - imgs[i + 1]).mean() for i in range(0, 150, 5)])
    apart = np.mean([np.abs(imgs[i] - imgs[i + 60]).mean() for i in range(0, 90, 5)])
    assert step < 0.6 * apart


def test_drive_is_deterministic() -> None:
    a = generate_drive("rain", 3, seed=9, width=80, height=40)
    b = generate_drive("rain", 3, seed=9, width=80, height=40)
    assert all(_same(x, y) for x, y in zip(a, b, strict=True))
    assert generate_drive("rain", 0) == []


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (
            lambda: generate_scene("track3"),
            "preset='track3' is invalid: one of track1, track2, rain, dashcam",
        ),
        (lambda: generate_scene(width=0), "width=0 is invalid: between 16 and 8192 pixels"),
        (lambda: generate_scene(height=2.5), "height=2.5 is invalid: an integer number of pixels"),
        (
            lambda: generate_scene(direction=3),
            "direction=3 is invalid: 0 (left), 1 (straight), 2 (right) or None",
        ),
        (lambda: generate_scene(seed=-1), "seed=-1 is invalid: a non-negative integer"),
        (lambda: generate_scenes("track1", -2), "n=-2 is invalid: a non-negative integer"),
        (
            lambda: generate_drive("track1", 5, fps=0),
            "fps=0 is invalid: a frame rate between 0.5 and 1000",
        ),
    ],
)
def test_bad_parameters_give_one_line_errors(call: object, message: str) -> None:
    with pytest.raises(ParameterError) as err:
        call()  # type: ignore[operator]
    assert str(err.value) == message


def test_shadow_mask_is_exactly_where_the_sun_is_blocked(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Render the same scenes again with the sun hidden. On the road, darkening is strong
    # inside the mask, bluish, and outside it only faint (penumbra and thin slivers whose
    # blurred shadow alpha stays below 0.5); most road pixels away from shadows are unchanged.
    import qdcnn.data.synthetic as synthetic

    lit = [generate_scene("track2", seed=s) for s in range(6)]
    make_take = synthetic.make_take

    def sunless(*args: object, **kwargs: object) -> object:
        take = make_take(*args, **kwargs)  # type: ignore[arg-type]
        take.sun_out = False
        return take

    monkeypatch.setattr(synthetic, "make_take", sunless)
    lost_in = lost_out = 0.0
    for with_sun in lit:
        no_sun = generate_scene("track2", seed=with_sun.seed)
        assert np.array_equal(no_sun.road_mask, with_sun.road_mask)
        assert not no_sun.shadow_mask.any()
        a = with_sun.image.astype(float)
        b = no_sun.image.astype(float)
        road, inside = with_sun.road_mask, with_sun.shadow_mask
        ga, gb = a.mean(axis=2), b.mean(axis=2)
        bright = gb > 40
        outside = road & ~inside & bright
        assert (ga[outside] / gb[outside] > 0.55).mean() > 0.995
        lost_in += float((gb - ga)[road & inside].sum())
        lost_out += float((gb - ga)[road & ~inside].sum())
        near = cv2.dilate(inside.astype(np.uint8), np.ones((27, 27))).astype(bool)  # 3 sigma
        far = road & ~near
        if far.sum() > 500:
            assert (np.abs(a - b).max(axis=2)[far] > 2).mean() < 0.1
        core = cv2.erode(inside.astype(np.uint8), np.ones((5, 5))).astype(bool) & road
        if core.sum() > 200:
            ratio = a[core].mean(axis=0) / b[core].mean(axis=0)
            assert ratio.mean() < 0.7
            assert ratio[2] > ratio[0]  # blue attenuated least (skylight)
    assert lost_out < 0.25 * lost_in


def _near_line(line: np.ndarray, height: int) -> tuple[float, float]:
    """x = a * y + b fitted to the lowest quarter of a marking's visible points."""
    part = line[line[:, 1] >= 0.75 * height]
    a, b = np.polyfit(part[:, 1], part[:, 0], 1)
    return float(a), float(b)


def test_dashcam_camera_truth_matches_its_markings() -> None:
    # on straight roads the near parts of the two true markings meet at the vanishing point
    w, h = 640, 480
    for seed in range(6):
        s = generate_scene("dashcam", seed=seed, width=w, height=h, direction=STRAIGHT)
        assert s.image.shape == (h, w, 3) and np.isfinite(s.horizon)
        assert 0.34 * h <= s.horizon <= 0.52 * h  # mount horizon 36-50 %, pitch +-0.6 %
        (a1, b1), (a2, b2) = (_near_line(line, h) for line in s.lane_lines)
        assert a1 < 0 < a2  # the car's lane: centre line left, edge line right
        y = (b2 - b1) / (a1 - a2)
        x = a1 * y + b1
        assert abs(y - s.vanishing_point[1]) < 0.03 * h
        assert abs(x - s.vanishing_point[0]) < 0.04 * w
        assert s.vanishing_point[1] == s.horizon


def test_dashcam_has_a_double_yellow_centre_line_and_a_white_edge_line() -> None:
    s = generate_scene("dashcam", seed=2, width=640, height=480, direction=STRAIGHT)
    lab = cv2.cvtColor(s.image, cv2.COLOR_RGB2LAB).astype(int)
    for side, line in enumerate(s.lane_lines):
        low = line[(line[:, 1] > 400) & (line[:, 1] < 470)]
        assert len(low) > 5
        yellowness, lightness = [], []
        for x, y in np.round(low).astype(int):
            patch = lab[y, max(x - 6, 0) : x + 7]
            yellowness.append(patch[:, 2].max() - 128)
            lightness.append(patch[:, 0].max())
        if side == 0:  # two yellow stripes either side of the centre line
            assert np.median(yellowness) > 30
            centre = lab[np.round(low[:, 1]).astype(int), np.round(low[:, 0]).astype(int)]
            assert np.median(centre[:, 2]) - 128 < np.median(yellowness)  # the gap between
        else:
            assert np.median(yellowness) < 15 and np.median(lightness) > 180


def test_dashcam_drive_has_its_own_camera_and_no_hood() -> None:
    drive = generate_drive("dashcam", 12, seed=9, width=320, height=240)
    horizons = np.array([s.horizon for s in drive]) / 239
    assert np.ptp(horizons) < 0.02  # one mount per drive, a little pitch
    other = generate_drive("dashcam", 12, seed=10, width=320, height=240)
    assert abs(np.median(horizons) - np.median([s.horizon for s in other]) / 239) > 0.005
    assert STYLES["dashcam"].hood is False and STYLES["dashcam"].size == (640, 480)
    bottom = np.array([s.image[-8:].astype(float).mean() for s in drive])
    assert bottom.std() > 0  # the road under the bumper moves: no static hood
