"""The navigation's errors that reach every detection (`recording.fix_quality_std`,
`pose_acceleration_std`, `heading_acceleration_std`; usvfast.pipeline.pose.NavErrors): the
pose's variances from the GGA fix quality and the interpolation between samples, the same in
`NavTrack` (run) and `LivePose` (process), and their NED covariance at a detection against the
numerical Jacobian of the detection's position in the pose."""

from __future__ import annotations

import math
from datetime import datetime, timezone

import numpy as np
import pynmea2
import pytest
from nav_config import nav_config

from usvfast.pipeline import ConfigError, Pipeline, load_config
from usvfast.pipeline.live_pose import LivePose, parse_sentence
from usvfast.pipeline.pose import NavErrors, NavTrack, VesselPose

T0 = 1_686_909_600.0
ORIGIN = (63.44, 10.40, 0.0)


def nmea(kind: str, fields: list[str]) -> str:
    msg = pynmea2.TalkerSentence.sentence_types[kind]("GN", kind, tuple(fields))
    return msg.render(checksum=True, dollar=True)


def hms(t: float) -> str:
    s = t % 86400.0
    return f"{int(s // 3600):02d}{int(s % 3600 // 60):02d}{s % 60:06.3f}"


def gga(t: float, north: float, quality: int) -> str:
    lat = ORIGIN[0] + north / 111_200.0
    d = int(lat)
    la = f"{d:02d}{(lat - d) * 60:010.7f}"
    lo = f"{int(ORIGIN[1]):03d}{(ORIGIN[1] - int(ORIGIN[1])) * 60:010.7f}"
    tail = ["12", "1", "10", "M", "40", "M", "", ""]
    return nmea("GGA", [hms(t), la, "N", lo, "E", str(quality), *tail])


def hdt(heading_deg: float) -> str:
    return nmea("HDT", [f"{heading_deg:.3f}", "T"])


def write_log(
    tmp_path, qualities: dict[int, int], gap: tuple[int, int] | None = None
) -> list[float]:
    """10 Hz GGA + HDT for 6 s (epoch k: quality qualities.get(k, 4)); epochs in `gap` (first,
    last) send nothing. Returns the fix times."""
    day = datetime.fromtimestamp(T0, timezone.utc)
    lines = [
        nmea("ZDA", [hms(T0), f"{day.day:02d}", f"{day.month:02d}", str(day.year), "00", "00"])
    ]
    times = []
    for k in range(61):
        if gap is not None and gap[0] <= k <= gap[1]:
            continue
        t = T0 + 0.1 * k
        times.append(t)
        lines += [gga(t, 0.5 * (t - T0), qualities.get(k, 4)), hdt(30.0)]
    (tmp_path / "gnss.nmea").write_text("\n".join(lines) + "\n")
    return times


def config(tmp_path, recording_keys: str):
    recording = f'navigation = "gnss"\norigin = [{ORIGIN[0]}, {ORIGIN[1]}, 0.0]\n{recording_keys}'
    streams = '[[stream]]\nid = "gnss"\ntype = "nmea"\npath = "gnss.nmea"'
    if not (tmp_path / "gnss.nmea").exists():
        (tmp_path / "gnss.nmea").write_text("")
    return load_config(nav_config(tmp_path, recording, streams))


def test_nav_errors_variances():
    e = NavErrors({5: 0.1, 2: 0.5}, acceleration_std=0.4, heading_acceleration_std=0.02)
    assert e.std_of([4, 5, 2, 1]).tolist() == [0.0, 0.1, 0.5, 0.0]
    # a constant acceleration a misses a/2 τ (T − τ) by linear interpolation
    assert e.position_var(0.1, 0.75 * 0.75) == pytest.approx(0.01 + (0.2 * 0.5625) ** 2)
    assert e.heading_var(0.25) == pytest.approx((0.01 * 0.25) ** 2)
    assert NavErrors().position_var(0.0, 1.0) == 0.0


def test_covariance_at_is_the_poses_jacobian():
    rng = np.random.default_rng(3)
    for _ in range(20):
        pose = VesselPose(
            0.0, *rng.normal(0, 50, 2), rng.uniform(0, 2 * math.pi), 0.0, 0.0,
            rng.uniform(0, 0.05), rng.uniform(0, 1e-3),
        )  # fmt: skip
        z = rng.normal(0, 30, (5, 2))
        # a detection is the pose's position plus its offset turned with the heading:
        # d z / d heading = the offset turned by 90°
        r = z - (pose.north, pose.east)
        eps = 1e-6
        rot = np.array([[math.cos(eps), -math.sin(eps)], [math.sin(eps), math.cos(eps)]])
        jac = (r @ rot.T - r @ rot) / (2 * eps)  # central difference
        expected = (
            pose.position_var * np.eye(2) + pose.heading_var * jac[:, :, None] * jac[:, None, :]
        )
        np.testing.assert_allclose(pose.covariance_at(z), expected, rtol=1e-5, atol=1e-12)
    assert VesselPose(0.0, 1.0, 2.0, 0.3).covariance_at(np.zeros((3, 2))) is None
    with pytest.raises(ValueError, match="positions"):
        pose.covariance_at([[1.0, np.nan]])
    with pytest.raises(ValueError, match="positions"):
        pose.covariance_at(np.zeros((3, 3)))


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"fix_std": {5: -0.1}}, "fix_std"),
        ({"fix_std": {5: math.nan}}, "fix_std"),
        ({"fix_std": {"5": 0.1}}, "fix_std"),
        ({"acceleration_std": -1.0}, "acceleration_std"),
        ({"heading_acceleration_std": math.inf}, "heading_acceleration_std"),
    ],
)
def test_nav_errors_refuse_bad_values(kwargs, name):
    with pytest.raises(ValueError, match=name):
        NavErrors(**kwargs)


def test_navtrack_variance_follows_the_fix_quality(tmp_path):
    write_log(tmp_path, {k: 5 for k in range(20, 30)})
    cfg = config(tmp_path, "fix_quality_std = [[5, 0.1], [2, 0.5]]")
    track = NavTrack.from_config(cfg)
    assert track.pose_at(T0 + 1.0).position_var == 0.0  # RTK fixed
    assert track.pose_at(T0 + 2.5).position_var == pytest.approx(0.01)  # RTK float
    # between a fixed and a float fix the std is interpolated like the position
    assert track.pose_at(T0 + 1.95).position_var == pytest.approx(0.05**2)
    assert track.pose_at(T0 + 2.5).heading_var == 0.0
    # no key: no variance, the pose itself unchanged
    plain = NavTrack.from_config(config(tmp_path, ""))
    p, q = plain.pose_at(T0 + 2.5), track.pose_at(T0 + 2.5)
    assert p.position_var == 0.0 and (p.north, p.east, p.heading) == (q.north, q.east, q.heading)


def test_navtrack_variance_grows_in_a_gap(tmp_path):
    write_log(tmp_path, {}, gap=(21, 35))  # no sentence from 2.1 to 3.5 s: T = 1.6 s
    cfg = config(tmp_path, "pose_acceleration_std = 0.5\nheading_acceleration_std = 2.0")
    track = NavTrack.from_config(cfg)
    mid = track.pose_at(T0 + 2.8)  # τ = T − τ = 0.8 s
    assert mid.position_var == pytest.approx((0.25 * 0.64) ** 2)
    assert mid.heading_var == pytest.approx((0.5 * math.radians(2.0) * 0.64) ** 2)
    near = track.pose_at(T0 + 1.05)  # between 10 Hz samples: τ (T − τ) = 0.0025 s²
    assert near.position_var == pytest.approx((0.25 * 0.0025) ** 2, rel=1e-4)  # UNIX-time rounding
    assert track.pose_at(T0 + 1.0).position_var == 0.0  # on a sample


def test_live_pose_gives_the_same_variances(tmp_path):
    write_log(tmp_path, {k: 5 for k in range(20, 30)})
    cfg = config(tmp_path, "fix_quality_std = [[5, 0.1]]")
    run = NavTrack.from_config(cfg)
    live = LivePose(ORIGIN, errors=cfg.nav_errors)
    for k in range(26):
        t = T0 + 0.1 * k
        _, (lat, lon, quality) = parse_sentence(gga(t, 0.5 * 0.1 * k, 5 if k >= 20 else 4))
        live.add_fix(t, lat, lon, quality)
        live.add_heading(t, math.radians(30.0))
        if k == 20:  # the last fixed fix and the first float one around 1.95 s
            assert live.at(T0 + 1.95).position_var == pytest.approx(0.05**2)
            assert run.pose_at(T0 + 1.95).position_var == pytest.approx(0.05**2)
        if k == 25:  # an RMC of the same epoch (no quality of its own) keeps the GGA's
            live.add_fix(t, lat, lon)
    assert live.at(T0 + 2.5).position_var == pytest.approx(0.01)
    assert run.pose_at(T0 + 2.5).position_var == pytest.approx(0.01)


@pytest.mark.parametrize(
    ("sentence", "quality"),
    [
        ("GGA", 5),
        ("RMC", 5),  # FAA mode F: RTK float
        ("GLL", 2),  # FAA mode D: differential
    ],
)
def test_live_fixes_carry_their_quality(sentence, quality):
    if sentence == "GGA":
        text = gga(T0, 0.0, quality)
    elif sentence == "RMC":
        fields = ["0.9", "20.0", "160623", "", "", "F"]
        text = nmea("RMC", [hms(T0), "A", "6326.4000", "N", "01024.0000", "E", *fields])
    else:
        text = nmea("GLL", ["6326.4000", "N", "01024.0000", "E", hms(T0), "A", "D"])
    kind, values = parse_sentence(text)
    assert kind == "fix" and values[2] == quality


@pytest.mark.parametrize(
    ("keys", "match"),
    [
        ("fix_quality_std = [[10, 0.1]]", "fix_quality_std.*quality 0-9"),
        ("fix_quality_std = [[5.5, 0.1]]", "fix_quality_std"),
        ("fix_quality_std = [[5, -0.1]]", "fix_quality_std"),
        ("fix_quality_std = [[5, 0.1], [5, 0.2]]", "fix quality 5 is given twice"),
        ("fix_quality_std = [5, 0.1]", "fix_quality_std"),
        ("fix_quality_std = []", "fix_quality_std"),
        ("pose_acceleration_std = -1.0", "pose_acceleration_std.*>= 0"),
        ("heading_acceleration_std = inf", "heading_acceleration_std"),
    ],
)
def test_bad_nav_error_keys_name_the_key(tmp_path, keys, match):
    with pytest.raises(ConfigError, match=match):
        config(tmp_path, keys)


def test_pipeline_adds_the_pose_covariance_to_each_detection(tmp_path):
    """Pipeline._end gives the tracker each detection's covariance plus the pose's."""
    cfg = config(tmp_path, "")
    pipe = Pipeline(cfg)
    seen = []
    pipe._track = lambda t, z, sid, covs, vessel, starts: seen.append(covs) or _Snapshot()
    from usvfast.pipeline.core import _Scan

    z = np.array([[10.0, 0.0], [0.0, 5.0]])
    covs = np.tile(np.eye(2) * 0.01, (2, 1, 1))
    for pose in (
        VesselPose(T0, 0.0, 0.0, 0.0),
        VesselPose(T0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.04, 1e-4),
    ):
        pipe.epoch = math.floor(T0)
        scan = _Scan(T0, "lidar", pipe.chains["lidar"], pose, None, (z, covs, np.ones(2)), None)
        pipe._end(scan, None)
    np.testing.assert_array_equal(seen[0], covs)
    np.testing.assert_allclose(seen[1] - covs, pose.covariance_at(z))
    assert seen[1][0, 1, 1] == pytest.approx(0.01 + 0.04 + 1e-4 * 100.0)  # across the sight line


class _Snapshot:
    ids = np.zeros(0, dtype=np.int64)
