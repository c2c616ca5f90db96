"""The LiDAR chain of the pipeline: level the frame with the vessel's roll and pitch and the
sensor mount, then the thesis's chain (`usvfast.lidar.LidarDetector`: prefilter -> raster +
LSD -> line memory -> line-of-sight -> buffered mean shift), each stage timed.

Frames: Velodyne points (x forward, y left, z up) -> sensor FRD (y, z flipped) -> body FRD by
the mount (`R_mount p + lever_arm`) -> level (roll and pitch removed) -> the detector's frame:
level axes, horizontal origin at the mount's lever arm, z up from the vessel reference point,
whose height above the water is `waterline_height`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from usvfast.frames import Mount, rotation_matrix
from usvfast.lidar.frame import LidarFrame
from usvfast.lidar.pipeline import (
    LidarConfig,
    LidarDetection,
    LidarDetector,
)
from usvfast.pipeline.pose import VesselPose
from usvfast.pipeline.timing import StageTimer

__all__ = ["LidarChain", "deskew_motion", "level_points"]

_FLU_FRD = np.diag([1.0, -1.0, -1.0])
_DETECTOR_KEYS = set(LidarConfig.__dataclass_fields__) - {"lever_arm", "mount_yaw", "sensor_id"}


def level_points(
    points: np.ndarray,
    mount: Mount,
    roll: float,
    pitch: float,
    motion: tuple[np.ndarray, np.ndarray, np.ndarray, float] | None = None,
) -> np.ndarray:
    """Structured Velodyne points (n,) -> the same fields with x, y, z in the detector's
    levelled frame at the frame's stamp (x forward along the heading, y left, z up from the
    vessel reference point, horizontal origin at the mount's lever arm), metres.

    motion: per point (d_north (n,), d_east (n,), d_heading (n,)) of the vessel at the point's
    firing time relative to the stamp (m, m, rad), and the heading at the stamp (rad): the
    rotation is de-skewed, each point is placed where the vessel was when it fired."""
    xyz = np.column_stack([points["x"], points["y"], points["z"]]).astype(np.float64)
    lever = np.asarray(mount.lever_arm, dtype=np.float64)
    # level <- body (remove roll, pitch) @ body <- sensor FRD @ sensor FRD <- Velodyne FLU
    r = rotation_matrix(roll, pitch, 0.0) @ mount.rotation @ _FLU_FRD
    level = xyz @ r.T + rotation_matrix(roll, pitch, 0.0) @ lever
    if motion is not None:
        # p_stamp = Rz(-h) (pos_i - pos) + Rz(h_i - h) p_i, horizontal part (level frame at the
        # stamp; dn, de are NED, rotated into it by the stamp heading h).
        dn, de, dh, h = motion
        c, s_ = np.cos(dh), np.sin(dh)
        x = c * level[:, 0] - s_ * level[:, 1]
        y = s_ * level[:, 0] + c * level[:, 1]
        ch, sh = np.cos(h), np.sin(h)
        level[:, 0] = x + ch * dn + sh * de
        level[:, 1] = y - sh * dn + ch * de
    out = points.copy()
    out["x"] = level[:, 0] - lever[0]
    out["y"] = -(level[:, 1] - lever[1])
    out["z"] = -level[:, 2]
    return out


def deskew_motion(
    points: np.ndarray,
    stamp: float,
    pose: VesselPose,
    pose_at: Callable[[float], VesselPose | None] | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float] | None:
    """The `motion` argument of `level_points` for a frame's points (their `time` field: s
    relative to the frame's stamp, <= 0): the vessel's motion from the first firing to the
    stamp, linear in time, from `pose` (at the stamp) and `pose_at(stamp + first firing)`;
    None without `pose_at` or an earlier pose."""
    dt = points["time"].astype(np.float64)
    t0 = float(dt.min()) if len(dt) else 0.0
    start = pose_at(stamp + t0) if pose_at is not None and t0 < 0 else None
    if start is None:
        return None
    f = dt / t0  # 1 at the first firing, 0 at the stamp
    dh = (start.heading - pose.heading + np.pi) % (2 * np.pi) - np.pi
    return (f * (start.north - pose.north), f * (start.east - pose.east), f * dh, pose.heading)


class LidarChain:
    """One LiDAR stream through the chain. `process(frame, pose)` returns the detections of a
    closed clustering cycle (a list of `LidarDetection`, world NED metres with covariance) or
    None between cycles.

    settings: the config's [lidar] table (`los_backend` "rust" or "numpy": the line-of-sight
    filter's implementation, the numpy one being the thesis-style reference; `covariance`
    "spread": each detection's R is its cluster's sample covariance, as LidarDetector gives
    it, or "centroid": that divided by the cluster size, the centroid's standard error; both
    floored at min_position_std², or "model": the measurement model of `_measurement_model`
    (keys surface_offset, range_std, cross_range_std, low_profile_std, low_profile_width,
    low_profile_height, metres; surface_offset_share, dimensionless; reference_points));
    `small_cluster_variance` (> 0, default 1): the factor on the covariance, in any of
    these modes, of a detection kept by the small-cluster rule (`small_cluster_points`);
    mount: the stream's mount (None: at the reference point, level); timer: a StageTimer
    for the per-stage times.
    """

    def __init__(self, settings: dict[str, Any], mount: Mount | None, timer: StageTimer) -> None:
        self.mount = mount or Mount()
        lever = np.asarray(self.mount.lever_arm, dtype=np.float64)
        water = settings.get("waterline_height")
        height = settings.get("mount_height")
        # The detector's frame starts at the reference point's height: its mount_height is
        # the reference point's height above the water.
        if water is None:
            if height is None:
                raise ValueError(
                    "lidar.waterline_height: missing; give the vessel reference point's height "
                    "above the water (or lidar.mount_height, the sensor's)"
                )
            ref_height = float(height) + float(lever[2])
        else:
            ref_height = float(water)
        kw = {k: v for k, v in settings.items() if k in _DETECTOR_KEYS and v is not None}
        kw["mount_height"] = ref_height
        self.config = LidarConfig(
            **kw, lever_arm=(float(lever[0]), float(lever[1])), mount_yaw=0.0, sensor_id="lidar"
        )
        self.timer = timer
        self.covariance = settings.get("covariance", "spread")
        self.surface_offset = float(settings.get("surface_offset", 0.0))
        self.range_std = float(settings.get("range_std", 0.1))
        self.cross_range_std = float(settings.get("cross_range_std", 0.065))
        self.reference_points = float(settings.get("reference_points", 0) or 0)
        self.surface_offset_share = float(settings.get("surface_offset_share", 0.0))
        self.low_profile_std = float(settings.get("low_profile_std", 0.0))
        self.low_profile_width = float(settings.get("low_profile_width", 0.3))
        self.low_profile_height = float(settings.get("low_profile_height", 0.15))
        self.small_cluster_variance = float(settings.get("small_cluster_variance", 1.0))
        for key in (
            "surface_offset",
            "range_std",
            "cross_range_std",
            "reference_points",
            "surface_offset_share",
            "low_profile_std",
        ):
            if not getattr(self, key) >= 0:
                raise ValueError(f"lidar.{key}: expected a number >= 0, got {getattr(self, key)}")
        for key in ("low_profile_width", "low_profile_height", "small_cluster_variance"):
            value = getattr(self, key)
            if not (value > 0 and np.isfinite(value)):
                raise ValueError(f"lidar.{key}: expected a number > 0, got {value}")
        if self.covariance == "model" and not (self.range_std > 0 and self.cross_range_std > 0):
            raise ValueError(
                "lidar.range_std, lidar.cross_range_std: must be > 0 with covariance = model"
            )
        self._reach2 = (self.config.radius + self.config.line_margin + 1.0) ** 2
        from usvfast.lidar.line_of_sight import line_of_sight_filter_numpy

        numpy_los = settings.get("los_backend", "rust") == "numpy"
        self.detector = LidarDetector(
            self.config,
            stage_timer=timer,
            line_of_sight=line_of_sight_filter_numpy if numpy_los else None,
        )
        self.frames = 0

    def process(
        self,
        frame: LidarFrame,
        pose: VesselPose,
        pose_at: Callable[[float], VesselPose | None] | None = None,
    ) -> list[LidarDetection] | None:
        """Level the frame at `pose` (de-skewed with `pose_at(t)`, the vessel pose at any
        time, when given), run one frame of the chain; detections when the buffer of
        `buffer_frames` frames closes (their time: this frame's stamp)."""
        with self.timer("lidar.level"):
            # Only points that can reach the raster (radius + line margin, plus 1 m for the
            # tilt) are levelled.
            p = frame.points[frame.points["x"] ** 2 + frame.points["y"] ** 2 <= self._reach2]
            motion = deskew_motion(p, frame.stamp, pose, pose_at)
            points = level_points(p, self.mount, pose.roll, pose.pitch, motion)
        levelled = LidarFrame(frame.stamp, points, frame.source, self.frames)
        self.frames += 1
        result = self.detector.process(levelled, pose.planar)
        if result.cycle is None:
            return None
        dets = result.cycle.detections
        if self.covariance == "model":
            self._measurement_model(dets, pose)
        elif self.covariance == "centroid":
            # The centroid's standard error (spread / n), floored at min_position_std².
            floor = self.config.min_position_std**2
            for d in dets:
                if d.extended:
                    continue
                w, v = np.linalg.eigh(d.covariance / max(d.n_points, 1))
                d.covariance = (v * np.maximum(w, floor)) @ v.T
        if self.small_cluster_variance != 1.0:
            # A cluster kept by the small-cluster rule is one ring's partial hit: its centroid
            # lies somewhere on the object's seen outline, not where many hits average out.
            for d in dets:
                if d.small:
                    d.covariance = d.covariance * self.small_cluster_variance
        return dets

    def _measurement_model(self, dets: list[LidarDetection], pose: VesselPose) -> None:
        """Per-detection measurement model, in place (in the frame of the horizontal line of
        sight u from the sensor to the cluster's centroid: along u, and across it).

        Centre. A cluster's points lie on the surface the sensor sees, so their centroid is
        nearer than the object's centre (for a round object of radius rho the visible-surface
        centroid lies pi/4 rho short of it): the centroid is moved away from the sensor along
        u by `surface_offset + surface_offset_share * b` metres, where b = sqrt(3) s_c is the
        cluster's seen half-width (s_c, m: the members' standard deviation across u, without
        the min_position_std floor; a uniformly covered width W has s_c = W / sqrt(12)): a
        bigger object's centre lies further behind its seen surface.

        Covariance, diag(s_along², s_across²) in the (u, across) frame, m²: the random error
        of one cycle's centroid (VLP-16 range noise, beam spread, the de-skewing of the
        buffered rotations), `range_std` along and `cross_range_std` across, both times
        sqrt(reference_points / n) for a cluster of n < reference_points points (a float
        that one beam grazes: which part of its surface is hit varies more than the mean of
        many hits); plus, along u only, a low-profile term
        `low_profile_std * (W / low_profile_width)² * max(0, 1 - top / low_profile_height)`
        (W = 2 b the seen width, top the highest member's height above the water, m): the
        rings reach a low float's top at grazing incidence, so the vessel's heave and pitch
        slide the hits over the top along the line of sight, while a tall object's hits stay
        on its face; a narrow float (a bottle) offers its top to few hits, a wide one (a bag)
        to most (measured on simulated floats: the slide's std is ~0 at W = 0.25 m and
        0.05-0.06 m at W = 0.3-0.45 m, growing faster than W; the square, with its
        coefficient set from the innovations, gives 0.04-0.11 m there: the innovations also
        carry the errors' correlation from cycle to cycle). The two terms add in variance.
        Detections without a spread or a top (built by hand, or a vessel's) get no width
        or low-profile term.

        Errors common to every sensor (the GNSS position and heading biases) are not in it:
        they do not show in the innovations, only against the truth."""
        lx, ly = float(self.mount.lever_arm[0]), float(self.mount.lever_arm[1])
        ch, sh = np.cos(pose.heading), np.sin(pose.heading)
        sensor = np.array([pose.north + ch * lx - sh * ly, pose.east + sh * lx + ch * ly])
        for d in dets:
            if d.extended:
                continue  # a vessel's centre and covariance come from its extent
            los = np.asarray(d.position, dtype=np.float64) - sensor
            r = float(np.hypot(los[0], los[1]))
            u = los / r if r > 1e-9 else np.array([1.0, 0.0])
            basis = np.array([[u[0], -u[1]], [u[1], u[0]]])  # columns: along, across
            half_width = 0.0
            if d.spread is not None:
                across = basis[:, 1]
                half_width = float(np.sqrt(3.0 * max(float(across @ d.spread @ across), 0.0)))
            scale = 1.0
            if self.reference_points > 0 and 0 < d.n_points < self.reference_points:
                scale = self.reference_points / d.n_points
            var_along = self.range_std**2 * scale
            if self.low_profile_std > 0 and d.top is not None:
                low = max(0.0, 1.0 - float(d.top) / self.low_profile_height)
                width = 2.0 * half_width / self.low_profile_width
                var_along += (self.low_profile_std * width * width * low) ** 2
            offset = self.surface_offset + self.surface_offset_share * half_width
            d.position = np.asarray(d.position, dtype=np.float64) + offset * u
            var = np.array([var_along, self.cross_range_std**2 * scale])
            d.covariance = (basis * var) @ basis.T
