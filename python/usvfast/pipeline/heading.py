"""The heading calibration of the pipeline: the first seconds of LiDAR (of the recording in
`Pipeline.run`, of the live frames in `Pipeline.process`), levelled and de-skewed as the LiDAR
chain does it, their points above the water kept (quays, piers, moored boats, buildings), and
`usvfast.nav.heading_offset.estimate_heading_offset` over them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from types import SimpleNamespace

import numpy as np

from usvfast.frames import Mount
from usvfast.lidar.frame import LidarFrame
from usvfast.nav.heading_offset import HeadingOffset, estimate_heading_offset
from usvfast.nav.replay import Replay
from usvfast.pipeline.config import PipelineConfig
from usvfast.pipeline.lidar_chain import LidarChain, deskew_motion, level_points
from usvfast.pipeline.pose import NavTrack, VesselPose

__all__ = ["HeadingCalibrator", "calibrate_heading", "static_points"]

#: Static returns: at least this high above the water (m; floats and waves stay below), and
#: between these ranges from the sensor (m; the own hull inside, sparse rings beyond).
MIN_HEIGHT = 0.5
MIN_RANGE = 3.0
MAX_RANGE = 40.0
#: The calibration takes every STRIDE-th LiDAR rotation.
STRIDE = 5


def static_points(levelled: np.ndarray, mount: Mount, waterline_height: float) -> np.ndarray:
    """(n, 2) body FRD horizontal coordinates (m, from the vessel reference point) of the
    points of a levelled frame (`level_points`: x forward, y left, z up from the reference
    point, horizontal origin at the mount) that stand `MIN_HEIGHT` m above the water at
    `MIN_RANGE`-`MAX_RANGE` m from the sensor."""
    x, y, z = levelled["x"], levelled["y"], levelled["z"]
    r2 = x * x + y * y
    keep = (z + waterline_height > MIN_HEIGHT) & (r2 > MIN_RANGE**2) & (r2 < MAX_RANGE**2)
    lever = mount.lever_arm
    return np.column_stack([x[keep] + lever[0], lever[1] - y[keep]]).astype(np.float64)


class HeadingCalibrator:
    """Collects the static returns of every `stride`-th LiDAR frame fed to `add` and, once
    the frames span `seconds` s, estimates the heading correction from them
    (`estimate_heading_offset`). Used by `Pipeline.run` over the recording's first seconds
    and by `Pipeline.process` on live frames."""

    def __init__(self, seconds: float, stride: int = STRIDE) -> None:
        self.seconds = float(seconds)
        self.stride = int(stride)
        self.frames = 0
        self.first: float | None = None
        self.points: list[np.ndarray] = []
        self.poses: list[tuple[float, float, float]] = []

    def add(
        self,
        frame: LidarFrame,
        pose: VesselPose,
        pose_at: Callable[[float], VesselPose | None] | None,
        chain: LidarChain,
    ) -> HeadingOffset | None:
        """Take one LiDAR frame (its pose at the stamp, `pose_at` for the de-skewing, its
        chain for the mount and the reference point's height above the water); the estimate
        when this frame closes the `seconds`, else None."""
        if self.first is None:
            self.first = frame.stamp
        if frame.stamp - self.first >= self.seconds:
            return self.estimate()
        if self.frames % self.stride == 0:
            motion = deskew_motion(frame.points, frame.stamp, pose, pose_at)
            levelled = level_points(frame.points, chain.mount, pose.roll, pose.pitch, motion)
            self.points.append(static_points(levelled, chain.mount, chain.config.mount_height))
            self.poses.append((pose.north, pose.east, pose.heading))
        self.frames += 1
        return None

    def estimate(self) -> HeadingOffset:
        """The estimate from the frames taken so far; not observable (offset NaN) when none
        has a point above the water."""
        if not any(len(p) for p in self.points):
            empty = np.zeros(0)
            return HeadingOffset(float("nan"), len(self.points), 0, 0.0, 1.0, False, empty, empty)
        return estimate_heading_offset(self.points, np.array(self.poses))


def calibrate_heading(
    config: PipelineConfig,
    nav: NavTrack,
    chains: dict[str, LidarChain],
    seconds: float,
) -> HeadingOffset:
    """The heading correction (degrees, to add to `nav`'s heading) from the LiDAR streams of
    `chains` (stream id -> its chain) over the recording's first `seconds` s
    (`HeadingCalibrator`). Each stream is read with `every` = STRIDE, so the rotations the
    calibration does not use are not decoded (a bag's are not even read)."""
    calibrator = HeadingCalibrator(seconds, stride=1)
    recording = config.recording
    strided = [
        replace(s, options={**s.options, "every": STRIDE}) if s.id in chains else s
        for s in recording.streams
    ]
    replay = Replay(
        replace(recording, streams=tuple(strided)),
        pose_track=SimpleNamespace(pose_at=nav.pose_at),  # type: ignore[arg-type]
        skip_without_pose=True,
        streams=list(chains),
        start=nav.start,
        end=nav.start + seconds,
    )
    for message in replay:
        calibrator.add(message.data, message.pose, nav.pose_at, chains[message.stream])
    return calibrator.estimate()
