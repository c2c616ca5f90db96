"""Eq. (2): AIS relative bearing against pymap3d on a sphere and a 3-D vector computation;
vessel-track interpolation; AIS reporting intervals."""

from __future__ import annotations

import numpy as np
import pymap3d
import pytest
from hypothesis import given
from hypothesis import strategies as st

import usvfast
from usvfast.bearing import (
    VesselTrack,
    ais_report_interval_s,
    reference_bearing_deg,
    relative_bearing_deg,
    wrap_deg,
)

SPHERE = pymap3d.Ellipsoid(semimajor_axis=6_371_008.8, semiminor_axis=6_371_008.8)


def vector_bearing_deg(lat1, lon1, lat2, lon2):
    """Great-circle initial bearing from unit vectors: the chord projected on the local
    north/east plane at point 1 (an independent construction of eq. (2)'s atan2)."""
    p1, l1, p2, l2 = np.radians([lat1, lon1, lat2, lon2])
    r2 = np.array([np.cos(p2) * np.cos(l2), np.cos(p2) * np.sin(l2), np.sin(p2)])
    r1 = np.array([np.cos(p1) * np.cos(l1), np.cos(p1) * np.sin(l1), np.sin(p1)])
    north = np.array([-np.sin(p1) * np.cos(l1), -np.sin(p1) * np.sin(l1), np.cos(p1)])
    east = np.array([-np.sin(l1), np.cos(l1), 0.0])
    d = r2 - r1
    return np.degrees(np.arctan2(d @ east, d @ north))


def angle_diff(a, b):
    return np.abs(wrap_deg(np.asarray(a) - np.asarray(b)))


@given(
    lat=st.floats(-80.0, 80.0),
    lon=st.floats(-180.0, 180.0),
    heading=st.floats(0.0, 360.0),
    dist_m=st.floats(50.0, 50_000.0),
    az=st.floats(-180.0, 180.0),
)
def test_matches_pymap3d_on_a_sphere(lat, lon, heading, dist_m, az):
    # place the target with pymap3d (ENU on the sphere), then compare its azimuth
    e, n = dist_m * np.sin(np.radians(az)), dist_m * np.cos(np.radians(az))
    lat_t, lon_t, _ = pymap3d.enu2geodetic(e, n, 0.0, lat, lon, 0.0, ell=SPHERE)
    az_peer, _, _ = pymap3d.geodetic2aer(lat_t, lon_t, 0.0, lat, lon, 0.0, ell=SPHERE)
    ours = relative_bearing_deg(lat, lon, heading, lat_t, wrap_deg(lon_t))
    # pymap3d's enu2aer zeroes |e| or |n| below 1 mm ("singularity stability"), so its azimuth
    # is only exact when both components are larger than that.
    if min(abs(e), abs(n)) >= 1e-3:
        assert angle_diff(ours, az_peer - heading) < 1e-7
    assert angle_diff(ours, vector_bearing_deg(lat, lon, lat_t, lon_t) - heading) < 1e-7
    assert -180.0 < ours <= 180.0


def test_random_global_pairs_match_vector_formula():
    rng = np.random.default_rng(11)
    n = 2000
    lat1, lat2 = rng.uniform(-89, 89, (2, n))
    lon1, lon2 = rng.uniform(-180, 180, (2, n))
    heading = rng.uniform(-720, 720, n)
    ours = relative_bearing_deg(lat1, lon1, heading, lat2, lon2)
    ref = np.array([vector_bearing_deg(*p) for p in zip(lat1, lon1, lat2, lon2, strict=True)])
    assert np.max(angle_diff(ours, ref - heading)) < 1e-8
    assert np.all((ours > -180.0) & (ours <= 180.0))


def test_sign_convention_known_values():
    lat, lon = 59.8, 24.85
    north, east = (lat + 0.01, lon), (lat, lon + 0.02)
    south = (lat - 0.01, lon)
    # heading north: a target to the east is +90 (starboard), dead astern is +180 not -180
    assert relative_bearing_deg(lat, lon, 0.0, *east) == pytest.approx(90.0, abs=0.02)
    assert relative_bearing_deg(lat, lon, 0.0, *north) == pytest.approx(0.0, abs=1e-9)
    assert relative_bearing_deg(lat, lon, 0.0, *south) == 180.0
    # heading east: a target to the north is on the port beam
    assert relative_bearing_deg(lat, lon, 90.0, *north) == pytest.approx(-90.0, abs=1e-9)
    assert relative_bearing_deg(lat, lon, 450.0, *north) == pytest.approx(-90.0, abs=1e-9)


def test_wrap_deg_interval():
    a = np.array([-540.0, -180.0, -179.5, 0.0, 180.0, 180.5, 359.0, 720.0])
    np.testing.assert_allclose(wrap_deg(a), [180.0, 180.0, -179.5, 0.0, 180.0, -179.5, -1.0, 0.0])


def test_bad_positions_name_the_argument():
    with pytest.raises(ValueError, match="lat2_deg"):
        relative_bearing_deg(0.0, 0.0, 0.0, 91.0, 0.0)
    with pytest.raises(usvfast.NonFiniteError, match="own_heading_deg"):
        relative_bearing_deg(0.0, 0.0, np.nan, 1.0, 0.0)


def test_ais_report_intervals_itu_r_m1371():
    assert ais_report_interval_s(0.0, moored=True) == 180.0
    assert ais_report_interval_s(8.0) == 10.0
    assert ais_report_interval_s(8.0, changing_course=True) == pytest.approx(10.0 / 3.0)
    assert ais_report_interval_s(14.0) == 10.0
    assert ais_report_interval_s(18.0) == 6.0
    assert ais_report_interval_s(18.0, changing_course=True) == 2.0
    assert ais_report_interval_s(30.0) == 2.0
    with pytest.raises(ValueError, match="speed_kn"):
        ais_report_interval_s(-1.0)


def test_track_interpolation_wraps_heading_and_longitude():
    track = VesselTrack(
        times=np.array([0.0, 10.0]),
        lat_deg=np.array([10.0, 11.0]),
        lon_deg=np.array([179.9, -179.9]),
        heading_deg=np.array([350.0, 10.0]),
    )
    lat, lon, heading = track.at([-1.0, 0.0, 5.0, 10.0, 11.0])
    np.testing.assert_allclose(lat[1:4], [10.0, 10.5, 11.0])
    np.testing.assert_allclose(lon[1:4], [179.9, 180.0, -179.9], atol=1e-9)
    np.testing.assert_allclose(heading[1:4], [350.0, 0.0, 10.0], atol=1e-9)
    assert np.isnan(lat[[0, 4]]).all() and np.isnan(heading[[0, 4]]).all()


def test_reference_bearing_interpolates_both_tracks():
    own = VesselTrack(np.array([0.0, 20.0]), np.array([59.8, 59.8]), np.array([24.85, 24.85]),
                      np.array([0.0, 0.0]))  # fmt: skip
    target = VesselTrack(np.array([5.0, 15.0]), np.array([59.9, 59.7]), np.array([24.9, 24.9]))
    ref = reference_bearing_deg([0.0, 10.0, 12.0, 20.0], own, target)
    assert np.isnan(ref[0]) and np.isnan(ref[3])
    # at t = 10 the target is due east at the same latitude (slightly south of east on a sphere)
    expected = relative_bearing_deg(59.8, 24.85, 0.0, 59.8, 24.9)
    assert ref[1] == pytest.approx(float(expected), abs=1e-9)
    assert ref[2] > ref[1]  # moving south: bearing grows towards the stern


def test_track_bad_input():
    with pytest.raises(usvfast.TimeOrderError, match="times"):
        VesselTrack(np.array([0.0, 0.0]), np.zeros(2), np.zeros(2))
    with pytest.raises(usvfast.DimensionError, match="lon_deg"):
        VesselTrack(np.array([0.0, 1.0]), np.zeros(2), np.zeros(3))
    with pytest.raises(usvfast.NonFiniteError, match="heading_deg"):
        VesselTrack(np.array([0.0, 1.0]), np.zeros(2), np.zeros(2), np.array([0.0, np.nan]))
    with pytest.raises(ValueError, match="at least 2"):
        VesselTrack(np.array([0.0]), np.zeros(1), np.zeros(1))
    target = VesselTrack(np.array([0.0, 1.0]), np.zeros(2), np.zeros(2))
    with pytest.raises(ValueError, match="own"):
        reference_bearing_deg([0.5], target, target)
