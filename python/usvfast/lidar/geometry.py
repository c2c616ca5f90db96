"""Geometry of a multi-beam spinning LiDAR over flat water (thesis section 3.3.1).

The sensor's `channels` beams are spread evenly over a vertical field of view `vfov_deg`
centred on the horizon (VLP-16: 16 beams, ±15°, 2° apart). Only beams below the horizon hit
the water; the nearest one bounds a dead zone around the sensor, and the gaps between the
others bound the height an object needs to be seen.
"""

from __future__ import annotations

import numpy as np

from usvfast._validate import finite_result, real


def _check(height: float, channels: int, vfov_deg: float) -> None:
    height, vfov_deg = real("height", height), real("vfov_deg", vfov_deg)
    if height <= 0:
        raise ValueError(f"height: expected a positive mount height in metres, got {height}")
    c = real("channels", channels)
    if not c.is_integer() or not 2 <= c <= 100_000:
        raise ValueError(f"channels: expected an integer in [2, 100000], got {channels}")
    if not 2e-9 < vfov_deg < 180:  # the lowest beam below the horizon (downward_angles_deg)
        raise ValueError(f"vfov_deg: expected 2e-9 < vfov_deg < 180, got {vfov_deg}")


def downward_angles_deg(channels: int = 16, vfov_deg: float = 30.0) -> np.ndarray:
    """Angles from the vertical (nadir) of the beams below the horizon, nearest ray first.

    Beam i (i = 0 lowest) points at 90° − FOV/2 + i·res from nadir, res = FOV/(channels−1);
    beams at or above the horizon (≥ 90°) never meet the water and are left out.
    """
    _check(1.0, channels, vfov_deg)
    res = vfov_deg / (channels - 1)
    angles = 90.0 - vfov_deg / 2.0 + res * np.arange(channels)
    return angles[angles < 90.0 - 1e-9]


def water_geometry(
    height: float, *, channels: int = 16, vfov_deg: float = 30.0
) -> tuple[np.ndarray, np.ndarray]:
    """Water intersection distance and worst-case visible object height of each downward ray.

    Parameters
    ----------
    height : mount height of the sensor above the water, m (> 0).
    channels, vfov_deg : number of beams and total vertical field of view (degrees), beams
        evenly spaced and centred on the horizon.

    Returns
    -------
    distance : (k,) horizontal distance at which each downward ray meets the water, m,
        nearest ray first (eq. 3.18: dist_i = h·tan(90° − FOV/2 + i·res)).
    min_height : (k,) the height an object just beyond ray i−1's water point needs to reach
        ray i (eq. 3.19: (dist_i − dist_{i−1}) / tan(90° − FOV/2 + i·res)), m; NaN for the
        nearest ray (nothing below it).

    Raises ValueError for a non-positive height or an invalid sensor description.

    Note: for the VLP-16 at 1 m this gives 0.67 m for ray 7, where the thesis's Table 3.1
    prints 0.8 m; the other entries match. We follow the equation.
    """
    _check(height, channels, vfov_deg)
    theta = np.deg2rad(downward_angles_deg(channels, vfov_deg))
    # eq. 3.18
    distance = height * np.tan(theta)
    # eq. 3.19
    min_height = np.full(distance.shape, np.nan)
    min_height[1:] = (distance[1:] - distance[:-1]) / np.tan(theta[1:])
    return distance, min_height


def dead_zone_radius(
    height: float, object_height: float, *, channels: int = 16, vfov_deg: float = 30.0
) -> float:
    """Radius (m) inside which an object `object_height` metres tall is missed by every beam.

    The lowest beam meets an object of height o at horizontal distance (h − o)·tan(θ₀)
    (thesis: 3.73 m − 0.1·tan 75° = 3.35 m for a 10 cm object under a VLP-16 at 1 m); an
    object as tall as the mount is never in a dead zone (0). Raises ValueError for a
    negative or non-finite object height or an invalid sensor.
    """
    _check(height, channels, vfov_deg)
    if not np.isfinite(object_height) or object_height < 0:
        raise ValueError(f"object_height: expected a height >= 0 in metres, got {object_height}")
    theta0 = np.deg2rad(downward_angles_deg(channels, vfov_deg)[0])
    with np.errstate(over="ignore"):
        radius = np.array(max(0.0, (height - object_height) * np.tan(theta0)))
    return float(finite_result("the radius", radius, "height, vfov_deg"))
