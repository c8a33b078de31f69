"""Synthetic road scenes with exact ground truth: the default data source of qdcnn.

Three presets imitate the paper's data sets (Sec. III-B): ``track1`` (Udacity lake track:
sunny, gentle bends, few shadows), ``track2`` (Udacity mountain track: hills, sharp bends,
many hard cast shadows from trees, poles and buildings, plus dark decoys such as tar
repairs and dark bushes) and ``rain`` (CARLA-like town road in rain: overcast, wet and
reflective, rain streaks, few weak shadows). A fourth, ``dashcam``, is a real windscreen
camera on a two-lane public road (:mod:`qdcnn.data.synthetic_world`): no hood, square pixels
at 640x480 (``STYLES["dashcam"].size``; pass ``width``/``height``), a horizon drawn per drive
between 36 % and 50 % of the height and a small camera yaw, a double yellow centre line and
white edge lines, roadside trees with their shadows across the lane, parked cars and other
traffic; ``RoadScene.horizon`` and ``vanishing_point`` give its exact camera geometry.

A scene is rendered from a small 3-D world (:mod:`qdcnn.data.synthetic_world`) by
:mod:`qdcnn.data.synthetic_render`, so the shadow mask, road mask and lane-marking polylines
are exact: they are the very polygons that were drawn. Steering follows the road curvature
(``steering = _STEERING_PER_CURVATURE * curvature``, Udacity sign convention: negative is
left), and the direction label comes from steering with :data:`LABEL_THRESHOLD`.

Examples
--------
>>> scene = generate_scene("track2", seed=3, direction=0)
>>> scene.image.shape, scene.direction, scene.steering < -0.05
((160, 320, 3), 0, True)
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from qdcnn.data.labels import LEFT, RIGHT, STRAIGHT
from qdcnn.data.synthetic_presets import PRESETS
from qdcnn.data.synthetic_render import render
from qdcnn.data.synthetic_world import (
    ROUTE_STEP,
    STYLES,
    FrameState,
    Style,
    Take,
    make_take,
    periodic_noise,
)
from qdcnn.errors import ParameterError

_STEERING_PER_CURVATURE = 20.0  # steering per unit of road curvature (1/m): radius 20 m -> 1.0
_STRAIGHT_MAX_STEERING = 0.02  # |steering| of straight scenes stays at or below this
LABEL_THRESHOLD = 0.05  # |steering| below this is "straight" (LabelConfig.threshold)
_MIN_SIZE, _MAX_SIZE = 16, 8192
_MPH = 0.44704  # metres per second in one mile per hour


@dataclass
class RoadScene:
    """One synthetic frame and its exact ground truth.

    Attributes
    ----------
    image : ndarray of uint8, shape (H, W, 3)
        The RGB frame.
    shadow_mask : ndarray of bool, shape (H, W)
        Cast-shadow pixels on the ground (blurred shadow coverage >= 0.5); the casters
        themselves, the sky and the car hood are never shadow.
    road_mask : ndarray of bool, shape (H, W)
        Visible drivable road surface (markings included, curbs and shoulders excluded).
    lane_lines : list of ndarray, shape (N, 2)
        ``[left, right]`` centre lines of the two boundary markings as drawn, as pixel
        ``(x, y)`` points ordered from near (bottom) to far; only the visible part (inside
        the frame, on visible ground, not under the hood). May be empty.
    curvature : float
        Signed road curvature in 1/m at the car (> 0 bends right).
    steering : float
        Steering in [-1, 1], negative = left (Udacity convention).
    direction : int
        0 left, 1 straight, 2 right (:mod:`qdcnn.data.labels`).
    preset : str
        The preset that made the scene.
    seed : int
        ``generate_scene(preset, seed=seed, direction=direction)`` makes this scene again
        (for frames of a drive: the seed of the drive).
    frame : int or None
        Index of the frame in a drive (``None`` for independent scenes).
    speed : float
        Speed as the Udacity simulator logs it (miles per hour).
    throttle : float
        Throttle in [0, 1] as the simulator logs it.
    horizon : float
        Image row (pixels) of the camera's flat-ground horizon.
    vanishing_point : (float, float)
        Image ``(x, y)`` (pixels) where the road's borders at the car vanish.
    """

    image: NDArray[np.uint8]
    shadow_mask: NDArray[np.bool_]
    road_mask: NDArray[np.bool_]
    lane_lines: list[NDArray[np.float64]]
    curvature: float
    steering: float
    direction: int
    preset: str
    seed: int
    frame: int | None = None
    speed: float = 30.19
    throttle: float = 1.0
    horizon: float = float("nan")
    vanishing_point: tuple[float, float] = (float("nan"), float("nan"))


def direction_of(steering: float, threshold: float = LABEL_THRESHOLD) -> int:
    """Direction class of a steering value: left below ``-threshold``, right above it."""
    if steering < -threshold:
        return LEFT
    if steering > threshold:
        return RIGHT
    return STRAIGHT


def _check(preset: str, width: int, height: int) -> Style:
    if preset not in STYLES:
        raise ParameterError("preset", preset, f"one of {', '.join(PRESETS)}")
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, int | np.integer):
            raise ParameterError(name, value, "an integer number of pixels")
        if not _MIN_SIZE <= value <= _MAX_SIZE:
            raise ParameterError(name, value, f"between {_MIN_SIZE} and {_MAX_SIZE} pixels")
    return STYLES[preset]


def _check_seed(seed: int) -> int:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ParameterError("seed", seed, "a non-negative integer")
    return int(seed)


def generate_scene(
    preset: str = "track1",
    *,
    seed: int = 0,
    width: int = 320,
    height: int = 160,
    direction: int | None = None,
    hood: bool | None = None,
) -> RoadScene:
    """Render one independent road scene.

    Parameters
    ----------
    preset : {"track1", "track2", "rain"}
        Look and statistics of the scene (see the module docstring).
    seed : int
        Seed of the scene; the same seed gives identical arrays. The content (road,
        scenery, shadows) does not depend on the frame size.
    width, height : int
        Frame size in pixels (16 to 8192 each).
    direction : {0, 1, 2} or None
        Force a left, straight or right road; ``None`` draws one from the seed.
    hood : bool or None
        Draw the car bonnet at the bottom; ``None`` follows the preset (Udacity presets
        have it, ``rain`` does not).

    Returns
    -------
    RoadScene
        A straight scene has ``|steering| <= 0.02``; a bend has ``|steering|`` in the
        preset's range (within [0.15, 0.8]) with the sign of the bend.
    """
    style = _check(preset, width, height)
    seed = _check_seed(seed)
    if direction is not None and direction not in (LEFT, STRAIGHT, RIGHT):
        raise ParameterError("direction", direction, "0 (left), 1 (straight), 2 (right) or None")
    world_ss, frame_ss = np.random.SeedSequence(seed).spawn(2)
    rng = np.random.default_rng(world_ss)
    drawn = int(rng.integers(3))
    direction = drawn if direction is None else int(direction)
    if direction == STRAIGHT:
        steering = float(rng.uniform(-_STRAIGHT_MAX_STEERING, _STRAIGHT_MAX_STEERING))
    else:
        steering = float(rng.uniform(*style.bend_steering)) * (1.0 if direction == RIGHT else -1.0)
    curvature = steering / _STEERING_PER_CURVATURE
    # Past ~120 degrees of turn the road is out of view: stop the route there.
    length = min(260.0, 2.1 / abs(curvature)) if curvature else 260.0
    s0 = -40.0
    n = int((length - s0) / ROUTE_STEP) + 1
    take = make_take(rng, style, np.full(n, curvature), s0, -30.0, min(length, 160.0))
    state = FrameState(
        s=0.0,
        lateral=float(rng.uniform(-0.35, 0.35)),
        heading=float(rng.uniform(-0.015, 0.015)),
        hill=float(rng.uniform(*style.hill_height)),
        hill_distance=float(rng.uniform(*style.hill_distance)),
        pitch=float(rng.uniform(-style.pitch, style.pitch)),
        steering=steering,
        curvature=curvature,
    )
    return _scene(
        take,
        state,
        preset,
        seed,
        width,
        height,
        np.random.default_rng(frame_ss),
        style.hood if hood is None else hood,
        None,
        direction,
    )


def _scene(
    take: Take,
    state: FrameState,
    preset: str,
    seed: int,
    width: int,
    height: int,
    rng: np.random.Generator,
    hood: bool,
    frame: int | None,
    direction: int | None = None,
) -> RoadScene:
    out = render(take, state, width, height, rng, hood)
    return RoadScene(
        image=out.image,
        shadow_mask=out.shadow_mask,
        road_mask=out.road_mask,
        lane_lines=out.lane_lines,
        curvature=float(state.curvature),
        steering=float(state.steering),
        direction=direction_of(state.steering) if direction is None else direction,
        preset=preset,
        seed=seed,
        frame=frame,
        speed=float(take.style.speed_mph + rng.normal(0, 0.002)),
        throttle=1.0,
        horizon=out.horizon,
        vanishing_point=out.vanishing_point,
    )


def generate_scenes(
    preset: str,
    n: int,
    *,
    seed: int = 0,
    width: int = 320,
    height: int = 160,
    hood: bool | None = None,
) -> list[RoadScene]:
    """Render ``n`` independent scenes with balanced classes.

    Directions cycle through left, straight and right in an order shuffled by ``seed``;
    scene ``i`` has its own seed (stored in ``RoadScene.seed``), derived from ``seed`` and
    ``i``, so any scene can be regenerated alone with :func:`generate_scene`.
    """
    _check(preset, width, height)
    seed = _check_seed(seed)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
        raise ParameterError("n", n, "a non-negative integer")
    order = np.random.default_rng(np.random.SeedSequence([seed, 2**31])).permutation(3)
    scenes = []
    for i in range(int(n)):
        scene_seed = int(np.random.SeedSequence([seed, i]).generate_state(1)[0])
        scenes.append(
            generate_scene(
                preset,
                seed=scene_seed,
                width=width,
                height=height,
                direction=int(order[i % 3]),
                hood=hood,
            )
        )
    return scenes


def drive_curvature(
    rng: np.random.Generator, style: Style, frames: int, min_frames: int = 25
) -> tuple[NDArray[np.float64], NDArray[np.int_]]:
    """Per-frame curvature of a drive: straight runs and bends joined by smooth ramps.

    Returns the curvature (1/m) of each frame and the segment kind of each frame
    (0 left, 1 straight, 2 right; ramps belong to the segment they lead into).
    """
    curv = np.zeros(frames)
    kinds = np.zeros(frames, dtype=int)
    t = 0
    kind = int(rng.integers(3))
    level = 0.0
    while t < frames:
        target = 0.0
        if kind != STRAIGHT:
            target = rng.uniform(*style.bend_steering) / _STEERING_PER_CURVATURE
            target *= 1.0 if kind == RIGHT else -1.0
        # ramps: 5-10 frames, longer for bigger changes (bend to opposite bend)
        jump = abs(target - level) * _STEERING_PER_CURVATURE
        ramp = int(rng.integers(5, 11) + 8 * jump) if t else 0
        hold = int(rng.integers(min_frames, 2 * min_frames + 10))
        r = np.arange(1, ramp + 1) / (ramp + 1)
        seg = np.concatenate(
            [level + (target - level) * (0.5 - 0.5 * np.cos(np.pi * r)), np.full(hold, target)]
        )
        curv[t : t + seg.size] = seg[: frames - t]
        kinds[t : t + seg.size] = kind
        t += seg.size
        level = target
        kind = int(rng.choice([k for k in (LEFT, STRAIGHT, RIGHT) if k != kind]))
    return curv, kinds


def _smooth(rng: np.random.Generator, t: NDArray[np.floating], beta: float) -> NDArray[np.float64]:
    """A smooth random process (unit std, ``1/f**beta`` spectrum) read at positions ``t``
    (in samples of the underlying periodic noise; long enough never to repeat within ``t``)."""
    size = 4096
    while size < 2 * (float(t.max()) + 2 if t.size else 0):
        size *= 2
    base = periodic_noise(rng, size, beta)
    return np.asarray(np.interp(t, np.arange(size + 1), np.append(base, base[0])))


def generate_drive(
    preset: str,
    n: int,
    *,
    seed: int = 0,
    width: int = 320,
    height: int = 160,
    fps: float = 10.0,
    hood: bool | None = None,
) -> list[RoadScene]:
    """Render a recording-like sequence of ``n`` frames taken ``1/fps`` seconds apart.

    The list of :func:`iter_drive`'s scenes (see there for the drive itself).
    """
    return list(iter_drive(preset, n, seed=seed, width=width, height=height, fps=fps, hood=hood))


def iter_drive(
    preset: str,
    n: int,
    *,
    seed: int = 0,
    width: int = 320,
    height: int = 160,
    fps: float = 10.0,
    hood: bool | None = None,
) -> Iterator[RoadScene]:
    """Render the frames of a drive one at a time (never all in memory).

    Arguments are checked when it is called, before the first scene is rendered; the
    scenes are identical to :func:`generate_drive`'s.

    The road curvature follows straight runs and left/right bends, each at least 25 frames
    long, joined by raised-cosine ramps (5-10 frames plus 8 per unit of steering change, so
    about 7-23 frames); the car drives along the road at the preset's speed with a slow
    lateral wander, so the scenery and its shadows move continuously from frame to frame.
    Steering follows the curvature under the car (with a little driver noise; straight runs
    stay within 0.02), so labels from steering are right
    except near the transitions, where the image already shows the next segment.
    """
    style = _check(preset, width, height)
    seed = _check_seed(seed)
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 0:
        raise ParameterError("n", n, "a non-negative integer")
    if not (isinstance(fps, int | float) and 0.5 <= float(fps) <= 1000.0):
        raise ParameterError("fps", fps, "a frame rate between 0.5 and 1000")
    n = int(n)
    if n == 0:
        return iter(())
    return _drive_scenes(style, preset, n, seed, width, height, float(fps), hood)


def _drive_scenes(
    style: Style,
    preset: str,
    n: int,
    seed: int,
    width: int,
    height: int,
    fps: float,
    hood: bool | None,
) -> Iterator[RoadScene]:
    world_ss, frame_ss = np.random.SeedSequence(seed).spawn(2)
    rng = np.random.default_rng(world_ss)
    step = style.speed_mph * _MPH / fps  # metres per frame
    curv_frames, _ = drive_curvature(rng, style, n)
    # Curvature along the route: frames at s = i * step; the road beyond the last frame
    # continues the last segment, the road behind the first frame is straight.
    s0, ahead = -40.0, 260.0
    s_grid = s0 + ROUTE_STEP * np.arange(int((n * step + ahead - s0) / ROUTE_STEP) + 1)
    curvature = np.interp(s_grid, step * np.arange(n), curv_frames, left=0.0)
    take = make_take(rng, style, curvature, s0, -30.0, n * step + ahead)

    s_frames = step * np.arange(n)
    wander = 0.3 * _smooth(rng, s_frames / 1.5, 3.0)  # lateral offset (m), slow
    heading = np.gradient(wander, step) if n > 1 else np.zeros(1)
    lo, hi = style.hill_height
    hills = lo + (hi - lo) * (0.5 + 0.5 * np.tanh(_smooth(rng, s_frames / 3.0, 3.5)))
    pitch = style.pitch * 0.5 * np.tanh(_smooth(rng, s_frames / 4.0, 3.5))
    noise = 0.004 * _smooth(rng, np.arange(n, dtype=float), 1.5)  # driver's small corrections
    hill_dist = float(np.mean(style.hill_distance))
    frame_seeds = frame_ss.spawn(n)
    use_hood = style.hood if hood is None else hood
    for i in range(n):
        k = float(curv_frames[i])
        steer = float(np.clip(_STEERING_PER_CURVATURE * k + noise[i], -1.0, 1.0))
        if k == 0.0:
            steer = float(np.clip(steer, -_STRAIGHT_MAX_STEERING, _STRAIGHT_MAX_STEERING))
        state = FrameState(
            s=float(s_frames[i]),
            lateral=float(wander[i]),
            heading=float(heading[i]),
            hill=float(hills[i]),
            hill_distance=hill_dist,
            pitch=float(pitch[i]),
            steering=steer,
            curvature=k,
        )
        frame_rng = np.random.default_rng(frame_seeds[i])
        yield _scene(take, state, preset, seed, width, height, frame_rng, use_hood, i)
