"""`usvfast inspect`: counts, spans, rates, gaps, damage and overlap of a recording built here
(GPX with a damaged point, MJPG video, ROS1 bag with a corrupt message), checked against the
known inputs; single files; errors."""

from __future__ import annotations

import math
import re
from datetime import datetime, timezone
from pathlib import Path

import cv2
import gpxpy
import gpxpy.gpx
import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Writer1
from typer.testing import CliRunner

from usvfast.cli import app
from usvfast.nav._damage import DamagedRecordsWarning
from usvfast.nav.bags import bag_typestore
from usvfast.nav.inspect import inspect_recording, recording_for_path
from usvfast.nav.replay import load_recording

from conftest import SHARED_DATA

T0 = 1_686_909_600.0
NMEA_DATA = SHARED_DATA / "nmea"
GPX_T = [0.0, 1.2, 2.0, 5.0, 6.0, 6.5, 9.0]  # largest gaps: 3.0, 2.5, 1.2
IMU_T = np.arange(30) * 0.1 + 2.0  # 2.0 .. 4.9 s


def _gpx(path):
    gpx = gpxpy.gpx.GPX()
    trk = gpxpy.gpx.GPXTrack()
    seg = gpxpy.gpx.GPXTrackSegment()
    gpx.tracks.append(trk)
    trk.segments.append(seg)
    for t in GPX_T:
        seg.points.append(
            gpxpy.gpx.GPXTrackPoint(
                63.4, 10.4, time=datetime.fromtimestamp(T0 + t, tz=timezone.utc)
            )
        )
    text = gpx.to_xml()
    # One damaged point: latitude out of range.
    text = text.replace(
        "</trkseg>", '<trkpt lat="123" lon="1"><time>2023-06-16T10:00:04Z</time></trkpt></trkseg>'
    )
    path.write_text(text)


def _bag(path, topic="/imu"):
    ts = bag_typestore(ros2=False)
    T = ts.types
    Vec, Quat = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"]
    with Writer1(path) as w:
        conn = w.add_connection(topic, "sensor_msgs/msg/Imu", typestore=ts)
        for i, t in enumerate(IMU_T):
            sec, nsec = divmod(round((T0 + t) * 1e9), 10**9)
            msg = T["sensor_msgs/msg/Imu"](
                header=T["std_msgs/msg/Header"](
                    seq=i,
                    stamp=T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                    frame_id="imu",
                ),
                orientation=Quat(x=0, y=0, z=0, w=1),
                orientation_covariance=np.zeros(9),
                angular_velocity=Vec(x=0, y=0, z=0),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=Vec(x=0, y=0, z=9.8),
                linear_acceleration_covariance=np.zeros(9),
            )
            raw = bytes(ts.serialize_ros1(msg, "sensor_msgs/msg/Imu"))
            if i == 5:
                w.write(conn, sec * 10**9 + nsec, raw[:10])  # corrupt copy
            w.write(conn, sec * 10**9 + nsec, raw)


@pytest.fixture
def recording(tmp_path):
    _gpx(tmp_path / "track.gpx")
    _bag(tmp_path / "run.bag")
    vw = cv2.VideoWriter(str(tmp_path / "cam.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 4.0, (32, 24))
    for i in range(16):
        vw.write(np.full((24, 32, 3), i, np.uint8))
    vw.release()
    (tmp_path / "rec.toml").write_text(
        f"""
[recording]
name = "inspect test"
[[stream]]
id = "gnss"
type = "gpx"
path = "track.gpx"
[[stream]]
id = "imu"
type = "bag"
path = "run.bag"
topic = "/imu"
clock_offset = -0.5
[[stream]]
id = "cam"
type = "video"
path = "cam.avi"
start_time = {T0 + 1.0}
"""
    )
    return tmp_path / "rec.toml"


def test_inspection_values(recording):
    ins = inspect_recording(load_recording(recording))
    gnss, imu, cam = ins.streams
    t = T0 + np.array(GPX_T)
    assert (gnss.count, gnss.damaged, gnss.start, gnss.end) == (7, 1, t[0], t[-1])
    assert gnss.mean_rate_hz == pytest.approx(6 / 9.0)
    gaps = np.diff(t)
    order = np.argsort(-gaps, kind="stable")[:3]
    assert [g for _, g in gnss.gaps] == pytest.approx(gaps[order].tolist())
    assert [s for s, _ in gnss.gaps] == t[order].tolist()
    imu_t = T0 + IMU_T - 0.5
    assert (imu.count, imu.damaged) == (30, 1)
    assert imu.start == pytest.approx(imu_t[0], abs=1e-6)
    assert imu.end == pytest.approx(imu_t[-1], abs=1e-6)
    assert imu.mean_rate_hz == pytest.approx(10.0, rel=1e-6)
    assert (cam.count, cam.damaged) == (16, 0)
    assert cam.start == T0 + 1.0 and cam.end == pytest.approx(T0 + 1.0 + 15 / 4.0, abs=1e-6)
    # Overlap: latest start (imu, 1.5 s) to earliest end (imu, 4.4 s).
    lo, hi = ins.overlap
    assert lo == pytest.approx(T0 + 1.5, abs=1e-6) and hi == pytest.approx(T0 + 4.4, abs=1e-6)
    assert ins.span == (T0, T0 + 9.0)


def test_cli_on_recording(recording):
    result = CliRunner().invoke(app, ["inspect", str(recording)])
    assert result.exit_code == 0, result.output
    out = result.output
    assert "inspect test" in out and "overlap of all streams" in out
    assert "2.900 s, 32.2% of the recording" in out  # (4.4 - 1.5) / 9
    rows = {line.split("│")[1].strip(): line for line in out.splitlines() if line.count("│") > 5}
    assert set(rows) >= {"gnss", "imu", "cam"}
    cells = [c.strip() for c in rows["gnss"].split("│")[1:-1]]
    assert cells[1] == "gpx" and cells[3] == "7" and cells[-1] == "1"
    assert cells[7] == "3.000, 2.500, 1.200"
    cells = [c.strip() for c in rows["imu"].split("│")[1:-1]]
    assert cells[3] == "30" and cells[6] == "10.000" and cells[-1] == "1"


def test_cli_single_files(recording):
    d = recording.parent
    res = CliRunner().invoke(app, ["inspect", str(d / "run.bag")])
    assert res.exit_code == 0, res.output
    assert "/imu" in res.output and "30" in res.output
    res = CliRunner().invoke(app, ["inspect", str(d / "track.gpx"), "--gaps", "1"])
    assert res.exit_code == 0 and "3.000" in res.output and "2.500" not in res.output
    rec = recording_for_path(d / "cam.avi")
    assert rec.streams[0].type == "video"


def test_cli_errors(tmp_path, recording):
    res = CliRunner().invoke(app, ["inspect", str(tmp_path / "nothing.gpx")])
    assert res.exit_code == 1 and "no such file" in res.output
    bad = tmp_path / "bad.toml"
    bad.write_text("[[stream]]\nid = 'x'\ntype = 'gpx'\n")
    res = CliRunner().invoke(app, ["inspect", str(bad)])
    assert res.exit_code == 1 and "key 'path'" in res.output
    # A stream whose file is missing is reported, the others still inspected.
    (tmp_path / "part.toml").write_text(
        recording.read_text().replace('path = "cam.avi"', 'path = "gone.avi"')
    )
    res = CliRunner().invoke(app, ["inspect", str(tmp_path / "part.toml")])
    assert res.exit_code == 0 and "gone.avi" in res.output
    assert "overlap of all streams: none" in res.output
    assert not math.isnan(
        inspect_recording(load_recording(tmp_path / "part.toml")).streams[0].start
    )


def test_readme_example(tmp_path, monkeypatch):
    """The README's recording runs: its TOML with files made here, `usvfast inspect`, replay."""
    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    section = readme.split("## Recordings")[1]
    toml = re.search(r"```toml\n(.*?)```", section, re.DOTALL).group(1)
    code = re.search(r"```python\n(.*?)```", section, re.DOTALL).group(1)
    (tmp_path / "harbour.toml").write_text(toml)
    _gpx(tmp_path / "track.gpx")
    _bag(tmp_path / "run.bag", topic="/imu/data")
    vw = cv2.VideoWriter(str(tmp_path / "cam.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 4.0, (32, 24))
    for i in range(8):
        vw.write(np.full((24, 32, 3), i, np.uint8))
    vw.release()
    monkeypatch.chdir(tmp_path)
    res = CliRunner().invoke(app, ["inspect", "harbour.toml"])
    assert res.exit_code == 0, res.output
    assert "harbour run" in res.output and "overlap of all streams: 2023" in res.output
    with pytest.warns(DamagedRecordsWarning):  # the damaged GPX point and bag message
        exec(compile(code, "README.md", "exec"), {})


def test_cli_on_shared_nmea_log():
    """The real u-blox log: one row per kind of record; the positions row matches an
    independent scan of the raw lines with pynmea2 (distinct fix epochs, their span)."""
    import pynmea2

    log = NMEA_DATA / "ublox-zed-f9p-nmea.log"
    epochs = set()
    for line in log.read_text(errors="replace").splitlines():
        try:
            msg = pynmea2.parse(line.strip(), check=True)
        except (pynmea2.ParseError, ValueError, AttributeError):
            continue
        if msg.sentence_type in ("GGA", "RMC", "GLL") and msg.timestamp is not None:
            ts = msg.timestamp
            epochs.add(ts.hour * 3600 + ts.minute * 60 + ts.second + ts.microsecond * 1e-6)
    res = CliRunner().invoke(app, ["inspect", str(log)])
    assert res.exit_code == 0, res.output
    rows = {
        line.split("│")[1].strip(): [c.strip() for c in line.split("│")[1:-1]]
        for line in res.output.splitlines()
        if line.count("│") > 5
    }
    pos = rows["ublox-zed-f9p-nmea:positions"]
    assert pos[1] == "nmea" and int(pos[3]) == len(epochs)
    assert float(pos[5]) == pytest.approx(max(epochs) - min(epochs))
    assert pos[4].startswith("2019-04-12T")  # the date comes from RMC
    assert pos[-1] == "0"


def test_nmea_stream_in_recording(tmp_path):
    """A damaged copy of the real log as the navigation stream of a recording: damaged lines
    are counted, the fixes of the good lines all reach the replay and navigation_fixes."""
    from usvfast.nav.fixes import navigation_fixes
    from usvfast.nav.nmea import read_nmea
    from usvfast.nav.replay import Replay
    from usvfast.nav.stream_types import NmeaFix

    lines = (NMEA_DATA / "ublox-zed-f9p-nmea.log").read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("$GNGGA"))
    lines[k] = lines[k][:-1] + "Z"  # checksum broken
    lines.insert(12, "$GNGGA,garbage")
    (tmp_path / "gnss.log").write_text("\n".join(lines) + "\n")
    (tmp_path / "rec.toml").write_text(
        '[recording]\nnavigation = "gnss"\n[[stream]]\nid = "gnss"\ntype = "nmea"\n'
        'path = "gnss.log"\nclock_offset = 0.2\n'
    )
    with pytest.warns(DamagedRecordsWarning):
        ref = read_nmea(tmp_path / "gnss.log")
    rec = load_recording(tmp_path / "rec.toml")
    with pytest.warns(DamagedRecordsWarning):
        replay = Replay(rec)
        items = list(replay)
    assert replay.counts["gnss"].damaged == ref.n_damaged == 2
    fixes = [it for it in items if isinstance(it.data, NmeaFix)]
    np.testing.assert_array_equal([f.time for f in fixes], ref.positions.time + 0.2)
    with pytest.warns(DamagedRecordsWarning):
        nav = navigation_fixes(rec)
    good = ref.positions.fix_quality > 0
    np.testing.assert_array_equal(nav.lat_deg, ref.positions.lat_deg[good])
    assert nav.no_fix == int((~good).sum()) and nav.damaged == 2
