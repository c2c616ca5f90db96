"""ROS bag readers: bags written here with rosbags' own writers (ROS1, ROS2 sqlite3 and mcap),
each with one deliberately corrupt message, read back and compared exactly."""

from __future__ import annotations

import datetime
from pathlib import Path

import cv2
import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2

from usvfast.nav._damage import DamagedRecordsWarning
from usvfast.nav.bags import (
    BagTopic,
    ImuSample,
    NavSatFixSample,
    PoseSample,
    bag_topics,
    bag_typestore,
    read_bag_imu,
    read_bag_navsatfix,
    read_bag_nmea,
    read_bag_poses,
)

T0 = 1_686_909_600  # 2023-06-16 10:00 UTC (the thesis's D3 day)
N = 6


def _msgs(ts, ros2: bool):
    """Messages of every supported kind, with known content, per topic."""
    T = ts.types
    Time = T["builtin_interfaces/msg/Time"]

    def header(i: int, stamp_ns: int | None = None):
        sec, nsec = divmod(T0 * 10**9 + i * 100_000_000 + 1234, 10**9)
        if stamp_ns is not None:
            sec, nsec = divmod(stamp_ns, 10**9)
        kw = {"stamp": Time(sec=sec, nanosec=nsec), "frame_id": "gnss"}
        if not ros2:
            kw["seq"] = i
        return T["std_msgs/msg/Header"](**kw)

    Vec = T["geometry_msgs/msg/Vector3"]
    Quat = T["geometry_msgs/msg/Quaternion"]
    Point = T["geometry_msgs/msg/Point"]
    Pose = T["geometry_msgs/msg/Pose"]
    rng = np.random.default_rng(5)
    out: dict[str, tuple[str, list]] = {}
    fixes = []
    for i in range(N):
        fixes.append(
            T["sensor_msgs/msg/NavSatFix"](
                header=header(i),
                status=T["sensor_msgs/msg/NavSatStatus"](status=i % 3 - 1, service=1),
                latitude=63.4386345 + i * 1e-6,
                longitude=10.3985848 - i * 1e-6,
                altitude=40.0 + i,
                position_covariance=np.arange(9, dtype=np.float64) + i,
                position_covariance_type=2,
            )
        )
    out["/fix"] = ("sensor_msgs/msg/NavSatFix", fixes)
    imus = []
    for i in range(N):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        imus.append(
            T["sensor_msgs/msg/Imu"](
                header=header(i),
                orientation=Quat(x=q[0], y=q[1], z=q[2], w=q[3]),
                orientation_covariance=np.zeros(9),
                angular_velocity=Vec(x=0.1 * i, y=-0.2, z=0.3),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=Vec(x=0.0, y=0.5, z=9.81 + i),
                linear_acceleration_covariance=np.zeros(9),
            )
        )
    out["/imu"] = ("sensor_msgs/msg/Imu", imus)

    def pose(i):
        return Pose(position=Point(x=i, y=2.0 * i, z=-0.5), orientation=Quat(x=0, y=0, z=0, w=1))

    out["/pose"] = (
        "geometry_msgs/msg/PoseStamped",
        [T["geometry_msgs/msg/PoseStamped"](header=header(i), pose=pose(i)) for i in range(N)],
    )
    PWC = T["geometry_msgs/msg/PoseWithCovariance"]
    out["/pose_cov"] = (
        "geometry_msgs/msg/PoseWithCovarianceStamped",
        [
            T["geometry_msgs/msg/PoseWithCovarianceStamped"](
                header=header(i), pose=PWC(pose=pose(i), covariance=np.arange(36.0) * i)
            )
            for i in range(N)
        ],
    )
    Twist = T["geometry_msgs/msg/TwistWithCovariance"](
        twist=T["geometry_msgs/msg/Twist"](linear=Vec(x=1, y=0, z=0), angular=Vec(x=0, y=0, z=0)),
        covariance=np.zeros(36),
    )
    out["/odom"] = (
        "nav_msgs/msg/Odometry",
        [
            T["nav_msgs/msg/Odometry"](
                header=header(i),
                child_frame_id="base_link",
                pose=PWC(pose=pose(i), covariance=np.eye(6).ravel() * (i + 1)),
                twist=Twist,
            )
            for i in range(N)
        ],
    )
    sentences = [
        "$HEHDT,274.07,T*19",
        "$GNGGA,100000.00,6326.31807,N,01023.91509,E,1,12,0.8,40.0,M,41.0,M,,*41",
    ]
    out["/nmea"] = (
        "nmea_msgs/msg/Sentence",
        [
            T["nmea_msgs/msg/Sentence"](header=header(i), sentence=sentences[i % 2])
            for i in range(N)
        ],
    )
    # Images: rgb8 with padded rows, big-endian mono16, and lossless PNG compressed.
    Image = T["sensor_msgs/msg/Image"]
    images = []
    for i in range(N):
        if i % 2 == 0:
            rgb = rng.integers(0, 256, size=(4, 5, 3), dtype=np.uint8)
            step = 5 * 3 + 3
            buf = np.zeros((4, step), np.uint8)
            buf[:, :15] = rgb.reshape(4, 15)
            images.append(
                Image(
                    header=header(i),
                    height=4,
                    width=5,
                    encoding="rgb8",
                    is_bigendian=0,
                    step=step,
                    data=buf.ravel(),
                )
            )
        else:
            depth = rng.integers(0, 65535, size=(3, 4), dtype=np.uint16)
            images.append(
                Image(
                    header=header(i),
                    height=3,
                    width=4,
                    encoding="16UC1",
                    is_bigendian=1,
                    step=8,
                    data=np.frombuffer(depth.astype(">u2").tobytes(), np.uint8),
                )
            )
    out["/image"] = ("sensor_msgs/msg/Image", images)
    comp = []
    for i in range(N):
        bgr = rng.integers(0, 256, size=(6, 7, 3), dtype=np.uint8)
        ok, png = cv2.imencode(".png", bgr)
        assert ok
        comp.append(
            T["sensor_msgs/msg/CompressedImage"](header=header(i), format="png", data=png.ravel())
        )
    out["/image/compressed"] = ("sensor_msgs/msg/CompressedImage", comp)
    # A header stamp of zero: the record time must be used.
    out["/fix_nostamp"] = (
        "sensor_msgs/msg/NavSatFix",
        [
            T["sensor_msgs/msg/NavSatFix"](
                header=header(0, stamp_ns=0),
                status=T["sensor_msgs/msg/NavSatStatus"](status=0, service=1),
                latitude=1.0,
                longitude=2.0,
                altitude=3.0,
                position_covariance=np.zeros(9),
                position_covariance_type=0,
            )
        ],
    )
    return out


CORRUPT_AT = 2  # index of the deliberately corrupt message in every topic


def _write(path: Path, kind: str):
    ros2 = kind != "ros1"
    ts = bag_typestore(ros2=ros2)
    msgs = _msgs(ts, ros2)
    if ros2:
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path, version=9, storage_plugin=plugin)
        serialize = ts.serialize_cdr
    else:
        writer = Writer1(path)
        serialize = ts.serialize_ros1
    with writer:
        for topic, (msgtype, items) in msgs.items():
            conn = writer.add_connection(topic, msgtype, typestore=ts)
            for i, m in enumerate(items):
                record_ns = (T0 + 100) * 10**9 + i * 10**8
                raw = bytes(serialize(m, msgtype))
                if i == CORRUPT_AT:
                    # Truncated in transit: too short for the message type.
                    writer.write(conn, record_ns, raw[:6])
                writer.write(conn, record_ns + 1, raw)
    return msgs


@pytest.fixture(scope="module", params=["ros1", "sqlite3", "mcap"])
def bag(request, tmp_path_factory):
    path = tmp_path_factory.mktemp(request.param) / (
        "run.bag" if request.param == "ros1" else "run"
    )
    msgs = _write(path, request.param)
    return path, msgs


def _read(path, topic, **kw):
    reader = BagTopic(path, topic, **kw)
    if topic == "/fix_nostamp":
        return reader, list(reader)
    with pytest.warns(DamagedRecordsWarning, match="skipped 1 damaged"):
        got = list(reader)
    return reader, got


def _stamp(m):
    return float(m.header.stamp.sec) + float(m.header.stamp.nanosec) * 1e-9


def test_topics_listed(bag):
    path, msgs = bag
    topics = bag_topics(path)
    for topic, (msgtype, items) in msgs.items():
        assert topics[topic].msgtype == msgtype
        n_corrupt = 1 if len(items) > CORRUPT_AT else 0
        assert topics[topic].count == len(items) + n_corrupt


def test_topics_are_read_again_when_the_bag_changes(tmp_path):
    """bag_topics opens a bag once while its files are unchanged; a bag rewritten at the same
    path is read again."""
    ts = bag_typestore(ros2=True)
    path = tmp_path / "run"
    for topic in ("/first", "/second"):
        if path.exists():
            for f in path.iterdir():
                f.unlink()
            path.rmdir()
        with Writer2(path, version=9) as writer:
            writer.add_connection(topic, "std_msgs/msg/String", typestore=ts)
        topics = bag_topics(path)
        assert list(topics) == [topic]
        topics.clear()  # the caller's copy: the next call is unaffected
        assert list(bag_topics(path)) == [topic]


def test_navsatfix_exact(bag):
    path, msgs = bag
    reader, got = _read(path, "/fix")
    src = msgs["/fix"][1]
    assert reader.damaged == 1 and len(got) == len(src) == reader.yielded
    for m, s in zip(got, src, strict=True):
        assert isinstance(m.data, NavSatFixSample)
        assert m.time == _stamp(s)
        assert (m.data.lat_deg, m.data.lon_deg, m.data.alt_m) == (
            s.latitude,
            s.longitude,
            s.altitude,
        )
        assert m.data.status == s.status.status
        np.testing.assert_array_equal(m.data.covariance, s.position_covariance.reshape(3, 3))
    # The record time is the bag's, after the corrupt one.
    assert got[CORRUPT_AT].index == CORRUPT_AT + 1
    assert got[CORRUPT_AT].record_time == ((T0 + 100) * 10**9 + CORRUPT_AT * 10**8 + 1) * 1e-9
    with pytest.warns(DamagedRecordsWarning):
        track = read_bag_navsatfix(path, "/fix")
    assert track.skipped == 1
    np.testing.assert_array_equal(track.lat_deg, [s.latitude for s in src])
    np.testing.assert_array_equal(track.times, [_stamp(s) for s in src])


def test_time_source_record_and_zero_stamp(bag):
    path, _ = bag
    _, got = _read(path, "/fix", time_source="record")
    assert all(m.time == m.record_time for m in got)
    _, got = _read(path, "/fix_nostamp")
    assert len(got) == 1 and got[0].time == got[0].record_time == (T0 + 100) * 10**9 * 1e-9 + 1e-9


def test_imu_and_poses_exact(bag):
    path, msgs = bag
    _, got = _read(path, "/imu")
    for m, s in zip(got, msgs["/imu"][1], strict=True):
        assert isinstance(m.data, ImuSample)
        o = s.orientation
        np.testing.assert_array_equal(m.data.orientation_xyzw, [o.x, o.y, o.z, o.w])
        a = s.linear_acceleration
        np.testing.assert_array_equal(m.data.linear_acceleration, [a.x, a.y, a.z])
    with pytest.warns(DamagedRecordsWarning):
        imu = read_bag_imu(path, "/imu")
    assert imu.orientation_xyzw.shape == (N, 4) and imu.skipped == 1
    for topic in ("/pose", "/pose_cov", "/odom"):
        _, got = _read(path, topic)
        src = msgs[topic][1]
        assert len(got) == N
        for m, s in zip(got, src, strict=True):
            assert isinstance(m.data, PoseSample)
            p = s.pose.position if topic == "/pose" else s.pose.pose.position
            np.testing.assert_array_equal(m.data.position, [p.x, p.y, p.z])
            if topic == "/pose":
                assert m.data.covariance is None
            else:
                np.testing.assert_array_equal(m.data.covariance, s.pose.covariance.reshape(6, 6))
        if topic == "/odom":
            assert got[0].data.child_frame_id == "base_link"
        with pytest.warns(DamagedRecordsWarning):
            poses = read_bag_poses(path, topic)
        np.testing.assert_array_equal(poses.position[:, 0], np.arange(N, dtype=float))


def test_images_decoded_exactly(bag):
    path, msgs = bag
    _, got = _read(path, "/image")
    for m, s in zip(got, msgs["/image"][1], strict=True):
        if s.encoding == "rgb8":
            rgb = s.data.reshape(4, s.step)[:, :15].reshape(4, 5, 3)
            np.testing.assert_array_equal(m.data, rgb[:, :, ::-1])  # BGR
        else:
            want = np.frombuffer(s.data.tobytes(), ">u2").reshape(3, 4)
            assert m.data.dtype == np.uint16
            np.testing.assert_array_equal(m.data, want)
    _, got = _read(path, "/image/compressed")
    for m, s in zip(got, msgs["/image/compressed"][1], strict=True):
        np.testing.assert_array_equal(m.data, cv2.imdecode(s.data, cv2.IMREAD_UNCHANGED))
    # Without decoding: the rosbags message object, for fast scans.
    _, raw = _read(path, "/image", decode_images=False)
    assert raw[0].data.encoding == "rgb8"


def test_nmea_sentences(bag):
    path, msgs = bag
    _, got = _read(path, "/nmea")
    assert [m.data for m in got] == [s.sentence for s in msgs["/nmea"][1]]
    # Fed to the NMEA reader: times come from the sentences (GGA time of day + given date).
    with pytest.warns(DamagedRecordsWarning):
        nmea = read_bag_nmea(path, "/nmea", date=datetime.date(2023, 6, 16))
    assert nmea.skipped_messages == 1
    pos = nmea.log.positions
    assert pos.time.tolist() == [T0 + 0.0]  # all GGA share one epoch
    assert pos.lat_deg[0] == pytest.approx(63 + 26.31807 / 60, abs=1e-12)
    assert pos.lon_deg[0] == pytest.approx(10 + 23.91509 / 60, abs=1e-12)
    # The first HDT comes before any time of day: untimed, dropped by read_nmea.
    assert nmea.log.headings.heading_deg.tolist() == [274.07] * 2 and nmea.log.n_untimed == 1
    with pytest.raises(ValueError, match="expected nmea_msgs"):
        read_bag_nmea(path, "/imu")


def test_bayer_encodings_match_pattern():
    """A constant-colour image mosaicked by hand demosaics back to that colour (interior)."""
    from types import SimpleNamespace

    from usvfast.nav.bags import decode_image

    b, g, r = 30, 120, 220
    patterns = {
        "rggb": [[r, g], [g, b]],
        "bggr": [[b, g], [g, r]],
        "gbrg": [[g, b], [r, g]],
        "grbg": [[g, r], [b, g]],
    }
    for name, tile in patterns.items():
        mosaic = np.tile(np.array(tile, np.uint8), (4, 4))
        msg = SimpleNamespace(
            encoding=f"bayer_{name}8",
            height=8,
            width=8,
            step=8,
            is_bigendian=0,
            data=mosaic.ravel(),
        )
        img = decode_image(msg)
        np.testing.assert_array_equal(img[3, 3], [b, g, r], err_msg=name)


def test_bad_inputs(tmp_path, bag):
    path, _ = bag
    with pytest.raises(ValueError, match="topic: '/nope' is not in bag"):
        BagTopic(path, "/nope")
    with pytest.raises(ValueError, match="bag: no such file"):
        BagTopic(tmp_path / "missing.bag", "/fix")
    with pytest.raises(ValueError, match="time_source"):
        BagTopic(path, "/fix", time_source="wall")
    with pytest.raises(ValueError, match="holds sensor_msgs/msg/Imu"):
        read_bag_navsatfix(path, "/imu")
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"not a bag at all")
    with pytest.raises(ValueError, match="bag: cannot read"):
        bag_topics(junk)
