"""LiDAR floating-object detection (issue 4): line-of-sight filtering and clustering.

Each stage is a separate function; the Rust hot paths are the line-of-sight filter
(`line_of_sight_filter`) and the flat-kernel mean shift.
"""

from usvfast.lidar.clustering import mean_shift
from usvfast.lidar.line_of_sight import (
    line_of_sight_filter,
    line_of_sight_filter_naive,
    line_of_sight_filter_numpy,
)

__all__ = [
    "line_of_sight_filter",
    "line_of_sight_filter_naive",
    "line_of_sight_filter_numpy",
    "mean_shift",
]
