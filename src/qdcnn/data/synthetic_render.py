"""Rasterise one camera pose of a synthetic take into an RGB frame and its exact ground truth.

Ground geometry is exact per image row: a row sees the ground at one depth ``Z`` (the camera
is pitched along the road and the ground height depends on depth only), so every ground pixel
has world coordinates, which drive procedural textures (sampled with a per-row mip level),
and every road, marking, decal and shadow is a world polygon projected with the same camera.
Shadows darken the lit colour multiplicatively, less in blue than in red and green (the
shadowed ground is lit by the blue sky only); their edges are blurred and the ground truth is
the blurred coverage ``>= 0.5``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from qdcnn.data.synthetic_world import (
    CAMERA_HEIGHT,
    CAR_COLOURS,
    ROUTE_STEP,
    SCENERY_DISTANCE,
    VIEW_DISTANCE,
    WHITE_LINE,
    Camera,
    FloatArray,
    FrameState,
    PolySet,
    Take,
)

_F32 = NDArray[np.float32]
_U8 = NDArray[np.uint8]
_SHIFT = 4  # sub-pixel bits for cv2 drawing
_ONE = 1 << _SHIFT
_FOLIAGE, _TRUNK, _POLE, _WALL, _CAR = 1, 2, 3, 4, 5
_MIN_Z = 1.0  # near clipping depth (metres); far below the bottom row
_MAX_TURN_COS = 0.5  # the road is drawn until it has turned 60 degrees from the view axis
_EDGE_COLOURS: dict[str, dict[str, tuple[float, float, float]]] = {
    "curb": {"a": (0.80, 0.20, 0.20), "b": (0.93, 0.93, 0.92)},
    "gravel": {"a": (0.52, 0.48, 0.42)},
    "sidewalk": {"b": (0.62, 0.62, 0.60), "c": (0.46, 0.45, 0.44)},
}


@dataclass
class Frame:
    """Pixels and ground truth of one rendered frame."""

    image: _U8
    shadow_mask: NDArray[np.bool_]
    road_mask: NDArray[np.bool_]
    lane_lines: list[NDArray[np.float64]]
    horizon: float = float("nan")  # image row of the flat-ground horizon
    vanishing_point: tuple[float, float] = (float("nan"), float("nan"))  # of the road at the car


# ----------------------------------------------------------------------------- textures


def _noise_tile(seed: int, beta: float, size: int = 256, stretch: float = 1.0) -> FloatArray:
    """Periodic ``1/f**beta`` noise tile (zero mean, unit std), features ``stretch`` x larger."""
    rng = np.random.default_rng(seed)
    spec = np.fft.fft2(rng.standard_normal((size, size)))
    f = np.hypot(np.fft.fftfreq(size)[:, None], np.fft.fftfreq(size)[None, :]) * stretch
    f[0, 0] = 1.0
    spec = spec / f ** (beta / 2.0) * (f <= 0.5)
    spec[0, 0] = 0.0
    base = np.real(np.fft.ifft2(spec))
    return np.asarray(base / base.std())


def _mips(tile: FloatArray, levels: int = 7) -> tuple[_F32, ...]:
    """Mip map of a periodic ``(n, n, c)`` tile: level ``k`` is blurred by ``0.6 * 2**k``
    texels (periodically) and subsampled by ``2**k``."""
    n = tile.shape[0]
    f2 = (np.fft.fftfreq(n)[:, None] ** 2 + np.fft.fftfreq(n)[None, :] ** 2)[..., None]
    spec = np.fft.fft2(tile, axes=(0, 1))
    out = []
    for k in range(levels):
        sigma = 0.0 if k == 0 else 0.6 * 2.0**k
        lvl = np.real(np.fft.ifft2(spec * np.exp(-2 * (np.pi * sigma) ** 2 * f2), axes=(0, 1)))
        out.append(np.ascontiguousarray(lvl[:: 2**k, :: 2**k], dtype=np.float32))
    return tuple(out)


@lru_cache(maxsize=4)
def _ground_textures(kind: str) -> tuple[_F32, ...]:
    """Two-channel noise tiles with mip levels.

    ``"fine"`` (0.03 m texels): asphalt grain, terrain grain (features twice larger).
    ``"coarse"`` (0.6 m texels): blotches, terrain colour patches (features 4x larger).
    """
    if kind == "fine":
        tile = np.stack([_noise_tile(11, 0.9), _noise_tile(13, 1.2, stretch=2.0)], -1)
    else:
        tile = np.stack([_noise_tile(12, 2.0), _noise_tile(14, 2.4, stretch=4.0)], -1)
    return _mips(tile)


@lru_cache(maxsize=16)
def _screen_noise(seed: int, beta: float, width: int, height: int, scale: float) -> _F32:
    """Read-only noise in image space: ``scale`` texels per pixel of a 320-wide frame."""
    k = np.float32(scale * 320 / width)
    gx, gy = np.meshgrid(
        np.arange(width, dtype=np.float32) * k, np.arange(height, dtype=np.float32) * k
    )
    tile = _noise_tile(seed, beta).astype(np.float32)
    out = np.asarray(
        cv2.remap(tile, gx, gy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP), dtype=np.float32
    )
    out.setflags(write=False)
    return out


@lru_cache(maxsize=4)
def _sensor_grain(width: int, height: int) -> _F32:
    """Read-only unit Gaussian noise twice the frame size; frames use random crops."""
    out = np.random.default_rng(99).standard_normal((2 * height, 2 * width, 3), np.float32)
    out.setflags(write=False)
    return out


def _sample(levels: tuple[_F32, ...], u: _F32, v: _F32, lod: FloatArray) -> _F32:
    """Bilinear, per-row mip-mapped lookup of a periodic ``(n, n, c)`` tile at texel
    coordinates ``(u, v)``; returns planar ``(c, h, w)``.

    ``lod`` (one value per row) blends the two nearest levels; it is monotonic in the row
    (depth is), so each level is looked up on one band of rows only.
    """
    lod = np.clip(lod, 0.0, len(levels) - 1.001)
    lo = np.floor(lod).astype(int)
    frac = (lod - lo).astype(np.float32)
    channels = levels[0].shape[2] if levels[0].ndim == 3 else 1
    out = np.zeros((channels, *u.shape), np.float32)
    for k in range(len(levels)):
        w = np.where(lo == k, 1.0 - frac, 0.0) + np.where(lo == k - 1, frac, 0.0)
        rows = np.flatnonzero(w > 0)
        if rows.size == 0:
            continue
        a, b = int(rows[0]), int(rows[-1]) + 1
        scale = np.float32(levels[k].shape[0] / levels[0].shape[0])
        sampled = cv2.remap(
            levels[k], u[a:b] * scale, v[a:b] * scale, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP
        )
        wk = w[a:b, None].astype(np.float32)
        for c, plane in enumerate(cv2.split(sampled) if channels > 1 else [sampled]):
            out[c, a:b] += plane * wk
    return out


# ----------------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class _View:
    cam: Camera
    x0: float  # camera position (world)
    z0: float
    heading: float  # camera heading (world)
    z_vis: float  # farthest visible ground depth
    top: int  # first image row showing ground

    def to_camera(self, x: FloatArray, z: FloatArray) -> tuple[FloatArray, FloatArray]:
        dx, dz = x - self.x0, z - self.z0
        c, s = math.cos(self.heading), math.sin(self.heading)
        return dx * c - dz * s, dx * s + dz * c

    def project(
        self, x_cam: FloatArray, z_cam: FloatArray, above: float | FloatArray = 0.0
    ) -> FloatArray:
        return np.stack([self.cam.column(x_cam, z_cam), self.cam.row(z_cam, above)], axis=-1)


def _fixed(points: FloatArray, limit: float) -> NDArray[np.int32]:
    """Pixel coordinates to cv2's fixed point (``_SHIFT`` fractional bits), clamped."""
    return np.round(np.clip(points, -limit, limit) * _ONE).astype(np.int32)


def _fill(
    canvas: NDArray[np.generic],
    polys: Sequence[FloatArray] | FloatArray,
    value: float | tuple[float, ...],
    aa: bool = True,
) -> None:
    """Fill polygons (a list of ``(k, 2)`` arrays or one ``(n, k, 2)`` array) in pixels.

    One cv2 call fills them with the even-odd rule (an overlap becomes a hole): use this
    for polygons that do not overlap, :func:`_fill_each` for the others.
    """
    limit = 8.0 * max(canvas.shape[:2])
    if isinstance(polys, np.ndarray):
        fixed = list(_fixed(polys, limit)) if polys.size else []
    else:
        polys = [p for p in polys if len(p) >= 3]
        if not polys:
            return
        cuts = np.cumsum([len(p) for p in polys])[:-1]
        fixed = np.split(_fixed(np.concatenate(polys), limit), cuts)
    if fixed:
        cv2.fillPoly(canvas, fixed, value, cv2.LINE_AA if aa else cv2.LINE_8, _SHIFT)


def _fill_each(
    canvas: NDArray[np.generic],
    polys: Sequence[FloatArray],
    values: Sequence[float] | float,
    aa: bool = True,
) -> None:
    """Fill polygons one at a time, in order (later ones paint over earlier ones)."""
    limit = 8.0 * max(canvas.shape[:2])
    vals = [values] * len(polys) if isinstance(values, float | int) else values
    line = cv2.LINE_AA if aa else cv2.LINE_8
    for p, v in zip(polys, vals, strict=True):
        if len(p) >= 3:
            cv2.fillPoly(canvas, [_fixed(p, limit)], v, line, _SHIFT)


def _coverage(
    shape: tuple[int, int], polys: Sequence[FloatArray] | FloatArray, overlapping: bool = False
) -> _F32:
    canvas = np.zeros(shape, np.uint8)
    if overlapping:
        _fill_each(canvas, list(polys), 255)
    else:
        _fill(canvas, polys, 255)
    return canvas.astype(np.float32) * np.float32(1 / 255)


@dataclass(frozen=True)
class _Centreline:
    """The road centre ahead of the camera, in camera coordinates, at arc lengths ``s``."""

    s: FloatArray
    x: FloatArray  # centre (camera coordinates)
    z: FloatArray
    nx: FloatArray  # unit normal to the right (camera coordinates)
    nz: FloatArray

    @staticmethod
    def ahead(view: _View, take: Take, s: FloatArray) -> _Centreline:
        x, z, h = take.route.pose(s)
        xc, zc = view.to_camera(x, z)
        rel = h - view.heading
        return _Centreline(s, xc, zc, np.cos(rel), -np.sin(rel))


def _curve(view: _View, line: _Centreline, d: float) -> FloatArray:
    """Image points of the road curve at offset ``d``, up to where it leaves the visible
    ground (over a crest, beyond the view distance, or turned away from the view)."""
    xc, zc = line.x + d * line.nx, line.z + d * line.nz
    first = int(np.argmax(zc >= _MIN_Z))
    s, xc, zc = line.s[first:], xc[first:], zc[first:]
    if s.size < 2 or zc[0] < _MIN_Z:
        return np.zeros((0, 2))
    turned = np.diff(zc) < _MAX_TURN_COS * np.diff(s)
    bad = np.concatenate([[False], turned | (zc[1:] > view.z_vis)])
    n = int(np.argmax(bad)) if bad.any() else s.size
    px, pz = xc[:n], zc[:n]
    if n < s.size and zc[n] > view.z_vis >= zc[n - 1] and not turned[n - 1]:
        t = (view.z_vis - zc[n - 1]) / (zc[n] - zc[n - 1])
        px = np.append(px, xc[n - 1] + t * (xc[n] - xc[n - 1]))
        pz = np.append(pz, view.z_vis)
    return view.project(px, pz)


def _strip(view: _View, line: _Centreline, d_in: float, d_out: float) -> FloatArray:
    return np.concatenate([_curve(view, line, d_in), _curve(view, line, d_out)[::-1]])


def _quads(
    view: _View, take: Take, s_a: FloatArray, length: float, d_in: float, d_out: float
) -> FloatArray:
    """Image quads ``(n, 4, 2)`` of road-aligned patches ``[s_a, s_a + length] x [d_in, d_out]``."""
    s = np.stack([s_a, s_a + length, s_a + length, s_a], 1)
    d = np.array([d_in, d_in, d_out, d_out])[None, :]
    x, z = take.route.offset(s.ravel(), np.broadcast_to(d, s.shape).ravel())
    xc, zc = view.to_camera(x.reshape(s.shape), z.reshape(s.shape))
    ok = (zc.min(1) >= _MIN_Z) & (zc.max(1) <= view.z_vis)
    return view.project(xc[ok], zc[ok])


def _ground_polys(view: _View, polys: PolySet) -> list[tuple[int, FloatArray]]:
    """Project world ground polygons that may show in the frame.

    Vertices behind the near plane are dropped (edges are at most ~0.5 m, so the bridging
    edge stays below the frame) and those beyond the visible ground are clamped to its end.
    """
    if not len(polys):
        return []
    starts, sizes = polys.starts, polys.sizes
    xc, zc = view.to_camera(polys.points[:, 0], polys.points[:, 1])
    keep = zc >= _MIN_Z
    uv = view.project(xc, np.clip(zc, _MIN_Z, view.z_vis))
    kept = np.add.reduceat(keep.astype(int), starts)
    umin = np.minimum.reduceat(np.where(keep, uv[:, 0], np.inf), starts)
    umax = np.maximum.reduceat(np.where(keep, uv[:, 0], -np.inf), starts)
    zmin = np.minimum.reduceat(zc, starts)
    show = (kept >= 3) & (zmin <= view.z_vis) & (umax > -2) & (umin < view.cam.width + 1)
    pieces = np.split(uv, starts[1:])
    masks = np.split(keep, starts[1:])
    return [
        (int(i), pieces[i] if kept[i] == sizes[i] else pieces[i][masks[i]])
        for i in np.flatnonzero(show)
    ]


# ----------------------------------------------------------------------------- rendering


def _rgb(colour: tuple[float, ...] | NDArray[np.floating]) -> _F32:
    """A colour as a ``(3, 1, 1)`` array, to broadcast over planar ``(3, h, w)`` images."""
    return np.asarray(colour, np.float32).reshape(3, 1, 1)


def _blend(dst: _F32, colour: _F32, cov: _F32) -> None:
    """Planar ``dst += (colour - dst) * cov`` in place, on the rows where ``cov`` is not 0.

    ``dst`` is ``(3, h, w)``; ``colour`` is ``(3, 1, 1)``, ``(3, 1, w)`` or ``(3, h, w)``.
    """
    rows = np.flatnonzero(cov.any(axis=1))
    if rows.size == 0:
        return
    a, b = int(rows[0]), int(rows[-1]) + 1
    col = colour[:, a:b] if colour.shape[1] > 1 else colour
    d = dst[:, a:b]
    d += (col - d) * cov[a:b]


def _soft(canvas: _F32, sigma_rows: FloatArray, top: int) -> _F32:
    """Blur rows ``top:`` of ``canvas`` with a per-row Gaussian width (pixels): blends of
    blurs at widths 0.5, 1.5 and 4.5 pixels (x width/320 on wider frames), interpolated in
    log width."""
    scale = max(1.0, canvas.shape[1] / 320)
    levels = (0.5 * scale, 1.5 * scale, 4.5 * scale)
    blurred = [cv2.GaussianBlur(canvas, (0, 0), sg) for sg in levels]
    t = np.interp(
        np.log(np.clip(sigma_rows, levels[0], levels[-1])), np.log(levels), np.arange(len(levels))
    )
    out = np.zeros_like(canvas)
    for k, b in enumerate(blurred):
        w = np.clip(1.0 - np.abs(t - k), 0.0, 1.0).astype(np.float32)
        out[top:] += b[top:] * w[:, None]
    return out


@dataclass(frozen=True)
class _GroundRows:
    """Depth and texture samples of the ground rows ``top:`` of a frame."""

    zr: FloatArray  # depth (metres) of each ground row
    fine_road: _F32
    fine_terr: _F32
    mid_road: _F32
    macro: _F32


def render(
    take: Take, state: FrameState, width: int, height: int, rng: np.random.Generator, hood: bool
) -> Frame:
    """Render the frame seen from ``state`` in ``take`` at ``width`` x ``height`` pixels."""
    view, yaw, zr = _frame_view(take, state, width, height)
    rows = _ground_rows(take, view, zr)
    ground = _terrain(take, rows)  # planar (3, h, w) until the objects are drawn
    centre = _Centreline.ahead(view, take, _road_ahead(take, state))
    road_cov = _paint_road(ground, take, view, centre, rows)
    s_hi = min(state.s + SCENERY_DISTANCE, take.route.s_end - 1.0)
    _paint_edges(ground, take, state, view, s_hi, rows.fine_terr)
    _paint_decals(ground, take, view, centre, rows)
    lines = _paint_markings(ground, take, state, view, centre, s_hi, rows.fine_road)
    # wet reflections first: shadows then darken them too (a wet road shows weak shadows)
    _paint_wet(ground, take, view, road_cov, rows)
    sh_alpha = _paint_shadows(ground, take, view, rows.zr)
    img = _with_sky(ground, take, view, rows.zr)
    labels = _draw_casters(img, take, state, view)
    image, hood_cov = _camera_effects(img, take, rng, hood)
    return _ground_truth(image, take, view, yaw, labels, hood_cov, sh_alpha, road_cov, lines)


def _frame_view(
    take: Take, state: FrameState, width: int, height: int
) -> tuple[_View, float, FloatArray]:
    """The camera view of ``state``, the camera's yaw from the road heading and the depth
    of each ground row."""
    style = take.style
    route = take.route
    cam = Camera(
        width,
        height,
        height * (take.horizon + state.pitch),
        state.hill,
        state.hill_distance,
        style.focal,
    )
    cx_w, cz_w = route.offset(np.array([state.s]), state.lateral + take.lane_offset)
    _, _, h_road = route.pose(np.array([state.s]))
    z_vis, v_top, rows_tab, z_tab = cam.visible_ground()
    top = min(max(math.ceil(v_top), 0), height)
    yaw = state.heading + take.yaw
    view = _View(cam, float(cx_w[0]), float(cz_w[0]), float(h_road[0]) + yaw, z_vis, top)
    zr = np.interp(np.arange(top, height, dtype=np.float64), rows_tab, z_tab)
    return view, yaw, zr


def _ground_rows(take: Take, view: _View, zr: FloatArray) -> _GroundRows:
    """World coordinates and textures of the ground rows at depths ``zr``."""
    cam = view.cam
    ox, oz = take.texture_offset
    c, s = math.cos(view.heading), math.sin(view.heading)
    k = (np.arange(cam.width, dtype=np.float32) - np.float32(cam.cx))[None, :] * (
        zr / cam.fx
    ).astype(np.float32)[:, None]
    zcol = zr.astype(np.float32)[:, None]
    footprint = np.sqrt(zr / cam.fx * zr**2 / (cam.fy * CAMERA_HEIGHT))

    def tex(kind: str, scale: float) -> _F32:
        q = np.float32(1.0 / scale)
        u = (k * np.float32(c) + zcol * np.float32(s) + np.float32(view.x0 + ox)) * q
        v = (zcol * np.float32(c) - k * np.float32(s) + np.float32(view.z0 + oz)) * q
        return _sample(_ground_textures(kind), u, v, np.log2(np.maximum(footprint / scale, 1.0)))

    fine_road, fine_terr = tex("fine", 0.03)
    mid_road, macro = tex("coarse", 0.6)
    return _GroundRows(zr, fine_road, fine_terr, mid_road, macro)


def _terrain(take: Take, rows: _GroundRows) -> _F32:
    """The bare terrain colour of the ground rows, planar ``(3, h - top, w)``."""
    style = take.style
    tint = take.tint.astype(np.float32)
    ta, tb = (np.asarray(col, np.float32) * tint for col in style.terrain)
    t_mix = np.clip(0.5 + 0.6 * rows.macro + 0.25 * rows.mid_road, 0.0, 1.0)
    ground = _rgb(ta) + _rgb(tb - ta) * t_mix
    ground *= 1.0 + style.terrain_grain * rows.fine_terr
    return ground


def _road_ahead(take: Take, state: FrameState) -> FloatArray:
    """Arc lengths at which the road centre ahead of the car is sampled."""
    s_near = state.s + np.geomspace(1.0, VIEW_DISTANCE, 480)
    return s_near[s_near <= take.route.s_end]


def _paint_road(
    ground: _F32, take: Take, view: _View, centre: _Centreline, rows: _GroundRows
) -> _F32:
    """Paint the asphalt onto ``ground``; return the road's coverage of the whole frame."""
    style = take.style
    half = take.route.width / 2.0
    road_cov = _coverage(_frame_shape(view), [_strip(view, centre, -half, half)])
    asphalt = np.asarray(style.asphalt, np.float32) * take.tint.astype(np.float32)
    grain = 1.0 + style.asphalt_grain * rows.fine_road + 0.07 * rows.mid_road
    _blend(ground, _rgb(asphalt) * grain, road_cov[view.top :])
    return road_cov


def _frame_shape(view: _View) -> tuple[int, int]:
    return (view.cam.height, view.cam.width)


def _paint_edges(
    ground: _F32, take: Take, state: FrameState, view: _View, s_hi: float, fine_terr: _F32
) -> None:
    """Paint the road's edge strips (curbs, gravel or sidewalks) where the take has them."""
    style = take.style
    route = take.route
    half = route.width / 2.0
    edge_polys: dict[str, list[FloatArray]] = {"a": [], "b": [], "c": []}
    seg = np.arange(math.floor(state.s), s_hi, 1.0)
    idx = np.clip(((seg - route.s0) / ROUTE_STEP).astype(int), 0, route.curvature.size - 1)
    for side, present in ((-1.0, take.edges[0]), (1.0, take.edges[1])):
        on = seg[present[idx]]
        if on.size == 0:
            continue
        if style.edge_kind == "curb":
            d0, d1 = side * half, side * (half + 0.7)
            red = np.mod(np.floor(on), 2) == 0
            edge_polys["a"].append(_quads(view, take, on[red], 1.0, d0, d1))
            edge_polys["b"].append(_quads(view, take, on[~red], 1.0, d0, d1))
        elif style.edge_kind == "gravel":
            edge_polys["a"].append(_quads(view, take, on, 1.0, side * half, side * (half + 1.3)))
        else:  # sidewalk: raised curb, then paving
            edge_polys["b"].append(_quads(view, take, on, 1.0, side * half, side * (half + 0.25)))
            edge_polys["c"].append(
                _quads(view, take, on, 1.0, side * (half + 0.25), side * (half + 3.2))
            )
    grit = 1.0 + 0.12 * fine_terr
    for key, colour in _EDGE_COLOURS[style.edge_kind].items():
        if edge_polys[key]:
            cov = _coverage(_frame_shape(view), np.concatenate(edge_polys[key]))[view.top :]
            _blend(ground, _rgb(colour) * grit, cov)


def _paint_decals(
    ground: _F32, take: Take, view: _View, centre: _Centreline, rows: _GroundRows
) -> None:
    """Paint tyre tracks (track2), bushes and tar patches onto ``ground``."""
    sc = take.scenery
    shape, top = _frame_shape(view), view.top
    if take.style.name == "track2":  # darker tyre tracks along the road
        streak = _coverage(
            shape, [_strip(view, centre, d - 0.3, d + 0.3) for d in (-0.85, 0.85)], True
        )
        streak = cv2.GaussianBlur(streak, (0, 0), max(0.6, view.cam.width / 320))[top:]
        ground *= 1.0 - 0.16 * streak * np.clip(0.8 + 0.4 * rows.mid_road, 0.4, 1.2)
    if len(sc.bushes):
        bush = _coverage(shape, [p for _, p in _ground_polys(view, sc.bushes)], True)[top:]
        _blend(ground, _rgb((0.10, 0.14, 0.07)) * (1.0 + 0.35 * rows.fine_terr), bush)
    if len(sc.tar):
        tar = _coverage(shape, [p for _, p in _ground_polys(view, sc.tar)], True)[top:]
        _blend(ground, ground * _rgb((0.48, 0.48, 0.50)), tar * 0.9)


def _paint_markings(
    ground: _F32,
    take: Take,
    state: FrameState,
    view: _View,
    centre: _Centreline,
    s_hi: float,
    fine_road: _F32,
) -> list[FloatArray]:
    """Paint the lane markings; return the image points of the car lane's two borders."""
    shape, top = _frame_shape(view), view.top
    half = take.route.width / 2.0
    line_d = half - take.line_inset - take.line_width / 2
    lw2 = take.line_width / 2
    wear = np.clip(0.85 + 0.15 * fine_road, 0.6, 1.0)
    if take.style.layout == "two-lane":
        # double yellow centre line, white edge lines at the lanes' outer borders; the car's
        # lane is the right one: its borders are the centre line and the right edge line
        lines = [_curve(view, centre, 0.0), _curve(view, centre, take.lane_width)]
        pair = lw2 + 0.05
        yellow = [_strip(view, centre, d - lw2, d + lw2) for d in (-pair, pair)]
        white = [
            _strip(view, centre, d - lw2, d + lw2) for d in (-take.lane_width, take.lane_width)
        ]
        _blend(ground, _rgb(WHITE_LINE), _coverage(shape, white, True)[top:] * wear)
        _blend(ground, _rgb(take.line_colour), _coverage(shape, yellow, True)[top:] * wear)
        return lines
    marks: list[FloatArray] = [_strip(view, centre, d - lw2, d + lw2) for d in (-line_d, line_d)]
    if take.centre_dash:
        dash = np.arange(math.floor(state.s / 9.0) * 9.0, s_hi, 9.0)
        marks += list(_quads(view, take, dash, 3.0, -lw2, lw2))
    mark = _coverage(shape, marks, True)[top:] * wear
    _blend(ground, _rgb(take.line_colour), mark)
    return [_curve(view, centre, -line_d), _curve(view, centre, line_d)]


def _paint_wet(ground: _F32, take: Take, view: _View, road_cov: _F32, rows: _GroundRows) -> None:
    """Paint the sky's reflection on a wet road and its puddles (rain preset)."""
    style = take.style
    if style.wet <= 0:
        return
    sc, top = take.scenery, view.top
    refl = style.wet * road_cov[top:] * np.clip(0.85 + 0.3 * rows.mid_road, 0.6, 1.1)
    if len(sc.puddles):
        puddles = [p for _, p in _ground_polys(view, sc.puddles)]
        puddle = _coverage(_frame_shape(view), puddles, True)[top:]
        refl = np.maximum(refl, 0.42 * puddle * np.clip(0.9 + 0.5 * rows.fine_road, 0.6, 1.1))
    horizon = np.asarray(style.sky_horizon, np.float32)
    refl_col = _rgb(horizon) * np.clip(0.85 + 0.6 * rows.mid_road, 0.6, 1.1)
    _blend(ground, refl_col, refl)


def _paint_shadows(ground: _F32, take: Take, view: _View, zr: FloatArray) -> _F32:
    """Darken ``ground`` under cast shadows; return their blurred coverage of the frame.

    Where shadows overlap the darkest wins; edges are blurred (penumbra).
    """
    sc, style, top = take.scenery, take.style, view.top
    shape = _frame_shape(view)
    sh_alpha = np.zeros(shape, np.float32)
    if not (take.sun_out and len(sc.shadows)):
        return sh_alpha
    projected = sorted(_ground_polys(view, sc.shadows), key=lambda ip: sc.shadows.values[ip[0]])
    if not projected:
        return sh_alpha
    dark = np.zeros(shape, np.uint8)  # darkness of the covering shadow, 0 = lit
    _fill_each(
        dark,
        [pts for _, pts in projected],
        [max(1, round(255 * sc.shadows.values[i])) for i, _ in projected],
        aa=False,
    )
    # penumbra: a fixed width on the ground, so wider in pixels near the camera
    sigma_rows = style.penumbra * view.cam.fx / zr
    sh_alpha = _soft((dark > 0).astype(np.float32), sigma_rows, top)
    sh_dark = _soft(dark.astype(np.float32) * np.float32(1 / 255), sigma_rows, top)[top:]
    ground *= 1.0 - sh_dark * _rgb(style.shadow_tint)
    return sh_alpha


def _with_sky(ground: _F32, take: Take, view: _View, zr: FloatArray) -> _F32:
    """Haze the ground, add the sky above it; the frame as ``(h, w, 3)`` for cv2 drawing."""
    cam, top = view.cam, view.top
    horizon = np.asarray(take.style.sky_horizon, np.float32)
    haze = (1.0 - np.exp(-zr / take.style.haze_distance)).astype(np.float32)
    ground += (_rgb(horizon) - ground) * haze[:, None]
    planes = np.empty((3, cam.height, cam.width), np.float32)
    planes[:, :top] = _sky(take, cam, view, cam.width, cam.height, top)
    planes[:, top:] = ground
    return np.asarray(cv2.merge(list(planes)), np.float32)


def _draw_casters(img: _F32, take: Take, state: FrameState, view: _View) -> _U8:
    """Draw the roadside objects and cars, far to near; return their label image."""
    width, height = view.cam.width, view.cam.height
    labels = np.zeros((height, width), np.uint8)
    _draw_objects(img, labels, take, view)
    if take.cars:
        _draw_cars(img, labels, take, view, state.s / (take.style.speed_mph * 0.44704))
    foliage = labels == _FOLIAGE
    if foliage.any():
        n = _screen_noise(16, 1.6, width, height, 1.0)
        img[foliage] *= (1.0 + 0.22 * np.clip(n[foliage], -2.0, 2.0))[:, None]
    return labels


def _camera_effects(
    img: _F32, take: Take, rng: np.random.Generator, hood: bool
) -> tuple[_U8, _F32]:
    """Car hood, weather and sensor; the 8-bit frame and the hood's coverage."""
    height, width = img.shape[:2]
    style = take.style
    hood_cov = np.zeros((height, width), np.float32)
    if hood:
        hood_cov, hood_keep, hood_add = _hood(width, height)
        img *= hood_keep
        img += hood_add
    if style.rain:
        img = _rain(img, rng, width, height)
    soft = 0.5 * min(1.0, width / 320)  # slight lens softness; hides polygon stair-steps
    if soft >= 0.25:
        img = cv2.GaussianBlur(img, (0, 0), soft)
    grain = _sensor_grain(width, height)
    oy, ox_ = int(rng.integers(0, height)), int(rng.integers(0, width))
    img += np.float32(0.01 if style.rain else 0.006) * grain[oy : oy + height, ox_ : ox_ + width]
    return np.clip(img * 255 + 0.5, 0, 255).astype(np.uint8), hood_cov


def _ground_truth(
    image: _U8,
    take: Take,
    view: _View,
    yaw: float,
    labels: _U8,
    hood_cov: _F32,
    sh_alpha: _F32,
    road_cov: _F32,
    lines: list[FloatArray],
) -> Frame:
    """The frame with its shadow and road masks and visible lane lines."""
    cam, top = view.cam, view.top
    width, height = cam.width, cam.height
    visible = np.zeros((height, width), bool)
    visible[top:] = True
    visible &= (labels == 0) & (hood_cov < 0.5)
    shadow_mask = (sh_alpha >= 0.5) & visible
    road_mask = (road_cov >= 0.5) & visible
    hidden = hood_cov
    if take.style.layout == "two-lane":  # markings behind cars and trees are not visible
        hidden = np.maximum(hood_cov, (labels > 0).astype(np.float32))
    lane_lines = [_visible(p, width, height, top, hidden) for p in lines]
    vp = (cam.cx + cam.fx * math.tan(-yaw), cam.horizon)
    return Frame(image, shadow_mask, road_mask, lane_lines, cam.horizon, vp)


def _visible(
    points: FloatArray, width: int, height: int, top: int, hood_cov: _F32
) -> NDArray[np.float64]:
    """Points of a projected marking inside the frame, on visible ground, not under the hood."""
    if points.size == 0:
        return np.zeros((0, 2))
    u, v = points[:, 0], points[:, 1]
    ok = (u >= 0) & (u <= width - 1) & (v >= top) & (v <= height - 1)
    ui = np.clip(np.round(u).astype(int), 0, width - 1)
    vi = np.clip(np.round(v).astype(int), 0, height - 1)
    ok &= hood_cov[vi, ui] < 0.5
    pts = points[ok]
    if len(pts) > 1:  # thin out far points that crowd onto the same pixel
        along = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        keep = np.concatenate([[True], np.diff(np.floor(along / 0.5)) > 0])
        keep[-1] = True
        pts = pts[keep]
    return np.asarray(pts, dtype=np.float64)


def _sky(take: Take, cam: Camera, view: _View, width: int, full_height: int, height: int) -> _F32:
    """Rows ``[0, height)``: sky gradient, distant skyline and tree line (they pan with the
    heading)."""
    style = take.style
    top_c = np.asarray(style.sky_top, np.float32)
    hor_c = np.asarray(style.sky_horizon, np.float32)
    y = np.arange(height, dtype=np.float32)
    t = np.clip(y / max(cam.horizon, 1.0), 0.0, 1.0) ** 0.7
    column = (top_c[:, None] + (hor_c - top_c)[:, None] * t[None, :])[:, :, None]
    img = np.ascontiguousarray(np.broadcast_to(column, (3, height, width)))
    if style.rain:  # overcast: soft cloud banks
        img *= 1.0 + 0.07 * _screen_noise(17, 2.6, width, full_height, 0.6)[:height]
    if height == 0:
        return img
    az = view.heading + np.arctan((np.arange(width) - cam.cx) / cam.fx)
    idx = (np.mod(az / (2 * np.pi), 1.0) * take.skyline.size).astype(int)
    ridge = take.skyline[idx]
    if style.background == "city":  # blocks of buildings
        ridge = take.skyline[(idx // 48) * 48] * 1.6
    ridge_row = cam.horizon - cam.fy * np.tan(ridge)
    tree_row = cam.horizon - cam.fy * np.tan(
        take.treeline[idx] * (1.5 if style.background == "lake" else 1.0)
    )
    rows = np.arange(height, dtype=np.float32)[:, None]
    speck = _screen_noise(18, 1.0, width, full_height, 1.0)[:height]
    ridge_col, tree_col = {
        "lake": ((0.50, 0.60, 0.58), (0.22, 0.32, 0.17)),
        "mountain": ((0.34, 0.32, 0.32), (0.45, 0.32, 0.15)),
        "city": ((0.48, 0.49, 0.52), (0.40, 0.42, 0.42)),
    }[style.background]
    fade = 0.45 if style.rain else 0.3
    ridge_shade = _rgb(ridge_col) * (1.0 + 0.12 * speck)
    _blend(
        img,
        ridge_shade + (_rgb(hor_c) - ridge_shade) * fade,
        (rows >= ridge_row[None, :]).astype(np.float32),
    )
    tree_shade = _rgb(tree_col) * (1.0 + 0.3 * speck)
    _blend(
        img,
        tree_shade + (_rgb(hor_c) - tree_shade) * (0.5 if style.rain else 0.15),
        ((rows >= tree_row[None, :]) & (rows < cam.horizon + 1.0)).astype(np.float32),
    )
    # below the horizon but above the visible ground (beyond a crest): distant land
    land = np.mean(np.asarray(style.terrain, np.float32), axis=0) * take.tint.astype(np.float32)
    land = land + (hor_c - land) * np.float32(0.45 if style.rain else 0.3)
    _blend(
        img,
        _rgb(land) * (1.0 + 0.1 * speck),
        np.broadcast_to(rows >= cam.horizon + 1.0, (height, width)).astype(np.float32),
    )
    return img


# ----------------------------------------------------------------------------- roadside objects


def _hazed(colours: FloatArray, z: FloatArray, take: Take) -> FloatArray:
    """Colours ``(n, 3)`` seen at depths ``z`` through the preset's haze."""
    h = (1.0 - np.exp(-np.asarray(z) / take.style.haze_distance))[:, None]
    return np.asarray(colours + (np.asarray(take.style.sky_horizon) - colours) * h)


# (depth, order, kind, polygons or a segment (fixed point), colour, label, thickness)
_Job = tuple[float, int, str, list[NDArray[np.int32]], tuple[float, ...], int, int]


def _draw_objects(img: _F32, labels: _U8, take: Take, view: _View) -> None:
    """Draw trees, poles and buildings standing on the ground, farthest first.

    Shapes are prepared for all visible objects at once; the loop only fills polygons.
    """
    cam = view.cam
    far = min(SCENERY_DISTANCE, view.z_vis + 1.0)
    limit = 8.0 * max(cam.width, cam.height)
    jobs = _tree_jobs(take, view, far, limit)
    jobs += _pole_jobs(take, view, far, limit)
    jobs += _building_jobs(take, view, limit)
    jobs.sort(key=lambda j: (-j[0], j[1]))
    for _, _, kind, shape_px, paint, label, thick in jobs:
        if kind == "poly":
            cv2.fillPoly(img, shape_px, paint, cv2.LINE_8, _SHIFT)
            cv2.fillPoly(labels, shape_px, label, cv2.LINE_8, _SHIFT)
        else:
            seg = shape_px[0]
            a_, b_ = (int(seg[0, 0]), int(seg[0, 1])), (int(seg[1, 0]), int(seg[1, 1]))
            cv2.line(img, a_, b_, paint, thick, cv2.LINE_8, _SHIFT)
            cv2.line(labels, a_, b_, label, thick, cv2.LINE_8, _SHIFT)


def _in_view(
    view: _View, xc: FloatArray, zc: FloatArray, far: float, margin: float | FloatArray
) -> NDArray[np.intp]:
    """Indices of the objects at camera ``(xc, zc)`` between the near plane and ``far``
    that may reach into the frame (``margin``: how far, in metres, an object reaches
    sideways from its centre)."""
    cam = view.cam
    zs = np.maximum(zc, _MIN_Z)
    ok = (zc > _MIN_Z) & (zc < far) & (np.abs(xc) - margin < (cam.cx + 2) * zs / cam.fx)
    return np.flatnonzero(ok)


def _standing_in_view(
    view: _View,
    objects: dict[str, FloatArray],
    far: float,
    reach: Callable[[dict[str, FloatArray]], float | FloatArray],
) -> tuple[NDArray[np.intp], FloatArray, FloatArray]:
    """Indices of the scenery ``objects`` (columns ``x``, ``z``; maybe none) that
    :func:`_in_view` keeps, reaching ``reach(objects)`` metres sideways, and their camera
    x and depth."""
    if not (objects and objects["x"].size):
        return np.zeros(0, np.intp), np.zeros(0), np.zeros(0)
    xc, zc = view.to_camera(objects["x"], objects["z"])
    i = _in_view(view, xc, zc, far, reach(objects))
    return i, xc[i], zc[i]


def _tree_jobs(take: Take, view: _View, far: float, limit: float) -> list[_Job]:
    """Trunk and canopy polygons of the trees in view nearer than ``far``."""
    t = take.scenery.trees
    cam = view.cam
    i, x, z = _standing_in_view(view, t, far, lambda trees: 1.7 * trees["radius"])
    if not i.size:
        return []
    r = t["radius"]
    w2 = t["trunk_w"][i] / 2
    ub_l, ub_r = cam.column(x - w2, z), cam.column(x + w2, z)
    vb, vt = cam.row(z), cam.row(z, t["trunk_top"][i])
    trunk = np.stack(
        [
            np.stack([ub_l, vb], 1),
            np.stack([ub_r, vb], 1),
            np.stack([ub_r, vt], 1),
            np.stack([ub_l, vt], 1),
        ],
        1,
    )
    outline = take.scenery.tree_outlines[i]
    uc, vc = cam.column(x, z), cam.row(z, t["crown"][i])
    sx, sy = cam.fx * r[i] / z, cam.fy * r[i] / z
    canopy = np.stack(
        [
            uc[:, None] + sx[:, None] * outline[..., 0],
            vc[:, None] - sy[:, None] * outline[..., 1],
        ],
        -1,
    )
    trunk_col = _hazed(np.tile([0.30, 0.22, 0.14], (i.size, 1)), z, take)
    palette = np.asarray(take.style.foliage)[t["colour"][i].astype(int)] * take.tint
    leaf_col = _hazed(palette, z, take)
    tf, cf = _fixed(trunk, limit), _fixed(canopy, limit)
    jobs: list[_Job] = []
    for j in range(i.size):
        jobs.append((float(z[j]), 0, "poly", [tf[j]], tuple(trunk_col[j]), _TRUNK, 0))
        jobs.append((float(z[j]), 1, "poly", [cf[j]], tuple(leaf_col[j]), _FOLIAGE, 0))
    return jobs


def _pole_jobs(take: Take, view: _View, far: float, limit: float) -> list[_Job]:
    """Pole and arm segments of the poles in view nearer than ``far``."""
    p = take.scenery.poles
    cam = view.cam
    i, x, z = _standing_in_view(view, p, far, lambda _: 3.0)
    if not i.size:
        return []
    hgt = p["height"][i]
    base = view.project(x, z)
    top = view.project(x, z, hgt)
    a = p["arm_dir"][i]
    tx, tz = view.to_camera(
        p["x"][i] + p["arm"][i] * np.sin(a), p["z"][i] + p["arm"][i] * np.cos(a)
    )
    tip = view.project(tx, np.maximum(tz, _MIN_Z), hgt)
    widths = np.maximum(1, np.round(cam.fx * p["width"][i] / z)).astype(int)
    col = _hazed(np.tile([0.38, 0.38, 0.40], (i.size, 1)), z, take)
    pole_seg = _fixed(np.stack([base, top], 1), limit)
    arm_seg = _fixed(np.stack([top, tip], 1), limit)
    jobs: list[_Job] = []
    for j in range(i.size):
        jobs.append((float(z[j]), 0, "line", [pole_seg[j]], tuple(col[j]), _POLE, int(widths[j])))
        if p["arm"][i[j]] > 0 and tz[j] > _MIN_Z:
            arm_width = max(1, int(widths[j]) - 1)
            jobs.append((float(z[j]), 1, "line", [arm_seg[j]], tuple(col[j]), _POLE, arm_width))
    return jobs


def _building_jobs(take: Take, view: _View, limit: float) -> list[_Job]:
    """Face polygons of the buildings in view, in drawing order per building."""
    jobs: list[_Job] = []
    for b, (corners, height_b, colour) in enumerate(take.scenery.buildings):
        _, zc = view.to_camera(corners[:, 0], corners[:, 1])
        if zc.max() > _MIN_Z and zc.min() < min(SCENERY_DISTANCE * 1.5, view.z_vis + 5.0):
            depth = float(np.mean(zc))
            faces = _building_faces(take, view, corners, height_b, colour)
            for order, (face, face_col) in enumerate(faces):
                fixed = np.split(
                    _fixed(np.concatenate(face), limit), np.cumsum([len(f) for f in face])[:-1]
                )
                jobs.append((depth + 1e-6 * b, order, "poly", fixed, face_col, _WALL, 0))
    return jobs


def _draw_cars(img: _F32, labels: _U8, take: Take, view: _View, t: float) -> None:
    """Draw the take's cars where they are at time ``t`` (seconds), farthest first.

    A car is three boxes: a dark underbody (wheels) up to 0.25 m, the body in its colour up
    to 60 % of its height, and a cabin of dark glass, shorter, above it.
    """
    cars = take.cars
    route = take.route
    s_now = cars["s"] + cars["speed"] * t
    ok = (s_now > route.s0 + 3.0) & (s_now < route.s_end - 3.0)
    idx = np.flatnonzero(ok)
    if idx.size == 0:
        return
    x, z = route.offset(s_now[idx], cars["d"][idx])
    _, _, heading = route.pose(s_now[idx])
    xc, zc = view.to_camera(x, z)
    far = min(SCENERY_DISTANCE, view.z_vis + 5.0)
    visible = (zc > 3.0) & (zc < far) & (np.abs(xc) < (view.cam.cx + 40) * zc / view.cam.fx)
    limit = 8.0 * max(view.cam.width, view.cam.height)
    order = np.argsort(-zc[visible])
    for j in np.flatnonzero(visible)[order]:
        i = idx[j]
        fwd = np.array([math.sin(heading[j]), math.cos(heading[j])])
        right = np.array([math.cos(heading[j]), -math.sin(heading[j])])
        centre = np.array([x[j], z[j]])
        length, width, height = (float(cars[k][i]) for k in ("length", "width", "height"))
        colour = np.asarray(CAR_COLOURS[int(cars["colour"][i])]) * take.tint
        glass = np.array([0.10, 0.12, 0.15])
        boxes = (
            (length * 0.96, width * 0.92, 0.0, 0.25, np.array([0.05, 0.05, 0.05]), 0.0),
            (length, width, 0.25, 0.6 * height, colour, 0.0),
            (length * 0.55, width * 0.86, 0.6 * height, height, glass, -0.08 * length),
        )
        for box_l, box_w, z0, z1, paint, shift in boxes:
            c = centre + shift * fwd
            corners = np.array(
                [c + a * fwd * box_l / 2 + b * right * box_w / 2 for a, b in _BOX_CORNERS]
            )
            for face, face_colour in _box_faces(take, view, corners, z0, z1, paint, zc[j]):
                fixed = [_fixed(face, limit)]
                cv2.fillPoly(img, fixed, face_colour, cv2.LINE_8, _SHIFT)
                cv2.fillPoly(labels, fixed, _CAR, cv2.LINE_8, _SHIFT)


_BOX_CORNERS = ((-1, -1), (1, -1), (1, 1), (-1, 1))


def _visible_walls(
    take: Take, view: _View, corners: FloatArray
) -> Iterator[tuple[FloatArray, FloatArray, FloatArray, bool]]:
    """``(a, b, mid, lit)`` for each wall of a box (ground ``corners`` in order) that faces
    the camera: its two ends, its middle and whether the sun shines on it."""
    centre = corners.mean(0)
    cam_pos = np.array([view.x0, view.z0])
    sun = -np.array([math.sin(take.shadow_direction), math.cos(take.shadow_direction)])
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        mid = (a + b) / 2
        normal = mid - centre
        if np.dot(normal, cam_pos - mid) <= 0:
            continue  # facing away from the camera
        yield a, b, mid, bool(take.sun_out and float(np.dot(normal, sun)) > 0)


def _box_faces(
    take: Take,
    view: _View,
    corners: FloatArray,
    z0: float,
    z1: float,
    colour: FloatArray,
    depth: float,
) -> list[tuple[FloatArray, tuple[float, ...]]]:
    """Image polygons and colours of a box's walls facing the camera, then its top."""
    out: list[tuple[FloatArray, tuple[float, ...]]] = []
    for a, b, _, lit in _visible_walls(take, view, corners):
        shade = 1.0 if lit else 0.7
        pts = _project_3d(view, np.array([[*a, z0], [*b, z0], [*b, z1], [*a, z1]]))
        if pts is not None:
            paint = _hazed((colour * shade)[None], np.array([depth]), take)[0]
            out.append((pts, tuple(float(v) for v in paint)))
    if z1 < CAMERA_HEIGHT:
        top = _project_3d(view, np.column_stack([corners, np.full(4, z1)]))
        if top is not None:
            paint = _hazed((colour * 1.1)[None], np.array([depth]), take)[0]
            out.append((top, tuple(float(v) for v in np.clip(paint, 0, 1))))
    return out


def _building_faces(
    take: Take,
    view: _View,
    corners: FloatArray,
    height_b: float,
    colour: tuple[float, float, float],
) -> list[tuple[list[FloatArray], tuple[float, ...]]]:
    """Visible walls of a box building, then their windows: image polygons and a colour."""
    out: list[tuple[list[FloatArray], tuple[float, ...]]] = []
    for a, b, mid, lit in _visible_walls(take, view, corners):
        factor = 1.0 if lit else (0.45 if take.sun_out else 0.8)
        z_mid = max(float(view.to_camera(mid[:1], mid[1:])[1][0]), _MIN_Z)
        wall_col = _hazed((np.asarray(colour) * take.tint * factor)[None], np.array([z_mid]), take)
        wall = np.array([[*a, 0.0], [*b, 0.0], [*b, height_b], [*a, height_b]])
        pts = _project_3d(view, wall)
        if pts is None:
            continue
        out.append(([pts], tuple(wall_col[0])))
        length = float(np.linalg.norm(b - a))
        if view.cam.fx * 1.0 / z_mid < 2.5:
            continue  # windows would be under ~2 pixels
        ncol, nrow = max(int(length / 3.2), 1), max(int(height_b / 3.2), 1)
        ca, cr = np.meshgrid(np.arange(ncol), np.arange(nrow))
        a0, a1 = (ca.ravel() + 0.25) / ncol, (ca.ravel() + 0.75) / ncol
        h0, h1 = cr.ravel() * 3.2 + 1.0, cr.ravel() * 3.2 + 2.4
        p0 = a[None] + (b - a)[None] * a0[:, None]
        p1 = a[None] + (b - a)[None] * a1[:, None]
        xs = np.stack([p0[:, 0], p1[:, 0], p1[:, 0], p0[:, 0]], 1)
        zs = np.stack([p0[:, 1], p1[:, 1], p1[:, 1], p0[:, 1]], 1)
        hs = np.stack([h0, h0, h1, h1], 1)
        xc, zc = view.to_camera(xs, zs)
        ok = zc.min(1) >= _MIN_Z
        glass = np.asarray((0.16, 0.19, 0.24) if lit else (0.10, 0.12, 0.15))
        glass_col = tuple(_hazed(glass[None], np.array([z_mid]), take)[0])
        if ok.any():
            out.append((list(view.project(xc[ok], zc[ok], hs[ok])), glass_col))
    return out


def _project_3d(view: _View, pts: FloatArray) -> FloatArray | None:
    """Project a world polygon with heights, clipped to the near plane (Sutherland-Hodgman)."""
    xc, zc = view.to_camera(pts[:, 0], pts[:, 1])
    poly = list(zip(xc, zc, pts[:, 2], strict=True))
    out = []
    for j in range(len(poly)):
        p, q = poly[j], poly[(j + 1) % len(poly)]
        p_in, q_in = p[1] >= _MIN_Z, q[1] >= _MIN_Z
        if p_in:
            out.append(p)
        if p_in != q_in:
            t = (_MIN_Z - p[1]) / (q[1] - p[1])
            out.append(tuple(pi + t * (qi - pi) for pi, qi in zip(p, q, strict=True)))
    if len(out) < 3:
        return None
    arr = np.asarray(out, dtype=np.float64)
    return view.project(arr[:, 0], arr[:, 1], arr[:, 2])


# ----------------------------------------------------------------------------- camera effects


def hood_coverage(width: int, height: int) -> _F32:
    """Coverage (0 to 1, read-only) of the car bonnet drawn with ``hood=True`` at this size."""
    return _hood(width, height)[0]


@lru_cache(maxsize=8)
def _hood(width: int, height: int) -> tuple[_F32, _F32, _F32]:
    """Read-only car bonnet at the bottom (Udacity frames): its coverage, and the factor and
    the term that paint it over an ``(h, w, 3)`` image (``img * keep + add``)."""
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    a, b = 0.62 * width, 0.26 * height
    cy = 1.11 * height
    q = np.sqrt(((x - (width - 1) / 2) / a) ** 2 + ((y - cy) / b) ** 2)
    cov = np.clip((1.0 - q) * b + 0.5, 0.0, 1.0).astype(np.float32)
    depth = np.clip((y - (cy - b)) / (0.12 * height), 0.0, 1.0)
    shade = 0.78 - 0.22 * depth + 0.08 * np.exp(-(((1.0 - q) * b - 1.5) ** 2) / 2.0)
    colour = (shade[..., None] * np.array([1.0, 0.98, 0.93])).astype(np.float32)
    keep = np.repeat(1.0 - cov[..., None], 3, axis=2).astype(np.float32)
    add = (colour * cov[..., None]).astype(np.float32)
    for part in (cov, keep, add):
        part.setflags(write=False)
    return cov, keep, add


def _rain(img: _F32, rng: np.random.Generator, width: int, height: int) -> _F32:
    """Rain streaks, then a lower-contrast, slightly blurred look."""
    layer = np.zeros((height, width), np.float32)
    n = int(0.004 * width * height)
    slant = rng.uniform(-0.3, 0.3)
    x0 = rng.uniform(-0.1 * width, width, n)
    y0 = rng.uniform(-0.1 * height, height, n)
    length = rng.uniform(0.02, 0.08, n) * height
    seg = np.stack([np.stack([x0, y0], 1), np.stack([x0 + slant * length, y0 + length], 1)], 1)
    fixed = np.round(seg * _ONE).astype(np.int32)
    thick = max(1, round(width / 400))
    for g, level in enumerate((0.4, 0.7, 1.0)):
        cv2.polylines(layer, list(fixed[g::3]), False, level, thick, cv2.LINE_AA, _SHIFT)
    layer = cv2.GaussianBlur(layer, (0, 0), 0.5 * max(width / 320, 1.0))
    streaks = cv2.merge([0.3 * layer] * 3)
    img += (np.float32(0.85) - img) * streaks
    mean = img.mean(axis=(0, 1), keepdims=True)
    img = img * np.float32(0.88) + np.float32(0.12) * mean
    return np.asarray(
        cv2.GaussianBlur(img, (0, 0), 0.45 * min(max(width / 320, 1.0), 2.5)), np.float32
    )
