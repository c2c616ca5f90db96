"""GPX reader: tracks written with gpxpy read back exactly; damaged points skipped and
counted, never losing good ones (bad numbers, bad times, a file cut off mid-write)."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import gpxpy
import gpxpy.gpx
import numpy as np
import pytest

from usvfast.nav._damage import DamagedRecordsWarning
from usvfast.nav.gpx import read_gpx

T0 = datetime(2023, 6, 16, 10, 0, 0, tzinfo=timezone.utc)


def _track(n_segments=2, n=5):
    gpx = gpxpy.gpx.GPX()
    trk = gpxpy.gpx.GPXTrack()
    gpx.tracks.append(trk)
    k = 0
    for _ in range(n_segments):
        seg = gpxpy.gpx.GPXTrackSegment()
        trk.segments.append(seg)
        for _ in range(n):
            seg.points.append(
                gpxpy.gpx.GPXTrackPoint(
                    63.4386345 + k * 1e-5,
                    10.3985848 - k * 2e-5,
                    elevation=1.5 * k,
                    time=T0 + timedelta(seconds=k * 0.5),
                )
            )
            k += 1
    return gpx


def test_roundtrip_exact(tmp_path):
    gpx = _track()
    path = tmp_path / "t.gpx"
    path.write_text(gpx.to_xml())
    got = read_gpx(path)
    # Independent reference: gpxpy's own parse of the written file.
    ref = [p for t in gpxpy.parse(path.read_text()).tracks for s in t.segments for p in s.points]
    assert len(got) == len(ref) == 10 and got.skipped == 0
    np.testing.assert_array_equal(got.lat_deg, [p.latitude for p in ref])
    np.testing.assert_array_equal(got.lon_deg, [p.longitude for p in ref])
    np.testing.assert_array_equal(got.ele_m, [p.elevation for p in ref])
    np.testing.assert_array_equal(got.times, [T0.timestamp() + 0.5 * k for k in range(10)])
    np.testing.assert_array_equal(got.segment, [0] * 5 + [1] * 5)


def test_time_zones_and_missing_elevation(tmp_path):
    path = tmp_path / "tz.gpx"
    path.write_text(
        '<?xml version="1.0"?><gpx version="1.1" xmlns="http://www.topografix.com/GPX/1/1">'
        "<trk><trkseg>"
        '<trkpt lat="1" lon="2"><time>2023-06-16T12:00:03+02:00</time></trkpt>'
        '<trkpt lat="1" lon="2"><time>2023-06-16T10:00:01</time></trkpt>'
        '<trkpt lat="1" lon="2"><ele>4</ele><time>2023-06-16T10:00:02.250Z</time></trkpt>'
        "</trkseg></trk></gpx>"
    )
    got = read_gpx(path)
    # Sorted by time; no zone means UTC; +02:00 shifts by two hours.
    np.testing.assert_array_equal(got.times, T0.timestamp() + np.array([1.0, 2.25, 3.0]))
    assert np.isnan(got.ele_m[0]) and got.ele_m[1] == 4.0


def _damaged_text():
    good = _track(1, 4).to_xml()
    pts = good.split("<trkpt")
    # pts[0] is the head; corrupt: a bad latitude number, an unreadable time, an
    # out-of-range latitude; then cut the file off inside an extra point.
    bad = [
        ' lat="6x3.4" lon="10.0"><time>2023-06-16T10:00:09Z</time></trkpt>\n',
        ' lat="63.4" lon="10.0"><time>not a time</time></trkpt>\n',
        ' lat="95.0" lon="10.0"><time>2023-06-16T10:00:09Z</time></trkpt>\n',
    ]
    body = pts[0] + "<trkpt" + pts[1] + "<trkpt" + bad[0] + "<trkpt" + pts[2]
    body += "<trkpt" + bad[1] + "<trkpt" + bad[2] + "<trkpt" + pts[3] + "<trkpt" + pts[4]
    cut = body.split("</trkseg>")[0] + '<trkpt lat="63.5" lon="10.'
    return good, cut


def test_damaged_points_skipped_and_counted(tmp_path):
    good, cut = _damaged_text()
    path = tmp_path / "cut.gpx"
    path.write_text(cut)
    with pytest.warns(DamagedRecordsWarning, match="skipped 4 damaged"):
        got = read_gpx(path)
    ref = read_gpx_text(tmp_path, good)
    assert got.skipped == 4
    for name in ("times", "lat_deg", "lon_deg", "ele_m"):
        np.testing.assert_array_equal(getattr(got, name), getattr(ref, name))
    # Only the time is bad: gpxpy parses the document, we still skip the point.
    path2 = tmp_path / "badtime.gpx"
    path2.write_text(good.replace("2023-06-16T10:00:01Z", "garbage", 1))
    with pytest.warns(DamagedRecordsWarning, match="time"):
        got2 = read_gpx(path2)
    assert got2.skipped == 1 and len(got2) == 3


def read_gpx_text(tmp_path, text):
    p = tmp_path / "ref.gpx"
    p.write_text(text)
    return read_gpx(p)


def test_unusable_files(tmp_path):
    with pytest.raises(ValueError, match="gpx: no such file"):
        read_gpx(tmp_path / "missing.gpx")
    empty = tmp_path / "empty.gpx"
    empty.write_text('<?xml version="1.0"?><gpx version="1.1"></gpx>')
    with pytest.raises(ValueError, match="no usable track point"):
        read_gpx(empty)
    junk = tmp_path / "junk.gpx"
    junk.write_text("this is not xml <trk")
    with pytest.raises(ValueError, match="no usable track point"):
        read_gpx(junk)
