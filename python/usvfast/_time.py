"""Time conversions shared by the readers and CLIs: ROS stamps and UNIX seconds as text."""

from __future__ import annotations

from datetime import datetime, timezone
from typing import Any

__all__ = ["ros_stamp_seconds", "unix_to_iso"]


def ros_stamp_seconds(stamp: Any) -> float:
    """UNIX seconds (float) of a ROS `builtin_interfaces/Time` (ROS 1 and 2 as rosbags
    deserialises them: integer fields `sec` and `nanosec`)."""
    return float(stamp.sec) + float(stamp.nanosec) * 1e-9


def unix_to_iso(t: float, sep: str = "T") -> str:
    """UNIX seconds -> ISO 8601 UTC text without the offset, to the millisecond (truncated),
    e.g. `2011-06-01T13:07:11.500`; `sep` between date and time."""
    return (
        datetime.fromtimestamp(t, tz=timezone.utc)
        .replace(tzinfo=None)
        .isoformat(sep=sep, timespec="milliseconds")
    )
