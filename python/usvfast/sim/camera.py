"""Camera images of the simulated harbour, ray-traced through a calibrated camera model.

Every pixel's ray comes from the camera's own lens model (OpenCV undistortion of the pixel
centre, `usvfast.camera.CameraModel`), so the images carry the lens distortion that the
pipeline undoes. A frame is: a sky with a sun glow and distant hills, a sea with wave
normals from a sum of gravity waves (Fresnel reflection of the sky, the sun's glint, haze
with distance), and the scene's bodies (walls, pier, buildings, boats, vessels, trash) as
shaded boxes in front of it, with exact occlusion (a z-buffer over the ray hits). Roll,
pitch and heave of the USV move the horizon. `render_frame` also returns the ground-truth
pixel boxes of the visible objects, taken from the rendered id buffer (so an object hidden
behind a boat or a wall has no box, and a half-hidden one a box around its visible part).

Frames: the camera is mounted body <- camera as in `usvfast.camera.georef.mount_rotation`
(yaw, pitch, roll in degrees; (0, 0, 0) looks along the bow), at `lever_arm` metres in the
body frame (FRD); the body reference point sits `waterline_height` m above the water.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np

from usvfast.camera.calibration import CameraModel
from usvfast.camera.georef import mount_rotation
from usvfast.frames import rotation_matrix
from usvfast.lidar.simulator import Box, Wall
from usvfast.sim.scene import TRUTH_KINDS, Body, Mover, World, make_world, place_body
from usvfast.sim.wake import (
    FOAM,
    MIN_SPEED,
    foam,
    mover_speed,
    splash_boxes,
    texture,
    wake_extent,
)

#: Camera mount: the thesis's Otter (eq. 4.2) has the camera 0.04 m aft of the body origin and
#: 0.27 m above it, looking along the bow; the simulated USV carries it on a mast 0.9 m above
#: the origin, pitched 5° down, so that trash at 10 m still covers a few pixels of a 640×360
#: frame (the thesis's frames were 2688×1520). The body origin is 0.30 m above the water
#: (section 4.1.5).
CAMERA_LEVER_ARM = (-0.04, 0.0, -0.9)
CAMERA_YPR_DEG = (0.0, -5.0, 0.0)
WATERLINE_HEIGHT = 0.30

_SKY_ZENITH = np.array([170.0, 110.0, 60.0], dtype=np.float32)  # BGR
_SKY_HORIZON = np.array([225.0, 205.0, 190.0], dtype=np.float32)
_WATER = np.array([62.0, 70.0, 38.0], dtype=np.float32)
_HAZE = np.array([200.0, 190.0, 180.0], dtype=np.float32)
_HILLS = np.array([90.0, 110.0, 95.0], dtype=np.float32)
_FOAM_RGB = (236, 240, 238)  # BGR of the white water above the surface
_WALL_PIECE = 10.0  # long walls are cut into pieces of at most this length, m
_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
_EDGES = np.array(
    [(i, j) for i in range(8) for j in range(i + 1, 8) if np.sum(_CORNERS[i] != _CORNERS[j]) == 1]
)


def default_camera(width: int = 640, height: int = 360) -> CameraModel:
    """The simulated camera: a wide-angle lens of about 110° × 67° field of view (the
    thesis's Hikvision DS-2CD2045FWD-I at its widest, section 4.1.4) with barrel distortion
    (k1 = −0.25, k2 = 0.06, slight decentring), `width` × `height` pixels (16:9 by default)."""
    if width < 16 or height < 16:
        raise ValueError(f"width, height: expected at least 16 px, got {width}x{height}")
    f = 300.0 * width / 640.0
    k = np.array([[f, 0.0, (width - 1) / 2 + 1.3], [0.0, f, (height - 1) / 2 - 0.8], [0, 0, 1]])
    dist = np.array([-0.25, 0.06, 0.0004, -0.0003, 0.0])
    return CameraModel(k, dist, (width, height), "pinhole", "harbour_sim")


@dataclass(frozen=True)
class PixelBox:
    """Ground truth of one visible object in an image: `object_id`, `kind` (a truth kind of
    `usvfast.sim.scene.TRUTH_KINDS`), the box around its visible pixels (x0, y0) – (x1, y1)
    in pixels (edges of the pixel squares, x1 and y1 exclusive, as for a detector's xyxy),
    `pixels` visible, and `visible_fraction` = visible / unoccluded pixels."""

    object_id: str
    kind: str
    x0: float
    y0: float
    x1: float
    y1: float
    pixels: int
    visible_fraction: float

    @property
    def xyxy(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) pixels."""
        return (self.x0, self.y0, self.x1, self.y1)


@dataclass(frozen=True)
class CameraPose:
    """Where the camera is at one instant: `position` (3,) NED m (down negative above the
    water), `rotation` (3, 3) NED <- camera (OpenCV axes)."""

    position: np.ndarray
    rotation: np.ndarray


def camera_pose(
    world: World,
    t: float,
    *,
    lever_arm: tuple[float, float, float] = CAMERA_LEVER_ARM,
    ypr_deg: tuple[float, float, float] = CAMERA_YPR_DEG,
    waterline_height: float = WATERLINE_HEIGHT,
) -> CameraPose:
    """The camera pose at time `t` s: the USV's path, heading and wave attitude, the mount."""
    n, e, heading = (float(v) for v in world.usv.pose(np.asarray(t)))
    roll, pitch, heave = (float(v) for v in world.waves.at(np.asarray(t)))
    r_nb = rotation_matrix(roll, pitch, heading)
    body = np.array([n, e, -(waterline_height + heave)])
    position = body + r_nb @ np.asarray(lever_arm, dtype=np.float64)
    return CameraPose(position, r_nb @ mount_rotation(ypr_deg))


def _rotate(v: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Rows of `v` (k, 3) float32 mapped by the (3, 3) matrix `m` (m @ v_i), without BLAS
    (whose threads crawl on a busy machine for this shape)."""
    m = np.asarray(m, dtype=np.float32)
    return v[:, 0:1] * m[:, 0] + v[:, 1:2] * m[:, 1] + v[:, 2:3] * m[:, 2]


def _dot(v: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Row-wise dot products of `v` (k, 3) with the vector `u` (3,), float32."""
    u = np.asarray(u, dtype=np.float32)
    return v[:, 0] * u[0] + v[:, 1] * u[1] + v[:, 2] * u[2]


def _box_axes(shape: Box) -> tuple[np.ndarray, np.ndarray]:
    """Unit axes (3, 3) rows (along, across, up) in NED, and the centre (3,) at mid height."""
    c, s = np.cos(shape.yaw), np.sin(shape.yaw)
    axes = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, -1.0]])
    centre = np.array([shape.center[0], shape.center[1], -(shape.bottom + shape.top) / 2])
    return axes, centre


def _wall_boxes(wall: Wall, thickness: float = 0.3) -> list[Box]:
    """A wall polyline as boxes of at most `_WALL_PIECE` m along its segments."""
    out = []
    poly = np.asarray(wall.polyline, dtype=np.float64)
    for a, b in itertools.pairwise(poly):
        d = b - a
        length = float(np.hypot(*d))
        pieces = max(1, int(np.ceil(length / _WALL_PIECE)))
        yaw = float(np.arctan2(d[1], d[0]))
        for k in range(pieces):
            c = a + d * (k + 0.5) / pieces
            out.append(Box((c[0], c[1]), length / pieces, thickness, yaw, 0.0, wall.height))
    return out


_RAY_CACHE: dict[tuple, np.ndarray] = {}


def pixel_rays(camera: CameraModel) -> np.ndarray:
    """Unit rays (height·width, 3) float32 in the camera frame (OpenCV axes) through every
    pixel centre, row by row: the lens model undone by OpenCV's undistortion (cached per
    camera; read-only)."""
    key = (
        camera.model,
        camera.image_size,
        camera.camera_matrix.tobytes(),
        camera.dist_coeffs.tobytes(),
    )
    if key not in _RAY_CACHE:
        w, h = camera.image_size
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        norm, _ = camera.normalized(np.column_stack([u.ravel(), v.ravel()]))
        rays = np.column_stack([norm, np.ones(len(norm))])
        rays = (rays / np.linalg.norm(rays, axis=1, keepdims=True)).astype(np.float32)
        rays.setflags(write=False)
        if len(_RAY_CACHE) > 4:
            _RAY_CACHE.clear()
        _RAY_CACHE[key] = rays
    return _RAY_CACHE[key]


class HarbourRenderer:
    """Renders camera frames of a `World`.

    camera : the CameraModel (default `default_camera()`); lever_arm, ypr_deg,
    waterline_height : the mount (see module doc). blur_sigma : optical blur, px; noise :
    sensor noise standard deviation, grey levels. wakes : draw the bow wave and the foam
    wake of every vessel under way on the water (`usvfast.sim.wake`).
    """

    def __init__(
        self,
        world: World,
        camera: CameraModel | None = None,
        *,
        lever_arm: tuple[float, float, float] = CAMERA_LEVER_ARM,
        ypr_deg: tuple[float, float, float] = CAMERA_YPR_DEG,
        waterline_height: float = WATERLINE_HEIGHT,
        blur_sigma: float = 0.7,
        noise: float = 2.0,
        wakes: bool = True,
    ) -> None:
        self.world = world
        self.camera = camera or default_camera()
        self.lever_arm = lever_arm
        self.ypr_deg = ypr_deg
        self.waterline_height = float(waterline_height)
        self.blur_sigma = float(blur_sigma)
        self.noise = float(noise)
        self.wakes = bool(wakes)
        self.width, self.height = self.camera.image_size
        self._rays = pixel_rays(self.camera)
        # truth objects get ids 0..k-1 in the id buffer, structure -1
        self._ids = [m.object_id for m in world.movers] + [b.object_id for b in world.moored]
        self._kinds = [m.kind for m in world.movers] + [b.kind for b in world.moored]
        self._index = {oid: k for k, oid in enumerate(self._ids)}
        self._static = self._expand(world.static)
        rng = np.random.default_rng([world.seed, 1])
        wind = rng.uniform(0, 2 * np.pi)
        dirs = wind + rng.uniform(-0.6, 0.6, 8)
        wavelengths = rng.uniform(0.6, 7.0, 8)
        k = 2 * np.pi / wavelengths
        self._wave_k = np.column_stack([k * np.cos(dirs), k * np.sin(dirs)])
        self._wave_slope = rng.uniform(0.05, 0.12, 8) / np.sqrt(4)  # a·k, steepness
        self._wave_omega = np.sqrt(9.81 * k)
        self._wave_phase = rng.uniform(0, 2 * np.pi, 8)
        self._hill_phase = rng.uniform(0, 2 * np.pi, 4)
        se, sa = world.sun_elevation, world.sun_azimuth
        self._sun = np.array([np.cos(se) * np.cos(sa), np.cos(se) * np.sin(sa), np.sin(se)])

    def _expand(self, bodies: list[Body]) -> list[tuple[Box, Body]]:
        out = []
        for b in bodies:
            if isinstance(b.shape, Wall):
                out.extend((box, b) for box in _wall_boxes(b.shape))
            else:
                out.append((b.shape, b))
        return out

    # --- background -----------------------------------------------------------------
    def _sky(self, d_up: np.ndarray, d_n: np.ndarray, d_e: np.ndarray) -> np.ndarray:
        """Sky colour (k, 3) of view directions given as (north, east, up) components."""
        f = np.sqrt(np.clip(d_up, 0.0, 1.0))
        col = _SKY_HORIZON * (1 - f[:, None]) + _SKY_ZENITH * f[:, None]
        cos_sun = d_n * self._sun[0] + d_e * self._sun[1] + d_up * self._sun[2]
        glow = np.exp((np.clip(cos_sun, -1, 1) - 1.0) * 20.0)
        return col + glow[:, None] * np.float32(60.0)

    def _background(self, pose: CameraPose, d: np.ndarray, t: float):
        """Colour (N, 3) and depth (N,) of sky, hills and sea along every ray."""
        d_n, d_e, d_up = d[:, 0], d[:, 1], -d[:, 2]
        colour = np.empty((len(d), 3), dtype=np.float32)
        depth = np.full(len(d), np.inf, dtype=np.float32)
        up = d_up >= -1e-4
        colour[up] = self._sky(d_up[up], d_n[up], d_e[up])
        # distant hills: a band a degree or two above the horizon
        az = np.arctan2(d_e[up], d_n[up])
        hill = np.radians(
            1.0
            + 0.6 * np.sin(3 * az + self._hill_phase[0])
            + 0.4 * np.sin(7 * az + self._hill_phase[1])
        )
        in_hill = d_up[up] < np.sin(hill)
        hills = colour[up]
        hills[in_hill] = _HILLS * np.float32(0.6) + hills[in_hill] * np.float32(0.4)
        colour[up] = hills
        sea = ~up
        height = -pose.position[2]
        dist = (height / d[sea, 2].astype(np.float64)).astype(np.float32)
        rel_n = dist * d_n[sea]  # sea point relative to the camera, m
        rel_e = dist * d_e[sea]
        wk = self._wave_k.astype(np.float32)
        shift = np.float32(
            self._wave_k @ pose.position[:2] - self._wave_omega * t + self._wave_phase
        )
        # phase of every wave at every sea point, relative to the camera position (float32)
        phase = np.outer(rel_n, wk[:, 0])
        phase += np.outer(rel_e, wk[:, 1])
        phase += shift
        c = np.cos(phase)
        att = (1.0 / (1.0 + (dist / 15.0) ** 2)).astype(np.float32)
        kn = self._wave_k[:, 0] / np.linalg.norm(self._wave_k, axis=1)
        ke = self._wave_k[:, 1] / np.linalg.norm(self._wave_k, axis=1)
        sn = (c * (self._wave_slope * kn).astype(np.float32)).sum(axis=1) * att
        se = (c * (self._wave_slope * ke).astype(np.float32)).sum(axis=1) * att
        nrm = np.column_stack([-sn, -se, np.ones_like(sn)])
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        v = np.column_stack([d_n[sea], d_e[sea], d_up[sea]])
        vn = (v * nrm).sum(axis=1)
        r = v - 2 * vn[:, None] * nrm
        r[:, 2] = np.abs(r[:, 2])
        cos_i = np.clip(-vn, 0.0, 1.0)
        fresnel = 0.02 + 0.98 * (1 - cos_i) ** 5
        sky = self._sky(r[:, 2], r[:, 0], r[:, 1])
        glint = np.clip(_dot(r, self._sun), 0.0, 1.0) ** 400 * (400.0 * att)
        water = _WATER * (1 - fresnel[:, None]) + sky * fresnel[:, None] + glint[:, None]
        haze = 1.0 - np.exp(-dist / 600.0)
        colour[sea] = water * (1 - haze[:, None]) + _HAZE * haze[:, None]
        depth[sea] = dist
        return colour, depth

    # --- bodies -----------------------------------------------------------------------
    def _candidates(self, pose: CameraPose, shape: Box) -> np.ndarray | None:
        """Flat pixel indices whose rays may hit `shape` (None: none can): the bounding box
        of its edges projected through the lens, clipped by a near plane 5 cm in front of
        the camera, padded for the curvature of the projected edges."""
        axes, centre = _box_axes(shape)
        half = np.array([shape.length / 2, shape.width / 2, (shape.top - shape.bottom) / 2])
        corners = centre + (_CORNERS * half) @ axes
        cam = (corners - pose.position) @ pose.rotation
        z_near = 0.05
        a, b = cam[_EDGES[:, 0]], cam[_EDGES[:, 1]]
        za, zb = a[:, 2:3], b[:, 2:3]
        keep = ((za > z_near) | (zb > z_near)).ravel()
        if not keep.any():
            return None
        a, b, za, zb = a[keep], b[keep], za[keep], zb[keep]
        with np.errstate(divide="ignore", invalid="ignore"):
            f = np.clip((z_near - za) / (zb - za), 0.0, 1.0)
        a2 = np.where(za > z_near, a, a + f * (b - a))
        b2 = np.where(zb > z_near, b, a + f * (b - a))
        s = np.linspace(0.0, 1.0, 9)[None, :, None]
        pts = (a2[:, None, :] + s * (b2 - a2)[:, None, :]).reshape(-1, 3)
        px = self.camera.project(pts)
        w, h = self.width, self.height
        lo, hi = px.min(axis=0) - 2.0, px.max(axis=0) + 2.0
        x0, y0 = int(max(np.floor(lo[0]), 0)), int(max(np.floor(lo[1]), 0))
        x1, y1 = int(min(np.ceil(hi[0]), w - 1)), int(min(np.ceil(hi[1]), h - 1))
        if x0 > x1 or y0 > y1:
            return None
        cols = np.arange(x0, x1 + 1)
        rows = np.arange(y0, y1 + 1)
        return (rows[:, None] * w + cols[None, :]).ravel()

    @staticmethod
    def _hit(
        pose: CameraPose, d: np.ndarray, shape: Box
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Ray/box intersection (slab method): distance (k,) (inf = miss), normal (k, 3) NED,
        height of the hit above the box bottom (k,) m."""
        axes, centre = _box_axes(shape)
        half = np.array([shape.length / 2, shape.width / 2, (shape.top - shape.bottom) / 2])
        o = (axes @ (pose.position - centre)).astype(np.float32)
        db = _rotate(d, axes)
        half = half.astype(np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-half - o) / db
            t2 = (half - o) / db
        lo = np.minimum(t1, t2)
        hi = np.maximum(t1, t2)
        np.nan_to_num(lo, copy=False, nan=-np.inf)
        np.nan_to_num(hi, copy=False, nan=np.inf)
        t_in = lo.max(axis=1)
        t_out = hi.min(axis=1)
        hit = (t_in <= t_out) & (t_in > 0)
        axis = lo.argmax(axis=1)
        sign = -np.sign(db[np.arange(len(d)), axis])
        normal = axes.astype(np.float32)[axis] * sign[:, None]
        z = o[2] + t_in * db[:, 2] + half[2]
        return np.where(hit, t_in, np.inf), normal, z

    def _shade(self, body: Body, normal: np.ndarray, z: np.ndarray, dist: np.ndarray):
        albedo = np.asarray(body.colour, dtype=np.float32)
        n_up = np.column_stack([normal[:, 0], normal[:, 1], -normal[:, 2]])
        lam = np.clip(_dot(n_up, self._sun), 0.0, 1.0).astype(np.float32)
        light = 0.45 + 0.55 * lam + 0.1 * np.clip(n_up[:, 2], 0, 1).astype(np.float32)
        col = albedo[None, :] * light[:, None]
        if body.kind in ("wall", "building"):
            # courses of stone / windows: darker bands with height
            band = (np.floor(z * (2.0 if body.kind == "wall" else 0.35)) % 2).astype(np.float32)
            col *= (1.0 - 0.08 * band)[:, None]
        if body.kind == "foam":
            return np.minimum(col * np.float32(1.15), np.float32(250.0))
        wet = np.exp(-np.maximum(z, 0.0) / 0.04).astype(np.float32)  # waterline darkening
        col *= (1.0 - 0.35 * wet)[:, None]
        haze = (1.0 - np.exp(-dist / 600.0)).astype(np.float32)
        return col * (1 - haze[:, None]) + _HAZE * haze[:, None]

    # --- frame ------------------------------------------------------------------------
    def render(self, t: float, *, min_pixels: int = 4) -> tuple[np.ndarray, list[PixelBox]]:
        """The image (height, width, 3) uint8 BGR at time `t` s and the boxes of the truth
        objects with at least `min_pixels` visible pixels."""
        pose = camera_pose(
            self.world,
            t,
            lever_arm=self.lever_arm,
            ypr_deg=self.ypr_deg,
            waterline_height=self.waterline_height,
        )
        d = _rotate(self._rays, pose.rotation)
        # sky and sea are smooth at the pixel scale: shade them on every other pixel and
        # interpolate (a quarter of the work); the water's depth is exact per pixel
        w, h = self.width, self.height
        half = d.reshape(h, w, 3)[::2, ::2]
        bg, _ = self._background(pose, half.reshape(-1, 3), t)
        bg = bg.reshape(half.shape[0], half.shape[1], 3)
        colour = cv2.resize(bg, (w, h), interpolation=cv2.INTER_LINEAR).reshape(-1, 3)
        down = d[:, 2] > 1e-4
        depth = np.full(len(d), np.inf, dtype=np.float32)
        depth[down] = np.float32(-pose.position[2]) / d[down, 2]
        sea_depth = depth.copy()
        ids = np.full(len(d), -1, dtype=np.int32)
        footprint: dict[int, list[np.ndarray]] = {}  # object -> pixels its bodies cover
        bodies = list(self._static)
        for m in self.world.movers:
            n, e, yaw = (float(v) for v in m.motion.pose(np.asarray(t)))
            for b in m.bodies:
                placed = place_body(b, n, e, yaw)
                bodies.append((placed.box, placed))
            if self.wakes and m.kind == "vessel":
                for box in splash_boxes(m, t):
                    bodies.append((box, Body(box, "", "foam", _FOAM_RGB, 0.0)))
        for shape, body in bodies:
            idx = self._candidates(pose, shape)
            if idx is None:
                continue
            dist, normal, z = self._hit(pose, d[idx], shape)
            got = np.isfinite(dist)
            k = self._index.get(body.object_id, -1)
            if k >= 0:
                footprint.setdefault(k, []).append(idx[got])
            near = got & (dist < depth[idx])
            if not near.any():
                continue
            sel = idx[near]
            depth[sel] = dist[near]
            ids[sel] = k
            colour[sel] = self._shade(body, normal[near], z[near], dist[near])
        if self.wakes:
            for m in self.world.movers:
                if m.kind == "vessel":
                    self._paint_wake(pose, d, depth, sea_depth, colour, m, t)
        img = colour.reshape(self.height, self.width, 3)
        if self.blur_sigma > 0:
            img = cv2.GaussianBlur(img, (0, 0), self.blur_sigma)
        if self.noise > 0:
            rng = np.random.default_rng([self.world.seed, 2, round(t * 1000)])
            img = img + rng.standard_normal(img.shape, dtype=np.float32) * np.float32(self.noise)
        image = np.clip(img + 0.5, 0, 255).astype(np.uint8)
        unoccluded = {k: np.unique(np.concatenate(v)).size for k, v in footprint.items()}
        return image, self._boxes(ids, unoccluded, min_pixels)

    def _paint_wake(
        self,
        pose: CameraPose,
        d: np.ndarray,
        depth: np.ndarray,
        sea_depth: np.ndarray,
        colour: np.ndarray,
        mover: Mover,
        t: float,
    ) -> None:
        """Blend the foam of `mover` (`usvfast.sim.wake.foam`) into `colour` on the pixels
        that still show the sea (their depth is the sea's: nothing in front of the water)."""
        speed = mover_speed(mover, t)
        if speed < MIN_SPEED:
            return
        length, beam, _ = mover.size
        n, e, yaw = (float(v) for v in mover.motion.pose(np.asarray(t)))
        c, s = np.cos(yaw), np.sin(yaw)
        fwd, aft, half = wake_extent(length, beam, speed)
        mid = (fwd + aft) / 2
        region = Box((n + c * mid, e + s * mid), fwd - aft, 2 * half, yaw, 0.0, 0.02)
        idx = self._candidates(pose, region)
        if idx is None:
            return
        idx = idx[np.isfinite(sea_depth[idx]) & (depth[idx] == sea_depth[idx])]
        if idx.size == 0:
            return
        p = pose.position[:2].astype(np.float32) + depth[idx, None] * d[idx, :2]
        rn, re = p[:, 0] - np.float32(n), p[:, 1] - np.float32(e)
        x = np.float32(c) * rn + np.float32(s) * re
        y = np.float32(-s) * rn + np.float32(c) * re
        f = foam(x, y, length=length, beam=beam, speed=speed)
        on = f > 0
        if not on.any():
            return
        f = (f[on] * texture(p[on, 0], p[on, 1], t))[:, None]
        sel = idx[on]
        colour[sel] = colour[sel] * (1 - f) + FOAM * f

    def _boxes(
        self, ids: np.ndarray, unoccluded: dict[int, int], min_pixels: int
    ) -> list[PixelBox]:
        grid = ids.reshape(self.height, self.width)
        present = np.unique(grid[grid >= 0])
        out = []
        for k in present.tolist():
            rows, cols = np.nonzero(grid == k)
            if rows.size < min_pixels:
                continue
            out.append(
                PixelBox(
                    self._ids[k],
                    self._kinds[k],
                    float(cols.min()),
                    float(rows.min()),
                    float(cols.max() + 1),
                    float(rows.max() + 1),
                    int(rows.size),
                    float(rows.size / max(unoccluded.get(k, 1), 1)),
                )
            )
        return out


def render_frame(
    seed: int,
    t: float,
    *,
    camera: CameraModel | None = None,
    duration: float = 60.0,
    world: World | None = None,
    min_pixels: int = 4,
) -> tuple[np.ndarray, list[PixelBox]]:
    """One rendered camera frame of the harbour of `seed` at `t` s after the start, and the
    ground-truth pixel boxes of its visible objects (kinds in TRUTH_KINDS: 'bottle', 'bag',
    'box' are the trash; 'vessel' and 'moored_boat' the boats).

    Building the world and the renderer costs about a second; to render many frames of one
    world, build a `HarbourRenderer` once and call its `render(t)`.
    """
    world = world or make_world(seed, duration)
    return HarbourRenderer(world, camera).render(t, min_pixels=min_pixels)


__all__ = [
    "CAMERA_LEVER_ARM",
    "CAMERA_YPR_DEG",
    "TRUTH_KINDS",
    "WATERLINE_HEIGHT",
    "CameraPose",
    "HarbourRenderer",
    "PixelBox",
    "camera_pose",
    "default_camera",
    "pixel_rays",
    "render_frame",
]
