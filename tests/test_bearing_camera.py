"""Eq. (1) of the bearing paper: known values, OpenCV pinhole parity, exact round trips."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import usvfast
from usvfast.bearing import (
    THERMAL_CAMERA,
    VISIBLE_CAMERA,
    BearingCamera,
    bearing_to_pixel,
    pixel_to_bearing,
)

PLAIN = BearingCamera(width_px=1000, height_px=500, hfov_deg=60.0, vfov_deg=32.0)


def test_paper_calibration_values():
    assert (VISIBLE_CAMERA.width_px, VISIBLE_CAMERA.height_px) == (1920, 1200)
    assert (VISIBLE_CAMERA.hfov_deg, VISIBLE_CAMERA.azimuth_offset_deg) == (20.0, -61.8)
    assert (VISIBLE_CAMERA.elevation_offset_deg, VISIBLE_CAMERA.horizon_roll_deg) == (3.5, -1.55)
    assert (THERMAL_CAMERA.width_px, THERMAL_CAMERA.height_px) == (320, 240)
    assert (THERMAL_CAMERA.hfov_deg, THERMAL_CAMERA.azimuth_offset_deg) == (19.0, -79.2)
    assert (THERMAL_CAMERA.elevation_offset_deg, THERMAL_CAMERA.horizon_roll_deg) == (2.7, 0.0)
    # vertical FoV for square pixels: the focal length in pixels is the same on both axes
    for cam in (VISIBLE_CAMERA, THERMAL_CAMERA):
        fx = cam.width_px / (2 * math.tan(math.radians(cam.hfov_deg / 2)))
        fy = cam.height_px / (2 * math.tan(math.radians(cam.vfov_deg / 2)))
        assert fx == pytest.approx(fy, rel=1e-12)


def test_known_values_centre_and_edges():
    cam = VISIBLE_CAMERA
    b, e = pixel_to_bearing(cam.width_px / 2, cam.height_px / 2, cam)
    assert b == pytest.approx(cam.azimuth_offset_deg, abs=1e-12)
    assert e == pytest.approx(cam.elevation_offset_deg, abs=1e-12)
    # right edge on the centre row: half the FoV to starboard, rotated by the horizon roll
    b, e = pixel_to_bearing(cam.width_px, cam.height_px / 2, cam)
    th = math.radians(cam.horizon_roll_deg)
    assert b == pytest.approx(-61.8 + math.cos(th) * 10.0, abs=1e-12)
    assert e == pytest.approx(3.5 - math.sin(th) * 10.0, abs=1e-12)
    # left edge, no roll: -f_x/2; bottom row: +f_y/2 (ψ grows downward)
    b, e = pixel_to_bearing([0.0, 500.0], [250.0, 500.0], PLAIN)
    np.testing.assert_allclose(b, [-30.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(e, [0.0, 16.0], atol=1e-12)


def test_pan_tilt_zoom_and_offsets():
    cam = BearingCamera(
        width_px=640, height_px=480, hfov_deg=40.0, vfov_deg=30.0, azimuth_offset_deg=10.0,
        elevation_offset_deg=-2.0, pan_deg=5.0, tilt_deg=1.0, zoom=2.0,
    )  # fmt: skip
    b, e = pixel_to_bearing(320.0, 240.0, cam)
    # (1/γ) [θp, θt] + [θ0, θε]
    assert b == pytest.approx(5.0 / 2 + 10.0)
    assert e == pytest.approx(1.0 / 2 - 2.0)
    # per-box pan overrides the camera's and broadcasts
    b, _ = pixel_to_bearing([320.0, 320.0], 240.0, cam, pan_deg=[0.0, 8.0], zoom=1.0)
    np.testing.assert_allclose(b, [10.0, 18.0])


@pytest.mark.parametrize("cam", [VISIBLE_CAMERA, THERMAL_CAMERA, PLAIN])
def test_matches_opencv_pinhole_without_roll(cam):
    """With θh = 0 and γ = 1, eq. (1)'s azimuth is the pinhole ray angle atan((x - cx)/f)."""
    cam = BearingCamera(**{**cam.to_dict(), "horizon_roll_deg": 0.0})
    rng = np.random.default_rng(3)
    pts = rng.uniform([0, 0], [cam.width_px, cam.height_px], size=(200, 2))
    fx = cam.width_px / (2 * math.tan(math.radians(cam.hfov_deg / 2)))
    fy = cam.height_px / (2 * math.tan(math.radians(cam.vfov_deg / 2)))
    k = np.array([[fx, 0, cam.width_px / 2], [0, fy, cam.height_px / 2], [0, 0, 1]])
    norm = cv2.undistortPoints(pts.reshape(-1, 1, 2), k, np.zeros(5)).reshape(-1, 2)
    b, e = pixel_to_bearing(pts[:, 0], pts[:, 1], cam, pan_deg=4.0)
    np.testing.assert_allclose(
        b, np.degrees(np.arctan(norm[:, 0])) + 4.0 + cam.azimuth_offset_deg, atol=1e-9
    )
    np.testing.assert_allclose(
        e, np.degrees(np.arctan(norm[:, 1])) + cam.elevation_offset_deg, atol=1e-9
    )


cameras = st.builds(
    BearingCamera,
    width_px=st.integers(64, 4096),
    height_px=st.integers(48, 3000),
    hfov_deg=st.floats(5.0, 120.0),
    vfov_deg=st.floats(5.0, 100.0),
    azimuth_offset_deg=st.floats(-180.0, 180.0),
    elevation_offset_deg=st.floats(-10.0, 10.0),
    horizon_roll_deg=st.floats(-10.0, 10.0),
    pan_deg=st.floats(-30.0, 30.0),
    tilt_deg=st.floats(-10.0, 10.0),
    zoom=st.floats(0.5, 4.0),
)


@given(cam=cameras, u=st.floats(-0.5, 1.5), v=st.floats(-0.5, 1.5))
def test_pixel_bearing_pixel_round_trip(cam, u, v):
    x, y = u * cam.width_px, v * cam.height_px
    b, e = pixel_to_bearing(x, y, cam)
    x2, y2 = bearing_to_pixel(b, e, cam)
    assert x2 == pytest.approx(x, abs=1e-6 * cam.width_px)
    assert y2 == pytest.approx(y, abs=1e-6 * cam.height_px)


@given(cam=cameras, db=st.floats(-40.0, 40.0), de=st.floats(-20.0, 20.0))
def test_bearing_pixel_bearing_round_trip(cam, db, de):
    # within the camera's ±90° (u = γ·Δβ after un-rolling, minus the pan)
    b = cam.azimuth_offset_deg + db / cam.zoom
    e = cam.elevation_offset_deg + de / cam.zoom
    x, y = bearing_to_pixel(b, e, cam)
    b2, e2 = pixel_to_bearing(x, y, cam)
    assert b2 == pytest.approx(b, abs=1e-9)
    assert e2 == pytest.approx(e, abs=1e-9)


def test_scalars_in_scalars_out():
    b, e = pixel_to_bearing(10.0, 20.0, PLAIN)
    x, y = bearing_to_pixel(1.0, 2.0, PLAIN)
    assert np.shape(b) == np.shape(e) == np.shape(x) == np.shape(y) == ()


def test_inverse_beyond_90_degrees_is_nan():
    x, y = bearing_to_pixel([0.0, 95.0, -100.0], [0.0, 0.0, 0.0], PLAIN)
    assert np.isfinite(x[0]) and np.isfinite(y[0])
    assert np.all(np.isnan(x[1:])) and np.all(np.isnan(y[1:]))


def test_bad_input_names_the_argument():
    with pytest.raises(usvfast.NonFiniteError, match="x_px"):
        pixel_to_bearing([1.0, np.nan], [1.0, 2.0], PLAIN)
    with pytest.raises(usvfast.NonFiniteError, match="elevation_deg"):
        bearing_to_pixel([1.0], [np.inf], PLAIN)
    with pytest.raises(ValueError, match="zoom"):
        pixel_to_bearing(1.0, 1.0, PLAIN, zoom=0.0)
    with pytest.raises(ValueError, match="x_px, y_px"):
        pixel_to_bearing([1.0, 2.0, 3.0], [1.0, 2.0], PLAIN)
    # Shape errors are DimensionErrors, as everywhere else.
    with pytest.raises(usvfast.DimensionError, match="x_px, y_px"):
        pixel_to_bearing([1.0, 2.0, 3.0], [1.0, 2.0], PLAIN)
    with pytest.raises(usvfast.DimensionError, match="bearing_deg, elevation_deg"):
        bearing_to_pixel([1.0, 2.0], [1.0, 2.0, 3.0], PLAIN)
    with pytest.raises(ValueError, match="hfov_deg"):
        BearingCamera(width_px=10, height_px=10, hfov_deg=180.0, vfov_deg=10.0)
    with pytest.raises(ValueError, match="width_px"):
        BearingCamera(width_px=0, height_px=10, hfov_deg=10.0, vfov_deg=10.0)
    with pytest.raises(ValueError, match="pan_deg"):
        BearingCamera(width_px=10, height_px=10, hfov_deg=10.0, vfov_deg=10.0, pan_deg=math.nan)
    with pytest.raises(ValueError, match="unknown field"):
        BearingCamera.from_dict({"width_px": 10, "height_px": 10, "hfov_deg": 10, "fov": 3})


def test_from_dict_derives_vertical_fov():
    cam = BearingCamera.from_dict({"width_px": 1920, "height_px": 1200, "hfov_deg": 20.0})
    assert cam.vfov_deg == pytest.approx(VISIBLE_CAMERA.vfov_deg, rel=1e-15)
    assert BearingCamera.from_dict(VISIBLE_CAMERA.to_dict()) == VISIBLE_CAMERA
