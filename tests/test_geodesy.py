"""usvfast.geodesy equals pymap3d (the peer) to well under 1 mm over the whole globe, and
round-trips to nanometres; same names, argument order, shapes and scalar behaviour."""

from __future__ import annotations

import inspect

import numpy as np
import pymap3d
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from usvfast import DimensionError, NonFiniteError
from usvfast import geodesy as ug

A = 6378137.0
MM = 1e-3
NAMES = [
    "geodetic2ecef",
    "ecef2geodetic",
    "geodetic2ned",
    "ned2geodetic",
    "geodetic2enu",
    "enu2geodetic",
    "ecef2ned",
    "ned2ecef",
    "ecef2enu",
    "enu2ecef",
]

# Edge values are drawn often: poles, equator, antimeridian.
lat_s = st.one_of(
    st.floats(-90.0, 90.0),
    st.sampled_from([-90.0, 90.0, 0.0, 89.9999999, -89.9999999, 45.0]),
)
lon_s = st.one_of(
    st.floats(-180.0, 180.0),
    st.sampled_from([-180.0, 180.0, 179.9999999, -179.9999999, 0.0]),
)
alt_s = st.floats(-1000.0, 100_000.0)


def points(n_min=1, n_max=40):
    n = st.integers(n_min, n_max)
    return n.flatmap(
        lambda k: st.tuples(
            hnp.arrays(np.float64, k, elements=lat_s),
            hnp.arrays(np.float64, k, elements=lon_s),
            hnp.arrays(np.float64, k, elements=alt_s),
        )
    )


def ground_error(lat1, lon1, lat2, lon2):
    """Approximate horizontal distance (m) between two geodetic points a few mm apart."""
    dlat = np.radians(lat1 - lat2)
    dlon = np.radians((lon1 - lon2 + 180.0) % 360.0 - 180.0)
    return A * np.hypot(dlat, dlon * np.cos(np.radians(lat1)))


@pytest.mark.parametrize("name", NAMES)
def test_same_signature_as_pymap3d(name):
    ours = list(inspect.signature(getattr(ug, name)).parameters)
    theirs = list(inspect.signature(getattr(pymap3d, name)).parameters)
    assert ours == theirs


@given(points())
def test_geodetic2ecef_equals_pymap3d(p):
    lat, lon, alt = p
    ours = ug.geodetic2ecef(lat, lon, alt)
    theirs = pymap3d.geodetic2ecef(lat, lon, alt)
    for a, b in zip(ours, theirs, strict=True):
        assert a.shape == lat.shape
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-6)


@given(points())
def test_ecef2geodetic_equals_pymap3d_and_round_trips(p):
    lat, lon, alt = p
    x, y, z = pymap3d.geodetic2ecef(lat, lon, alt)
    lat1, lon1, alt1 = ug.ecef2geodetic(x, y, z)
    lat2, lon2, alt2 = pymap3d.ecef2geodetic(x, y, z)
    assert np.all(ground_error(lat1, lon1, lat2, lon2) < MM)
    np.testing.assert_allclose(alt1, alt2, rtol=0, atol=MM)
    # Against the truth the points were made from: far tighter than pymap3d's tolerance.
    assert np.all(ground_error(lat1, lon1, lat, lon) < 1e-6)
    np.testing.assert_allclose(alt1, alt, rtol=0, atol=1e-6)
    assert np.all((lon1 > -180.0) | np.isclose(lon1, -180.0)) and np.all(lon1 <= 180.0)


@given(points(), lat_s, lon_s, st.floats(-100.0, 1000.0))
def test_local_frames_equal_pymap3d(p, lat0, lon0, h0):
    lat, lon, alt = p
    for fwd, inv in [("geodetic2ned", "ned2geodetic"), ("geodetic2enu", "enu2geodetic")]:
        ours = getattr(ug, fwd)(lat, lon, alt, lat0, lon0, h0)
        theirs = getattr(pymap3d, fwd)(lat, lon, alt, lat0, lon0, h0)
        for a, b in zip(ours, theirs, strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=MM)
        back = getattr(ug, inv)(*ours, lat0, lon0, h0)
        peer = getattr(pymap3d, inv)(*ours, lat0, lon0, h0)
        assert np.all(ground_error(back[0], back[1], peer[0], peer[1]) < MM)
        np.testing.assert_allclose(back[2], peer[2], rtol=0, atol=MM)
        assert np.all(ground_error(back[0], back[1], lat, lon) < 1e-6)
        np.testing.assert_allclose(back[2], alt, rtol=0, atol=1e-6)


@given(points(), lat_s, lon_s, st.floats(-100.0, 1000.0))
def test_ecef_local_equal_pymap3d(p, lat0, lon0, h0):
    x, y, z = pymap3d.geodetic2ecef(*p)
    for fwd, inv in [("ecef2ned", "ned2ecef"), ("ecef2enu", "enu2ecef")]:
        ours = getattr(ug, fwd)(x, y, z, lat0, lon0, h0)
        theirs = getattr(pymap3d, fwd)(x, y, z, lat0, lon0, h0)
        for a, b in zip(ours, theirs, strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=MM)
        back = getattr(ug, inv)(*ours, lat0, lon0, h0)
        peer = getattr(pymap3d, inv)(*ours, lat0, lon0, h0)
        for a, b, c in zip(back, peer, (x, y, z), strict=True):
            np.testing.assert_allclose(a, b, rtol=0, atol=MM)
            np.testing.assert_allclose(a, c, rtol=0, atol=1e-6)


def test_poles_and_antimeridian_exactly():
    lat = np.array([90.0, -90.0, 90.0, 0.0, 0.0, -45.0])
    lon = np.array([0.0, 123.0, -180.0, 180.0, -180.0, 180.0])
    alt = np.array([0.0, 100.0, -1000.0, 5.0, 100_000.0, 0.0])
    x, y, z = ug.geodetic2ecef(lat, lon, alt)
    lat1, lon1, alt1 = ug.ecef2geodetic(x, y, z)
    np.testing.assert_allclose(lat1, lat, rtol=0, atol=1e-12)
    np.testing.assert_allclose(alt1, alt, rtol=0, atol=1e-8)
    # Longitude is only defined off the poles; ±180 are the same meridian.
    off = np.abs(lat) < 90
    assert np.all(ground_error(lat1[off], lon1[off], lat[off], lon[off]) < 1e-8)


def test_radians_and_other_ellipsoid():
    grs80 = pymap3d.Ellipsoid.from_name("grs80")
    lat, lon, h = np.radians([10.0, -60.0]), np.radians([170.0, -5.0]), np.array([3.0, 4.0])
    ours = ug.geodetic2ecef(lat, lon, h, grs80, deg=False)
    theirs = pymap3d.geodetic2ecef(lat, lon, h, grs80, deg=False)
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-6)
    back = ug.ecef2geodetic(*ours, ell=grs80, deg=False)
    np.testing.assert_allclose(back[0], lat, rtol=0, atol=1e-12)
    ned = ug.geodetic2ned(lat, lon, h, 0.1, 0.2, 0.0, grs80, False)
    peer = pymap3d.geodetic2ned(lat, lon, h, 0.1, 0.2, 0.0, grs80, False)
    np.testing.assert_allclose(ned, peer, rtol=0, atol=MM)


def test_shapes_like_pymap3d():
    # Scalars in -> numpy float64 scalars out.
    ours = ug.geodetic2ecef(10, 20, 30)
    for a, b in zip(ours, pymap3d.geodetic2ecef(10, 20, 30), strict=True):
        assert isinstance(a, np.float64) and np.ndim(a) == 0
        assert a == pytest.approx(b, abs=1e-6)
    # 2-D arrays keep their shape; lists work; a single origin broadcasts.
    lat = np.linspace(-80, 80, 6).reshape(2, 3)
    n, e, d = ug.geodetic2ned(lat, [[1.0, 2.0, 3.0]], 0.0, 1.0, 2.0, 3.0)
    assert n.shape == e.shape == d.shape == (2, 3)
    peer = pymap3d.geodetic2ned(lat, np.array([[1.0, 2.0, 3.0]]), 0.0, 1.0, 2.0, 3.0)
    np.testing.assert_allclose((n, e, d), peer, rtol=0, atol=MM)
    # Per-point origins broadcast too and equal one call per origin.
    lat0 = np.array([1.0, 50.0, -30.0])
    n, e, d = ug.geodetic2enu(10.0, 20.0, 0.0, lat0, 21.0, 5.0)
    for i in range(3):
        one = ug.geodetic2enu(10.0, 20.0, 0.0, lat0[i], 21.0, 5.0)
        assert (n[i], e[i], d[i]) == one
    empty = ug.ecef2geodetic(np.empty((0, 2)), 0.0, 0.0)
    assert all(a.shape == (0, 2) for a in empty)


def test_bad_input_fails_loudly_naming_the_argument():
    with pytest.raises(ValueError, match="lat"):
        ug.geodetic2ecef(90.5, 0, 0)
    with pytest.raises(ValueError, match="lat0"):
        ug.geodetic2ned(0, 0, 0, -91.0, 0, 0)
    with pytest.raises(NonFiniteError, match="y"):
        ug.ecef2geodetic([1e7, 2e7], [np.nan, 0.0], 0.0)
    with pytest.raises(DimensionError, match="broadcast"):
        ug.geodetic2ecef([1.0, 2.0], [1.0, 2.0, 3.0], 0.0)
    with pytest.raises(TypeError, match="ell"):
        ug.geodetic2ecef(1.0, 2.0, 3.0, ell="wgs84")
    with pytest.raises(TypeError, match="lat"):
        ug.geodetic2ecef("north", 2.0, 3.0)
