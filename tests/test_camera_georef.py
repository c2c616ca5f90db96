"""Georeferencing: the thesis's FOV model and its published numbers, the calibrated model
round trip through OpenCV's projection, and the covariance against Monte Carlo."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from usvfast import DimensionError, NonFiniteError
from usvfast.camera import (
    REASONS,
    FovCamera,
    box_contact_points,
    georeference,
    georeference_fov,
    mount_rotation,
    rotation_zyx,
    sensitivity,
)
from usvfast.camera.calibration import CameraModel

# The thesis's camera (sections 4.1, 5.3.6): 2688 x 1520 px, FOV 109 x 60 deg, 0.705 m (D2).
SIZE = (2688, 1520)
FOV = (109.0, 60.0)
H = 0.705
CAM = FovCamera(SIZE, FOV)


def thesis_code_5_6(u, v, height):
    """Code 5.6 with the camera looking ahead, written out: forward = h / tan(psi), starboard =
    forward * tan(theta) (psi the angle below the image centre)."""
    theta = (u - 1344) / 2688 * np.radians(109)
    psi = (v - 760) / 1520 * np.radians(60)
    return height / np.tan(psi), height * np.tan(theta) / np.tan(psi)


def pixels_of(forward, starboard, height):
    """Inverse of the thesis model (level camera): the pixel that lands on (forward, starboard)."""
    psi = np.arctan2(height, forward)
    theta = np.arctan2(starboard, forward)
    return 1344 + theta / np.radians(109) * 2688, 760 + psi / np.radians(60) * 1520


def test_fov_equals_thesis_code_on_a_grid():
    u, v = np.meshgrid(np.linspace(0, 2688, 25), np.linspace(800, 1520, 19))
    x, y = georeference_fov(u, v, image_size=SIZE, fov_deg=FOV, height=H)
    xr, yr = thesis_code_5_6(u, v, H)
    assert x.shape == u.shape
    np.testing.assert_allclose(x, xr, rtol=1e-12)
    np.testing.assert_allclose(y, yr, rtol=1e-12, atol=1e-12)


def test_fov_section_7_2_4_worked_numbers():
    """Section 7.2.4: at 84 deg from vertical (6 deg below the centre) and h = 0.705 m, a +1 deg
    tilt gives tan(85 deg) * 0.705 = 8.06 m; at h = 1.41 m and 78.2 deg,
    tan(79.2) * 1.41 = 7.39 m."""
    v84 = 760 + 6.0 / 60 * 1520
    x0, _ = georeference_fov(1344.0, v84, image_size=SIZE, fov_deg=FOV, height=0.705)
    x1, _ = georeference_fov(
        1344.0, v84, image_size=SIZE, fov_deg=FOV, height=0.705, mount_ypr_deg=(0, 1, 0)
    )
    assert float(x0) == pytest.approx(0.705 * np.tan(np.radians(84)), abs=1e-9)
    assert round(float(x1), 2) == 8.06
    v78 = 760 + (90 - 78.2) / 60 * 1520
    x2, _ = georeference_fov(
        1344.0, v78, image_size=SIZE, fov_deg=FOV, height=1.41, mount_ypr_deg=(0, 1, 0)
    )
    assert round(float(x2), 2) == 7.39


# Table 6.4 (pinhole, m): Boxes 1, 2, 4, 5, 6 (Box 3 cropped away).
T64 = np.array([[6.45, 1.60], [5.30, -2.22], [1.46, 0.02], [3.74, 1.24], [6.53, -0.66]])
# Table 6.6 rows: dx(+2px), dy(+2px), dx(-2px), dy(-2px).
T66 = np.array(
    [
        [0.07, 0.05, 0.01, 0.02, 0.08],
        [0.02, 0.03, 0.00, 0.01, 0.00],
        [0.15, 0.05, 0.00, 0.03, 0.08],
        [0.02, 0.02, 0.00, 0.01, 0.01],
    ]
)
# Table 6.7 rows: dx(+1deg), dy(+1deg), dx(-1deg), dy(-1deg).
T67 = np.array(
    [
        [1.15, 0.74, 0.05, 0.35, 1.18],
        [0.30, 0.33, 0.00, 0.12, 0.13],
        [0.84, 0.58, 0.05, 0.28, 0.86],
        [0.20, 0.25, 0.00, 0.10, 0.09],
    ]
)


def test_sensitivity_tables_6_6_and_6_7():
    """The box pixels of Figure 6.4 are not in the text, so they are recovered from Table 6.4 by
    inverting the thesis model; the sensitivities then follow. Table 6.6 and the starboard rows
    of Table 6.7 reproduce to the table's 1-2 cm rounding (Box 1 at -2 px excepted: the thesis
    prints 0.15 m where +2 px gives 0.07 m, which no smooth model does). The forward rows of
    Table 6.7 come out consistently 7-8 % larger than printed: the thesis does not say how its
    1 deg was applied, so this test bounds that gap instead of hiding it."""
    u, v = pixels_of(T64[:, 0], T64[:, 1], H)
    px = np.stack([u, v], axis=1)
    base = georeference(px, CAM, height=H).positions
    np.testing.assert_allclose(base, T64, atol=1e-9)
    s = sensitivity(px, CAM, height=H, pixels_step=2.0, pitch_step_deg=1.0)
    ours66 = np.stack(
        [s.pixel_plus[:, 0], s.pixel_plus[:, 1], s.pixel_minus[:, 0], s.pixel_minus[:, 1]]
    )
    mask = np.ones_like(T66, dtype=bool)
    mask[2, 0] = False
    np.testing.assert_allclose(ours66[mask], T66[mask], atol=0.015)
    ours67 = np.stack(
        [s.pitch_plus[:, 0], s.pitch_plus[:, 1], s.pitch_minus[:, 0], s.pitch_minus[:, 1]]
    )
    np.testing.assert_allclose(ours67[[1, 3]], T67[[1, 3]], atol=0.022)
    ratio = T67[[0, 2]] / ours67[[0, 2]]
    assert np.all((ratio > 0.72) & (ratio < 1.0)), ratio
    big = T67[[0, 2]] > 0.2
    assert np.all((ratio[big] > 0.84) & (ratio[big] < 0.95)), ratio


def test_horizon_rejected_with_reason():
    px = np.array([[1344.0, 760.0], [1344.0, 500.0], [1344.0, 1000.0]])
    res = georeference(px, CAM, height=H, pixel_sigma=1.0)
    assert [REASONS[r] for r in res.reason] == ["above_horizon", "above_horizon", "ok"]
    assert np.isnan(res.positions[:2]).all() and np.isnan(res.covariances[:2]).all()
    assert np.isfinite(res.covariances[2]).all()
    res = georeference(px, CAM, height=H, max_range=0.5)
    assert REASONS[res.reason[2]] == "beyond_max_range"


def test_bad_input_names_argument():
    with pytest.raises(DimensionError, match="pixels"):
        georeference(np.zeros(3), CAM, height=1.0)
    with pytest.raises(NonFiniteError, match="roll"):
        georeference(np.zeros((1, 2)), CAM, height=1.0, roll=np.nan)
    with pytest.raises(ValueError, match="height"):
        georeference(np.zeros((1, 2)), CAM, height=-1.0)
    with pytest.raises(ValueError, match="pixel_sigma"):
        georeference(np.zeros((1, 2)), CAM, height=1.0, pixel_sigma=-1)
    with pytest.raises(ValueError, match="boxes"):
        box_contact_points(np.zeros((2, 3)))


# --- calibrated camera ------------------------------------------------------------------
K = np.array([[900.0, 0.0, 652.0], [0.0, 905.0, 371.0], [0.0, 0.0, 1.0]])
PINHOLE = CameraModel(K, np.array([-0.28, 0.09, 0.0012, -0.0008, -0.012]), (1280, 720))
FISHEYE = CameraModel(K, np.array([0.05, -0.02, 0.004, -0.001]), (1280, 720), "fisheye")
MOUNT = mount_rotation((3.0, -8.0, 1.5))
MOUNT_POS = np.array([1.2, -0.3, -1.8])


def _project_water(cam, pts_level, roll, pitch, height):
    """Water points (n, 2) in the level frame -> pixels, through OpenCV's projection."""
    n = len(pts_level)
    roll, pitch = np.broadcast_to(roll, (n,)), np.broadcast_to(pitch, (n,))
    out = np.empty((n, 3))
    for i in range(n):
        r_lb = rotation_zyx(0.0, pitch[i], roll[i])
        c = r_lb @ MOUNT_POS
        p = np.array([pts_level[i, 0] - c[0], pts_level[i, 1] - c[1], height])
        out[i] = (r_lb @ MOUNT).T @ p
    return cam.project(out)


@pytest.mark.parametrize("cam", [PINHOLE, FISHEYE], ids=["pinhole", "fisheye"])
def test_calibrated_round_trip_1mm(cam):
    rng = np.random.default_rng(1)
    fwd = rng.uniform(4.0, 60.0, 300)
    stb = rng.uniform(-0.5, 0.5, 300) * fwd
    pts = np.stack([fwd, stb], axis=1)
    roll = rng.uniform(-0.08, 0.08, 300)
    pitch = rng.uniform(-0.05, 0.05, 300)
    px = _project_water(cam, pts, roll, pitch, 2.5)
    inside = (px[:, 0] > 0) & (px[:, 0] < 1280) & (px[:, 1] > 0) & (px[:, 1] < 720)
    assert inside.sum() > 100
    res = georeference(
        px[inside],
        cam,
        height=2.5,
        mount_rotation=MOUNT,
        mount_position=MOUNT_POS,
        roll=roll[inside],
        pitch=pitch[inside],
    )
    assert res.valid.all()
    np.testing.assert_allclose(res.positions, pts[inside], atol=1e-3)


def test_ned_output_rotates_and_shifts():
    px = _project_water(PINHOLE, np.array([[20.0, 5.0]]), 0.0, 0.0, 2.5)
    lvl = georeference(
        px, PINHOLE, height=2.5, mount_rotation=MOUNT, mount_position=MOUNT_POS, pixel_sigma=1.0
    )
    psi = np.radians(30.0)
    ned = georeference(
        px,
        PINHOLE,
        height=2.5,
        mount_rotation=MOUNT,
        mount_position=MOUNT_POS,
        pixel_sigma=1.0,
        heading=psi,
        vessel_ne=(100.0, -50.0),
    )
    r = np.array([[np.cos(psi), -np.sin(psi)], [np.sin(psi), np.cos(psi)]])
    np.testing.assert_allclose(ned.positions[0], r @ lvl.positions[0] + [100.0, -50.0], atol=1e-9)
    np.testing.assert_allclose(ned.covariances[0], r @ lvl.covariances[0] @ r.T, rtol=1e-9)
    assert ned.frame == "ned" and lvl.frame == "level"


@pytest.mark.parametrize("fwd,stb", [(8.0, 2.0), (25.0, -6.0), (45.0, 10.0)])
def test_covariance_matches_monte_carlo(fwd, stb):
    rng = np.random.default_rng(7)
    roll0, pitch0, h0 = 0.03, -0.02, 2.5
    sig_px, sig_att, sig_h = (1.5, 1.0), (np.radians(0.3), np.radians(0.2)), 0.03
    px0 = _project_water(PINHOLE, np.array([[fwd, stb]]), roll0, pitch0, h0)
    lin = georeference(
        px0,
        PINHOLE,
        height=h0,
        mount_rotation=MOUNT,
        mount_position=MOUNT_POS,
        roll=roll0,
        pitch=pitch0,
        pixel_sigma=sig_px,
        attitude_sigma=sig_att,
        height_sigma=sig_h,
    )
    m = 40_000
    px = px0 + rng.normal(size=(m, 2)) * sig_px
    mc = georeference(
        px,
        PINHOLE,
        height=h0 + sig_h * rng.normal(size=m),
        mount_rotation=MOUNT,
        mount_position=MOUNT_POS,
        roll=roll0 + sig_att[0] * rng.normal(size=m),
        pitch=pitch0 + sig_att[1] * rng.normal(size=m),
    )
    assert mc.valid.all()
    emp = np.cov(mc.positions.T)
    cov = lin.covariances[0]
    # Compare the ellipse: each standard deviation along the principal axes within 5 %.
    w, vec = np.linalg.eigh(cov)
    emp_axes = np.einsum("ij,jk,ki->i", vec.T, emp, vec)
    np.testing.assert_allclose(np.sqrt(emp_axes), np.sqrt(w), rtol=0.05)
    np.testing.assert_allclose(emp, cov, rtol=0.1, atol=0.05 * np.sqrt(w[0] * w[1]))
    # Far detections get long thin ellipses along the line of sight.
    assert w[1] / w[0] > 2.0


@given(
    st.floats(1344.0 - 1000, 1344.0 + 1000),
    st.floats(790.0, 1520.0),
    st.floats(0.3, 5.0),
)
def test_fov_matches_code_5_6_property(u, v, h):
    x, y = georeference_fov(u, v, image_size=SIZE, fov_deg=FOV, height=h)
    xr, yr = thesis_code_5_6(u, v, h)
    assert float(x) == pytest.approx(xr, rel=1e-10)
    assert float(y) == pytest.approx(yr, rel=1e-10, abs=1e-10)


def test_offset_and_mount_yaw():
    x0, y0 = georeference_fov(1500.0, 1100.0, image_size=SIZE, fov_deg=FOV, height=1.0)
    x1, y1 = georeference_fov(
        1500.0, 1100.0, image_size=SIZE, fov_deg=FOV, height=1.0, offset=(0.5, -0.2)
    )
    assert (x1 - x0, y1 - y0) == pytest.approx((0.5, -0.2))
    # Yawing the camera 90 deg to starboard: what was ahead is now to starboard.
    x2, y2 = georeference_fov(
        1500.0, 1100.0, image_size=SIZE, fov_deg=FOV, height=1.0, mount_ypr_deg=(90.0, 0.0, 0.0)
    )
    assert (float(x2), float(y2)) == pytest.approx((-float(y0), float(x0)))


@pytest.mark.parametrize("cam", [CAM, PINHOLE], ids=["fov", "pinhole"])
@pytest.mark.parametrize("roll,pitch", [(0.0, 0.0), (0.04, -0.06), (-0.05, 0.03)])
def test_horizon_line_separates_valid_from_rejected(cam, roll, pitch):
    from usvfast.camera import horizon_line

    r = mount_rotation((0.0, -4.0, 0.0))
    a, b = horizon_line(cam, mount_rotation=r, roll=roll, pitch=pitch, spread_deg=5.0)
    w = cam.image_size[0]
    u = np.linspace(0.4 * w, 0.6 * w, 7)
    v = a * u + b
    below = georeference(
        np.stack([u, v + 3], 1), cam, height=2.0, mount_rotation=r, roll=roll, pitch=pitch
    )
    above = georeference(
        np.stack([u, v - 3], 1), cam, height=2.0, mount_rotation=r, roll=roll, pitch=pitch
    )
    assert below.valid.all() and not above.valid.any()
    if cam is CAM and roll == 0.0 and pitch == 0.0:
        assert (a, b) == pytest.approx((0.0, 760.0 - 4.0 / 60.0 * 1520.0), abs=1e-9)


def test_rays_at_the_horizon_and_overflow_are_not_ok():
    # Rolled 90 degrees the image's vertical centre line is horizontal up to round-off (this
    # ray gave ~7e16 m marked "ok").
    g = georeference([[1344.0, 1000.0]], CAM, height=H, roll=np.pi / 2)
    assert REASONS[g.reason[0]] == "above_horizon"
    assert np.all(np.isnan(g.positions)) and np.all(np.isnan(g.covariances))
    # A height that overflows the position is not "ok" with inf either.
    g = georeference([[1344.0, 1200.0]], CAM, height=1e308, height_sigma=1.0)
    assert REASONS[g.reason[0]] == "above_horizon"
    assert np.all(np.isnan(g.positions)) and np.all(np.isnan(g.covariances))


def test_bad_arguments_are_named_not_internal():
    px = [[1344.0, 1000.0]]
    with pytest.raises(ValueError, match="mount_rotation"):
        georeference(px, CAM, height=H, mount_rotation=np.eye(2))
    with pytest.raises(ValueError, match="mount_rotation"):
        georeference(px, CAM, height=H, mount_rotation=2 * np.eye(3))
    with pytest.raises(ValueError, match="height_sigma"):
        georeference(px, CAM, height=H, height_sigma=-1.0)
    with pytest.raises(ValueError, match="heading_sigma"):
        georeference(px, CAM, height=H, heading=0.0, heading_sigma=-1.0)
    with pytest.raises(ValueError, match="heading_sigma"):
        georeference(px, CAM, height=H, heading_sigma=0.01)  # no heading: would be ignored
    for size in ((0, 0), (100, -1), (100,)):
        with pytest.raises(ValueError, match="image_size"):
            FovCamera(size, FOV)
    for fov in ((0.0, 60.0), (109.0, -1.0), (180.0, 60.0), (np.nan, 60.0)):
        with pytest.raises(ValueError, match="fov_deg"):
            FovCamera(SIZE, fov)


def test_horizon_line_needs_finite_attitude_and_spread():
    from usvfast.camera import horizon_line

    with pytest.raises(ValueError, match="spread_deg"):
        horizon_line(CAM, spread_deg=0.0)
    with pytest.raises(ValueError, match="pitch"):
        horizon_line(CAM, pitch=np.nan)
    with pytest.raises(ValueError, match="roll"):
        horizon_line(CAM, roll=np.inf)
    a, b = horizon_line(CAM)
    assert np.isfinite(a) and np.isfinite(b)


def test_max_range_is_from_the_camera_in_ned_too():
    # Camera 10 m to starboard looking ahead: a contact straight ahead of it at f metres is f
    # from the camera but sqrt(f² + 100) from the vessel reference point.
    pos = (0.0, 10.0, -H)
    px = [[1344.0, 900.0]]
    f = georeference(px, CAM, height=H, mount_position=pos).positions[0, 0]
    assert 5.0 < f < 40.0
    for heading, ne in ((0.0, None), (np.pi / 2, (100.0, -50.0)), (-2.0, (3.0, 4.0))):
        kw = {} if ne is None and heading == 0.0 else {"heading": heading, "vessel_ne": ne}
        keep = georeference(px, CAM, height=H, mount_position=pos, max_range=f + 1.0, **kw)
        drop = georeference(px, CAM, height=H, mount_position=pos, max_range=f - 1.0, **kw)
        assert REASONS[keep.reason[0]] == "ok", heading
        assert REASONS[drop.reason[0]] == "beyond_max_range", heading
