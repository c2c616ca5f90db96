"""Rigid-body frames: the thesis's ZYX roll–pitch–yaw rotation (eq. 3.9), SE(3) transforms
(eq. 3.10), sensor mounts body ← sensor with lever arms, sensor points → local NED given the
vessel pose (Rust), dual-antenna heading and bearing/range helpers.

Conventions: radians; `R = Rz(yaw) Ry(pitch) Rx(roll)` maps vectors from the rotated frame to
the reference frame (equal to scipy's `Rotation.from_euler("ZYX", [yaw, pitch, roll])`); body
frame FRD (x forward, y starboard, z down) at the vessel reference point; world frame NED;
headings and bearings clockwise from north.

Example (a camera 1.2 m forward of the reference point, 0.8 m above it, pitched 5° down)::

    import numpy as np
    from usvfast.frames import Mount, sensor_to_ned
    cam = Mount(lever_arm=[1.2, 0.0, -0.8], pitch=np.radians(-5.0))
    sensor_to_ned([[10.0, 0.0, 0.0]], cam, roll=0.0, pitch=0.0, yaw=np.pi / 2,
                  position_ned=[100.0, 50.0, 0.0])
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast import _core, geodesy
from usvfast._angles import wrap_2pi, wrap_pi
from usvfast._core import DimensionError
from usvfast._validate import as_float_array, real

__all__ = [
    "Mount",
    "bearing_range",
    "dual_antenna_heading",
    "euler_angles",
    "relative_bearing",
    "rotation_matrix",
    "se3",
    "sensor_to_ned",
]


def rotation_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """The (3, 3) rotation `Rz(yaw) Ry(pitch) Rx(roll)` of eq. 3.9 (radians). Raises
    NonFiniteError / TypeError naming the angle that is not a finite real number."""
    roll, pitch, yaw = real("roll", roll), real("pitch", pitch), real("yaw", yaw)
    sf, cf = np.sin(roll), np.cos(roll)
    st, ct = np.sin(pitch), np.cos(pitch)
    sp, cp = np.sin(yaw), np.cos(yaw)
    # Eq. 3.10's rotation block.
    return np.array(
        [
            [ct * cp, sf * st * cp - cf * sp, cf * st * cp + sf * sp],
            [ct * sp, sf * st * sp + cf * cp, cf * st * sp - sf * cp],
            [-st, sf * ct, cf * ct],
        ]
    )


def euler_angles(rotation: ArrayLike) -> tuple[float, float, float]:
    """(roll, pitch, yaw) in radians of a (3, 3) rotation, inverse of `rotation_matrix`; pitch
    in [-π/2, π/2]. At gimbal lock (|pitch| = π/2) roll is reported as 0."""
    r = as_float_array("rotation", rotation, ndim=2)
    if r.shape != (3, 3):
        raise DimensionError(f"rotation: expected shape (3, 3), got {r.shape}")
    pitch = float(np.arcsin(np.clip(-r[2, 0], -1.0, 1.0)))
    if abs(r[2, 0]) < 1.0 - 1e-12:
        return float(np.arctan2(r[2, 1], r[2, 2])), pitch, float(np.arctan2(r[1, 0], r[0, 0]))
    return 0.0, pitch, float(np.arctan2(-r[0, 1], r[1, 1]))


def se3(roll: float, pitch: float, yaw: float, translation: ArrayLike) -> np.ndarray:
    """The (4, 4) homogeneous transform of eq. 3.10: rotation `rotation_matrix(roll, pitch,
    yaw)`, translation (3,) in metres."""
    t = as_float_array("translation", translation, ndim=1)
    if t.shape != (3,):
        raise DimensionError(f"translation: expected shape (3,), got {t.shape}")
    m = np.eye(4)
    m[:3, :3] = rotation_matrix(roll, pitch, yaw)
    m[:3, 3] = t
    return m


@dataclass(frozen=True)
class Mount:
    """A sensor mount body ← sensor: `lever_arm` (3,) is the sensor origin in the body frame
    (FRD metres from the vessel reference point); roll, pitch, yaw (radians) rotate sensor
    axes into body axes (ZYX). For a camera, compose with the fixed OpenCV → FRD axis swap
    yourself (x right, y down, z forward → FRD: [[0, 0, 1], [1, 0, 0], [0, 1, 0]]).

    Example values: the thesis's Otter (Figure 4.2) has every sensor on the centre plane
    (y = 0) with LiDAR, camera and two GNSS lever arms; its numbers are only in the figure
    image, so enter them from the figure for that platform.

    Raises NonFiniteError (naming the field, e.g. `Mount.roll`) on NaN/inf and TypeError on
    non-numbers."""

    lever_arm: Any = field(default_factory=lambda: np.zeros(3))
    roll: float = 0.0
    pitch: float = 0.0
    yaw: float = 0.0

    def __post_init__(self) -> None:
        as_float_array("Mount.lever_arm", self.lever_arm)
        for name in ("roll", "pitch", "yaw"):
            as_float_array(f"Mount.{name}", getattr(self, name))

    @property
    def rotation(self) -> np.ndarray:
        """(3, 3) body ← sensor rotation."""
        return rotation_matrix(self.roll, self.pitch, self.yaw)

    @property
    def matrix(self) -> np.ndarray:
        """(4, 4) body ← sensor homogeneous transform."""
        return se3(self.roll, self.pitch, self.yaw, self.lever_arm)


def _per_pose(name: str, value: Any, n: int) -> np.ndarray:
    a = as_float_array(name, value).reshape(-1)
    if a.size not in (1, n):
        raise DimensionError(f"{name}: expected 1 or {n} values, got {a.size}")
    return a


def sensor_to_ned(
    points: ArrayLike,
    mount: Mount,
    roll: Any,
    pitch: Any,
    yaw: Any,
    position_ned: ArrayLike,
) -> np.ndarray:
    """Points (n, 3) in the sensor frame (metres) → (n, 3) NED metres:
    `p = R(roll, pitch, yaw) (R_mount p_s + lever_arm) + position_ned`.

    The vessel pose is one pose (scalars and a (3,) position) or one per point ((n,) angles and
    an (n, 3) position, e.g. a LiDAR sweep with per-point times). No points (n = 0) give a
    (0, 3) result. Raises DimensionError on wrong shapes (an empty pose with n > 0 included),
    NonFiniteError on NaN/inf."""
    p = as_float_array("points", points, ndim=2)
    if p.shape[1] != 3:
        raise DimensionError(f"points: expected shape (n, 3), got {p.shape}")
    n = p.shape[0]
    pos = as_float_array("position_ned", position_ned)
    pos = pos.reshape(1, 3) if pos.shape == (3,) else pos
    if pos.ndim != 2 or pos.shape[1] != 3 or pos.shape[0] not in (1, n):
        raise DimensionError(f"position_ned: expected shape (3,) or ({n}, 3), got {pos.shape}")
    lever = as_float_array("mount.lever_arm", mount.lever_arm)
    if lever.shape != (3,):
        raise DimensionError(f"mount.lever_arm: expected shape (3,), got {lever.shape}")
    return _core.sensor_to_ned(
        p,
        np.ascontiguousarray(mount.rotation),
        lever,
        _per_pose("roll", roll, n),
        _per_pose("pitch", pitch, n),
        _per_pose("yaw", yaw, n),
        np.ascontiguousarray(pos),
    )


def dual_antenna_heading(
    aft: ArrayLike, fore: ArrayLike, baseline_yaw: float = 0.0, ell: Any = None
) -> tuple[np.ndarray, np.ndarray]:
    """Heading (radians, clockwise from true north, in [0, 2π)) and baseline length (m) from two
    GNSS antenna positions `aft` and `fore`, each (lat_deg, lon_deg, h) or arrays of shape
    (3, n), exact on the WGS84 ellipsoid (NED at the aft antenna). `baseline_yaw` is the
    angle of the aft → fore baseline in the body frame (0 when it points forward)."""
    a = as_float_array("aft", aft)
    f = as_float_array("fore", fore)
    if a.shape[0] != 3 or f.shape[0] != 3:
        raise DimensionError(f"aft/fore: expected (3,) or (3, n), got {a.shape} and {f.shape}")
    n, e, d = geodesy.geodetic2ned(f[0], f[1], f[2], a[0], a[1], a[2], ell)
    heading = wrap_2pi(np.arctan2(e, n) - baseline_yaw)
    return heading, np.sqrt(n * n + e * e + d * d)


def bearing_range(origin_ne: ArrayLike, target_ne: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Bearing (radians clockwise from north, in [0, 2π)) and horizontal range (m) from
    `origin_ne` to `target_ne`, both (..., 2) arrays of (north, east) metres."""
    o = as_float_array("origin_ne", origin_ne)
    t = as_float_array("target_ne", target_ne)
    if o.shape[-1] != 2 or t.shape[-1] != 2:
        raise DimensionError(f"origin_ne/target_ne: last axis must be 2, got {o.shape}, {t.shape}")
    d = t - o
    return wrap_2pi(np.arctan2(d[..., 1], d[..., 0])), np.hypot(d[..., 0], d[..., 1])


def relative_bearing(bearing: ArrayLike, heading: ArrayLike) -> np.ndarray:
    """Bearing relative to the bow, wrapped to [-π, π) (positive = starboard), radians."""
    b = as_float_array("bearing", bearing)
    h = as_float_array("heading", heading)
    return wrap_pi(b - h)
