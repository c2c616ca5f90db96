"""Fused targets in the camera image and their match with image detections (the radar/AIS
paper's §1.4): each target is projected into the calibrated camera (mount and own-ship
attitude), the angle γ at the camera between the ray to the target and the ray through a
detection's box centre is computed, and a target and a detection are the same object when
γ < γ_max (one-to-one, smallest total γ). A target behind the camera, outside the image or
beyond the horizon seen from the camera is not projected and never matched.

Frames as in `usvfast.camera.georef`: camera = OpenCV (x right, y down, z forward), body =
FRD, NED. NED ← camera = R_z(heading) R_y(pitch) R_x(roll) · mount_rotation.

Example::

    proj = project_targets(targets_ne, camera, own_ne=(n, e), heading=h, height=12.0)
    pairs = match_detections(proj, camera, boxes, gamma_max_deg=2.0)   # [(target, box)]
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment

from usvfast._validate import as_float_array, instance, with_methods
from usvfast.camera.georef import mount_rotation as _mount_rotation
from usvfast.camera.georef import rotation_zyx

__all__ = [
    "EARTH_RADIUS",
    "REASONS",
    "Projection",
    "detection_rays",
    "horizon_distance",
    "match_detections",
    "project_targets",
]

#: Mean Earth radius (m) for the horizon distance.
EARTH_RADIUS = 6_371_000.0
VISIBLE, BEHIND, OUTSIDE, BEYOND_HORIZON = 0, 1, 2, 3
#: Reason codes of `Projection.reason`, index = code.
REASONS = ("visible", "behind_camera", "outside_image", "beyond_horizon")


def horizon_distance(camera_height: float, target_height: float = 0.0) -> float:
    """Geometric distance (m) at which a point `target_height` m above the sea drops below
    the horizon of an eye `camera_height` m above it: √(2Rh_c) + √(2Rh_t)."""
    return math.sqrt(2 * EARTH_RADIUS * max(camera_height, 0.0)) + math.sqrt(
        2 * EARTH_RADIUS * max(target_height, 0.0)
    )


@dataclass(frozen=True)
class Projection:
    """Targets in the camera: pixels (k, 2) (NaN unless visible), rays (k, 3) unit vectors
    in the camera frame (NaN when behind), range_m (k,) horizontal distance from the camera,
    bearing_deg (k,) true bearing from the camera, reason (k,) codes of `REASONS`."""

    pixels: np.ndarray
    rays: np.ndarray
    range_m: np.ndarray
    bearing_deg: np.ndarray
    reason: np.ndarray

    @property
    def visible(self) -> np.ndarray:
        """(k,) bool: projected inside the image, in front of the camera, above the horizon."""
        return self.reason == VISIBLE


def project_targets(
    targets_ne: ArrayLike,
    camera: Any,
    *,
    own_ne: ArrayLike,
    heading: float,
    height: float,
    roll: float = 0.0,
    pitch: float = 0.0,
    mount_rotation: ArrayLike | None = None,
    mount_position: ArrayLike = (0.0, 0.0, 0.0),
    aim_height: float = 0.0,
    target_height: float = 0.0,
) -> Projection:
    """Project targets (k, 2) (north, east m, at the water) into `camera` (a CameraModel or
    FovCamera: `project` and `image_size`). own_ne (2,) the own-ship reference point, heading
    (rad from north), roll, pitch (rad), height (m, camera above the water), mount_rotation
    (3, 3) body ← camera (default: looking ahead), mount_position (3,) body FRD m. The point
    projected is `aim_height` m above the water (use about half the superstructure height
    to aim at a box centre); a target farther than `horizon_distance(height,
    target_height)` is beyond the horizon."""
    with_methods("camera", camera, "a CameraModel or FovCamera", "project")
    if getattr(camera, "image_size", None) is None:
        raise TypeError(
            f"camera: expected a CameraModel or FovCamera (with image_size), got {camera!r}"
        )
    pts = as_float_array("targets_ne", targets_ne, ndim=2)
    if pts.shape[1] != 2:
        raise ValueError(f"targets_ne: expected shape (k, 2), got {pts.shape}")
    own = as_float_array("own_ne", own_ne, ndim=1)
    if own.shape != (2,):
        raise ValueError(f"own_ne: expected shape (2,), got {own.shape}")
    for name, v in (("heading", heading), ("roll", roll), ("pitch", pitch)):
        if not math.isfinite(v):
            raise ValueError(f"{name}: must be finite, got {v!r}")
    if not (math.isfinite(height) and height > 0):
        raise ValueError(f"height: must be > 0 metres, got {height!r}")
    if mount_rotation is None:
        r_bc = _mount_rotation((0.0, 0.0, 0.0))
    else:
        r_bc = as_float_array("mount_rotation", mount_rotation, ndim=2)
        if r_bc.shape != (3, 3):
            raise ValueError(f"mount_rotation: expected shape (3, 3), got {r_bc.shape}")
    mpos = as_float_array("mount_position", mount_position, ndim=1)
    r_nc = rotation_zyx(heading, pitch, roll) @ r_bc
    c, s = math.cos(heading), math.sin(heading)
    cam_ne = own + np.array([c * mpos[0] - s * mpos[1], s * mpos[0] + c * mpos[1]])
    d = np.column_stack([pts - cam_ne, np.full(len(pts), height - aim_height)])
    rng = np.hypot(d[:, 0], d[:, 1])
    brg = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360.0
    d_cam = d @ r_nc  # rows: R_nc^T d
    norm = np.linalg.norm(d_cam, axis=1, keepdims=True)
    rays = d_cam / np.where(norm > 0, norm, 1.0)
    reason = np.full(len(pts), VISIBLE, dtype=np.int64)
    reason[rng > horizon_distance(height, target_height)] = BEYOND_HORIZON
    behind = d_cam[:, 2] <= 1e-9 * norm[:, 0]
    reason[behind] = BEHIND
    pixels = np.full((len(pts), 2), np.nan)
    front = ~behind
    if front.any():
        pixels[front] = camera.project(d_cam[front])
    w, h = camera.image_size
    inside = (pixels[:, 0] >= 0) & (pixels[:, 0] < w) & (pixels[:, 1] >= 0) & (pixels[:, 1] < h)
    reason[front & ~inside & (reason == VISIBLE)] = OUTSIDE
    pixels[reason != VISIBLE] = np.nan
    rays[behind] = np.nan
    return Projection(pixels, rays, rng, brg, reason)


def detection_rays(camera: Any, boxes: ArrayLike) -> np.ndarray:
    """Unit rays (n, 3) in the camera frame through the centres of boxes (n, 4) x1, y1, x2,
    y2 (original image pixels; distortion removed by `camera.normalized`)."""
    with_methods("camera", camera, "a CameraModel or FovCamera", "normalized")
    b = as_float_array("boxes", boxes, ndim=2)
    if b.shape[1] != 4:
        raise ValueError(f"boxes: expected shape (n, 4), got {b.shape}")
    centres = np.column_stack([(b[:, 0] + b[:, 2]) / 2.0, (b[:, 1] + b[:, 3]) / 2.0])
    norm, _ = camera.normalized(centres)
    r = np.column_stack([norm, np.ones(len(norm))])
    return r / np.linalg.norm(r, axis=1, keepdims=True)


def match_detections(
    projection: Projection, camera: Any, boxes: ArrayLike, *, gamma_max_deg: float = 2.0
) -> tuple[list[tuple[int, int]], np.ndarray]:
    """Match visible targets to detection boxes (n, 4) by the angle γ between their rays:
    pairs (target index, box index) with γ < gamma_max_deg, one-to-one by minimum total γ.
    Returns (pairs, γ (k, n) degrees; NaN for targets that are not visible)."""
    instance("projection", projection, Projection)
    if not (math.isfinite(gamma_max_deg) and gamma_max_deg > 0):
        raise ValueError(f"gamma_max_deg: must be > 0, got {gamma_max_deg!r}")
    b = as_float_array("boxes", boxes).reshape(-1, 4)
    k = len(projection.reason)
    gamma = np.full((k, len(b)), np.nan)
    if len(b) == 0 or k == 0:
        return [], gamma
    rays = detection_rays(camera, b)
    vis = projection.visible
    cosg = np.clip(projection.rays[vis] @ rays.T, -1.0, 1.0)
    gamma[vis] = np.degrees(np.arccos(cosg))
    cost = np.where(np.isfinite(gamma) & (gamma < gamma_max_deg), gamma, 1e6)
    rows, cols = linear_sum_assignment(cost)
    pairs = [(int(r), int(c)) for r, c in zip(rows, cols, strict=True) if cost[r, c] < 1e6]
    return pairs, gamma
