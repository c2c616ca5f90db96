"""Shared time helpers: ROS stamps against rosbags' own Time type, ISO text against
datetime.strftime (the formats the inspect and bearing CLIs printed before)."""

from __future__ import annotations

from datetime import datetime, timezone

from hypothesis import given
from hypothesis import strategies as st
from rosbags.typesys import Stores, get_typestore

from usvfast._time import ros_stamp_seconds, unix_to_iso

Time = get_typestore(Stores.ROS2_HUMBLE).types["builtin_interfaces/msg/Time"]


@given(st.integers(0, 2**31 - 1), st.integers(0, 999_999_999))
def test_ros_stamp_seconds(sec, nanosec):
    t = ros_stamp_seconds(Time(sec=sec, nanosec=nanosec))
    assert isinstance(t, float)
    assert abs(t - (sec + nanosec / 1e9)) <= 1e-6
    assert abs((t - sec) * 1e9 - nanosec) < 500


@given(st.floats(0.0, 4e9))
def test_unix_to_iso(t):
    dt = datetime.fromtimestamp(t, tz=timezone.utc)
    assert unix_to_iso(t) == dt.strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3]
    assert unix_to_iso(t, sep=" ") == dt.strftime("%Y-%m-%d %H:%M:%S.%f")[:-3]


def test_unix_to_iso_example():
    assert unix_to_iso(1306933631.5) == "2011-06-01T13:07:11.500"
