"""Georeferencing of camera detections onto the water plane, with per-detection covariance.

Frames: camera = OpenCV (x right, y down, z forward); body = FRD at the vessel reference point;
*level* = body with the vessel's roll and pitch removed (x forward along the heading, y
starboard, z down); NED when the vessel heading (and position) are given. The water surface is
the plane `height` metres below the camera. Angles are radians unless a name ends in `_deg`.

Two camera models share one Rust core (`usvfast._core.georeference_rays`):

* :class:`FovCamera` — the thesis's model (eqs. 3.12–3.14): angles linear in pixels across
  the field of view; :func:`georeference_fov` is the thesis's Code 5.6 as a batch function.
* :class:`usvfast.camera.CameraModel` — a calibrated OpenCV pinhole or fisheye camera whose
  points are undistorted with OpenCV before the ray is built.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike

from usvfast import _core
from usvfast._validate import as_float_array, with_methods

#: Reason codes of :attr:`Georeferenced.reason`, index = code.
REASONS = ("ok", "above_horizon", "beyond_max_range", "low_confidence", "own_vessel")
OK, ABOVE_HORIZON, BEYOND_MAX_RANGE, LOW_CONFIDENCE, OWN_VESSEL = 0, 1, 2, 3, 4

#: Rotation body <- camera of a camera looking straight ahead (cam z -> x, x -> y, y -> z).
_R_AHEAD = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def rotation_zyx(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Rotation matrix `R_z(yaw) R_y(pitch) R_x(roll)` (radians; thesis eq. 3.9), shape (3, 3)."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def mount_rotation(mount_ypr_deg: ArrayLike = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Rotation body (FRD) <- camera (OpenCV) of a camera turned by (yaw, pitch, roll) degrees.

    (0, 0, 0) looks straight ahead along the bow; positive yaw turns to starboard, positive
    pitch tilts up, positive roll turns the image clockwise as seen from behind the camera
    (FRD conventions). Shape (3, 3).
    """
    ypr = as_float_array("mount_ypr_deg", mount_ypr_deg, ndim=1)
    if ypr.shape != (3,):
        raise ValueError(f"mount_ypr_deg: expected (yaw, pitch, roll), got shape {ypr.shape}")
    y, p, r = np.radians(ypr)
    return rotation_zyx(y, p, r) @ _R_AHEAD


class Camera(Protocol):
    """Anything that maps pixels to undistorted normalised image coordinates."""

    def normalized(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """`(n, 2)` pixels -> (`(n, 2)` normalised `(X/Z, Y/Z)`, `(n, 2, 2)` d(norm)/d(pixel))."""
        ...


@dataclass(frozen=True)
class FovCamera:
    """The thesis's camera model: bearing and elevation linear in pixels (eqs. 3.12–3.13).

    `image_size` = (width, height) pixels, `fov_deg` = (horizontal, vertical) field of view.
    """

    image_size: tuple[int, int]
    fov_deg: tuple[float, float]

    def __post_init__(self) -> None:
        size = np.asarray(self.image_size, dtype=np.float64)
        if size.shape != (2,) or not np.all(np.isfinite(size)) or np.any(size <= 0):
            raise ValueError(
                f"image_size: expected (width, height) > 0 pixels, got {self.image_size!r}"
            )
        fov = np.asarray(self.fov_deg, dtype=np.float64)
        if fov.shape != (2,) or not np.all((fov > 0) & (fov < 180)):
            raise ValueError(
                f"fov_deg: expected (horizontal, vertical) in (0, 180) degrees, "
                f"got {self.fov_deg!r}"
            )

    def normalized(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Normalised coordinates `(tan θ_c, tan φ_c)` (eq. 3.14) and their pixel Jacobian."""
        w, h = (float(s) for s in self.image_size)
        fx, fy = np.radians(np.asarray(self.fov_deg, dtype=np.float64))
        # eqs. (3.12)-(3.13): theta = (u - W/2) / W * F_x, phi = (v - H/2) / H * F_y
        theta = (pixels[:, 0] - w / 2.0) / w * fx
        phi = (pixels[:, 1] - h / 2.0) / h * fy
        norm = np.stack([np.tan(theta), np.tan(phi)], axis=1)
        jac = np.zeros((len(pixels), 2, 2))
        jac[:, 0, 0] = fx / w / np.cos(theta) ** 2
        jac[:, 1, 1] = fy / h / np.cos(phi) ** 2
        return norm, jac

    def project(self, points: np.ndarray) -> np.ndarray:
        """Camera-frame points (n, 3) (OpenCV axes, Z > 0) -> pixels (n, 2); inverse of
        :meth:`normalized`."""
        p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        w, h = (float(s) for s in self.image_size)
        fx, fy = np.radians(np.asarray(self.fov_deg, dtype=np.float64))
        u = w / 2.0 + np.arctan(p[:, 0] / p[:, 2]) / fx * w
        v = h / 2.0 + np.arctan(p[:, 1] / p[:, 2]) / fy * h
        return np.stack([u, v], axis=1)


@dataclass(frozen=True)
class Georeferenced:
    """Detections on the water plane.

    `positions` (n, 2) metres: (forward, starboard) in the level frame, or (north, east) in NED
    when a heading was given (`frame` says which); `covariances` (n, 2, 2) m²; `reason` (n,)
    int codes into :data:`REASONS`; rejected detections hold NaN.
    """

    positions: np.ndarray
    covariances: np.ndarray
    reason: np.ndarray
    frame: str

    @property
    def valid(self) -> np.ndarray:
        """(n,) bool: True where the detection was georeferenced."""
        return self.reason == OK


def _per_detection(name: str, value: Any, n: int) -> np.ndarray:
    arr = as_float_array(name, value)
    if arr.ndim > 1 or (arr.ndim == 1 and arr.shape[0] not in (1, n)):
        raise ValueError(f"{name}: expected a scalar or shape ({n},), got shape {arr.shape}")
    return np.ascontiguousarray(np.broadcast_to(arr, (n,)))


def _rotation(name: str, value: Any) -> np.ndarray:
    if value is None:
        return _R_AHEAD
    r = as_float_array(name, value)
    if r.shape != (3, 3):
        raise ValueError(f"{name}: expected shape (3, 3), got {r.shape}")
    if np.abs(r.T @ r - np.eye(3)).max() > 1e-6 or np.linalg.det(r) < 0:
        raise ValueError(f"{name}: must be a rotation matrix (orthonormal, det +1)")
    return r


def _sigma(name: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"{name}: expected a number, got {type(value).__name__}") from exc
    if not (np.isfinite(v) and v >= 0):
        raise ValueError(f"{name}: must be finite and >= 0, got {value!r}")
    return v


def _pair(name: str, value: Any) -> tuple[float, float]:
    arr = as_float_array(name, value)
    arr = np.broadcast_to(arr.ravel(), (2,)) if arr.size == 1 else arr
    if arr.shape != (2,) or np.any(arr < 0):
        raise ValueError(f"{name}: expected one or two values >= 0, got {value!r}")
    return float(arr[0]), float(arr[1])


def georeference(
    pixels: ArrayLike,
    camera: Camera,
    *,
    height: Any,
    mount_rotation: Any = None,
    mount_position: ArrayLike = (0.0, 0.0, 0.0),
    roll: Any = 0.0,
    pitch: Any = 0.0,
    heading: Any = None,
    vessel_ne: ArrayLike | None = None,
    pixel_sigma: Any = 0.0,
    attitude_sigma: Any = 0.0,
    height_sigma: float = 0.0,
    heading_sigma: float = 0.0,
    min_depression_deg: float = 0.0,
    max_range: float | None = None,
) -> Georeferenced:
    """Intersect the rays through `pixels` with the water plane; first-order covariance.

    `pixels` (n, 2) are the water-contact points in original image pixels (use
    :func:`box_contact_points` for boxes). `height` (m, scalar or (n,)) is the camera height
    above the water; `mount_rotation` (3, 3) body <- camera (default: looking ahead, see
    :func:`mount_rotation`); `mount_position` (3,) camera position in the body frame (FRD m;
    only its horizontal part moves results). `roll`, `pitch` (rad, scalar or (n,)) the vessel
    attitude from the IMU. With `heading` (rad from north, scalar or (n,)) the result is NED,
    shifted by `vessel_ne` ((2,) or (n, 2) metres) when given; otherwise the level frame.

    Noise: `pixel_sigma` (σ_u, σ_v) px, `attitude_sigma` (σ_roll, σ_pitch) rad, `height_sigma`
    m, `heading_sigma` rad (NED only). Rays shallower than `min_depression_deg` below the
    horizontal get reason `above_horizon`; points farther than `max_range` metres from the
    camera (horizontal) get `beyond_max_range`; both have NaN positions and covariances.
    """
    px = as_float_array("pixels", pixels, ndim=2)
    if px.shape[1] != 2:
        raise ValueError(f"pixels: expected shape (n, 2), got {px.shape}")
    n = px.shape[0]
    camera = with_methods("camera", camera, "a CameraModel or FovCamera", "normalized")
    norm, jac = camera.normalized(px)
    r_bc = _rotation("mount_rotation", mount_rotation)
    pos = as_float_array("mount_position", mount_position, ndim=1)
    if pos.shape != (3,):
        raise ValueError(f"mount_position: expected shape (3,), got {pos.shape}")
    head = None if heading is None else _per_detection("heading", heading, n)
    ne = None
    if vessel_ne is not None:
        if head is None:
            raise ValueError("vessel_ne: only meaningful with a heading (NED output)")
        ne = as_float_array("vessel_ne", vessel_ne)
        if ne.shape not in ((2,), (n, 2)):
            raise ValueError(f"vessel_ne: expected shape (2,) or ({n}, 2), got {ne.shape}")
        ne = np.ascontiguousarray(np.broadcast_to(ne, (n, 2)))
    height_sigma = _sigma("height_sigma", height_sigma)
    heading_sigma = _sigma("heading_sigma", heading_sigma)
    if heading_sigma > 0 and head is None:
        raise ValueError("heading_sigma: only meaningful with a heading (NED output)")
    if not (np.isfinite(min_depression_deg) and 0.0 <= min_depression_deg < 90.0):
        raise ValueError(f"min_depression_deg: must be in [0, 90), got {min_depression_deg}")
    positions, covariances, status = _core.georeference_rays(
        np.ascontiguousarray(norm),
        np.ascontiguousarray(jac),
        _per_detection("roll", roll, n),
        _per_detection("pitch", pitch, n),
        _per_detection("height", height, n),
        np.ascontiguousarray(r_bc),
        (float(pos[0]), float(pos[1]), float(pos[2])),
        heading=head,
        vessel_ne=ne,
        min_depression=float(np.radians(min_depression_deg)),
        sigma_px=_pair("pixel_sigma", pixel_sigma),
        sigma_roll_pitch=_pair("attitude_sigma", attitude_sigma),
        sigma_height=height_sigma,
        sigma_heading=heading_sigma,
    )
    reason = status.astype(np.int64)
    if max_range is not None:
        if not max_range > 0:
            raise ValueError(f"max_range: must be > 0, got {max_range}")
        # Horizontal distance from the camera: subtract its (horizontal) mount offset, turned
        # into NED by the heading when the output is NED.
        if head is None:
            rel = positions - pos[:2]
        else:
            c, s = np.cos(head), np.sin(head)
            cam_ne = np.stack([c * pos[0] - s * pos[1], s * pos[0] + c * pos[1]], axis=1)
            rel = positions - cam_ne - (ne if ne is not None else 0.0)
        far = (reason == OK) & (np.hypot(rel[:, 0], rel[:, 1]) > max_range)
        reason[far] = BEYOND_MAX_RANGE
        positions[far] = np.nan
        covariances[far] = np.nan
    return Georeferenced(positions, covariances, reason, "ned" if head is not None else "level")


def horizon_line(
    camera: Any,
    *,
    mount_rotation: Any = None,
    roll: float = 0.0,
    pitch: float = 0.0,
    margin_deg: float = 0.0,
    spread_deg: float = 10.0,
) -> tuple[float, float]:
    """The horizon in the image as a line `v = a·u + b` (pixels), from the camera's attitude.

    Projects the two level-frame directions `margin_deg` below the horizontal at ± `spread_deg`
    of azimuth around the optical axis (`camera` needs a `project` method: :class:`FovCamera`
    or :class:`usvfast.camera.CameraModel`). Contact points with v <= a·u + b are at or above
    it. With lens distortion the true horizon is curved; the line is exact at the two points.
    """
    with_methods("camera", camera, "a CameraModel or FovCamera", "project")
    r_bc = _rotation("mount_rotation", mount_rotation)
    for name, v in (("roll", roll), ("pitch", pitch), ("margin_deg", margin_deg)):
        if not np.isfinite(v):
            raise ValueError(f"{name}: must be finite, got {v!r}")
    if not (np.isfinite(spread_deg) and 0.0 < spread_deg < 90.0):
        raise ValueError(f"spread_deg: must be in (0, 90), got {spread_deg!r}")
    r_lc = rotation_zyx(0.0, pitch, roll) @ r_bc
    axis = r_lc[:, 2]
    az = np.arctan2(axis[1], axis[0])
    dz = np.tan(np.radians(margin_deg))
    dirs = np.array(
        [[np.cos(az + s), np.sin(az + s), dz] for s in np.radians([-spread_deg, spread_deg])]
    )
    cam_pts = dirs @ r_lc  # rows: R_lc^T d
    if np.any(cam_pts[:, 2] <= 0):
        raise ValueError("camera: the horizon is not in front of the camera for this attitude")
    (u0, v0), (u1, v1) = camera.project(cam_pts)
    a = (v1 - v0) / (u1 - u0)
    return float(a), float(v0 - a * u0)


def box_contact_points(boxes: ArrayLike) -> np.ndarray:
    """Water-contact pixel of each box: bottom centre `((x1 + x2) / 2, y2)`; (n, 4) -> (n, 2)."""
    b = as_float_array("boxes", boxes, ndim=2)
    if b.shape[1] != 4:
        raise ValueError(f"boxes: expected shape (n, 4) [x1, y1, x2, y2], got {b.shape}")
    return np.stack([(b[:, 0] + b[:, 2]) / 2.0, b[:, 3]], axis=1)


def georeference_fov(
    u: ArrayLike,
    v: ArrayLike,
    *,
    image_size: tuple[int, int],
    fov_deg: tuple[float, float],
    height: float,
    mount_ypr_deg: Any = (0.0, 0.0, 0.0),
    offset: ArrayLike = (0.0, 0.0),
) -> tuple[np.ndarray, np.ndarray]:
    """The thesis's georeferencing (eqs. 3.12–3.17, Code 5.6): pixels -> (forward, starboard) m.

    `u`, `v` pixel coordinates (any matching shapes); `image_size` = (width, height) px;
    `fov_deg` = (horizontal, vertical); `height` of the camera above the water (m);
    `mount_ypr_deg` the camera's (yaw, pitch, roll) from looking straight ahead (degrees,
    positive pitch = tilted up); `offset` the camera's (forward, starboard) position relative to
    the reference point (m, added to the intersection as eq. 3.17 does). Points at or above the
    horizon come back as NaN (use :func:`georeference` for reasons and covariances).
    """
    uu = as_float_array("u", u)
    vv = as_float_array("v", v)
    if np.shape(u) != np.shape(v):
        raise ValueError(f"u, v: shapes differ: {np.shape(u)} vs {np.shape(v)}")
    off = as_float_array("offset", offset, ndim=1)
    if off.shape != (2,):
        raise ValueError(f"offset: expected (forward, starboard), got shape {off.shape}")
    cam = FovCamera(tuple(image_size), tuple(fov_deg))  # type: ignore[arg-type]
    res = georeference(
        np.stack([uu.ravel(), vv.ravel()], axis=1),
        cam,
        height=height,
        mount_rotation=mount_rotation(mount_ypr_deg),
        mount_position=(off[0], off[1], 0.0),
    )
    shape = np.shape(u)
    return res.positions[:, 0].reshape(shape), res.positions[:, 1].reshape(shape)


@dataclass(frozen=True)
class Sensitivity:
    """Absolute position change |Δ(forward, starboard)| per detection (n, 2) metres, as in the
    thesis's Tables 6.6 (contact point moved ±k pixels down/up the image) and 6.7 (camera
    pitched ±δ degrees)."""

    pixel_plus: np.ndarray
    pixel_minus: np.ndarray
    pitch_plus: np.ndarray
    pitch_minus: np.ndarray


def sensitivity(
    pixels: ArrayLike,
    camera: Camera,
    *,
    height: Any,
    mount_rotation: Any = None,
    pixels_step: float = 2.0,
    pitch_step_deg: float = 1.0,
    **kwargs: Any,
) -> Sensitivity:
    """Tables 6.6–6.7 for any detections: georeference with v ± `pixels_step` and with the
    camera mount pitched ± `pitch_step_deg` (up is +), report |Δ| against the unperturbed
    result. Extra keyword arguments go to :func:`georeference` (roll, pitch, mount_position, ...).
    """
    px = as_float_array("pixels", pixels, ndim=2)
    r_bc = _rotation("mount_rotation", mount_rotation)

    def run(p: np.ndarray, r: np.ndarray) -> np.ndarray:
        return georeference(p, camera, height=height, mount_rotation=r, **kwargs).positions

    base = run(px, r_bc)
    dv = np.array([0.0, pixels_step])
    d = np.radians(pitch_step_deg)
    return Sensitivity(
        pixel_plus=np.abs(run(px + dv, r_bc) - base),
        pixel_minus=np.abs(run(px - dv, r_bc) - base),
        pitch_plus=np.abs(run(px, rotation_zyx(0.0, d, 0.0) @ r_bc) - base),
        pitch_minus=np.abs(run(px, rotation_zyx(0.0, -d, 0.0) @ r_bc) - base),
    )
