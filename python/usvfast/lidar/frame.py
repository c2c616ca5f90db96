"""The LiDAR frame type shared by the readers, the simulator and the pipeline.

One frame is one sensor rotation: a numpy structured array of points with the fields of
`POINT_DTYPE` plus the frame timestamp. Point coordinates are in the sensor frame as
Velodyne delivers them (x forward, y left, z up, metres); `time` is the offset of each
point from the frame timestamp in seconds (negative before it, as velodyne-decoder and the
ROS velodyne driver report it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Fields of one LiDAR point: position (m, sensor frame, x forward / y left / z up),
#: intensity (sensor units, 0..255 for Velodyne), ring (laser index ordered by elevation,
#: 0 = lowest), time (s relative to the frame stamp).
POINT_DTYPE = np.dtype(
    [
        ("x", "<f4"),
        ("y", "<f4"),
        ("z", "<f4"),
        ("intensity", "<f4"),
        ("ring", "<u2"),
        ("time", "<f4"),
    ]
)


@dataclass
class LidarFrame:
    """One rotation of a spinning LiDAR.

    Attributes
    ----------
    stamp : float
        Frame timestamp, UNIX seconds (UTC).
    points : (n,) structured array of `POINT_DTYPE`.
    source : str
        Where the frame came from (file name, topic, "simulator").
    index : int
        Position of the frame in its stream (0-based).
    """

    stamp: float
    points: np.ndarray
    source: str = ""
    index: int = 0
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return int(self.points.shape[0])

    @property
    def xyz(self) -> np.ndarray:
        """(n, 3) float64 positions in the sensor frame, metres."""
        p = self.points
        return np.column_stack([p["x"], p["y"], p["z"]]).astype(np.float64)


def make_points(
    x: np.ndarray,
    y: np.ndarray,
    z: np.ndarray,
    intensity: np.ndarray | float = 0.0,
    ring: np.ndarray | int = 0,
    time: np.ndarray | float = 0.0,
) -> np.ndarray:
    """Pack columns into a (n,) structured array of `POINT_DTYPE` (scalars broadcast)."""
    n = np.asarray(x).shape[0]
    out = np.empty(n, dtype=POINT_DTYPE)
    out["x"] = x
    out["y"] = y
    out["z"] = z
    out["intensity"] = intensity
    out["ring"] = ring
    out["time"] = time
    return out
