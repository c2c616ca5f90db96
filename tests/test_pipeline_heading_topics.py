"""Headings from a GNSS driver's orientation topics (QuaternionStamped, Imu) beside a NavSatFix,
and from a GNSS compass's proprietary sentences: the same navigation, and the same tracks, as
the NMEA HDT sentences they were made from."""

from __future__ import annotations

import math
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Writer
from scipy.spatial.transform import Rotation

from usvfast.lidar.readers import make_header
from usvfast.nav.bags import QuaternionSample, bag_typestore, read_bag_nmea
from usvfast.pipeline import Pipeline, config_from_dict
from usvfast.pipeline.orientation import imu_roll_pitch, quaternion_heading, usable_orientations
from usvfast.pipeline.pose import NavigationError, NavTrack

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

HARBOUR = Path(str(resources.files("usvfast") / "data" / "harbour"))


def test_quaternion_heading_against_scipy():
    rng = np.random.default_rng(4)
    euler = rng.uniform([-math.pi, -0.4, -0.4], [math.pi, 0.4, 0.4], size=(500, 3))
    q = Rotation.from_euler("ZYX", euler).as_quat()  # x, y, z, w; yaw about z first
    yaw = euler[:, 0]
    np.testing.assert_allclose(
        np.angle(np.exp(1j * (quaternion_heading(q) - (math.pi / 2 - yaw)))), 0, atol=1e-12
    )
    np.testing.assert_allclose(
        np.angle(np.exp(1j * (quaternion_heading(q, "north_clockwise") - yaw))), 0, atol=1e-12
    )
    h = quaternion_heading(q)
    assert np.all((h >= 0) & (h < 2 * math.pi))
    with pytest.raises(ValueError, match="yaw_convention: expected one of"):
        quaternion_heading(q, "ned")


@pytest.fixture(scope="module")
def nav_bag(tmp_path_factory):
    """The bundled recording's NMEA as a driver would publish it: /fix (NavSatFix) at the fix
    times, and its HDT headings as /heading (nmea_navsat_driver: the heading as the yaw),
    /heading_enu (REP-103) and /gnss_imu (an Imu, REP-103, tilted by random roll and pitch)."""
    log = read_bag_nmea(HARBOUR / "bag", "/gnss/nmea").log
    p, h = log.positions, log.headings
    ts = bag_typestore()
    T = ts.types
    path = tmp_path_factory.mktemp("nav") / "nav"
    rng = np.random.default_rng(9)
    heading = np.radians(h.heading_deg)
    tilt = rng.uniform(-0.15, 0.15, size=(len(heading), 2))
    q_north = Rotation.from_euler("z", heading[:, None]).as_quat()
    q_enu = Rotation.from_euler("z", (math.pi / 2 - heading)[:, None]).as_quat()
    q_tilted = Rotation.from_euler("ZYX", np.c_[math.pi / 2 - heading, tilt]).as_quat()

    def quat(q):
        return T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])

    with Writer(path, version=8) as w:
        fix = w.add_connection("/fix", "sensor_msgs/msg/NavSatFix", typestore=ts)
        status = T["sensor_msgs/msg/NavSatStatus"](status=0, service=1)
        for t, lat, lon, quality in zip(p.time, p.lat_deg, p.lon_deg, p.fix_quality, strict=True):
            msg = T["sensor_msgs/msg/NavSatFix"](
                header=make_header(ts, float(t), "gnss"),
                status=T["sensor_msgs/msg/NavSatStatus"](status=-1, service=1)
                if quality <= 0
                else status,
                latitude=float(lat),
                longitude=float(lon),
                altitude=40.0,
                position_covariance=np.zeros(9),
                position_covariance_type=0,
            )
            w.write(fix, round(t * 1e9), bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/NavSatFix")))
        for topic, qs in (("/heading", q_north), ("/heading_enu", q_enu)):
            conn = w.add_connection(topic, "geometry_msgs/msg/QuaternionStamped", typestore=ts)
            for t, q in zip(h.time, qs, strict=True):
                msg = T["geometry_msgs/msg/QuaternionStamped"](
                    header=make_header(ts, float(t), "gnss"), quaternion=quat(q)
                )
                raw = ts.serialize_cdr(msg, "geometry_msgs/msg/QuaternionStamped")
                w.write(conn, round(t * 1e9), bytes(raw))
        conn = w.add_connection("/gnss_imu", "sensor_msgs/msg/Imu", typestore=ts)
        v3 = T["geometry_msgs/msg/Vector3"]
        for t, q in zip(h.time, q_tilted, strict=True):
            msg = T["sensor_msgs/msg/Imu"](
                header=make_header(ts, float(t), "gnss"),
                orientation=quat(q),
                orientation_covariance=np.zeros(9),
                angular_velocity=v3(x=0.0, y=0.0, z=0.0),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=v3(x=0.0, y=0.0, z=9.81),
                linear_acceleration_covariance=np.zeros(9),
            )
            w.write(conn, round(t * 1e9), bytes(ts.serialize_cdr(msg, "sensor_msgs/msg/Imu")))
        # the same Imu with every fourth orientation missing, and one with none at all
        # (zeros and orientation covariance[0] = -1, REP-145)
        for topic, missing in (("/gnss_imu_gaps", slice(None, None, 4)), ("/imu_raw", slice(None))):
            conn = w.add_connection(topic, "sensor_msgs/msg/Imu", typestore=ts)
            qs = q_tilted.copy()
            qs[missing] = 0.0
            for t, q in zip(h.time, qs, strict=True):
                msg = T["sensor_msgs/msg/Imu"](
                    header=make_header(ts, float(t), "gnss"),
                    orientation=quat(q),
                    orientation_covariance=np.r_[-1.0 if not q.any() else 0.0, np.zeros(8)],
                    angular_velocity=v3(x=0.0, y=0.0, z=0.0),
                    angular_velocity_covariance=np.zeros(9),
                    linear_acceleration=v3(x=0.0, y=0.0, z=9.81),
                    linear_acceleration_covariance=np.zeros(9),
                )
                raw = ts.serialize_cdr(msg, "sensor_msgs/msg/Imu")
                w.write(conn, round(t * 1e9), bytes(raw))
    return path


def _config(nav_bag: Path | None, heading: str | None = None, **options) -> dict:
    """The bundled recording's config; with `nav_bag`, its GNSS stream replaced by /fix and
    the heading topic `heading` of that bag (with the stream `options`)."""
    data = tomllib.loads((HARBOUR / "recording.toml").read_text())
    data["camera"]["enabled"] = False
    if nav_bag is None:
        return data
    gnss = next(s for s in data["stream"] if s["id"] == "gnss")
    others = [s for s in data["stream"] if s["id"] != "gnss"]
    fix = {**gnss, "path": str(nav_bag), "topic": "/fix"}
    head = {"id": "heading", "type": "bag", "path": str(nav_bag), "topic": heading, **options}
    data["stream"] = [fix, head, *others]
    data["recording"]["navigation"] = ["gnss", "heading"]
    return data


@pytest.mark.parametrize(
    ("topic", "options"),
    [
        ("/heading", {"yaw_convention": "north_clockwise"}),
        ("/heading_enu", {}),
        ("/gnss_imu", {"yaw_convention": "enu"}),
    ],
)
def test_navigation_equals_the_nmea(nav_bag, topic, options):
    ours = NavTrack.from_config(config_from_dict(_config(nav_bag, topic, **options), HARBOUR))
    nmea = NavTrack.from_config(config_from_dict(_config(None), HARBOUR))
    t = np.linspace(nmea.heading.time[0], nmea.heading.time[-1], 997)
    for a, b in zip((ours.pose_at(x) for x in t), (nmea.pose_at(x) for x in t), strict=True):
        assert a is not None and b is not None
        assert abs(math.remainder(a.heading - b.heading, 2 * math.pi)) < 1e-9
        assert abs(a.north - b.north) < 1e-6 and abs(a.east - b.east) < 1e-6


def test_the_wrong_convention_is_another_heading(nav_bag):
    # the same topic read as REP-103 is the mirror heading about north-east: not the NMEA's
    ours = NavTrack.from_config(config_from_dict(_config(nav_bag, "/heading"), HARBOUR))
    nmea = NavTrack.from_config(config_from_dict(_config(None), HARBOUR))
    t = float(np.median(nmea.heading.time))
    a, b = ours.pose_at(t), nmea.pose_at(t)
    assert a is not None and b is not None
    assert abs(math.remainder(a.heading - (math.pi / 2 - b.heading), 2 * math.pi)) < 1e-9


def test_an_unknown_convention_is_an_error_naming_it(nav_bag):
    cfg = config_from_dict(_config(nav_bag, "/heading", yaw_convention="ned"), HARBOUR)
    with pytest.raises(NavigationError, match=r"stream 'heading': option 'yaw_convention'"):
        NavTrack.from_config(cfg)


def test_same_tracks_as_with_the_nmea(nav_bag):
    def tracks(data: dict) -> list:
        pipe = Pipeline(config_from_dict(data, HARBOUR))
        return [(u.time, u.tracks.ids.tolist(), u.tracks.states) for u in pipe.run()]

    ours = tracks(_config(nav_bag, "/heading", yaw_convention="north_clockwise"))
    nmea = tracks(_config(None))
    assert len(ours) == len(nmea) and sum(len(i) for _, i, _ in nmea) > 100
    for (ta, ia, sa), (tb, ib, sb) in zip(ours, nmea, strict=True):
        assert ta == tb and ia == ib
        np.testing.assert_allclose(sa, sb, atol=1e-6)


def test_live_heading_from_a_quaternion_message(nav_bag):
    pipe = Pipeline(config_from_dict(_config(nav_bag, "/heading_enu"), HARBOUR))
    from types import SimpleNamespace

    from usvfast.nav.bags import NavSatFixSample

    fix = NavSatFixSample(63.44, 10.40, 40.0, 0, np.zeros((3, 3)), 0)
    q = Rotation.from_euler("z", math.pi / 2 - 0.7).as_quat()  # heading 0.7 rad, REP-103
    for t in (100.0, 100.1):
        pipe.process(SimpleNamespace(time=t, stream="gnss", data=fix))
        pipe.process(SimpleNamespace(time=t, stream="heading", data=QuaternionSample(q, "gnss")))
    pose = pipe.live.at(100.05)
    assert pose is not None and abs(pose.heading - 0.7) < 1e-12


def test_usable_orientations_and_errors_on_the_rest():
    q = np.array([[0, 0, 0, 1], [0, 0, 0, 0], [0, 0, 0, 1.05], [0, 0, 0, 1.2], [np.nan, 0, 0, 1]])
    np.testing.assert_array_equal(usable_orientations(q), [True, False, True, False, False])
    np.testing.assert_array_equal(usable_orientations(np.full((1, 4), 1e300)), [False])
    for f in (quaternion_heading, imu_roll_pitch):
        with pytest.raises(ValueError, match=r"orientation_xyzw: row 1 .* 3 such rows"):
            f(q)


def test_missing_orientations_are_skipped_and_counted(nav_bag):
    cfg = config_from_dict(_config(nav_bag, "/gnss_imu_gaps"), HARBOUR)
    ours = NavTrack.from_config(cfg)
    nmea = NavTrack.from_config(config_from_dict(_config(None), HARBOUR))
    n = len(nmea.heading.time)
    assert ours.damaged["heading"] == len(range(0, n, 4))
    kept = np.delete(nmea.heading.time, np.s_[::4])
    np.testing.assert_array_equal(ours.heading.time, kept)
    for t in kept[::7]:
        a, b = ours.pose_at(float(t)), nmea.pose_at(float(t))
        assert a is not None and b is not None
        assert abs(math.remainder(a.heading - b.heading, 2 * math.pi)) < 1e-9


def test_an_imu_without_orientation_is_an_error_naming_it(nav_bag):
    cfg = config_from_dict(_config(nav_bag, "/imu_raw"), HARBOUR)
    with pytest.raises(NavigationError, match=r"stream 'heading': topic '/imu_raw' carries no or"):
        NavTrack.from_config(cfg)
    data = _config(None)
    imu = next(s for s in data["stream"] if s["id"] == data["recording"]["attitude"])
    imu.update(path=str(nav_bag), topic="/imu_raw")
    with pytest.raises(NavigationError, match=r"stream 'imu': topic '/imu_raw' carries no orie"):
        NavTrack.from_config(config_from_dict(data, HARBOUR))


def test_live_message_without_orientation_is_counted_not_used(nav_bag):
    from types import SimpleNamespace

    from usvfast.nav.bags import NavSatFixSample

    pipe = Pipeline(config_from_dict(_config(nav_bag, "/heading_enu"), HARBOUR))
    fix = NavSatFixSample(63.44, 10.40, 40.0, 0, np.zeros((3, 3)), 0)
    q = Rotation.from_euler("z", math.pi / 2 - 0.7).as_quat()
    for t, quat in ((100.0, q), (100.1, np.zeros(4)), (100.2, q)):
        pipe.process(SimpleNamespace(time=t, stream="gnss", data=fix))
        pipe.process(SimpleNamespace(time=t, stream="heading", data=QuaternionSample(quat, "g")))
    assert pipe.counts["heading"]["damaged"] == 1
    pose = pipe.live.at(100.1)
    assert pose is not None and abs(pose.heading - 0.7) < 1e-12


def test_gnss_compass_sentences_give_the_hdt_navigation(tmp_path):
    """The bundled NMEA as a text log, each HDT rewritten as $PSAT,HPR carrying the time of
    day of the epoch it belongs to (the latest GGA/RMC before it, which times the HDT)."""
    from usvfast.nav.bags import BagTopic
    from usvfast.nav.nmea import read_nmea

    lines, tod, replaced = [], None, 0
    for m in BagTopic(HARBOUR / "bag", "/gnss/nmea"):
        line = m.data.strip()
        body = line[1 : line.index("*")]
        fields = body.split(",")
        if fields[0][2:] in ("GGA", "RMC"):
            tod = fields[1]
        if fields[0][2:] == "HDT" and tod is not None:
            cs = 0
            for c in (hpr := f"PSAT,HPR,{tod},{fields[1]},,,N").encode():
                cs ^= c
            line, replaced = f"${hpr}*{cs:02X}", replaced + 1
        lines.append(line)
    (tmp_path / "gnss.nmea").write_text("\n".join(lines) + "\n")
    assert replaced > 100
    assert set(read_nmea(tmp_path / "gnss.nmea").headings.sentence) == {"HPR"}
    data = _config(None)
    gnss = next(s for s in data["stream"] if s["id"] == "gnss")
    del gnss["topic"]
    gnss.update(type="nmea", path=str(tmp_path / "gnss.nmea"))
    ours = NavTrack.from_config(config_from_dict(data, HARBOUR))
    nmea = NavTrack.from_config(config_from_dict(_config(None), HARBOUR))
    np.testing.assert_array_equal(ours.heading.time, nmea.heading.time)
    t = np.linspace(nmea.heading.time[0], nmea.heading.time[-1], 503)
    for a, b in zip((ours.pose_at(x) for x in t), (nmea.pose_at(x) for x in t), strict=True):
        assert a is not None and b is not None
        assert abs(math.remainder(a.heading - b.heading, 2 * math.pi)) < 1e-12
        assert a.north == b.north and a.east == b.east
