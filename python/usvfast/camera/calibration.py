"""Camera models and checkerboard calibration (OpenCV): Zhang pinhole (k1, k2, p1, p2, k3) and
fisheye (equidistant k1..k4), per-image reprojection errors, ROS `camera_info` YAML and JSON.

Pixels are image coordinates (x right, y down, origin at the top-left pixel's centre as in
OpenCV); normalised coordinates are `(X/Z, Y/Z)` in the OpenCV camera frame.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from numpy.typing import ArrayLike

from usvfast._core import DimensionError
from usvfast._validate import as_float_array, instance, integer, real

MODELS = ("pinhole", "fisheye")
_ROS_MODEL = {"pinhole": "plumb_bob", "fisheye": "equidistant"}
_FROM_ROS = {"plumb_bob": "pinhole", "rational_polynomial": "pinhole", "equidistant": "fisheye"}
_TERM = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-14)


@dataclass(frozen=True)
class CameraModel:
    """A calibrated camera: `camera_matrix` (3, 3) K, `dist_coeffs` (OpenCV order: 4, 5, 8, 12
    or 14 values for `pinhole`, 4 for `fisheye`), `image_size` (width, height) px."""

    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    image_size: tuple[int, int]
    model: str = "pinhole"
    name: str = "camera"

    def __post_init__(self) -> None:
        k = as_float_array("camera_matrix", self.camera_matrix, ndim=2)
        if k.shape != (3, 3) or k[0, 0] <= 0 or k[1, 1] <= 0:
            raise ValueError(f"camera_matrix: expected a (3, 3) K with fx, fy > 0, got {k}")
        d = as_float_array("dist_coeffs", self.dist_coeffs).ravel()
        if self.model not in MODELS:
            raise ValueError(f"model: expected one of {MODELS}, got {self.model!r}")
        allowed = (4,) if self.model == "fisheye" else (4, 5, 8, 12, 14)
        if d.size not in allowed:
            raise ValueError(f"dist_coeffs: {self.model} needs {allowed} values, got {d.size}")
        object.__setattr__(self, "camera_matrix", k)
        object.__setattr__(self, "dist_coeffs", d)
        object.__setattr__(self, "image_size", (int(self.image_size[0]), int(self.image_size[1])))

    # --- points ------------------------------------------------------------------------
    def _undistort(self, px: np.ndarray) -> np.ndarray:
        if px.size == 0:  # OpenCV returns None for no points
            return np.zeros((0, 2))
        src = px.reshape(-1, 1, 2)
        if self.model == "fisheye":
            out = cv2.fisheye.undistortPoints(
                src, self.camera_matrix, self.dist_coeffs, criteria=_TERM
            )
        else:
            out = cv2.undistortPoints(
                src, self.camera_matrix, self.dist_coeffs, None, None, criteria=_TERM
            )
        return out.reshape(-1, 2).astype(np.float64)

    def normalized(self, pixels: Any, step: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
        """Undistorted normalised coordinates (n, 2) of `pixels` (n, 2) and their Jacobian
        d(norm)/d(pixel) (n, 2, 2).

        Pinhole: the inverse of OpenCV's analytic projection Jacobian at the undistorted point
        (`cv2.projectPoints`); fisheye: central differences of ± `step` pixels.
        """
        px = _pixels(pixels)
        n = len(px)
        if n == 0:
            return np.zeros((0, 2)), np.zeros((0, 2, 2))
        if self.model == "pinhole":
            norm = self._undistort(px)
            pts = np.hstack([norm, np.ones((n, 1))]).reshape(-1, 1, 3)
            z = np.zeros(3)
            _, jp = cv2.projectPoints(pts, z, z, self.camera_matrix, self.dist_coeffs)
            # d(u, v)/d(t_x, t_y) at Z = 1 equals d(u, v)/d(x_n, y_n).
            fwd = jp[:, 3:5].reshape(n, 2, 2)
            return norm, np.linalg.inv(fwd)
        e = np.array([[0.0, 0.0], [step, 0.0], [-step, 0.0], [0.0, step], [0.0, -step]])
        allp = (px[None, :, :] + e[:, None, :]).reshape(-1, 2)
        und = self._undistort(allp).reshape(5, n, 2)
        jac = np.empty((n, 2, 2))
        jac[:, :, 0] = (und[1] - und[2]) / (2 * step)
        jac[:, :, 1] = (und[3] - und[4]) / (2 * step)
        return und[0], jac

    def undistort_points(self, pixels: Any) -> np.ndarray:
        """Pixels (n, 2) of the distorted image -> pixels of the ideal pinhole image with the
        same K (n, 2)."""
        px = _pixels(pixels)
        norm = self._undistort(px)
        k = self.camera_matrix
        return np.stack(
            [k[0, 0] * norm[:, 0] + k[0, 1] * norm[:, 1] + k[0, 2], k[1, 1] * norm[:, 1] + k[1, 2]],
            axis=1,
        )

    def project(self, points: ArrayLike) -> np.ndarray:
        """Camera-frame points (n, 3) (OpenCV axes, Z > 0) -> distorted pixels (n, 2)."""
        p = as_float_array("points", points, ndim=2).reshape(-1, 1, 3)
        z = np.zeros(3)
        if self.model == "fisheye":
            out, _ = cv2.fisheye.projectPoints(p, z, z, self.camera_matrix, self.dist_coeffs)
        else:
            out, _ = cv2.projectPoints(p, z, z, self.camera_matrix, self.dist_coeffs)
        return out.reshape(-1, 2).astype(np.float64)

    def undistort_image(self, image: np.ndarray, alpha: float = 0.0) -> np.ndarray:
        """Whole-image undistortion, for display (`alpha` 0 crops to valid pixels, 1 keeps all)."""
        size = self.image_size
        if self.model == "fisheye":
            new_k = cv2.fisheye.estimateNewCameraMatrixForUndistortRectify(
                self.camera_matrix, self.dist_coeffs, size, np.eye(3), balance=alpha
            )
            return cv2.fisheye.undistortImage(
                image, self.camera_matrix, self.dist_coeffs, Knew=new_k, new_size=size
            )
        new_k, _ = cv2.getOptimalNewCameraMatrix(
            self.camera_matrix, self.dist_coeffs, size, alpha, size
        )
        return cv2.undistort(image, self.camera_matrix, self.dist_coeffs, None, new_k)

    # --- persistence -------------------------------------------------------------------
    def to_ros(self) -> dict[str, Any]:
        """The ROS `sensor_msgs/CameraInfo` calibration YAML layout as a dict."""
        w, h = self.image_size
        k = self.camera_matrix
        p = np.hstack([k, np.zeros((3, 1))])
        d = self.dist_coeffs
        model = _ROS_MODEL[self.model]
        if self.model == "pinhole" and d.size > 5:
            model = "rational_polynomial"

        def mat(a: np.ndarray, rows: int, cols: int) -> dict[str, Any]:
            return {"rows": rows, "cols": cols, "data": [float(x) for x in a.ravel()]}

        return {
            "image_width": w,
            "image_height": h,
            "camera_name": self.name,
            "camera_matrix": mat(k, 3, 3),
            "distortion_model": model,
            "distortion_coefficients": mat(d, 1, d.size),
            "rectification_matrix": mat(np.eye(3), 3, 3),
            "projection_matrix": mat(p, 3, 4),
        }

    @classmethod
    def from_ros(cls, data: dict[str, Any]) -> CameraModel:
        """Build from a ROS camera_info calibration dict (as written by camera_calibration)."""
        try:
            model = _FROM_ROS[data["distortion_model"]]
            k = np.reshape(data["camera_matrix"]["data"], (3, 3))
            d = np.asarray(data["distortion_coefficients"]["data"], dtype=np.float64)
            size = (int(data["image_width"]), int(data["image_height"]))
        except KeyError as exc:
            raise ValueError(f"camera_info: missing or unsupported field {exc}") from exc
        return cls(k, d, size, model, str(data.get("camera_name", "camera")))

    def save(self, path: str | Path) -> None:
        """Write ROS camera_info YAML (`.yaml`/`.yml`) or JSON (`.json`, same fields)."""
        path = Path(path)
        data = self.to_ros()
        if path.suffix.lower() == ".json":
            path.write_text(json.dumps(data, indent=2))
        else:
            path.write_text(yaml.safe_dump(data, sort_keys=False))

    @classmethod
    def load(cls, path: str | Path) -> CameraModel:
        """Read a camera written by :meth:`save` or by ROS camera_calibration (YAML or JSON)."""
        path = Path(path)
        text = path.read_text()
        data = json.loads(text) if path.suffix.lower() == ".json" else yaml.safe_load(text)
        return cls.from_ros(data)


@dataclass(frozen=True)
class CalibrationResult:
    """Outcome of :func:`calibrate`: the camera, overall RMS reprojection error (px), the
    per-image RMS errors (px) of the `used` images (indices into the input), and the indices
    of images where the board was `not_found`."""

    camera: CameraModel
    rms: float
    per_image_error: np.ndarray
    used: list[int] = field(default_factory=list)
    not_found: list[int] = field(default_factory=list)


def find_board(image: np.ndarray, board_size: tuple[int, int]) -> np.ndarray | None:
    """Inner-corner pixels (k, 2) of a `board_size` = (columns, rows) checkerboard, refined to
    sub-pixel, or None when the board is not found."""
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    ok, corners = cv2.findChessboardCorners(
        gray, board_size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    )
    if not ok:
        return None
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
    corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), crit)
    return corners.reshape(-1, 2).astype(np.float64)


def board_points(board_size: tuple[int, int], square_size: float) -> np.ndarray:
    """Board-frame coordinates (k, 3) metres of the inner corners, row by row (z = 0).
    `board_size` (columns, rows) of inner corners, integers in [2, 1000]; `square_size` > 0 m."""
    if not isinstance(board_size, tuple | list) or len(board_size) != 2:
        raise TypeError(f"board_size: expected (columns, rows), got {board_size!r}")
    cols, rows = (
        integer(f"board_size[{i}]", v, low=2, high=1000) for i, v in enumerate(board_size)
    )
    square_size = real("square_size", square_size, positive=True)
    g = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square_size
    return np.hstack([g, np.zeros((len(g), 1))])


def calibrate(
    images: Iterable[np.ndarray | str | Path],
    board_size: tuple[int, int],
    square_size: float,
    *,
    model: str = "pinhole",
    name: str = "camera",
) -> CalibrationResult:
    """Calibrate from checkerboard images (arrays or file paths) with OpenCV.

    `board_size` = inner corners (columns, rows); `square_size` in metres. `pinhole` is
    Zhang's method with k1, k2, p1, p2, k3; `fisheye` the equidistant model. Images where the
    board is not found are listed in `not_found`; raises ValueError when fewer than 3 remain.
    """
    if model not in MODELS:
        raise ValueError(f"model: expected one of {MODELS}, got {model!r}")
    obj = board_points(board_size, square_size)
    obj_pts: list[np.ndarray] = []
    img_pts: list[np.ndarray] = []
    used: list[int] = []
    not_found: list[int] = []
    size: tuple[int, int] | None = None
    for i, im in enumerate(images):
        img = cv2.imread(str(im), cv2.IMREAD_GRAYSCALE) if isinstance(im, str | Path) else im
        if img is None:
            not_found.append(i)
            continue
        this = (img.shape[1], img.shape[0])
        if size is not None and this != size:
            raise ValueError(f"images: image {i} is {this}, earlier ones {size}")
        size = this
        corners = find_board(img, board_size)
        if corners is None:
            not_found.append(i)
            continue
        obj_pts.append(obj)
        img_pts.append(corners)
        used.append(i)
    if len(used) < 3 or size is None:
        raise ValueError(
            f"images: the board was found in {len(used)} images, need at least 3 "
            f"(not found: {not_found})"
        )
    if model == "pinhole":
        rms, k, d, rvecs, tvecs = cv2.calibrateCamera(
            [o.astype(np.float32) for o in obj_pts],
            [p.astype(np.float32) for p in img_pts],
            size,
            None,
            None,
        )
    else:
        # OpenCV >= 5 moved the fisheye flags to the cv2 namespace.
        ns = cv2.fisheye if hasattr(cv2.fisheye, "CALIB_FIX_SKEW") else cv2
        flags = ns.CALIB_RECOMPUTE_EXTRINSIC | ns.CALIB_FIX_SKEW  # pyright: ignore[reportAttributeAccessIssue]
        rms, k, d, rvecs, tvecs = cv2.fisheye.calibrate(
            [o.reshape(1, -1, 3) for o in obj_pts],
            [p.reshape(1, -1, 2) for p in img_pts],
            size,
            np.eye(3),
            np.zeros(4),
            flags=flags,
            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10),
        )
    cam = CameraModel(k, np.ravel(d), size, model, name)
    errors = []
    for o, p, r, t in zip(obj_pts, img_pts, rvecs, tvecs, strict=True):
        rot, _ = cv2.Rodrigues(np.asarray(r, dtype=np.float64).reshape(3))
        proj = cam.project(o @ rot.T + np.asarray(t, dtype=np.float64).reshape(1, 3))
        errors.append(float(np.sqrt(np.mean(np.sum((proj - p) ** 2, axis=1)))))
    return CalibrationResult(cam, float(rms), np.asarray(errors), used, not_found)


def undistort_points(pixels: Any, camera: CameraModel) -> np.ndarray:
    """Shorthand for :meth:`CameraModel.undistort_points`."""
    return instance("camera", camera, CameraModel).undistort_points(pixels)


def _pixels(pixels: Any) -> np.ndarray:
    px = as_float_array("pixels", pixels, ndim=2)
    if px.shape[1] != 2:
        raise DimensionError(f"pixels: expected shape (n, 2), got {px.shape}")
    return px


__all__: Sequence[str] = (
    "CalibrationResult",
    "CameraModel",
    "board_points",
    "calibrate",
    "find_board",
    "undistort_points",
)
