"""The GNSS heading carried across its gaps by the IMU's gyro (usvfast.pipeline.gyro_bridge,
`[recording] gyro_heading_bridge`): the heading rate of body rates against scipy's rotations
(the peer), the bridge against the known heading of a turn made inside a gap (with a gyro bias
that the bridge's drift correction must remove), and the option end to end on a small bag."""

from __future__ import annotations

import math

import numpy as np
import pytest
from nav_config import nav_config
from scipy.spatial.transform import Rotation

from usvfast.pipeline import load_config
from usvfast.pipeline.gyro_bridge import bridge_heading_gaps, heading_rates
from usvfast.pipeline.live_pose import LivePose
from usvfast.pipeline.pose import NavigationError, NavTrack

T0 = 1_686_909_600.0
ORIGIN = (63.44, 10.40, 0.0)
# FLU <-> FRD and ENU <-> NED axis swaps (REP-103 to the thesis's frames)
FLU_FRD = np.diag([1.0, -1.0, -1.0])


def attitude(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heading, pitch and roll (rad) of a vessel turning while it rolls and pitches."""
    return 0.3 + 0.4 * np.sin(0.7 * t), 0.05 * np.sin(1.3 * t), 0.08 * np.cos(1.1 * t)


def true_heading(t: np.ndarray) -> np.ndarray:
    return np.mod(1.2 + 0.35 * t + 0.6 * np.sin(0.9 * t), 2 * np.pi)


def true_rate(t: np.ndarray) -> np.ndarray:
    return 0.35 + 0.54 * np.cos(0.9 * t)


def test_heading_rates_against_scipy_rotations():
    t = np.linspace(0.0, 10.0, 2001)
    yaw, pitch, roll = attitude(t)
    r_nb = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_matrix()
    # body rates: the skew part of R^T dR/dt (central differences), FRD -> FLU
    dr = np.gradient(r_nb, t, axis=0)
    skew = np.einsum("kji,kjl->kil", r_nb, dr)
    frd = np.column_stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]])
    flu = frd @ FLU_FRD.T
    rates = heading_rates(flu, roll, pitch)
    expected = np.gradient(np.unwrap(yaw), t)
    np.testing.assert_allclose(rates[5:-5], expected[5:-5], atol=2e-4)
    # level: the heading rate is minus the FLU z rate
    level = heading_rates([[0.1, 0.2, -0.3]], [0.0], [0.0])
    assert level[0] == pytest.approx(0.3)


def test_bridge_follows_a_turn_inside_the_gap_despite_gyro_bias():
    t_gnss = T0 + np.round(np.arange(0.0, 10.0, 0.1), 6)
    keep = (t_gnss - T0 < 4.0) | (t_gnss - T0 > 5.8)  # no heading from 3.9 to 5.9 s
    t_head, head = t_gnss[keep], true_heading(t_gnss[keep] - T0)
    t_imu = T0 + np.arange(0.0, 10.0, 0.02)
    bias = 0.02  # rad/s: the gyro's own
    times, bridged = bridge_heading_gaps(t_head, head, t_imu, true_rate(t_imu - T0) + bias, 0.3)
    inside = (times > t_head[39]) & (times < t_head[40])
    assert inside.sum() == 99  # the 50 Hz IMU samples strictly inside the 2 s gap
    err = np.angle(np.exp(1j * (bridged - true_heading(times - T0))))
    assert np.abs(err).max() < 2e-4  # the bias is removed by the drift correction
    # linear interpolation across the same gap misses the turn by degrees
    lin = np.interp(times[inside], t_head, np.unwrap(head))
    assert np.abs(np.angle(np.exp(1j * (lin - true_heading(times[inside] - T0))))).max() > 0.05
    assert np.all(np.diff(times) > 0) and np.all((bridged >= 0) & (bridged < 2 * np.pi))


def test_bridge_leaves_short_or_uncovered_gaps_and_checks_its_input():
    t = T0 + np.array([0.0, 0.1, 0.2, 1.5, 1.6])
    h = np.array([6.2, 6.25, 6.28, 0.05, 0.1])  # across north
    rt = T0 + np.arange(0.0, 1.0, 0.02)  # the rates end before the gap does
    out_t, out_h = bridge_heading_gaps(t, h, rt, np.zeros(rt.size), 0.3)
    np.testing.assert_array_equal(out_t, t)
    np.testing.assert_array_equal(out_h, h)
    rt = T0 + np.arange(0.0, 2.0, 0.02)
    out_t, out_h = bridge_heading_gaps(t, h, rt, np.zeros(rt.size), 0.3)
    assert out_t.size > t.size and np.all((out_h < 0.2) | (out_h > 6.1))  # the short arc
    with pytest.raises(ValueError, match="rate_times"):
        bridge_heading_gaps(t, h, rt[::-1], np.zeros(rt.size), 0.3)
    with pytest.raises(ValueError, match="headings"):
        bridge_heading_gaps(t, h[:-1], rt, np.zeros(rt.size), 0.3)
    with pytest.raises(ValueError, match="min_gap"):
        bridge_heading_gaps(t, h, rt, np.zeros(rt.size), 0.0)
    with pytest.raises(ValueError, match="rates"):
        bridge_heading_gaps(t, h, rt, np.full(rt.size, np.nan), 0.3)
    with pytest.raises(ValueError, match="angular_velocity_flu"):
        heading_rates(np.zeros((3, 2)), np.zeros(3), np.zeros(3))


def _write_bag(path, with_imu: bool) -> None:
    from rosbags.rosbag2 import Writer

    from usvfast.lidar.readers import make_header
    from usvfast.nav.bags import bag_typestore

    from pipeline_recording import nmea_sentences

    store = bag_typestore()
    types = store.types
    with Writer(path, version=8) as w:
        c_nmea = w.add_connection("/gnss/nmea", "nmea_msgs/msg/Sentence", typestore=store)
        c_imu = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=store)
        for k in range(100):
            t = T0 + 0.1 * k
            if not 40 <= k <= 57 or k == 40:  # 1.8 s without sentences after 4.0 s
                heading = math.degrees(true_heading(np.array(t - T0)))
                for s in nmea_sentences(t, ORIGIN[0], ORIGIN[1], heading):
                    msg = types["nmea_msgs/msg/Sentence"](
                        header=make_header(store, t, "gnss"), sentence=s
                    )
                    w.write(
                        c_nmea, round(t * 1e9), store.serialize_cdr(msg, "nmea_msgs/msg/Sentence")
                    )
            if not with_imu:
                continue
            for j in range(5):
                ti = t + 0.02 * j
                v3 = types["geometry_msgs/msg/Vector3"]
                imu = types["sensor_msgs/msg/Imu"](
                    header=make_header(store, ti, "imu"),
                    orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=np.zeros(9),
                    angular_velocity=v3(x=0.0, y=0.0, z=-float(true_rate(np.array(ti - T0)))),
                    angular_velocity_covariance=np.zeros(9),
                    linear_acceleration=v3(x=0.0, y=0.0, z=9.81),
                    linear_acceleration_covariance=np.zeros(9),
                )
                w.write(c_imu, round(ti * 1e9), store.serialize_cdr(imu, "sensor_msgs/msg/Imu"))


def _config(tmp_path, attitude: bool, bridge: bool):
    recording = 'navigation = "gnss"\n' + ('attitude = "imu"\n' if attitude else "")
    recording += f"origin = [{ORIGIN[0]}, {ORIGIN[1]}, 0.0]\n"
    recording += f"gyro_heading_bridge = {str(bridge).lower()}"
    streams = '[[stream]]\nid = "gnss"\ntype = "bag"\npath = "bag"\ntopic = "/gnss/nmea"\n'
    if attitude:
        streams += '[[stream]]\nid = "imu"\ntype = "bag"\npath = "bag"\ntopic = "/imu/data"\n'
    return load_config(nav_config(tmp_path, recording, streams))


def test_navtrack_bridges_the_heading_gap_with_the_imu(tmp_path):
    _write_bag(tmp_path / "bag", with_imu=True)
    probe = T0 + np.array([4.45, 4.9, 5.35])  # inside the gap, mid-turn
    truth = true_heading(probe - T0)

    def worst(track: NavTrack) -> float:
        h = np.array([track.pose_at(float(t)).heading for t in probe])
        return float(np.degrees(np.abs(np.angle(np.exp(1j * (h - truth))))).max())

    assert worst(NavTrack.from_config(_config(tmp_path, True, True))) < 0.02  # HDT's 0.01 deg
    assert worst(NavTrack.from_config(_config(tmp_path, True, False))) > 1.0  # linear


def test_bridge_without_an_imu_is_an_error(tmp_path):
    _write_bag(tmp_path / "bag", with_imu=False)
    with pytest.raises(NavigationError, match="gyro_heading_bridge needs an attitude"):
        NavTrack.from_config(_config(tmp_path, False, True))


def test_live_pose_carries_the_heading_through_a_gap():
    def live(bridge: bool, until: float) -> LivePose:
        """Headings at 10 Hz up to 4.0 s, then none; the 50 Hz rates (biased) up to `until`."""
        pose = LivePose(ORIGIN, gyro_bridge=bridge)
        for k in range(41):
            t = T0 + 0.1 * k
            pose.add_fix(t, ORIGIN[0], ORIGIN[1], 4)
            pose.add_heading(t, float(true_heading(np.array(t - T0))))
        for ti in T0 + np.arange(0.0, until - T0, 0.02):
            pose.add_heading_rate(float(ti), float(true_rate(np.array(ti - T0)) + 0.005))
        return pose

    def error(bridge: bool, t: float, until: float) -> float:
        h = live(bridge, until).at(t).heading
        return abs(math.degrees(np.angle(np.exp(1j * (h - true_heading(np.array(t - T0)))))))

    for t in T0 + np.array([4.5, 5.0, 5.5]):
        # a sensor message comes 15 ms after the newest IMU sample, as in a replay
        assert error(True, t, t - 0.015) < 0.5  # 0.005 rad/s of bias over 1.5 s: 0.43 deg
    assert error(False, T0 + 5.5, T0 + 5.5) > 3.0  # the last two headings extrapolated
    assert error(True, T0 + 5.5, T0 + 5.3) > 3.0  # rates 0.2 s old: not held that long
    # inside three heading intervals the last two are extrapolated as before
    near = T0 + 4.05
    assert live(True, near).at(near).heading == live(False, near).at(near).heading
