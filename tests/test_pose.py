"""Pose track: linear position (numpy.interp as the peer), shortest-arc angles (scipy Slerp on
yaw-only rotations as the peer), gaps and spans as errors, clock offsets, NMEA input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from scipy.spatial.transform import Rotation, Slerp

from usvfast import TimeOrderError
from usvfast.nav.nmea import read_nmea
from usvfast.nav.pose import PoseGapError, PoseTrack

from conftest import SHARED_DATA

DATA = SHARED_DATA / "nmea"


@given(
    hnp.arrays(np.float64, 6, elements=st.floats(0.1, 1.0)),
    hnp.arrays(np.float64, 6, elements=st.floats(-3.0, 3.0)),
    st.floats(0.0, 1.0),
)
def test_interpolation_equals_peers(steps, turns, frac):
    # Consecutive headings differ by less than π, so the shortest arc is unique.
    headings = np.cumsum(turns)
    t = 1000.0 + np.concatenate([[0.0], np.cumsum(steps[:5])])
    lat = 59.0 + 0.001 * np.arange(6)
    lon = 10.0 - 0.002 * np.arange(6) ** 2
    track = PoseTrack(t, lat, lon, heading_time=t, heading=headings, max_gap=1.0)
    q = t[0] + frac * (t[-1] - t[0])
    pose = track.at([q, t[2]])
    assert pose.lat_deg[0] == pytest.approx(np.interp(q, t, lat), abs=1e-12)
    assert pose.lon_deg[0] == pytest.approx(np.interp(q, t, lon), abs=1e-12)
    slerp = Slerp(t, Rotation.from_euler("z", headings[:, None]))
    ref = np.mod(slerp([q]).as_euler("zyx")[0, 0], 2 * np.pi)
    diff = (pose.heading[0] - ref + np.pi) % (2 * np.pi) - np.pi
    assert abs(diff) < 1e-9
    on_sample = (pose.heading[1] - headings[2] + np.pi) % (2 * np.pi) - np.pi
    assert abs(on_sample) < 1e-12
    assert np.all((pose.heading >= 0) & (pose.heading < 2 * np.pi))


def test_shortest_arc_and_antimeridian():
    t = [0.0, 1.0]
    track = PoseTrack(
        t, [0.0, 0.0], [179.9, -179.9], heading_time=t, heading=np.radians([359.0, 3.0]),
        attitude_time=t, roll=[3.1, -3.1], pitch=[0.0, 0.2],
    )  # fmt: skip
    pose = track.at(0.5)
    assert pose.lon_deg[0] == pytest.approx(180.0, abs=1e-9) or pose.lon_deg[0] == pytest.approx(
        -180.0, abs=1e-9
    )
    assert np.degrees(pose.heading[0]) == pytest.approx(1.0)
    assert abs(abs(pose.roll[0]) - np.pi) < 1e-9 and pose.pitch[0] == pytest.approx(0.1)
    assert np.isnan(pose.altitude[0])


def test_gaps_spans_and_offsets():
    t = np.array([0.0, 1.0, 2.0, 10.0, 11.0])
    track = PoseTrack(t, np.arange(5.0), np.zeros(5), max_gap=1.5, position_offset=100.0)
    assert track.at([100.5, 111.0]).lat_deg.tolist() == [0.5, 4.0]
    with pytest.raises(PoseGapError, match="105"):
        track.at([101.0, 105.0])
    with pytest.raises(PoseGapError):
        track.at(99.9)
    with pytest.raises(PoseGapError):
        track.at(111.1)
    with pytest.raises(TimeOrderError):
        PoseTrack([1.0, 0.0], [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(ValueError, match="max_gap"):
        PoseTrack([0.0], [0.0], [0.0], max_gap=0.0)


def test_from_nmea_saab():
    log = read_nmea(DATA / "saab-r4.log")
    track = PoseTrack.from_nmea(log, max_gap=1.5, heading_offset=0.0)
    p = log.positions
    pose = track.at(p.time)
    np.testing.assert_allclose(pose.lat_deg, p.lat_deg)
    np.testing.assert_allclose(np.degrees(pose.heading), log.headings.heading_deg)
    mid = track.at(p.time[:-1] + 0.5)
    np.testing.assert_allclose(mid.lat_deg, 0.5 * (p.lat_deg[:-1] + p.lat_deg[1:]))
    # The heading stream 0.25 s late: shifting its clock moves the samples.
    late = PoseTrack.from_nmea(log, max_gap=1.5, heading_offset=0.25)
    with pytest.raises(PoseGapError, match="heading"):
        late.at(p.time[0])


def _nmea_like(altitude):
    """A stand-in for a read_nmea result: four fixes 1 s apart, no headings."""
    from types import SimpleNamespace

    n = len(altitude)
    positions = SimpleNamespace(
        time=np.arange(n, dtype=float),
        lat_deg=59.0 + 1e-4 * np.arange(n),
        lon_deg=np.full(n, 10.0),
        altitude=np.asarray(altitude, dtype=float),
        fix_quality=np.ones(n, dtype=int),
    )
    headings = SimpleNamespace(time=np.empty(0), heading_deg=np.empty(0))
    return SimpleNamespace(positions=positions, headings=headings)


def test_one_fix_without_altitude_keeps_the_others():
    # One missing altitude used to make every altitude NaN.
    track = PoseTrack.from_nmea(_nmea_like([10.0, np.nan, 14.0, 16.0]), max_gap=2.5)
    pose = track.at([0.0, 0.5, 2.0, 2.5, 3.0])
    lat = 59.0 + 1e-4 * np.array([0.0, 0.5, 2.0, 2.5, 3.0])
    np.testing.assert_allclose(pose.lat_deg, lat, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        pose.altitude, np.interp([0.0, 0.5, 2.0, 2.5, 3.0], [0, 2, 3], [10, 14, 16])
    )
    # Altitude samples further apart than max_gap: position still known, altitude NaN.
    tight = PoseTrack.from_nmea(_nmea_like([10.0, np.nan, 14.0, 16.0]), max_gap=1.5)
    pose = tight.at([0.5, 1.0, 2.5])
    np.testing.assert_allclose(pose.lat_deg, 59.0 + 1e-4 * np.array([0.5, 1.0, 2.5]), atol=1e-12)
    np.testing.assert_array_equal(np.isnan(pose.altitude), [True, True, False])
    assert pose.altitude[2] == pytest.approx(15.0)
    # No altitude at all: NaN altitude, positions unaffected.
    none = PoseTrack.from_nmea(_nmea_like([np.nan] * 4))
    assert not none.has_altitude and np.all(np.isnan(none.at([0.5, 1.0]).altitude))


def test_constructor_altitude_gaps_keep_positions():
    t = [0.0, 1.0, 2.0]
    track = PoseTrack(t, [1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [5.0, np.nan, 7.0], max_gap=2.0)
    pose = track.at([1.0])
    assert pose.lat_deg[0] == 2.0 and pose.altitude[0] == pytest.approx(6.0)
    # The sample without altitude used to be dropped whole: a gap for the position too.
    track = PoseTrack(t, [1.0, 2.0, 3.0], [0.0, 0.0, 0.0], [5.0, np.nan, 7.0], max_gap=1.5)
    pose = track.at([0.5, 1.0, 2.0])
    np.testing.assert_allclose(pose.lat_deg, [1.5, 2.0, 3.0])
    np.testing.assert_array_equal(np.isnan(pose.altitude), [True, True, False])


def test_errors_name_the_arguments():
    with pytest.raises(TimeOrderError, match="heading_time"):
        PoseTrack([0.0, 1.0], [0, 0], [0, 0], heading_time=[1.0, 0.0], heading=[0.0, 0.1])
    with pytest.raises(TimeOrderError, match="position_time"):
        PoseTrack([1.0, 0.0], [0, 0], [0, 0])
    with pytest.raises(TimeOrderError, match="attitude_time"):
        PoseTrack([0.0], [0], [0], attitude_time=[1.0, 0.0], roll=[0, 0], pitch=[0, 0])
    with pytest.raises(TypeError, match="lat_deg"):
        PoseTrack([0.0], ["north"], [0.0])
    with pytest.raises(TypeError, match="heading"):
        PoseTrack([0.0], [0.0], [0.0], heading_time=[0.0], heading=[object()])
