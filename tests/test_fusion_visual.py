"""Fused targets in the camera (§1.4 of the radar/AIS/visible paper) and the camera ↔ VTS
rotation: projections equal OpenCV's `projectPoints` with the camera pose as rvec/tvec, invert
exactly through `usvfast.camera.georeference`; targets behind, outside the image or beyond
the horizon are never matched; γ matching is one-to-one under γ_max; θ in closed form equals
scipy's `Rotation.align_vectors`, and the calibrator resolves ambiguous candidates."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from usvfast.camera import CameraModel, georeference, mount_rotation, rotation_zyx
from usvfast.fusion.rotation import RotationCalibrator, rotation_from_velocities
from usvfast.fusion.visual import (
    BEHIND,
    BEYOND_HORIZON,
    OUTSIDE,
    VISIBLE,
    horizon_distance,
    match_detections,
    project_targets,
)

CAM = CameraModel(
    np.array([[800.0, 0, 640], [0, 800.0, 360], [0, 0, 1]]),
    np.array([-0.05, 0.01, 0.0, 0.0, 0.0]),
    (1280, 720),
)
OWN = np.array([100.0, -50.0])
HEADING = math.radians(30.0)
POSE = dict(own_ne=OWN, heading=HEADING, height=10.0, roll=0.02, pitch=-0.01)
MOUNT = mount_rotation((5.0, -2.0, 0.0))


def _targets():
    brg = np.radians([30.0, 40.0, 20.0, 210.0, 120.0, 30.0])
    rng = np.array([500.0, 800.0, 300.0, 400.0, 600.0, 20000.0])
    return OWN + np.stack([rng * np.cos(brg), rng * np.sin(brg)], axis=1)


def test_projection_equals_opencv_and_inverts_through_georeference():
    t = _targets()
    proj = project_targets(t, CAM, mount_rotation=MOUNT, **POSE)
    assert proj.reason.tolist() == [VISIBLE] * 3 + [BEHIND, OUTSIDE, BEYOND_HORIZON]
    r_nc = rotation_zyx(HEADING, -0.01, 0.02) @ MOUNT
    cam = np.array([OWN[0], OWN[1], -10.0])
    world = np.column_stack([t, np.zeros(len(t))])[:3]
    rvec, _ = cv2.Rodrigues(r_nc.T)
    px, _ = cv2.projectPoints(world, rvec, -r_nc.T @ cam, CAM.camera_matrix, CAM.dist_coeffs)
    np.testing.assert_allclose(proj.pixels[:3], px.reshape(-1, 2), atol=1e-6)
    geo = georeference(
        proj.pixels[:3],
        CAM,
        height=10.0,
        mount_rotation=MOUNT,
        roll=0.02,
        pitch=-0.01,
        heading=HEADING,
        vessel_ne=OWN,
    )
    np.testing.assert_allclose(geo.positions, t[:3], atol=1e-3)
    np.testing.assert_allclose(proj.range_m[:3], [500, 800, 300], rtol=1e-12)
    np.testing.assert_allclose(proj.bearing_deg[:3], [30, 40, 20], atol=1e-9)
    assert horizon_distance(10.0) == pytest.approx(11288, rel=1e-3)


def test_gamma_matching_one_to_one_under_gamma_max():
    t = _targets()
    proj = project_targets(t, CAM, mount_rotation=MOUNT, aim_height=2.0, **POSE)
    u, v = proj.pixels[0]
    boxes = np.array(
        [
            [u - 20, v - 10, u + 20, v + 10],  # centred on target 0
            [u - 18, v - 12, u + 22, v + 8],  # a second box on it: one-to-one
            [proj.pixels[1, 0] + 60, 300, proj.pixels[1, 0] + 100, 340],  # ~3-4 deg off target 1
            [0, 0, 40, 40],  # sky, nothing
        ]
    )
    pairs, gamma = match_detections(proj, CAM, boxes, gamma_max_deg=2.0)
    assert pairs == [(0, 0)]
    assert gamma[0, 0] < 1e-6 and 2.0 < gamma[1, 2] < 8.0
    assert np.all(np.isnan(gamma[3:]))  # behind, outside, beyond the horizon: never matched
    pairs, _ = match_detections(proj, CAM, boxes, gamma_max_deg=10.0)
    assert (1, 2) in pairs and (0, 0) in pairs
    with pytest.raises(ValueError, match="gamma_max_deg"):
        match_detections(proj, CAM, boxes, gamma_max_deg=0.0)
    with pytest.raises(ValueError, match="height"):
        project_targets(t, CAM, own_ne=OWN, heading=0.0, height=-1.0)


@pytest.mark.parametrize("theta_deg", [-170.0, -25.0, 0.0, 37.0, 120.0])
def test_rotation_equals_scipy_align_vectors(theta_deg):
    rng = np.random.default_rng(int(theta_deg) + 200)
    v_c = rng.normal(0, 5, (20, 2))
    th = math.radians(theta_deg)
    rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    v_r = v_c @ rot.T + rng.normal(0, 0.3, (20, 2))
    theta, spread = rotation_from_velocities(v_c, v_r)
    pad = np.zeros((20, 1))
    ref, _ = Rotation.align_vectors(np.hstack([v_r, pad]), np.hstack([v_c, pad]))
    assert theta == pytest.approx(ref.as_rotvec()[2], abs=1e-9)
    assert abs(math.degrees(theta) - theta_deg) < 2.0 and 0 < spread < math.radians(10)
    with pytest.raises(ValueError, match="v_camera"):
        rotation_from_velocities(v_c[:3], v_r)
    # scale-free: the same θ and spread from vectors near float64's ends (products overflow
    # or underflow unscaled), and the inputs are left as they were
    big, tiny = v_c * 1e250, v_r * 1e-250
    t2, s2 = rotation_from_velocities(big, tiny, np.full(20, 1e-200))
    assert t2 == pytest.approx(theta, abs=1e-12) and s2 == pytest.approx(spread, rel=1e-9)
    np.testing.assert_array_equal(big, v_c * 1e250)


def test_calibrator_keeps_candidates_until_unique():
    th = math.radians(25.0)
    rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    rng = np.random.default_rng(5)
    cal = RotationCalibrator(speed_tol=0.5, angle_tol_deg=8.0)
    history = []
    for k in range(30):
        # VTS vessels 10 and 11 have the same speed; 11 starts turning at k = 10, 12 is faster.
        a10 = 0.3
        a11 = 0.3 + (0.15 * (k - 10) if k > 10 else 0.0)
        vts = {
            10: 5 * np.array([math.cos(a10), math.sin(a10)]),
            11: 5 * np.array([math.cos(a11 + 2.0), math.sin(a11 + 2.0)]),
            12: np.array([8.0, 1.0]),
        }
        # The camera sees 10 and 11 as camera tracks 1 and 2, rotated by -theta.
        cam = {1: rot.T @ vts[10], 2: rot.T @ vts[11]}
        cam = {i: v + rng.normal(0, 0.05, 2) for i, v in cam.items()}
        cal.add(list(cam), np.array(list(cam.values())), list(vts), np.array(list(vts.values())))
        history.append(cal.matches())
    # Same speeds and both straight at first: camera track 1 could be 10 or 11 (the relative
    # angle is constant for both) until 11 turns.
    assert cal.candidates()[1] == [10] and history[-1] == {1: 10, 2: 11}
    assert history[2] != {1: 10, 2: 11}
    theta, spread, n = cal.estimate()
    assert abs(math.degrees(theta) - 25.0) < 0.5 and math.degrees(spread) < 1.5 and n >= 40
