"""The thesis's LiDAR chain (section 3.3, Figure 3.6), stage by stage, and `LidarDetector`.

prefilter -> raster + blur + LSD -> line memory -> line-of-sight filter -> buffer K frames in
the world frame -> mean shift -> detections. Each stage is a function of its own; the
detector wires them with a `LidarConfig` and keeps every intermediate product on its
results for plotting and debugging.

Frames: points arrive in the sensor frame (x forward, y left, z up; Velodyne's). The world
frame is NED; a vessel pose is (north m, east m, heading rad clockwise from north). The
LiDAR sits at `lever_arm` (forward, starboard m) on the vessel, rotated by `mount_yaw`
(rad, clockwise) and `mount_height` metres above the water.
"""

from __future__ import annotations

from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from usvfast._core import DimensionError
from usvfast._validate import as_float_array, real
from usvfast.lidar.detections import (
    LidarDetection,
    check_small_cluster,
    cluster_detections,
)
from usvfast.lidar.frame import LidarFrame
from usvfast.lidar.lines import LineMemory, blur, detect_segments, extend_segments, rasterize
from usvfast.lidar.vessels import VesselFinder


@dataclass
class LidarConfig:
    """Parameters of the LiDAR chain (defaults from the thesis, docs/seeds.md).

    radius : keep points within this horizontal range of the sensor, m.
    line_margin : lines are extracted from points up to radius + line_margin (the raster's
        half-width), so walls and boats crossing the radius are still seen as lines, m.
    mount_height : sensor height above the water, m.
    slice_min, slice_max : keep points whose height above the water is in this slice, m.
    min_intensity : drop points below this intensity (None: no threshold).
    pixel : raster pixel size, m.
    min_segment_length : LSD segments shorter than this are ignored, m.
    line_memory_frames : frames a segment is remembered (N).
    cover_tolerance : a segment within this distance of a longer one is dropped, m.
    segment_extension : segments are lengthened by this at both ends before the
        line-of-sight filter (closes LSD's short ends and open corners), m.
    los_tolerance : points within this distance of a segment are dropped, m.
    buffer_frames : frames buffered in the world frame before clustering (K).
    bandwidth, bin_seeding, cluster_all, backend : mean shift parameters.
    min_cluster_points : clusters with fewer points are dropped (but see small_cluster_points).
    small_cluster_points, small_cluster_radius : None (the thesis): no exception to
        min_cluster_points. An integer K >= 2 (points) and a length r (m): a cluster (core)
        of fewer than min_cluster_points members is still a detection when at least K of
        them lie within r of their coordinate-wise median, made of those members only
        (`usvfast.lidar.detections.cluster_detections`). A small float that one ring grazes
        in a single rotation returns a few points within centimetres of each other, while
        sparse water returns that fall into a small core scatter over decimetres.
    core_radius : None (the thesis): a detection is the mean of all its cluster's members.
        A number (m): only the members within this distance of the cluster's core count —
        the core found from the members' median by a mean shift of this flat radius — so
        sparse surface clutter gathered by the wide `bandwidth` neither moves a small
        object's detection nor makes up the point count of a clutter cluster.
    min_position_std : floor of the detection's standard deviation along any axis, m.
    vessels : also find moving vessels among the points the line-of-sight filter removed
        (`usvfast.lidar.vessels.VesselFinder`): one detection per vessel near its centre,
        and the mean-shift detections on its hull dropped.
    vessel_beam, vessel_length, vessel_max_length, vessel_min_speed : the finder's beam and
        nominal length (m), the longest group taken for a vessel (m) and the speed (m/s) of
        its ends above which it is moving.
    lever_arm, mount_yaw : LiDAR position (forward, starboard m) and yaw (rad) on the vessel.
    sensor_id : written on every detection.
    """

    radius: float = 10.0
    line_margin: float = 2.0
    mount_height: float = 1.0
    slice_min: float = -0.5
    slice_max: float = 0.5
    min_intensity: float | None = None
    pixel: float = 0.2
    min_segment_length: float = 1.0
    line_memory_frames: int = 3
    cover_tolerance: float = 0.2
    segment_extension: float = 0.4
    los_tolerance: float = 0.4
    buffer_frames: int = 4
    bandwidth: float = 2.0
    bin_seeding: bool = False
    cluster_all: bool = False
    backend: str = "rust"
    min_cluster_points: int = 15
    small_cluster_points: int | None = None
    small_cluster_radius: float = 0.1
    core_radius: float | None = None
    min_position_std: float = 0.1
    vessels: bool = False
    vessel_beam: float = 2.2
    vessel_length: float = 6.0
    vessel_max_length: float = 9.0
    vessel_min_speed: float = 0.8
    lever_arm: tuple[float, float] = (0.0, 0.0)
    mount_yaw: float = 0.0
    sensor_id: str = "lidar"

    def __post_init__(self) -> None:
        for name in (
            "radius",
            "mount_height",
            "pixel",
            "bandwidth",
            "vessel_beam",
            "vessel_length",
            "vessel_max_length",
            "vessel_min_speed",
        ):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: expected a positive number, got {v}")
        for name in ("line_memory_frames", "buffer_frames", "min_cluster_points"):
            v = getattr(self, name)
            if not (np.isfinite(v) and int(v) == v and v >= 1):
                raise ValueError(f"{name}: expected an integer >= 1, got {v}")
        if self.core_radius is not None and not (
            np.isfinite(self.core_radius) and self.core_radius > 0
        ):
            raise ValueError(f"core_radius: expected a positive number, got {self.core_radius}")
        self.small_cluster_points, self.small_cluster_radius = check_small_cluster(
            self.small_cluster_points, self.small_cluster_radius
        )
        if not self.slice_min < self.slice_max:
            raise ValueError(
                f"slice_min/slice_max: expected slice_min < slice_max, got "
                f"{self.slice_min}, {self.slice_max}"
            )
        for name in (
            "los_tolerance",
            "line_margin",
            "cover_tolerance",
            "min_position_std",
            "min_segment_length",
            "segment_extension",
        ):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name}: expected a number >= 0, got {v}")


# --------------------------------------------------------------------------------------
# stage 1: prefilter
# --------------------------------------------------------------------------------------
def prefilter(
    points: np.ndarray,
    *,
    radius: float = 10.0,
    mount_height: float = 1.0,
    slice_min: float = -0.5,
    slice_max: float = 0.5,
    min_intensity: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Keep unique points near the water and within range; drop z.

    Parameters
    ----------
    points : (n,) structured array with fields x, y, z (and intensity when `min_intensity`
        is given), sensor frame, m.
    radius : maximum horizontal range from the sensor, m (inclusive).
    mount_height, slice_min, slice_max : a point is kept when slice_min <= z + mount_height
        <= slice_max (its height above the water, m).
    min_intensity : keep points with intensity >= this; None keeps all.

    Returns
    -------
    xy : (k, 2) float64 positions of the kept points, sensor frame, m.
    index : (k,) int64 index of each kept point in `points`, ascending (of exact duplicates
        the first is kept).
    """
    radius = real("radius", radius, positive=True)
    mount_height = real("mount_height", mount_height)
    slice_min, slice_max = real("slice_min", slice_min), real("slice_max", slice_max)
    if min_intensity is not None:
        min_intensity = real("min_intensity", min_intensity)
    if not isinstance(points, np.ndarray) or points.dtype.names is None:
        raise TypeError("points: expected a structured array with fields x, y, z")
    missing = {"x", "y", "z"} - set(points.dtype.names)
    if missing:
        raise ValueError(f"points: missing field(s) {sorted(missing)}")
    px, py, pz = points["x"], points["y"], points["z"]
    x = np.asarray(px, dtype=np.float64)
    y = np.asarray(py, dtype=np.float64)
    h = np.asarray(pz, dtype=np.float64) + mount_height
    mask = (x * x + y * y <= radius * radius) & (h >= slice_min) & (h <= slice_max)
    if min_intensity is not None:
        mask &= np.asarray(points["intensity"]) >= min_intensity
    index = np.flatnonzero(mask)
    if index.size > 1:
        # exact duplicates: sort on the coordinates' bit patterns (+0.0 folds -0.0 into 0.0)
        cols = [np.ascontiguousarray(np.asarray(c)[index] + 0.0) for c in (pz, py, px)]
        keys = [c.view(f"u{c.dtype.itemsize}") for c in cols]
        order = np.lexsort(keys)
        new = np.ones(order.size, dtype=bool)
        new[1:] = np.any([k[order[1:]] != k[order[:-1]] for k in keys], axis=0)
        index = index[np.sort(order[new])]
    return np.column_stack([x[index], y[index]]), index


# --------------------------------------------------------------------------------------
# frames and poses
# --------------------------------------------------------------------------------------
def _pose(name: str, pose) -> np.ndarray:
    p = as_float_array(name, pose, ndim=1)
    if p.shape != (3,):
        raise ValueError(f"{name}: expected (north, east, heading), got shape {p.shape}")
    return p


def _xy(name: str, value) -> np.ndarray:
    a = as_float_array(name, value)
    if a.ndim > 2 or a.size % 2 or (a.ndim == 2 and a.shape[1] != 2):
        raise DimensionError(f"{name}: expected shape (n, 2), got {a.shape}")
    return a.reshape(-1, 2)


def _lever(name: str, value) -> np.ndarray:
    a = as_float_array(name, value)
    if a.shape != (2,):
        raise DimensionError(f"{name}: expected (forward, starboard) m, got shape {a.shape}")
    return a


def sensor_to_world(
    xy: np.ndarray,
    pose,
    *,
    lever_arm: tuple[float, float] = (0.0, 0.0),
    mount_yaw: float = 0.0,
) -> np.ndarray:
    """(n, 2) sensor-frame points (x forward, y left, m) -> (n, 2) world (north, east, m).

    `pose` = (north, east, heading rad clockwise from north) of the vessel; the sensor sits
    at `lever_arm` (forward, starboard) and is yawed by `mount_yaw` (clockwise).
    """
    n0, e0, psi = _pose("pose", pose)
    xy = _xy("xy", xy)
    (lx, ly), mount_yaw = _lever("lever_arm", lever_arm), real("mount_yaw", mount_yaw)
    # sensor (x fwd, y left) -> body FRD (x fwd, y starboard), then the mount yaw
    cm, sm = np.cos(mount_yaw), np.sin(mount_yaw)
    bx = lx + cm * xy[:, 0] + sm * xy[:, 1]
    by = ly + sm * xy[:, 0] - cm * xy[:, 1]
    c, s = np.cos(psi), np.sin(psi)
    return np.column_stack([n0 + c * bx - s * by, e0 + s * bx + c * by])


def world_to_sensor(
    ne: np.ndarray,
    pose,
    *,
    lever_arm: tuple[float, float] = (0.0, 0.0),
    mount_yaw: float = 0.0,
) -> np.ndarray:
    """Inverse of `sensor_to_world`: (n, 2) world (north, east) -> sensor (x fwd, y left)."""
    n0, e0, psi = _pose("pose", pose)
    ne = _xy("ne", ne)
    (lx, ly), mount_yaw = _lever("lever_arm", lever_arm), real("mount_yaw", mount_yaw)
    c, s = np.cos(psi), np.sin(psi)
    dn, de = ne[:, 0] - n0, ne[:, 1] - e0
    bx = c * dn + s * de - lx
    by = -s * dn + c * de - ly
    cm, sm = np.cos(mount_yaw), np.sin(mount_yaw)
    return np.column_stack([cm * bx + sm * by, sm * bx - cm * by])


def sensor_motion(
    previous_pose,
    pose,
    *,
    lever_arm: tuple[float, float] = (0.0, 0.0),
    mount_yaw: float = 0.0,
) -> tuple[float, float, float]:
    """Sensor motion between two vessel poses as (dx, dy, dyaw) for `move_segments`.

    (dx, dy): new sensor position in the previous sensor frame (m, x forward, y left);
    dyaw: rotation counter-clockwise seen from above (rad) = −Δheading, wrapped to (−π, π].
    """
    p0 = _pose("previous_pose", previous_pose)
    p1 = _pose("pose", pose)
    origin = sensor_to_world(np.zeros((1, 2)), p1, lever_arm=lever_arm, mount_yaw=mount_yaw)
    d = world_to_sensor(origin, p0, lever_arm=lever_arm, mount_yaw=mount_yaw)[0]
    dyaw = -float(np.angle(np.exp(1j * (p1[2] - p0[2]))))
    return float(d[0]), float(d[1]), dyaw


# --------------------------------------------------------------------------------------
# the detector
# --------------------------------------------------------------------------------------
@dataclass
class FrameResult:
    """Intermediate products of one frame (sensor frame unless noted).

    xy / index : prefiltered points within `radius` (k, 2) and their indices in the frame;
    image : blurred raster (of the points up to radius + line_margin); new_segments : LSD
    output this frame; segments : active line memory; los_segments : the memory extended
    by `segment_extension`, as given to the line-of-sight filter; keep : (k,) mask of
    points that passed it; world : (j, 2) kept points in the world frame (north, east);
    cycle : a `CycleResult` when this frame closed a buffer, else None.
    """

    stamp: float
    pose: np.ndarray
    xy: np.ndarray
    index: np.ndarray
    image: np.ndarray
    new_segments: np.ndarray
    segments: np.ndarray
    los_segments: np.ndarray
    keep: np.ndarray
    world: np.ndarray
    cycle: CycleResult | None = None


@dataclass
class CycleResult:
    """One buffered clustering cycle.

    points : (n, 2) buffered world points; frame_index / point_index : (n,) where each
    point came from (stream index of the frame, index in that frame's points); labels :
    (n,) cluster of each point (−1: none kept); centres : mean-shift centres;
    detections : kept clusters as `LidarDetection`s (and moving vessels' with
    `LidarConfig.vessels`); vessels : the `VesselCandidate`s judged moving vessels; stamp :
    time of the last frame.
    """

    stamp: float
    points: np.ndarray
    frame_index: np.ndarray
    point_index: np.ndarray
    labels: np.ndarray
    centres: np.ndarray
    detections: list[LidarDetection] = field(default_factory=list)
    vessels: list[Any] = field(default_factory=list)


class LidarDetector:
    """Run the LiDAR chain frame by frame: `process(frame, pose)` -> `FrameResult`.

    Every `config.buffer_frames` frames the buffered world points are clustered and the
    result (with its detections) is attached to that frame's `FrameResult.cycle`; the
    buffer then starts afresh.

    stage_timer: optional callable `stage_timer(name)` returning a context manager that times
    the stage named lidar.prefilter, lidar.lines, lidar.line_memory, lidar.line_of_sight or
    lidar.mean_shift (e.g. the pipeline's StageTimer); line_of_sight: the filter function
    (default the Rust sweep `line_of_sight_filter`; `line_of_sight_filter_numpy` for the
    reference implementation), same signature.
    """

    def __init__(
        self,
        config: LidarConfig | None = None,
        *,
        stage_timer: Callable[[str], AbstractContextManager] | None = None,
        line_of_sight: Callable[..., Any] | None = None,
    ) -> None:
        from usvfast.lidar.line_of_sight import line_of_sight_filter

        self.config = config or LidarConfig()
        self._stage = stage_timer or (lambda name: nullcontext())
        self._line_of_sight = line_of_sight or line_of_sight_filter
        self.memory = LineMemory(self.config.line_memory_frames, self.config.cover_tolerance)
        self._previous_pose: np.ndarray | None = None
        # per buffered frame: world points (k, 2), frame index, point indices, heights (k,)
        self._buffer: list[tuple[np.ndarray, int, np.ndarray, np.ndarray]] = []
        self._frames = 0
        self._removed = (np.zeros((0, 2)), np.zeros(2))
        self.vessel_finder: VesselFinder | None = None
        if self.config.vessels:
            cfg = self.config
            self.vessel_finder = VesselFinder(
                radius=cfg.radius,
                beam=cfg.vessel_beam,
                length=cfg.vessel_length,
                max_length=cfg.vessel_max_length,
                min_speed=cfg.vessel_min_speed,
            )

    def reset(self) -> None:
        """Forget line memory, buffer and previous pose."""
        self.memory.reset()
        self._previous_pose = None
        self._buffer = []
        self._frames = 0
        if self.vessel_finder is not None:
            self.vessel_finder.reset()

    def process(self, frame: LidarFrame, pose) -> FrameResult:
        """Run every stage on one frame taken at vessel `pose` (north, east, heading rad)."""
        cfg, stage = self.config, self._stage
        pose = _pose("pose", pose)
        mount = {"lever_arm": cfg.lever_arm, "mount_yaw": cfg.mount_yaw}
        line_radius = cfg.radius + cfg.line_margin
        with stage("lidar.prefilter"):
            xy, index = prefilter(
                frame.points,
                radius=line_radius,
                mount_height=cfg.mount_height,
                slice_min=cfg.slice_min,
                slice_max=cfg.slice_max,
                min_intensity=cfg.min_intensity,
            )
        with stage("lidar.lines"):
            image = blur(rasterize(xy, radius=line_radius, pixel=cfg.pixel))
            new = detect_segments(
                image, radius=line_radius, pixel=cfg.pixel, min_length=cfg.min_segment_length
            )
        inside = (xy**2).sum(axis=1) <= cfg.radius**2
        xy, index = xy[inside], index[inside]
        with stage("lidar.line_memory"):
            motion = (0.0, 0.0, 0.0)
            if self._previous_pose is not None:
                motion = sensor_motion(self._previous_pose, pose, **mount)
            segments = self.memory.update(new, motion)
            self._previous_pose = pose
            los_segments = extend_segments(segments, cfg.segment_extension)
        with stage("lidar.line_of_sight"):
            keep = np.zeros(0, dtype=bool)
            if xy.shape[0]:
                keep = np.asarray(
                    self._line_of_sight(
                        xy, los_segments, sensor=(0.0, 0.0), tolerance=cfg.los_tolerance
                    ),
                    dtype=bool,
                )
            world = sensor_to_world(xy[keep], pose, **mount)
        if self.vessel_finder is not None and len(self._buffer) + 1 >= cfg.buffer_frames:
            # the cycle's last frame: the removed points, for the vessel finder
            sensor = sensor_to_world(np.zeros((1, 2)), pose, **mount)[0]
            self._removed = (sensor_to_world(xy[~keep], pose, **mount), sensor)
        heights = np.asarray(frame.points["z"], dtype=np.float64)[index[keep]] + cfg.mount_height
        self._buffer.append((world, frame.index, index[keep], heights))
        self._frames += 1
        result = FrameResult(
            frame.stamp, pose, xy, index, image, new, segments, los_segments, keep, world
        )
        if len(self._buffer) >= cfg.buffer_frames:
            with stage("lidar.mean_shift"):
                result.cycle = self._cluster(frame.stamp)
            self._buffer = []
        return result

    def _cluster(self, stamp: float) -> CycleResult:
        cfg = self.config
        points = np.vstack([b[0] for b in self._buffer]).reshape(-1, 2)
        frame_index = np.concatenate(
            [np.full(b[0].shape[0], b[1], dtype=np.int64) for b in self._buffer]
        )
        point_index = np.concatenate([b[2] for b in self._buffer]).astype(np.int64)
        heights = np.concatenate([b[3] for b in self._buffer])
        detections, labels, centres = cluster_detections(
            points,
            time=stamp,
            bandwidth=cfg.bandwidth,
            min_cluster_points=cfg.min_cluster_points,
            min_position_std=cfg.min_position_std,
            core_radius=cfg.core_radius,
            small_cluster_points=cfg.small_cluster_points,
            small_cluster_radius=cfg.small_cluster_radius,
            bin_seeding=cfg.bin_seeding,
            cluster_all=cfg.cluster_all,
            backend=cfg.backend,
            sensor_id=cfg.sensor_id,
            heights=heights,
        )
        result = CycleResult(stamp, points, frame_index, point_index, labels, centres, detections)
        if self.vessel_finder is not None:
            self._add_vessels(result)
        return result

    def _add_vessels(self, result: CycleResult) -> None:
        """Moving vessels among the last frame's removed points: their detections replace
        the mean-shift detections that lie on their hulls (within 0.5 m of the hull's
        outline)."""
        finder = self.vessel_finder
        if finder is None:
            return
        removed, sensor = self._removed
        result.vessels = finder.update(removed, result.stamp, sensor)
        for cand in result.vessels:
            centre, cov = finder.detection(cand, sensor)
            u = cand.axis
            n = np.array([-u[1], u[0]])
            half_len = finder.hull_length(cand) / 2 + 0.5
            half_beam = finder.beam / 2 + 0.5
            result.detections = [
                d
                for d in result.detections
                if d.extended
                or abs(float((d.position - centre) @ u)) > half_len
                or abs(float((d.position - centre) @ n)) > half_beam
            ]
            result.detections.append(
                LidarDetection(
                    result.stamp, centre, cov, cand.n_points, self.config.sensor_id, True
                )
            )
