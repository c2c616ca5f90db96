"""The heading calibration of `Pipeline.run`: the recording's first seconds of LiDAR, levelled
and de-skewed as the LiDAR chain does it, their points above the water kept (quays, piers,
moored boats, buildings), and `usvfast.nav.heading_offset.estimate_heading_offset` over them.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from usvfast.frames import Mount
from usvfast.nav.heading_offset import HeadingOffset, estimate_heading_offset
from usvfast.nav.replay import Replay
from usvfast.pipeline.config import PipelineConfig
from usvfast.pipeline.lidar_chain import LidarChain, deskew_motion, level_points
from usvfast.pipeline.pose import NavTrack

__all__ = ["calibrate_heading", "static_points"]

#: Static returns: at least this high above the water (m; floats and waves stay below), and
#: between these ranges from the sensor (m; the own hull inside, sparse rings beyond).
MIN_HEIGHT = 0.5
MIN_RANGE = 3.0
MAX_RANGE = 40.0


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


def calibrate_heading(
    config: PipelineConfig,
    nav: NavTrack,
    chains: dict[str, LidarChain],
    seconds: float,
    stride: int = 5,
) -> HeadingOffset:
    """The heading correction (degrees, to add to `nav`'s heading) from every `stride`-th
    frame of the LiDAR streams of `chains` (stream id -> its chain: mount and the reference
    point's height above the water) over the recording's first `seconds` s. Not observable
    (offset NaN) when no frame has a point above the water."""
    replay = Replay(
        config.recording,
        pose_track=SimpleNamespace(pose_at=nav.pose_at),  # type: ignore[arg-type]
        skip_without_pose=True,
        streams=list(chains),
        start=nav.start,
        end=nav.start + seconds,
    )
    points: list[np.ndarray] = []
    poses: list[tuple[float, float, float]] = []
    for k, message in enumerate(replay):
        if k % stride:
            continue
        frame, pose = message.data, message.pose
        chain = chains[message.stream]
        motion = deskew_motion(frame.points, frame.stamp, pose, nav.pose_at)
        levelled = level_points(frame.points, chain.mount, pose.roll, pose.pitch, motion)
        points.append(static_points(levelled, chain.mount, chain.config.mount_height))
        poses.append((pose.north, pose.east, pose.heading))
    if not any(len(p) for p in points):
        empty = np.zeros(0)
        return HeadingOffset(float("nan"), len(points), 0, 0.0, 1.0, False, empty, empty)
    return estimate_heading_offset(points, np.array(poses))
