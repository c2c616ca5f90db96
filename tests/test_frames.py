"""Frames against scipy.spatial.transform.Rotation (ZYX = eq. 3.9), sensor → NED against a
plain numpy composition of eq. 3.10 transforms, dual-antenna heading against pymap3d."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy.spatial.transform import Rotation

from usvfast import DimensionError, NonFiniteError
from usvfast.frames import (
    Mount,
    bearing_range,
    dual_antenna_heading,
    euler_angles,
    relative_bearing,
    rotation_matrix,
    se3,
    sensor_to_ned,
)

angle = st.floats(-np.pi, np.pi)
pitch_s = st.floats(-1.5, 1.5)


@given(angle, pitch_s, angle)
def test_rotation_equals_scipy_zyx(roll, pitch, yaw):
    ours = rotation_matrix(roll, pitch, yaw)
    ref = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
    np.testing.assert_allclose(ours, ref, atol=1e-14)
    r, p, y = euler_angles(ours)
    sr = Rotation.from_matrix(ours).as_euler("ZYX")
    # Equal as angles: ±π are the same yaw/roll.
    diff = (np.array([y, p, r]) - sr + np.pi) % (2 * np.pi) - np.pi
    np.testing.assert_allclose(diff, 0.0, atol=1e-9)
    np.testing.assert_allclose(rotation_matrix(r, p, y), ours, atol=1e-12)


@given(
    hnp.arrays(np.float64, (7, 3), elements=st.floats(-50, 50)),
    st.tuples(angle, pitch_s, angle),
    st.tuples(angle, pitch_s, angle),
    hnp.arrays(np.float64, 3, elements=st.floats(-5, 5)),
    hnp.arrays(np.float64, 3, elements=st.floats(-1e3, 1e3)),
)
def test_sensor_to_ned_equals_composed_transforms(points, mount_rpy, pose_rpy, lever, pos):
    mount = Mount(lever_arm=lever, roll=mount_rpy[0], pitch=mount_rpy[1], yaw=mount_rpy[2])
    ours = sensor_to_ned(points, mount, *pose_rpy, pos)
    # Eq. 3.10 twice, homogeneous coordinates, and scipy for the rotations.
    t = se3(*pose_rpy, pos) @ mount.matrix
    hom = np.c_[points, np.ones(len(points))]
    np.testing.assert_allclose(ours, (t @ hom.T).T[:, :3], atol=1e-9)
    rs = Rotation.from_euler("ZYX", pose_rpy[::-1])
    rm = Rotation.from_euler("ZYX", mount_rpy[::-1])
    np.testing.assert_allclose(ours, rs.apply(rm.apply(points) + lever) + pos, atol=1e-9)


def test_per_point_poses():
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(5, 3))
    yaw = rng.uniform(-3, 3, 5)
    pos = rng.normal(size=(5, 3))
    mount = Mount(lever_arm=[1.0, 0.0, -2.0], yaw=0.3)
    many = sensor_to_ned(pts, mount, 0.1, 0.0, yaw, pos)
    for i in range(5):
        one = sensor_to_ned(pts[i : i + 1], mount, 0.1, 0.0, yaw[i], pos[i])
        np.testing.assert_array_equal(many[i], one[0])


def test_known_geometry():
    # Sensor 2 m forward and 1 m up, vessel heading east: 10 m ahead of it is 12 m east.
    out = sensor_to_ned(
        [[10.0, 0.0, 0.0]], Mount([2.0, 0.0, -1.0]), 0.0, 0.0, np.pi / 2, [100, 50, 0]
    )
    np.testing.assert_allclose(out, [[100.0, 62.0, -1.0]], atol=1e-12)


def test_bad_input():
    with pytest.raises(DimensionError, match="points"):
        sensor_to_ned([[1.0, 2.0]], Mount(), 0, 0, 0, [0, 0, 0])
    with pytest.raises(DimensionError, match="yaw"):
        sensor_to_ned(np.zeros((3, 3)), Mount(), 0, 0, [0, 1], [0, 0, 0])
    with pytest.raises(NonFiniteError, match="roll"):
        sensor_to_ned(np.zeros((3, 3)), Mount(), np.nan, 0, 0, [0, 0, 0])


def test_no_points_give_empty_output():
    # Used to panic in Rust (PanicException) indexing the empty pose arrays.
    out = sensor_to_ned(np.zeros((0, 3)), Mount(), [], [], [], np.zeros((0, 3)))
    assert out.shape == (0, 3)
    out = sensor_to_ned(np.zeros((0, 3)), Mount(), 0.1, 0.2, 0.3, [1.0, 2.0, 3.0])
    assert out.shape == (0, 3)
    # With points, an empty pose is a shape error naming the argument.
    with pytest.raises(DimensionError, match="roll"):
        sensor_to_ned(np.zeros((2, 3)), Mount(), [], 0, 0, [0, 0, 0])
    with pytest.raises(DimensionError, match="position_ned"):
        sensor_to_ned(np.zeros((2, 3)), Mount(), 0, 0, 0, np.zeros((0, 3)))


@pytest.mark.parametrize("field", ["roll", "pitch", "yaw"])
def test_non_finite_mount_is_rejected(field):
    # Used to give NaN output silently.
    with pytest.raises(NonFiniteError, match=rf"Mount\.{field}"):
        Mount(**{field: np.nan})
    with pytest.raises(NonFiniteError, match=r"Mount\.lever_arm"):
        Mount(lever_arm=[0.0, np.inf, 0.0])


@given(st.floats(-80, 80), st.floats(-180, 180), st.floats(0, 2 * np.pi - 1e-9), st.floats(0.5, 20))
def test_dual_antenna_heading(lat, lon, heading, baseline):
    # Place the fore antenna with pymap3d along the heading, recover it.
    aft = (lat, lon, 10.0)
    fore = pymap3d.ned2geodetic(baseline * np.cos(heading), baseline * np.sin(heading), 0.0, *aft)
    h, b = dual_antenna_heading(aft, fore)
    assert b == pytest.approx(baseline, abs=1e-6)
    diff = (h - heading + np.pi) % (2 * np.pi) - np.pi
    assert abs(diff) < 1e-6
    # A baseline mounted athwartships (pointing to starboard) shifts the heading by -90°.
    h2, _ = dual_antenna_heading(aft, fore, baseline_yaw=np.pi / 2)
    assert abs(((h2 - heading + np.pi / 2) + np.pi) % (2 * np.pi) - np.pi) < 1e-6


def test_bearing_range_and_relative_bearing():
    b, r = bearing_range([[0.0, 0.0], [10.0, 10.0]], [[0.0, 5.0], [7.0, 6.0]])
    np.testing.assert_allclose(b, [np.pi / 2, np.pi + np.arctan2(4, 3)])
    np.testing.assert_allclose(r, [5.0, 5.0])
    np.testing.assert_allclose(
        relative_bearing([0.1, 3.0, 6.0], [6.2, 0.0, 0.5]),
        [0.1 - 6.2 + 2 * np.pi, 3.0, 5.5 - 2 * np.pi],
    )
