"""A VLP-16 scan simulator over a flat water plane (vectorised numpy ray casting).

The world is a local frame (north, east) in metres with heights measured up from the
water surface (z = 0). A scene holds vertical walls / piers (polylines with a top height),
moored boats (oriented boxes) and floating objects (small boxes or vertical cylinders a few
centimetres to decimetres above the water). Water absorbs every beam (no return), except
optional sparse surface clutter (wakes, spray) drawn at random water hits. Frames come out
in the readers' format (`LidarFrame`, sensor frame x forward / y left / z up) so the
pipeline cannot tell them apart, together with per-point ground truth.

The sensor pose is held constant during one rotation (at 1 m/s the vessel moves 0.1 m per
rotation); point times still follow the azimuth.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from usvfast.lidar.frame import LidarFrame, make_points
from usvfast.lidar.pipeline import sensor_to_world

#: Kinds of scene objects, as reported in the ground truth.
WALL, BOAT, FLOAT = "wall", "boat", "float"


@dataclass
class Wall:
    """A vertical wall or pier face: a polyline (k, 2) of (north, east) m from the water to
    `height` m above it."""

    polyline: np.ndarray
    height: float = 2.0
    kind: str = WALL


@dataclass
class Box:
    """An oriented box: centre (north, east) m, `length` along `yaw` (rad clockwise from
    north), `width` across, from `bottom` to `top` m above the water."""

    center: tuple[float, float]
    length: float
    width: float
    yaw: float = 0.0
    bottom: float = 0.0
    top: float = 1.5
    kind: str = BOAT


@dataclass
class Cylinder:
    """A vertical cylinder: centre (north, east) m, `radius` m, from `bottom` to `top` m
    above the water."""

    center: tuple[float, float]
    radius: float
    bottom: float = 0.0
    top: float = 0.2
    kind: str = FLOAT


@dataclass
class Scene:
    """Objects over the water; `clutter_probability` is the chance that a beam meeting the
    water between `clutter_min_range` and `clutter_range` m returns a surface point anyway."""

    objects: list = field(default_factory=list)
    clutter_probability: float = 0.0
    clutter_range: float = 15.0
    clutter_min_range: float = 0.0

    def kinds(self) -> np.ndarray:
        """(k,) kind of each object, indexed like the ground-truth labels."""
        return np.array([o.kind for o in self.objects])


@dataclass
class SimulatedFrame:
    """A simulated rotation: the frame, the per-point object label (index into
    `Scene.objects`, −1 for surface clutter) and the number of returns per object."""

    frame: LidarFrame
    labels: np.ndarray
    hits: dict[int, int]
    sensor_position: np.ndarray


def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


class VLP16Simulator:
    """Ray-cast a spinning multi-beam LiDAR (VLP-16 by default) in a `Scene`.

    Parameters
    ----------
    scene : the objects.
    mount_height : sensor height above the water, m.
    channels, vfov_deg : beams evenly spread over ±vfov/2 (VLP-16: 16 beams, 30°, 2° apart);
        ring i is the i-th lowest beam.
    azimuth_step_deg : horizontal resolution (0.2° at 600 rpm).
    rpm : rotation speed; sets point times and the frame period.
    range_noise : standard deviation of the Gaussian range error, m.
    max_range : returns beyond this slant range are dropped, m.
    lever_arm, mount_yaw : sensor position (forward, starboard m) and yaw (rad) on the vessel.
    seed : seeds the noise; the same seed gives the same frames.
    """

    def __init__(
        self,
        scene: Scene,
        *,
        mount_height: float = 1.0,
        channels: int = 16,
        vfov_deg: float = 30.0,
        azimuth_step_deg: float = 0.2,
        rpm: float = 600.0,
        range_noise: float = 0.03,
        max_range: float = 100.0,
        lever_arm: tuple[float, float] = (0.0, 0.0),
        mount_yaw: float = 0.0,
        seed: int = 0,
    ) -> None:
        if not mount_height > 0:
            raise ValueError(f"mount_height: expected > 0, got {mount_height}")
        self.scene = scene
        self.mount_height = float(mount_height)
        self.elevations = np.deg2rad(np.linspace(-vfov_deg / 2, vfov_deg / 2, channels))
        self.azimuths = np.deg2rad(np.arange(0.0, 360.0, azimuth_step_deg))
        self.period = 60.0 / rpm
        self.range_noise = float(range_noise)
        self.max_range = float(max_range)
        self.lever_arm = lever_arm
        self.mount_yaw = float(mount_yaw)
        self.rng = np.random.default_rng(seed)
        self._frames = 0
        # rays: column-major over (azimuth, ring) like a Velodyne packet stream
        az, el = np.meshgrid(self.azimuths, self.elevations, indexing="ij")
        self._az, self._el = az.ravel(), el.ravel()
        self._ring = np.tile(np.arange(channels, dtype=np.uint16), self.azimuths.size)
        self._col = np.repeat(np.arange(self.azimuths.size), channels)
        self._tan = np.tan(self._el)

    def scan(self, pose, stamp: float) -> SimulatedFrame:
        """One rotation with the vessel at `pose` = (north, east, heading rad); the frame
        stamp (end of the rotation) is `stamp` UNIX s."""
        pose = np.asarray(pose, dtype=np.float64)
        sensor = sensor_to_world(
            np.zeros((1, 2)), pose, lever_arm=self.lever_arm, mount_yaw=self.mount_yaw
        )[0]
        bearing = pose[2] + self.mount_yaw + self._az  # clockwise from north
        un, ue = np.cos(bearing), np.sin(bearing)
        h, tan = self.mount_height, self._tan
        n_rays = un.size
        best, label = self.cast(self.scene.objects, sensor, h, un, ue, tan)
        # water: downward beams meet z = 0 at r = h / tan(-elevation)
        with np.errstate(divide="ignore"):
            r_water = np.where(tan < 0, h / -np.where(tan < 0, tan, -1.0), np.inf)
        hit = np.isfinite(best) & (best < r_water)
        clutter = np.zeros(n_rays, dtype=bool)
        if self.scene.clutter_probability > 0:
            draw = self.rng.random(n_rays) < self.scene.clutter_probability
            in_band = (r_water >= self.scene.clutter_min_range) & (
                r_water <= self.scene.clutter_range
            )
            clutter = ~hit & in_band & draw
        r = np.where(hit, best, np.where(clutter, r_water, np.nan))
        ok = hit | clutter
        cos_el = np.cos(self._el)
        slant = r / cos_el + self.rng.normal(0.0, self.range_noise, n_rays)
        ok &= (slant > 0.3) & (slant <= self.max_range)
        idx = np.flatnonzero(ok)
        s, az, el = slant[idx], self._az[idx], self._el[idx]
        horizontal = s * np.cos(el)
        times = (self._col[idx] + 1) / self.azimuths.size * self.period - self.period
        intensity = np.where(clutter[idx], 3.0, 40.0)
        points = make_points(
            horizontal * np.cos(az),
            -horizontal * np.sin(az),
            s * np.sin(el),
            intensity,
            self._ring[idx],
            times,
        )
        labels = np.where(clutter[idx], -1, label[idx])
        ids, counts = np.unique(labels[labels >= 0], return_counts=True)
        frame = LidarFrame(float(stamp), points, source="simulator", index=self._frames)
        self._frames += 1
        return SimulatedFrame(
            frame, labels, dict(zip(ids.tolist(), counts.tolist(), strict=True)), np.asarray(sensor)
        )

    def cast(self, objects, origin, height, un, ue, tan) -> tuple[np.ndarray, np.ndarray]:
        """Nearest object along each ray: (horizontal distance m, inf when none; index into
        `objects`, −1 when none), each (n,).

        Rays start at `origin` = (north, east) m and `height` m above the water (scalars or
        (n,) arrays, one per ray) and run along the horizontal unit vector (`un`, `ue`)
        rising `tan` m per horizontal metre. The water itself is not tested.
        """
        best = np.full(np.shape(un), np.inf)
        label = np.full(np.shape(un), -1, dtype=np.int64)
        for k, obj in enumerate(objects):
            if isinstance(obj, Wall):
                r = self._hit_wall(obj, origin, un, ue, tan, height)
            elif isinstance(obj, Box):
                r = self._hit_box(obj, origin, un, ue, tan, height)
            elif isinstance(obj, Cylinder):
                r = self._hit_cylinder(obj, origin, un, ue, tan, height)
            else:
                raise TypeError(f"scene.objects[{k}]: unknown object {type(obj).__name__}")
            closer = r < best
            best[closer] = r[closer]
            label[closer] = k
        return best, label

    def _hit_wall(self, wall: Wall, sensor, un, ue, tan, height=None) -> np.ndarray:
        h = self.mount_height if height is None else height
        poly = np.asarray(wall.polyline, dtype=np.float64).reshape(-1, 2)
        out = np.full(un.size, np.inf)
        for a, b in itertools.pairwise(poly):
            dn, de = b[0] - a[0], b[1] - a[1]
            den = _cross(un, ue, dn, de)
            wn, we = a[0] - sensor[0], a[1] - sensor[1]
            with np.errstate(divide="ignore", invalid="ignore"):
                r = _cross(wn, we, dn, de) / den
                s = _cross(wn, we, un, ue) / den
            z = h + r * tan
            ok = (den != 0) & (r > 0) & (s >= 0) & (s <= 1) & (z >= 0) & (z <= wall.height)
            out = np.where(ok & (r < out), r, out)
        return out

    def _hit_box(self, box: Box, sensor, un, ue, tan, height=None) -> np.ndarray:
        h = self.mount_height if height is None else height
        c, s = np.cos(box.yaw), np.sin(box.yaw)
        # sensor and directions in the box frame (x along yaw, y across), z up
        on, oe = sensor[0] - box.center[0], sensor[1] - box.center[1]
        ox, oy = c * on + s * oe, -s * on + c * oe
        dx, dy = c * un + s * ue, -s * un + c * ue
        t_min = np.full(un.size, -np.inf)
        t_max = np.full(un.size, np.inf)
        for o, d, lo, hi in (
            (ox, dx, -box.length / 2, box.length / 2),
            (oy, dy, -box.width / 2, box.width / 2),
            (h, tan, box.bottom, box.top),
        ):
            with np.errstate(divide="ignore", invalid="ignore"):
                t1, t2 = (lo - o) / d, (hi - o) / d
            parallel = d == 0
            inside = (o >= lo) & (o <= hi)
            # a beam parallel to a slab misses the box unless it runs inside the slab
            t1 = np.where(parallel, np.where(inside, -np.inf, np.inf), t1)
            t2 = np.where(parallel, np.where(inside, np.inf, np.inf), t2)
            t_min = np.maximum(t_min, np.minimum(t1, t2))
            t_max = np.minimum(t_max, np.maximum(t1, t2))
        ok = (t_min <= t_max) & (t_min > 0)
        return np.where(ok, t_min, np.inf)

    def _hit_cylinder(self, cyl: Cylinder, sensor, un, ue, tan, height=None) -> np.ndarray:
        h = self.mount_height if height is None else height
        wn, we = cyl.center[0] - sensor[0], cyl.center[1] - sensor[1]
        b = un * wn + ue * we
        disc = b * b - (wn * wn + we * we - cyl.radius**2)
        root = np.sqrt(np.maximum(disc, 0.0))
        r_side = b - root
        z = h + r_side * tan
        side = (disc >= 0) & (r_side > 0) & (z >= cyl.bottom) & (z <= cyl.top)
        out = np.where(side, r_side, np.inf)
        # top cap, met by downward beams
        with np.errstate(divide="ignore", invalid="ignore"):
            r_top = (cyl.top - h) / tan
        pn, pe = r_top * un - wn, r_top * ue - we
        cap = (tan < 0) & (r_top > 0) & (pn * pn + pe * pe <= cyl.radius**2)
        return np.where(cap & (r_top < out), r_top, out)


def harbour_scene(
    *,
    seed: int = 0,
    walls: int = 2,
    boats: int = 3,
    floats: int = 8,
    channel_width: float = 16.0,
    length: float = 60.0,
    near: float = 3.5,
    far: float = 10.0,
    separation: float = 4.0,
    clutter_probability: float = 0.0,
) -> Scene:
    """A straight harbour channel along north around a vessel starting at the origin.

    Quay walls 2 m high at east = ±channel_width/2 (`walls` = 1 keeps the eastern one; the
    western side is then open water), `boats` boxes (2.5 m wide, 1.4 m high, 5–9 m long,
    at least 3 m apart) moored against the eastern wall from north −10 m on, and `floats`
    floating objects (boxes 0.3–0.6 m across or cylinders of radius 0.15–0.3 m, tops 5–30 cm
    above the water) between `near` and `far` metres from the origin, at least `separation`
    apart (mean shift with a 2 m bandwidth merges objects closer than about twice that) and
    1.5 m from walls and boats. Deterministic given `seed`; raises ValueError when the
    objects or the boats (along the wall, up to north = `length`) do not fit.
    """
    if boats < 0:
        raise ValueError(f"boats: expected >= 0, got {boats}")
    rng = np.random.default_rng(seed)
    half = channel_width / 2
    objects: list = [Wall(np.array([[-length, half], [length, half]]), height=2.0)]
    if walls >= 2:
        objects.append(Wall(np.array([[length, -half], [-length, -half]]), height=2.0))
    boat_width = 2.5
    n0 = -10.0 + rng.uniform(0.0, 3.0)
    for k in range(boats):
        ln = rng.uniform(5.0, 9.0)
        if n0 + ln > length:
            raise ValueError(f"boats: only {k} of {boats} fit along the {2 * length:g} m wall")
        centre = (n0 + ln / 2, half - boat_width / 2 - 0.3)
        objects.append(Box(centre, ln, boat_width, 0.0, 0.0, 1.4, BOAT))
        n0 += ln + rng.uniform(3.0, 6.0)
    east_limit = (half - boat_width - 0.3 - 1.5) if boats else half - 1.5
    west_limit = -half + 1.5 if walls >= 2 else -far
    placed: list[np.ndarray] = []
    for _ in range(10000):
        if len(placed) == floats:
            break
        p = np.array([rng.uniform(-far, far), rng.uniform(west_limit, east_limit)])
        if not near <= np.hypot(*p) <= far:
            continue
        if any(np.hypot(*(p - q)) < separation for q in placed):
            continue
        placed.append(p)
    if len(placed) < floats:
        raise ValueError(f"floats: could not place {floats} objects {separation} m apart")
    for p in placed:
        top = rng.uniform(0.05, 0.30)
        if rng.random() < 0.5:
            objects.append(Cylinder(tuple(p), rng.uniform(0.15, 0.3), 0.0, top, FLOAT))
        else:
            size = rng.uniform(0.3, 0.6)
            yaw = rng.uniform(0, np.pi)
            objects.append(Box(tuple(p), size, size * rng.uniform(0.6, 1.0), yaw, 0.0, top, FLOAT))
    return Scene(objects, clutter_probability=clutter_probability)
