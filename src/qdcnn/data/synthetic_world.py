"""World model of the synthetic road scenes: presets, road geometry, camera and scenery.

Everything here is geometry and random layout in metres; :mod:`qdcnn.data.synthetic_render`
turns one camera pose in such a world into pixels. World coordinates are ``(x, z)`` on the
ground plane (``z`` is the initial driving direction, ``x`` to its right). A heading ``h``
points along ``(sin h, cos h)``, so a growing heading turns right; the curvature of the road
is ``dh/ds`` (1/m), positive for a right bend.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

FloatArray = NDArray[np.float64]
RGB = tuple[float, float, float]

ROUTE_STEP = 0.5  # metres between route samples
CAMERA_HEIGHT = 1.5  # metres above the road
VIEW_DISTANCE = 250.0  # farthest ground drawn (metres)
SCENERY_DISTANCE = 140.0  # farthest roadside objects drawn (metres)


@dataclass(frozen=True)
class Style:
    """Look and statistics of one preset (colours are RGB in [0, 1])."""

    name: str
    bend_steering: tuple[float, float]  # |steering| range of bends
    road_width: tuple[float, float]
    hill_height: tuple[float, float]  # height (m) reached by the ground far ahead; < 0 descends
    hill_distance: tuple[float, float]  # distance (m) over which it is reached
    pitch: float  # horizon jitter as a fraction of the frame height
    sky_top: RGB
    sky_horizon: RGB
    asphalt: RGB
    asphalt_grain: float
    terrain: tuple[RGB, RGB]
    terrain_grain: float
    line_colours: tuple[RGB, ...]
    line_width: tuple[float, float]
    line_inset: tuple[float, float]
    centre_dash_prob: float
    edge_kind: str  # "curb" (red/white), "gravel" or "sidewalk"
    edge_prob: float
    background: str  # "lake", "mountain" or "city"
    hills: tuple[float, float]  # amplitude of the distant skyline (radians)
    tree_kind: str  # "pine" or "broadleaf"
    foliage: tuple[RGB, ...]
    near_trees: float  # trees per 100 m and side within a few metres of the road
    far_trees: float  # trees per 100 m and side further out
    poles: float  # poles per 100 m and side
    buildings: float  # buildings per 100 m and side
    building_colours: tuple[RGB, ...]
    sun_prob: float  # probability that the sun is out (cast shadows at all)
    sun_elevation: tuple[float, float]  # degrees
    shadow_ratio: tuple[float, float]  # shadowed / lit intensity
    shadow_tint: RGB  # relative darkening per channel (blue darkened least)
    penumbra: float  # shadow edge blur (Gaussian sigma, metres on the ground)
    tar_patches: float  # dark road repairs per 100 m
    dark_bushes: float  # dark vegetation patches per 100 m and side
    puddles: float  # puddles per 100 m
    wet: float  # specular reflectance of the road (0 = dry)
    haze_distance: float  # metres
    hood: bool
    rain: bool
    speed_mph: float
    # --- real-camera geometry (the "dashcam" preset); the defaults are the Udacity-like camera
    layout: str = "edges"  # "edges": two boundary lines; "two-lane": double yellow + white edges
    lane_width: tuple[float, float] = (3.4, 3.7)  # "two-lane": width of each lane (m)
    focal: tuple[float, float | None] = (0.6, 1.2)  # fx / W and fy / H (None: fy = fx)
    horizon: tuple[float, float] = (0.40, 0.40)  # camera horizon row / H, drawn per take
    yaw: float = 0.0  # camera yaw to the car's axis, drawn per take in [-yaw, yaw] (radians)
    parked_cars: float = 0.0  # parked cars per 100 m on the right shoulder
    traffic: float = 0.0  # oncoming cars per 100 m in the other lane
    lead_cars: float = 0.0  # cars per 100 m ahead in the car's own lane
    size: tuple[int, int] = (320, 160)  # the preset's natural frame size (width, height)


STYLES: dict[str, Style] = {
    "track1": Style(
        name="track1",
        bend_steering=(0.15, 0.45),
        road_width=(7.5, 9.0),
        hill_height=(-1.5, 2.5),
        hill_distance=(60.0, 120.0),
        pitch=0.015,
        sky_top=(0.30, 0.50, 0.86),
        sky_horizon=(0.78, 0.86, 0.95),
        asphalt=(0.43, 0.43, 0.44),
        asphalt_grain=0.22,
        terrain=((0.63, 0.55, 0.38), (0.55, 0.58, 0.27)),
        terrain_grain=0.18,
        line_colours=((0.88, 0.76, 0.22), (0.86, 0.72, 0.18), (0.92, 0.92, 0.88)),
        line_width=(0.14, 0.22),
        line_inset=(0.15, 0.45),
        centre_dash_prob=0.0,
        edge_kind="curb",
        edge_prob=0.45,
        background="lake",
        hills=(0.02, 0.06),
        tree_kind="pine",
        foliage=((0.20, 0.33, 0.14), (0.25, 0.38, 0.16), (0.17, 0.27, 0.13)),
        near_trees=1.2,
        far_trees=14.0,
        poles=0.6,
        buildings=0.0,
        building_colours=((0.6, 0.58, 0.55),),
        sun_prob=0.5,
        sun_elevation=(55.0, 75.0),
        shadow_ratio=(0.40, 0.60),
        shadow_tint=(1.0, 0.96, 0.84),
        penumbra=0.08,
        tar_patches=0.0,
        dark_bushes=1.0,
        puddles=0.0,
        wet=0.0,
        haze_distance=600.0,
        hood=True,
        rain=False,
        speed_mph=30.19,
    ),
    "track2": Style(
        name="track2",
        bend_steering=(0.30, 0.80),
        road_width=(7.0, 8.5),
        hill_height=(-10.0, 12.0),
        hill_distance=(35.0, 70.0),
        pitch=0.025,
        sky_top=(0.16, 0.32, 0.78),
        sky_horizon=(0.58, 0.70, 0.90),
        asphalt=(0.45, 0.45, 0.48),
        asphalt_grain=0.20,
        terrain=((0.38, 0.32, 0.22), (0.50, 0.40, 0.20)),
        terrain_grain=0.25,
        line_colours=((0.86, 0.70, 0.18), (0.90, 0.76, 0.25), (0.88, 0.88, 0.84)),
        line_width=(0.12, 0.20),
        line_inset=(0.15, 0.40),
        centre_dash_prob=0.0,
        edge_kind="gravel",
        edge_prob=0.8,
        background="mountain",
        hills=(0.06, 0.20),
        tree_kind="broadleaf",
        foliage=((0.55, 0.36, 0.13), (0.40, 0.32, 0.12), (0.28, 0.33, 0.13), (0.62, 0.45, 0.16)),
        near_trees=12.0,
        far_trees=14.0,
        poles=4.0,
        buildings=0.6,
        building_colours=((0.62, 0.60, 0.56), (0.55, 0.38, 0.30), (0.70, 0.66, 0.58)),
        sun_prob=1.0,
        sun_elevation=(25.0, 50.0),
        shadow_ratio=(0.28, 0.50),
        shadow_tint=(1.0, 0.95, 0.80),
        penumbra=0.10,
        tar_patches=5.0,
        dark_bushes=6.0,
        puddles=0.0,
        wet=0.0,
        haze_distance=450.0,
        hood=True,
        rain=False,
        speed_mph=20.0,
    ),
    "rain": Style(
        name="rain",
        bend_steering=(0.20, 0.60),
        road_width=(7.0, 8.0),
        hill_height=(-1.5, 1.5),
        hill_distance=(60.0, 120.0),
        pitch=0.015,
        sky_top=(0.40, 0.42, 0.46),
        sky_horizon=(0.62, 0.64, 0.67),
        asphalt=(0.22, 0.22, 0.23),
        asphalt_grain=0.12,
        terrain=((0.30, 0.33, 0.25), (0.36, 0.36, 0.32)),
        terrain_grain=0.15,
        line_colours=((0.90, 0.90, 0.88), (0.85, 0.75, 0.30)),
        line_width=(0.12, 0.16),
        line_inset=(0.25, 0.45),
        centre_dash_prob=0.4,
        edge_kind="sidewalk",
        edge_prob=0.9,
        background="city",
        hills=(0.03, 0.10),
        tree_kind="broadleaf",
        foliage=((0.20, 0.27, 0.15), (0.24, 0.30, 0.17)),
        near_trees=3.0,
        far_trees=4.0,
        poles=3.0,
        buildings=3.0,
        building_colours=((0.55, 0.52, 0.48), (0.45, 0.40, 0.36), (0.62, 0.60, 0.57)),
        sun_prob=0.25,
        sun_elevation=(30.0, 55.0),
        shadow_ratio=(0.50, 0.68),
        shadow_tint=(1.0, 0.97, 0.90),
        penumbra=0.30,
        tar_patches=0.5,
        dark_bushes=0.5,
        puddles=6.0,
        wet=0.35,
        haze_distance=90.0,
        hood=False,
        rain=True,
        speed_mph=18.0,
    ),
    "dashcam": Style(
        name="dashcam",
        bend_steering=(0.12, 0.45),
        road_width=(8.2, 8.8),
        hill_height=(-2.0, 2.0),
        hill_distance=(70.0, 140.0),
        pitch=0.012,
        sky_top=(0.42, 0.60, 0.88),
        sky_horizon=(0.80, 0.86, 0.92),
        asphalt=(0.36, 0.36, 0.38),
        asphalt_grain=0.10,
        terrain=((0.36, 0.40, 0.22), (0.50, 0.45, 0.30)),
        terrain_grain=0.25,
        line_colours=((0.86, 0.70, 0.16), (0.82, 0.66, 0.20)),  # the centre line's yellows
        line_width=(0.10, 0.15),
        line_inset=(0.0, 0.0),
        centre_dash_prob=0.0,
        edge_kind="gravel",
        edge_prob=0.7,
        background="mountain",
        hills=(0.04, 0.12),
        tree_kind="broadleaf",
        foliage=((0.16, 0.26, 0.12), (0.22, 0.30, 0.14), (0.28, 0.34, 0.16), (0.12, 0.20, 0.10)),
        near_trees=9.0,
        far_trees=22.0,
        poles=1.5,
        buildings=0.4,
        building_colours=((0.70, 0.68, 0.64), (0.58, 0.50, 0.42), (0.80, 0.78, 0.74)),
        sun_prob=0.8,
        sun_elevation=(25.0, 55.0),
        shadow_ratio=(0.30, 0.50),
        shadow_tint=(1.0, 0.96, 0.84),
        penumbra=0.10,
        tar_patches=1.0,
        dark_bushes=4.0,
        puddles=0.0,
        wet=0.0,
        haze_distance=500.0,
        hood=False,
        rain=False,
        speed_mph=28.0,
        layout="two-lane",
        focal=(0.8, None),
        horizon=(0.36, 0.50),
        yaw=0.04,
        parked_cars=2.0,
        traffic=3.0,
        lead_cars=0.5,
        size=(640, 480),
    ),
}

#: colours of the "two-lane" layout's white edge lines (the yellow comes from line_colours)
WHITE_LINE = (0.90, 0.90, 0.88)
CAR_COLOURS: tuple[RGB, ...] = (
    (0.92, 0.92, 0.90),
    (0.08, 0.08, 0.09),
    (0.62, 0.63, 0.65),
    (0.55, 0.10, 0.10),
    (0.15, 0.22, 0.45),
    (0.35, 0.36, 0.38),
)


@dataclass(frozen=True)
class Route:
    """Road centreline sampled every :data:`ROUTE_STEP` metres of arc length from ``s0``."""

    s0: float
    curvature: FloatArray
    heading: FloatArray
    x: FloatArray
    z: FloatArray
    width: float

    @property
    def s(self) -> FloatArray:
        return self.s0 + ROUTE_STEP * np.arange(self.curvature.size, dtype=np.float64)

    @property
    def s_end(self) -> float:
        return self.s0 + ROUTE_STEP * (self.curvature.size - 1)

    @cached_property
    def kdtree(self) -> cKDTree:
        return cKDTree(np.stack([self.x, self.z], axis=1))

    def pose(self, s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Centre ``x``, ``z`` and heading at arc lengths ``s`` (linear interpolation)."""
        grid = self.s
        return (
            np.interp(s, grid, self.x),
            np.interp(s, grid, self.z),
            np.interp(s, grid, self.heading),
        )

    def offset(self, s: FloatArray, d: float | FloatArray) -> tuple[FloatArray, FloatArray]:
        """World points at lateral offset ``d`` (metres, positive right) from the centreline."""
        x, z, h = self.pose(s)
        return x + d * np.cos(h), z - d * np.sin(h)


def _build_route(curvature: FloatArray, s0: float, width: float) -> Route:
    """Integrate a curvature profile (sampled every :data:`ROUTE_STEP` m from ``s0``)."""
    k = np.asarray(curvature, dtype=np.float64)
    heading = np.concatenate([[0.0], np.cumsum(0.5 * (k[1:] + k[:-1]) * ROUTE_STEP)])
    i0 = round(-s0 / ROUTE_STEP)
    heading -= heading[min(max(i0, 0), k.size - 1)]  # heading 0 at s = 0
    mid = heading[:-1] + 0.5 * np.diff(heading)
    x = np.concatenate([[0.0], np.cumsum(np.sin(mid) * ROUTE_STEP)])
    z = np.concatenate([[0.0], np.cumsum(np.cos(mid) * ROUTE_STEP)])
    j = min(max(i0, 0), k.size - 1)
    return Route(s0, k, heading, x - x[j], z - z[j], width)


@dataclass(frozen=True)
class Camera:
    """Pinhole camera ``CAMERA_HEIGHT`` above the road, pitched along the road at the car.

    The ground ahead rises by ``hill * r**2 / (1 + r**2)`` metres at distance ``Z``
    (``r = Z / hill_distance``): a bounded hill (``hill > 0``) or dip (``hill < 0``).
    """

    width: int
    height: int
    horizon: float  # image row of the flat-ground horizon
    hill: float
    hill_distance: float
    focal: tuple[float, float | None] = (0.6, 1.2)  # fx / width, fy / height (None: fy = fx)

    @property
    def fx(self) -> float:
        return self.focal[0] * self.width

    @property
    def fy(self) -> float:
        fy = self.focal[1]
        return self.fx if fy is None else fy * self.height

    @property
    def cx(self) -> float:
        return (self.width - 1) / 2.0

    def ground_height(self, z: FloatArray) -> FloatArray:
        r2 = (np.asarray(z, dtype=np.float64) / self.hill_distance) ** 2
        return np.asarray(self.hill * r2 / (1.0 + r2))

    def row(self, z: FloatArray, above: float | FloatArray = 0.0) -> FloatArray:
        """Image row of a point ``above`` metres over the ground at depth ``z``."""
        z = np.asarray(z, dtype=np.float64)
        return np.asarray(
            self.horizon + self.fy * (CAMERA_HEIGHT - self.ground_height(z) - above) / z
        )

    def column(self, x: FloatArray, z: FloatArray) -> FloatArray:
        return np.asarray(self.cx + self.fx * np.asarray(x) / np.asarray(z))

    def visible_ground(self) -> tuple[float, float, FloatArray, FloatArray]:
        """Depth where the visible ground ends, its row, and a (row, depth) table to invert."""
        zs = np.geomspace(0.5, VIEW_DISTANCE, 768)
        rows = self.row(zs)
        rising = np.flatnonzero(np.diff(rows) >= 0.0)  # beyond a crest the ground is hidden
        end = int(rising[0]) if rising.size else zs.size - 1
        return float(zs[end]), float(rows[end]), rows[: end + 1][::-1], zs[: end + 1][::-1]


@dataclass
class PolySet:
    """Closed polygons stored end to end: ``points[starts[i]: starts[i] + sizes[i]]``."""

    points: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    sizes: NDArray[np.int_] = field(default_factory=lambda: np.zeros(0, dtype=int))
    values: FloatArray = field(default_factory=lambda: np.zeros(0))

    @property
    def starts(self) -> NDArray[np.int_]:
        return np.concatenate([[0], np.cumsum(self.sizes)[:-1]]).astype(int)

    def __len__(self) -> int:
        return int(self.sizes.size)

    @staticmethod
    def join(parts: list[tuple[FloatArray, FloatArray]]) -> PolySet:
        """Concatenate batches ``(polygons (n, k, 2), values (n,))``."""
        parts = [(p, v) for p, v in parts if len(p)]
        if not parts:
            return PolySet()
        return PolySet(
            np.concatenate([p.reshape(-1, 2) for p, _ in parts]),
            np.concatenate([np.full(len(p), p.shape[1], dtype=int) for p, _ in parts]),
            np.concatenate([np.asarray(v, dtype=np.float64) for _, v in parts]),
        )


@dataclass
class Scenery:
    """Roadside objects and ground decals of one take, in world coordinates."""

    trees: dict[str, FloatArray] = field(default_factory=dict)
    tree_outlines: FloatArray = field(default_factory=lambda: np.zeros((0, 0, 2)))
    poles: dict[str, FloatArray] = field(default_factory=dict)
    buildings: list[tuple[FloatArray, float, RGB]] = field(default_factory=list)
    shadows: PolySet = field(default_factory=PolySet)  # values: darkness (1 - shadow/lit)
    tar: PolySet = field(default_factory=PolySet)
    bushes: PolySet = field(default_factory=PolySet)
    puddles: PolySet = field(default_factory=PolySet)


@dataclass
class Take:
    """A world to film: route, materials, sun and scenery (one scene or one drive)."""

    style: Style
    route: Route
    scenery: Scenery
    line_colour: RGB
    line_width: float
    line_inset: float
    centre_dash: bool
    edges: tuple[NDArray[np.bool_], NDArray[np.bool_]]  # edge strip present, per route sample
    sun_out: bool
    shadow_direction: float  # world heading of cast shadows
    sun_elevation: float  # radians
    skyline: FloatArray  # distant ridge elevation (radians) over 4096 headings
    treeline: FloatArray
    tint: FloatArray  # per-take colour gain of the materials
    texture_offset: tuple[float, float]
    horizon: float = 0.40  # camera horizon row / frame height (before pitch)
    yaw: float = 0.0  # camera yaw to the car's axis (radians, > 0 looks right)
    lane_width: float = 0.0  # "two-lane": width of each lane (m); the car drives in the right
    cars: dict[str, FloatArray] = field(default_factory=dict)  # traffic and parked cars

    @property
    def lane_offset(self) -> float:
        """Lateral position (m right of the centreline) of the car's own lane centre."""
        return 0.5 * self.lane_width


@dataclass(frozen=True)
class FrameState:
    """Where the car is in a take, and what it records there."""

    s: float
    lateral: float  # metres right of the centreline
    heading: float  # radians relative to the road direction
    hill: float
    hill_distance: float
    pitch: float  # horizon shift as a fraction of the frame height
    steering: float
    curvature: float


def periodic_noise(rng: np.random.Generator, n: int, beta: float) -> FloatArray:
    """Zero-mean, unit-std periodic 1-D noise with a ``1/f**beta`` power spectrum."""
    spec = np.fft.rfft(rng.standard_normal(n))
    f = np.fft.rfftfreq(n)
    f[0] = 1.0
    spec /= f ** (beta / 2.0)
    spec[0] = 0.0
    out = np.fft.irfft(spec, n)
    return np.asarray(out / (out.std() + 1e-12))


def _blobs(
    rng: np.random.Generator, n: int, points: int = 48, roughness: float = 0.12
) -> FloatArray:
    """``n`` irregular closed outlines of about unit radius, shape ``(n, points, 2)``.

    The radius is modulated by random harmonics 2..13 with amplitudes falling as ``1/k``.
    """
    t = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)
    k = np.arange(2, 14)
    amp = roughness * rng.normal(size=(n, k.size)) * (2.0 / k)[None, :]
    phase = rng.uniform(0, 2 * np.pi, (n, k.size))
    kt = k[:, None] * t[None, :]  # cos(kt + phase) = cos kt cos phase - sin kt sin phase
    r = 1.0 + (amp * np.cos(phase)) @ np.cos(kt) - (amp * np.sin(phase)) @ np.sin(kt)
    r = np.clip(r, 0.5, 1.5)
    return np.stack([r * np.cos(t), r * np.sin(t)], axis=-1)


def shapes(
    centre: FloatArray,
    outline: FloatArray,
    along: FloatArray,
    across: FloatArray,
    angle: FloatArray | float,
) -> FloatArray:
    """Scale unit outlines ``(n, k, 2)`` to semi-axes (along, across) about ``centre (n, 2)``,
    with the first axis along world heading ``angle``."""
    angle = np.broadcast_to(np.asarray(angle, dtype=np.float64), (len(centre),))
    fwd = np.stack([np.sin(angle), np.cos(angle)], -1)[:, None, :]
    right = np.stack([np.cos(angle), -np.sin(angle)], -1)[:, None, :]
    a = (outline[..., 0] * np.asarray(along)[:, None])[..., None]
    b = (outline[..., 1] * np.asarray(across)[:, None])[..., None]
    return np.asarray(centre[:, None, :] + a * fwd + b * right)


def strips(a: FloatArray, b: FloatArray, width: FloatArray, pieces: int = 24) -> FloatArray:
    """Rectangles of ``width`` around segments ``a``-``b`` (both ``(n, 2)``), the long
    sides cut into ``pieces`` edges (so their projection bends with the ground)."""
    v = b - a
    nrm = np.stack([-v[:, 1], v[:, 0]], -1) / (np.linalg.norm(v, axis=1, keepdims=True) + 1e-9)
    off = nrm * (np.asarray(width)[:, None] / 2)
    t = np.linspace(0.0, 1.0, pieces + 1)[None, :, None]
    side = a[:, None, :] + v[:, None, :] * t
    return np.concatenate([side + off[:, None, :], (side - off[:, None, :])[:, ::-1]], axis=1)


def _positions(rng: np.random.Generator, s_lo: float, s_hi: float, per_100m: float) -> FloatArray:
    n = rng.poisson(max(per_100m, 0.0) * max(s_hi - s_lo, 0.0) / 100.0)
    return np.sort(rng.uniform(s_lo, s_hi, n))


def _off_road(route: Route, x: FloatArray, z: FloatArray, clearance: float) -> NDArray[np.bool_]:
    """Points at least ``clearance`` metres from every part of the route (loops included)."""
    if x.size == 0:
        return np.zeros(0, dtype=bool)
    dist, _ = route.kdtree.query(np.stack([x, z], axis=1))
    return np.asarray(dist >= clearance)


def _roadside(
    rng: np.random.Generator,
    route: Route,
    s_lo: float,
    s_hi: float,
    per_100m: float,
    gap: tuple[float, float],
    clearance: float,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Random points on both sides, ``gap`` metres beyond the road edge: x, z, side."""
    left, right = (_positions(rng, s_lo, s_hi, per_100m) for _ in range(2))
    s = np.concatenate([left, right])
    side = np.concatenate([np.full(left.size, -1.0), np.full(right.size, 1.0)])
    d = side * (route.width / 2 + rng.uniform(*gap, s.size))
    x, z = route.offset(s, d)
    keep = _off_road(route, x, z, clearance)
    return x[keep], z[keep], np.stack([s[keep], side[keep]])


_ShadowParts = list[tuple[FloatArray, FloatArray]]  # ground polygons and their darkness


@dataclass(frozen=True)
class _Sun:
    """The sun of a take: shadow geometry and the per-take base of the shadows' darkness."""

    direction: float  # shadow direction on the ground (radians)
    elevation: float
    out: bool
    base_ratio: float  # shadowed/lit ratio of the take
    ratio_range: tuple[float, float]

    @property
    def cot(self) -> float:
        return float(1.0 / np.tan(self.elevation))

    @property
    def sdir(self) -> FloatArray:
        return np.array([np.sin(self.direction), np.cos(self.direction)])

    def darkness(self, rng: np.random.Generator, n: int) -> FloatArray:
        """Darkness (1 - shadowed/lit ratio) of ``n`` casters' shadows, around the take's."""
        lo_r, hi_r = self.ratio_range
        ratio = np.clip(self.base_ratio + rng.normal(0, 0.04, n), lo_r - 0.05, hi_r + 0.05)
        return np.asarray(np.round((1.0 - ratio) * 50) / 50)  # a few levels: fewer fills


@dataclass
class _Layout:
    """What the scenery placers share: the random stream (drawn from in a fixed order),
    the style, the stretch of route, the sun, and the shadows laid so far."""

    rng: np.random.Generator
    style: Style
    route: Route
    s_lo: float
    s_hi: float
    sun: _Sun
    shadow_parts: _ShadowParts = field(default_factory=list)


def _make_scenery(
    rng: np.random.Generator,
    style: Style,
    route: Route,
    s_lo: float,
    s_hi: float,
    shadow_direction: float,
    sun_elevation: float,
    sun_out: bool,
) -> Scenery:
    """Lay out trees, poles, buildings and ground decals along ``route`` between two arc lengths.

    Cast shadows are ground polygons computed from each caster's shape and the sun; their
    darkness (1 - shadowed/lit ratio) varies a little per caster around a per-take value.
    """
    sc = Scenery()
    base_ratio = rng.uniform(*style.shadow_ratio)
    sun = _Sun(shadow_direction, sun_elevation, sun_out, base_ratio, style.shadow_ratio)
    lay = _Layout(rng, style, route, s_lo, s_hi, sun)
    sc.trees, sc.tree_outlines = _place_trees(lay)
    sc.poles = _place_poles(lay)
    sc.buildings = _place_buildings(lay)
    sc.shadows = PolySet.join(lay.shadow_parts)
    # Ground decals: tar repairs on the road, dark bushes beside it, puddles on the road.
    sc.tar = _road_decals(lay, style.tar_patches, (0.5, 2.0), (1.0, 2.5))
    sc.puddles = _road_decals(lay, style.puddles, (0.6, 2.0), (1.2, 3.0))
    sc.bushes = _bushes(lay)
    return sc


def _place_trees(lay: _Layout) -> tuple[dict[str, FloatArray], FloatArray]:
    """Trees and their outlines; their shadows go to ``lay.shadow_parts``.

    Near trees cast shadows onto the road, far ones make the landscape.
    """
    rng, style, route, s_lo, s_hi, sun = lay.rng, lay.style, lay.route, lay.s_lo, lay.s_hi, lay.sun
    half = route.width / 2.0
    near = _roadside(rng, route, s_lo, s_hi, style.near_trees, (1.2, 7.0), half + 1.0)
    far = _roadside(rng, route, s_lo, s_hi, style.far_trees, (7.0, 45.0), half + 1.0)
    x = np.concatenate([near[0], far[0]])
    z = np.concatenate([near[1], far[1]])
    n = x.size
    pine = style.tree_kind == "pine"
    height = rng.uniform(6.0, 13.0, n) if pine else rng.uniform(5.0, 11.0, n)
    radius = height * (rng.uniform(0.18, 0.26, n) if pine else rng.uniform(0.28, 0.42, n))
    crown = height - radius * (1.6 if pine else 1.0)  # canopy centre height
    trunk_top = crown - radius * (1.2 if pine else 0.7)
    trees = {
        "x": x,
        "z": z,
        "height": height,
        "radius": radius,
        "crown": crown,
        "trunk_top": trunk_top,
        "trunk_w": rng.uniform(0.25, 0.45, n),
        "colour": rng.integers(0, len(style.foliage), n).astype(np.float64),
    }
    outlines = _pine_outlines(rng, n) if pine else _blobs(rng, n, 56, 0.13)
    if not pine:
        outlines[..., 1] *= 1.1
    if sun.out and n:
        base = np.stack([x, z], -1)
        along = radius / np.sin(sun.elevation) * (1.3 if pine else 1.0)
        canopy = shapes(
            base + sun.sdir * (crown * sun.cot)[:, None],
            _blobs(rng, n, 64, 0.10 if pine else 0.18),
            along,
            radius * (0.8 if pine else 1.0),
            sun.direction,
        )
        dark = sun.darkness(rng, n)
        trunk = strips(base, base + sun.sdir * (trunk_top * sun.cot)[:, None], trees["trunk_w"])
        lay.shadow_parts += [(canopy, dark), (trunk, dark)]
    return trees, outlines


def _place_poles(lay: _Layout) -> dict[str, FloatArray]:
    """Poles (street lights / power poles), most with an arm reaching over the road; their
    shadows go to ``lay.shadow_parts``."""
    rng, style, route, s_lo, s_hi, sun = lay.rng, lay.style, lay.route, lay.s_lo, lay.s_hi, lay.sun
    half = route.width / 2.0
    px, pz, (ps, pside) = _roadside(rng, route, s_lo, s_hi, style.poles, (0.6, 2.5), half + 0.4)
    _, _, h_road = route.pose(ps)
    m = px.size
    poles = {
        "x": px,
        "z": pz,
        "height": rng.uniform(6.0, 9.5, m),
        "width": rng.uniform(0.16, 0.26, m),
        "arm": rng.uniform(1.2, 2.8, m) * (rng.random(m) < 0.7),
        "arm_dir": h_road + np.where(pside < 0, np.pi / 2, -np.pi / 2),
    }
    if sun.out and m:
        base = np.stack([px, pz], -1)
        top = base + sun.sdir * (poles["height"] * sun.cot)[:, None]
        dark = sun.darkness(rng, m)
        lay.shadow_parts.append((strips(base, top, poles["width"]), dark))
        arm = poles["arm"] > 0
        a = poles["arm_dir"][arm]
        tip = top[arm] + poles["arm"][arm, None] * np.stack([np.sin(a), np.cos(a)], -1)
        lay.shadow_parts.append((strips(top[arm], tip, poles["width"][arm] * 0.8, 6), dark[arm]))
    return poles


def _place_buildings(lay: _Layout) -> list[tuple[FloatArray, float, RGB]]:
    """Buildings: boxes set back from the road (corners, height, colour); their shadows go
    to ``lay.shadow_parts``."""
    rng, style, route, s_lo, s_hi, sun = lay.rng, lay.style, lay.route, lay.s_lo, lay.s_hi, lay.sun
    half = route.width / 2.0
    buildings: list[tuple[FloatArray, float, RGB]] = []
    for side in (-1.0, 1.0):
        for s in _positions(rng, s_lo, s_hi, style.buildings):
            depth, length = rng.uniform(6.0, 14.0), rng.uniform(7.0, 18.0)
            setback = half + rng.uniform(3.0, 8.0 if style.background == "city" else 14.0)
            _, _, h = route.pose(np.array([s]))
            angle = float(h[0]) + rng.normal(0, 0.05)
            fwd = np.array([np.sin(angle), np.cos(angle)])
            right = np.array([np.cos(angle), -np.sin(angle)])
            cx_, cz_ = route.offset(np.array([s]), side * (setback + depth / 2))
            c = np.array([cx_[0], cz_[0]])
            corners = np.array(
                [
                    c + a_ * fwd * length / 2 + b_ * right * depth / 2
                    for a_, b_ in ((-1, -1), (1, -1), (1, 1), (-1, 1))
                ]
            )
            if not _off_road(route, corners[:, 0], corners[:, 1], half + 1.5).all():
                continue
            height_b = rng.uniform(6.0, 16.0 if style.background == "city" else 11.0)
            colour = style.building_colours[int(rng.integers(len(style.building_colours)))]
            buildings.append((corners, height_b, colour))
            if sun.out:
                moved = corners + sun.sdir * height_b * sun.cot
                hull = _convex_hull(np.concatenate([corners, moved]).astype(np.float32))
                lay.shadow_parts.append((_densify(hull, 0.5)[None], sun.darkness(rng, 1)))
    return buildings


def _road_decals(
    lay: _Layout, per_100m: float, size: tuple[float, float], stretch: tuple[float, float]
) -> PolySet:
    """Rough blobs lying on the road (tar repairs, puddles)."""
    rng, route, s_lo, s_hi = lay.rng, lay.route, lay.s_lo, lay.s_hi
    half = route.width / 2.0
    s = _positions(rng, s_lo, s_hi, per_100m)
    d = rng.uniform(-half + 0.8, half - 0.8, s.size)
    xx, zz = route.offset(s, d)
    _, _, hh = route.pose(s)
    r = rng.uniform(*size, s.size)
    polys = shapes(
        np.stack([xx, zz], -1),
        _blobs(rng, s.size, 32, 0.25),
        r * rng.uniform(*stretch, s.size),
        r,
        hh + rng.normal(0, 0.3, s.size),
    )
    return PolySet.join([(polys, np.ones(s.size))])


def _bushes(lay: _Layout) -> PolySet:
    """Dark bushes beside the road."""
    rng, style, route, s_lo, s_hi = lay.rng, lay.style, lay.route, lay.s_lo, lay.s_hi
    half = route.width / 2.0
    bx, bz, _ = _roadside(rng, route, s_lo, s_hi, style.dark_bushes, (1.0, 9.0), half + 0.8)
    r = rng.uniform(0.8, 2.5, bx.size)
    bushes = shapes(
        np.stack([bx, bz], -1),
        _blobs(rng, bx.size, 32, 0.3),
        r * rng.uniform(1.0, 2.0, bx.size),
        r,
        rng.uniform(0, 2 * np.pi, bx.size),
    )
    return PolySet.join([(bushes, np.ones(bx.size))])


def _pine_outlines(rng: np.random.Generator, n: int, tiers: int = 5) -> FloatArray:
    """Tiered conifer silhouettes in units of the canopy radius (x right, y up)."""
    t = np.linspace(0.0, 1.0, 2 * tiers + 1)
    saw = np.where(np.arange(t.size) % 2 == 1, 1.0, 0.72)
    y = 1.6 - 2.8 * t
    half_r = (0.1 + 0.9 * t) * saw * rng.uniform(0.9, 1.1, (n, t.size))
    half_l = (0.1 + 0.9 * t) * saw * rng.uniform(0.9, 1.1, (n, t.size))
    right = np.stack([half_r, np.broadcast_to(y, (n, t.size))], -1)
    left = np.stack([-half_l[:, ::-1], np.broadcast_to(y[::-1], (n, t.size))], -1)
    apex = np.broadcast_to(np.array([0.0, 1.65]), (n, 1, 2))
    return np.concatenate([apex, right, left], axis=1)


def _densify(poly: FloatArray, step: float) -> FloatArray:
    """Insert vertices so that no edge of the closed polygon is longer than ``step``."""
    nxt = np.roll(poly, -1, axis=0)
    counts = np.maximum(1, np.ceil(np.linalg.norm(nxt - poly, axis=1) / step).astype(int))
    t = np.concatenate([np.arange(c) / c for c in counts])
    idx = np.repeat(np.arange(len(poly)), counts)
    return np.asarray(poly[idx] + (nxt[idx] - poly[idx]) * t[:, None])


def _convex_hull(points: NDArray[np.float32]) -> FloatArray:
    return np.asarray(cv2.convexHull(points)[:, 0, :], dtype=np.float64)


def make_take(
    rng: np.random.Generator,
    style: Style,
    curvature: FloatArray,
    s0: float,
    s_lo: float,
    s_hi: float,
) -> Take:
    """Draw the materials, sun and scenery of a take on a curvature profile."""
    route = _build_route(curvature, s0, float(rng.uniform(*style.road_width)))
    base_line = np.asarray(style.line_colours[int(rng.integers(len(style.line_colours)))])
    line_colour = np.clip(base_line + rng.uniform(-0.04, 0.04, 3), 0.0, 1.0)
    sun_out = bool(rng.random() < style.sun_prob)
    shadow_direction = float(rng.uniform(0, 2 * np.pi))
    elevation = float(np.radians(rng.uniform(*style.sun_elevation)))
    edges = _edge_presence(rng, style, route)
    scenery = _make_scenery(rng, style, route, s_lo, s_hi, shadow_direction, elevation, sun_out)
    lo, hi = style.hills
    take = Take(
        style=style,
        route=route,
        scenery=scenery,
        line_colour=(float(line_colour[0]), float(line_colour[1]), float(line_colour[2])),
        line_width=float(rng.uniform(*style.line_width)),
        line_inset=float(rng.uniform(*style.line_inset)),
        centre_dash=bool(rng.random() < style.centre_dash_prob),
        edges=edges,
        sun_out=sun_out,
        shadow_direction=shadow_direction,
        sun_elevation=elevation,
        skyline=np.abs(periodic_noise(rng, 4096, 2.2)) * rng.uniform(lo, hi) * 0.6 + lo * 0.3,
        treeline=periodic_noise(rng, 4096, 1.2) * 0.004 + 0.008,
        tint=1.0 + rng.uniform(-0.05, 0.05, 3),
        texture_offset=(float(rng.uniform(0, 1000)), float(rng.uniform(0, 1000))),
    )
    if style.layout != "two-lane":
        return take  # the Udacity-like presets draw nothing more (their takes stay as they were)
    lane = float(rng.uniform(*style.lane_width))
    return replace(
        take,
        horizon=float(rng.uniform(*style.horizon)),
        yaw=float(rng.uniform(-style.yaw, style.yaw)),
        lane_width=lane,
        cars=_make_cars(rng, style, route, s_lo, s_hi, lane),
    )


def _make_cars(
    rng: np.random.Generator,
    style: Style,
    route: Route,
    s_lo: float,
    s_hi: float,
    lane_width: float,
) -> dict[str, FloatArray]:
    """Parked cars on the right shoulder, oncoming traffic and cars ahead in the own lane.

    Each car is a box on the road: ``s`` (arc length at time 0), ``d`` (lateral offset, m),
    ``speed`` (m/s along the route: 0 parked, < 0 oncoming), ``length``, ``width``,
    ``height`` (m) and ``colour`` (index into :data:`CAR_COLOURS`). The renderer moves each
    car to ``s + speed * t`` at the frame's time ``t``.
    """
    half = route.width / 2.0
    span_hi = s_hi + 400.0  # oncoming cars start far ahead
    parked = _positions(rng, s_lo, s_hi, style.parked_cars)
    oncoming = _positions(rng, s_lo, span_hi, style.traffic)
    ahead = _positions(rng, 20.0, s_hi, style.lead_cars)
    n_p, n_o, n_a = parked.size, oncoming.size, ahead.size
    ego = style.speed_mph * 0.44704
    d = np.concatenate(
        [
            half + rng.uniform(0.6, 1.4, n_p),
            -0.5 * lane_width + rng.normal(0.0, 0.15, n_o),
            0.5 * lane_width + rng.normal(0.0, 0.1, n_a),
        ]
    )
    speed = np.concatenate(
        [np.zeros(n_p), -rng.uniform(0.8, 1.2, n_o) * ego, rng.uniform(0.9, 1.0, n_a) * ego]
    )
    n = n_p + n_o + n_a
    return {
        "s": np.concatenate([parked, oncoming, ahead]),
        "d": d,
        "speed": speed,
        "length": rng.uniform(4.0, 5.0, n),
        "width": rng.uniform(1.7, 1.95, n),
        "height": rng.uniform(1.35, 1.8, n),
        "colour": rng.integers(0, len(CAR_COLOURS), n).astype(np.float64),
    }


def _edge_presence(
    rng: np.random.Generator, style: Style, route: Route
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """Where the roadside strips (curbs, gravel, sidewalk) are laid, per side."""
    n = route.curvature.size
    out = []
    for _ in range(2):
        if style.edge_kind == "curb":
            # red/white curbs line the bends (and a little either side of them)
            bend = np.abs(route.curvature) > 0.004
            grow = int(20 / ROUTE_STEP)
            bend = np.convolve(bend.astype(float), np.ones(2 * grow + 1), "same") > 0
            on = bend & (rng.random() < style.edge_prob * 1.6)
            if rng.random() < style.edge_prob * 0.4:
                on = np.ones(n, dtype=bool)
        else:
            on = np.full(n, rng.random() < style.edge_prob)
        out.append(np.asarray(on, dtype=bool))
    return out[0], out[1]
