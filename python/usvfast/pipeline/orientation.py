"""Orientations of navigation and attitude streams: REP-103 quaternions (body FLU relative to
world ENU) turned into FRD/NED roll and pitch (`imu_roll_pitch`) and into headings
(`quaternion_heading`, with a stream's `yaw_convention`), and which quaternions are
orientations at all (`usable_orientations`: an IMU without an orientation estimate publishes
zeros).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "HEADING_MSGTYPES",
    "YAW_CONVENTIONS",
    "imu_roll_pitch",
    "quaternion_heading",
    "usable_orientations",
]

#: Yaw conventions of heading quaternions (the stream option `yaw_convention`).
YAW_CONVENTIONS = ("enu", "north_clockwise")
#: Message types whose orientation gives a navigation stream's heading.
HEADING_MSGTYPES = ("geometry_msgs/msg/QuaternionStamped", "sensor_msgs/msg/Imu")

# ENU -> NED (world) and FLU -> FRD (body) axis swaps.
_ENU_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
_FLU_FRD = np.diag([1.0, -1.0, -1.0])


def usable_orientations(orientation_xyzw: ArrayLike) -> np.ndarray:
    """(n,) bool: which quaternions (n, 4) x, y, z, w are orientations — finite, with a norm
    within 0.1 of one. An IMU without an orientation estimate publishes zeros (REP-145:
    orientation covariance[0] = -1), which is no rotation."""
    q = np.asarray(orientation_xyzw, dtype=np.float64).reshape(-1, 4)
    with np.errstate(over="ignore", invalid="ignore"):
        norm = np.linalg.norm(q, axis=1)
    return np.isfinite(q).all(axis=1) & (np.abs(norm - 1.0) <= 0.1)


def _rotations(orientation_xyzw: ArrayLike) -> np.ndarray:
    """(n, 3, 3) rotation matrices of unit-normalised quaternions (n, 4) x, y, z, w (the
    tests check them against scipy's Rotation; importing scipy.spatial costs more than the
    whole navigation read). Raises ValueError naming the first quaternion that is no
    orientation (`usable_orientations`)."""
    q = np.asarray(orientation_xyzw, dtype=np.float64).reshape(-1, 4)
    bad = np.flatnonzero(~usable_orientations(q))
    if bad.size:
        raise ValueError(
            f"orientation_xyzw: row {bad[0]} {q[bad[0]].tolist()} is no orientation "
            f"(a finite quaternion of norm 1 ± 0.1), {bad.size} such rows"
        )
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    x, y, z, w = q.T
    r = np.empty((len(q), 3, 3))
    r[:, 0, 0] = 1 - 2 * (y * y + z * z)
    r[:, 0, 1] = 2 * (x * y - z * w)
    r[:, 0, 2] = 2 * (x * z + y * w)
    r[:, 1, 0] = 2 * (x * y + z * w)
    r[:, 1, 1] = 1 - 2 * (x * x + z * z)
    r[:, 1, 2] = 2 * (y * z - x * w)
    r[:, 2, 0] = 2 * (x * z - y * w)
    r[:, 2, 1] = 2 * (y * z + x * w)
    r[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return r


def quaternion_heading(orientation_xyzw: ArrayLike, yaw_convention: str = "enu") -> np.ndarray:
    """Headings (n,) rad clockwise from north in [0, 2π) of quaternions (n, 4) x, y, z, w:
    with "enu" (REP-103) the direction of the body's x axis (FLU in ENU) in the horizontal
    plane; with "north_clockwise" the quaternion's own yaw, which is then the heading.
    Raises ValueError for another convention or a quaternion that is no orientation."""
    if yaw_convention not in YAW_CONVENTIONS:
        raise ValueError(
            f"yaw_convention: expected one of {YAW_CONVENTIONS}, got {yaw_convention!r}"
        )
    r = _rotations(orientation_xyzw)
    east, north = r[:, 0, 0], r[:, 1, 0]  # the x axis in the quaternion's frame
    if yaw_convention == "enu":
        heading = np.arctan2(east, north)
    else:
        heading = np.arctan2(north, east)  # the yaw itself
    return np.mod(heading, 2 * math.pi)


def imu_roll_pitch(orientation_xyzw: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Roll and pitch (rad, FRD body in NED) from REP-103 quaternions (n, 4) x, y, z, w of
    the body FLU in ENU. Returns two (n,) arrays. Raises ValueError for a quaternion that is
    no orientation (`usable_orientations`)."""
    r = _rotations(orientation_xyzw)
    r_ned = _ENU_NED @ r @ _FLU_FRD  # NED <- FRD = Rz(yaw) Ry(pitch) Rx(roll), eq. 3.9
    pitch = np.arcsin(np.clip(-r_ned[:, 2, 0], -1.0, 1.0))
    roll = np.arctan2(r_ned[:, 2, 1], r_ned[:, 2, 2])
    return roll, pitch
