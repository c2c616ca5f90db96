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

from usvfast._core import DimensionError
from usvfast._validate import as_float_array

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
    """Pack columns into a (n,) structured array of `POINT_DTYPE` (scalars broadcast).

    x, y, z: (n,) finite sensor-frame coordinates, m; intensity, time (s relative to the
    frame stamp): (n,) or scalars, finite; ring: (n,) or a scalar, integers >= 0. Raises
    DimensionError / NonFiniteError / TypeError naming the column."""
    cols = {"x": x, "y": y, "z": z}
    for k, v in cols.items():
        if np.ndim(v) != 1:
            raise DimensionError(f"{k}: expected a 1-D array, got shape {np.shape(v)}")
    arrays = {k: as_float_array(k, v, ndim=1) for k, v in cols.items()}
    n = arrays["x"].shape[0]
    for k, v in {"intensity": intensity, "time": time}.items():
        arrays[k] = as_float_array(k, v).reshape(np.shape(v))
    ring_a = np.asarray(ring)
    if ring_a.dtype.kind not in "iu" or (ring_a < 0).any() or (ring_a > 65535).any():
        raise TypeError("ring: expected integers in [0, 65535]")
    arrays["ring"] = ring_a
    for k, v in arrays.items():
        if v.ndim > 1 or (v.ndim == 1 and v.shape[0] != n):
            raise DimensionError(f"{k}: expected shape ({n},) or a scalar, got {v.shape}")
    out = np.empty(n, dtype=POINT_DTYPE)
    for k, v in arrays.items():
        out[k] = v
    return out
