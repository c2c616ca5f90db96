"""Calibration from synthetic checkerboard images rendered through a known camera (OpenCV's
own distortion model), recovering the intrinsics; camera_info YAML / JSON round trips."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from usvfast.camera.calibration import CameraModel, board_points, calibrate

BOARD = (9, 6)  # inner corners (columns, rows)
SQUARE = 0.04  # m
W, H = 640, 480
K = np.array([[500.0, 0.0, 323.0], [0.0, 496.0, 238.0], [0.0, 0.0, 1.0]])


def pixel_rays(cam: CameraModel) -> np.ndarray:
    """The ray (x_n, y_n, 1) of every pixel of `cam`'s image, (H * W, 3)."""
    uu, vv = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    norm = cam._undistort(np.stack([uu.ravel(), vv.ravel()], axis=1))
    return np.hstack([norm, np.ones((len(norm), 1))])


def render(rays: np.ndarray, rvec, tvec, px_per_square: int = 24) -> np.ndarray:
    """Image of the board at pose (rvec, tvec) seen through `rays` (see `pixel_rays`): every
    pixel's ray is intersected with the board plane and looked up in a texture (cv2.remap)."""
    cols, rows = BOARD[0] + 1, BOARD[1] + 1
    margin = 1
    tex = np.full(
        ((rows + 2 * margin) * px_per_square, (cols + 2 * margin) * px_per_square), 255, np.uint8
    )
    for r in range(rows):
        for c in range(cols):
            if (r + c) % 2 == 0:
                y0, x0 = (r + margin) * px_per_square, (c + margin) * px_per_square
                tex[y0 : y0 + px_per_square, x0 : x0 + px_per_square] = 0
    rot, _ = cv2.Rodrigues(np.asarray(rvec, float))
    t = np.asarray(tvec, float)
    # Board plane z_b = 0: points X = R x_b + t; ray s*d: solve in board coordinates.
    nrm = rot[:, 2]
    s = (nrm @ t) / (rays @ nrm)
    pts = rays * s[:, None] - t
    xb = pts @ rot  # board frame
    # Inner corner (0, 0) sits at the corner between the first and second squares.
    mx = (xb[:, 0] / SQUARE + 1 + margin) * px_per_square - 0.5
    my = (xb[:, 1] / SQUARE + 1 + margin) * px_per_square - 0.5
    img = cv2.remap(
        tex,
        mx.reshape(H, W).astype(np.float32),
        my.reshape(H, W).astype(np.float32),
        cv2.INTER_LINEAR,
        borderValue=255,
    )
    return cv2.GaussianBlur(img, (3, 3), 0.6)


def poses(n: int, seed: int = 3):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        rvec = rng.normal(scale=0.3, size=3)
        tvec = np.array([rng.uniform(-0.3, -0.06), rng.uniform(-0.2, -0.04), rng.uniform(0.6, 0.8)])
        out.append((rvec, tvec))
    return out


@pytest.mark.parametrize(
    "truth",
    [
        CameraModel(K, np.array([-0.25, 0.08, 0.001, -0.0007, 0.0]), (W, H)),
        CameraModel(K, np.array([0.04, -0.01, 0.003, -0.001]), (W, H), "fisheye"),
    ],
    ids=["pinhole", "fisheye"],
)
def test_calibration_recovers_intrinsics(truth):
    rays = pixel_rays(truth)
    images = [render(rays, r, t) for r, t in poses(12)]
    images.insert(3, np.full((H, W), 200, np.uint8))  # no board here
    res = calibrate(images, BOARD, SQUARE, model=truth.model)
    assert len(res.used) >= 9
    assert res.rms < 0.3 and res.per_image_error.max() < 0.5
    assert len(res.per_image_error) == len(res.used)
    np.testing.assert_allclose(res.camera.camera_matrix, K, rtol=0.01, atol=2.0)
    assert 3 in res.not_found
    # The recovered model maps pixels to the same rays as the truth across the image.
    grid = np.stack(np.meshgrid(np.linspace(80, W - 80, 9), np.linspace(60, H - 60, 7)), -1)
    grid = grid.reshape(-1, 2)
    a, _ = truth.normalized(grid)
    b, _ = res.camera.normalized(grid)
    assert np.abs(a - b).max() * K[0, 0] < 1.0  # under a pixel


def test_board_points_layout():
    p = board_points((3, 2), 0.5)
    np.testing.assert_allclose(p[:4], [[0, 0, 0], [0.5, 0, 0], [1.0, 0, 0], [0, 0.5, 0]])


@pytest.mark.parametrize("suffix", [".yaml", ".json"])
@pytest.mark.parametrize("model", ["pinhole", "fisheye"])
def test_save_load_round_trip(tmp_path, suffix, model):
    d = np.array([-0.2, 0.05, 0.001, 0.002, 0.01]) if model == "pinhole" else np.arange(4) * 0.01
    cam = CameraModel(K, d, (W, H), model, "bow")
    path = tmp_path / f"cam{suffix}"
    cam.save(path)
    back = CameraModel.load(path)
    np.testing.assert_array_equal(back.camera_matrix, cam.camera_matrix)
    np.testing.assert_array_equal(back.dist_coeffs, cam.dist_coeffs)
    assert (back.image_size, back.model, back.name) == ((W, H), model, "bow")


ROS_YAML = """\
image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [430.215550, 0.000000, 306.691343, 0.000000, 430.531693, 227.224800, 0.0, 0.0, 1.0]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.337586, 0.111063, -0.000207, -0.000240, 0.000000]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1.000000, 0.000000, 0.000000, 0.000000, 1.000000, 0.000000, 0.0, 0.0, 1.0]
projection_matrix:
  rows: 3
  cols: 4
  data: [3.0e2, 0.0, 3.0e2, 0.0, 0.0, 3.0e2, 2.0e2, 0.0, 0.0, 0.0, 1.0, 0.0]
"""


def test_loads_ros_camera_calibration_yaml(tmp_path):
    path = tmp_path / "ost.yaml"
    path.write_text(ROS_YAML)
    cam = CameraModel.load(path)
    assert cam.image_size == (640, 480) and cam.model == "pinhole"
    assert cam.camera_matrix[0, 0] == 430.215550 and cam.dist_coeffs[0] == -0.337586


def test_undistort_points_matches_opencv_and_image():
    cam = CameraModel(K, np.array([-0.25, 0.08, 0.001, -0.0007, 0.0]), (W, H))
    pts = np.array([[50.0, 40.0], [600.0, 450.0], [K[0, 2], K[1, 2]]])
    ours = cam.undistort_points(pts)
    ocv = cv2.undistortPoints(pts.reshape(-1, 1, 2), K, cam.dist_coeffs, P=K).reshape(-1, 2)
    np.testing.assert_allclose(ours, ocv, atol=0.05)  # OpenCV's default stops early
    np.testing.assert_allclose(ours[2], K[:2, 2], atol=1e-9)
    np.testing.assert_allclose(
        cam.project(np.hstack([cam.normalized(pts)[0], np.ones((3, 1))])), pts, atol=1e-6
    )
    img = cam.undistort_image(np.zeros((H, W, 3), np.uint8), alpha=1.0)
    assert img.shape == (H, W, 3)
    with pytest.raises(ValueError, match="dist_coeffs"):
        CameraModel(K, np.zeros(3), (W, H))


def test_pinhole_jacobian_matches_finite_differences():
    cam = CameraModel(K, np.array([-0.25, 0.08, 0.001, -0.0007, 0.01]), (W, H))
    px = np.array([[30.0, 20.0], [600.0, 400.0], [320.0, 240.0]])
    _, jac = cam.normalized(px)
    ex, ey = np.array([0.01, 0.0]), np.array([0.0, 0.01])
    num = np.stack(
        [
            (cam._undistort(px + ex) - cam._undistort(px - ex)) / 0.02,
            (cam._undistort(px + ey) - cam._undistort(px - ey)) / 0.02,
        ],
        axis=2,
    )
    np.testing.assert_allclose(jac, num, rtol=1e-5, atol=1e-9)
