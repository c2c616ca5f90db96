"""Eq. (2): AIS-based relative bearing of a target, vessel tracks interpolated in time, and
the AIS reporting intervals of ITU-R M.1371.

Angles are degrees (names end in `_deg`); latitudes/longitudes are WGS84 degrees on a
sphere (great-circle initial bearing), headings degrees clockwise from true north.

Sign convention: the relative bearing is positive clockwise, i.e. to starboard of own
heading, and wrapped to (-180°, 180°]: 0° dead ahead, +90° abeam to starboard, -90° abeam to
port, 180° dead astern. This is the convention of eq. (1) (x to the right in the image is
clockwise). The paper prints eq. (2) as heading - bearing (counter-clockwise positive) with a
plain arctan; we use atan2 (full circle) and bearing - heading so eq. (1) and eq. (2) agree.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike

from usvfast._angles import wrap_360_deg, wrap_deg
from usvfast._core import DimensionError, TimeOrderError
from usvfast._validate import as_float_array, instance
from usvfast.bearing.angles import float_array
from usvfast.bearing.angles import unwrap_raw_deg as unwrap_deg


def _latitudes(name: str, value: Any) -> np.ndarray:
    lat = float_array(name, value)
    if np.any(np.abs(lat) > 90.0):
        raise ValueError(f"{name}: latitudes must be in [-90, 90] degrees")
    return lat


def great_circle_bearing_deg(
    lat1_deg: Any, lon1_deg: ArrayLike, lat2_deg: Any, lon2_deg: ArrayLike
) -> np.ndarray:
    """Initial great-circle bearing from point 1 to point 2 (degrees clockwise from true north,
    in (-180°, 180°]), on a sphere; arrays broadcast. Undefined (returns 0°, north) when the
    points coincide. Raises ValueError naming the argument on non-finite or |lat| > 90°.
    """
    phi_r = np.radians(_latitudes("lat1_deg", lat1_deg))
    phi_t = np.radians(_latitudes("lat2_deg", lat2_deg))
    dlam = np.radians(float_array("lon2_deg", lon2_deg) - float_array("lon1_deg", lon1_deg))
    # eq. (2): atan2(sin Δλ cos φT, cos φR sin φT - sin φR cos φT cos Δλ)
    y = np.sin(dlam) * np.cos(phi_t)
    x = np.cos(phi_r) * np.sin(phi_t) - np.sin(phi_r) * np.cos(phi_t) * np.cos(dlam)
    return wrap_deg(np.degrees(np.arctan2(y, x)))


def relative_bearing_deg(
    own_lat_deg: Any,
    own_lon_deg: Any,
    own_heading_deg: ArrayLike,
    target_lat_deg: Any,
    target_lon_deg: Any,
) -> np.ndarray:
    """Eq. (2): bearing of the target relative to own heading, degrees in (-180°, 180°],
    positive clockwise (starboard). All arguments are degrees and broadcast together.

    β0 = wrap(atan2(sin Δλ cos φT, cos φR sin φT − sin φR cos φT cos Δλ) − heading).
    Raises ValueError naming the argument on non-finite values or |lat| > 90°.
    """
    true_bearing = great_circle_bearing_deg(
        own_lat_deg, own_lon_deg, target_lat_deg, target_lon_deg
    )
    return wrap_deg(true_bearing - float_array("own_heading_deg", own_heading_deg))


def ais_report_interval_s(
    speed_kn: float, *, changing_course: bool = False, moored: bool = False
) -> float:
    """Nominal reporting interval (seconds) of a Class A AIS position report (ITU-R M.1371-5,
    Table 1): moored/anchored and not faster than 3 kn 180 s; 0–14 kn 10 s (changing course
    3⅓ s); 14–23 kn 6 s (changing course 2 s); over 23 kn 2 s. Raises ValueError on a
    negative or non-finite speed_kn.
    """
    if not np.isfinite(speed_kn) or speed_kn < 0:
        raise ValueError(f"speed_kn: expected a finite speed >= 0, got {speed_kn}")
    if moored and speed_kn <= 3.0:
        return 180.0
    if speed_kn <= 14.0:
        return 10.0 / 3.0 if changing_course else 10.0
    if speed_kn <= 23.0:
        return 2.0 if changing_course else 6.0
    return 2.0


@dataclass(frozen=True)
class VesselTrack:
    """Time-stamped positions of one vessel (AIS reports, or own GNSS + gyro).

    times: (n,) UNIX seconds, strictly increasing, n >= 2. lat_deg, lon_deg: (n,) degrees.
    heading_deg: (n,) degrees clockwise from true north, or None (target AIS: not needed).
    Raises ValueError subclasses naming the field on bad shapes, non-finite values, |lat| >
    90° or times not strictly increasing.
    """

    times: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    heading_deg: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = as_float_array("times", self.times, ndim=1)
        fields = {"times": t, "lat_deg": _latitudes("lat_deg", self.lat_deg)}
        fields["lon_deg"] = float_array("lon_deg", self.lon_deg)
        if self.heading_deg is not None:
            fields["heading_deg"] = float_array("heading_deg", self.heading_deg)
        for name, arr in fields.items():
            if arr.shape != t.shape:
                raise DimensionError(f"{name}: expected shape {t.shape}, got {arr.shape}")
            object.__setattr__(self, name, arr)
        if len(t) < 2:
            raise ValueError(f"times: need at least 2 positions to interpolate, got {len(t)}")
        if np.any(np.diff(t) <= 0):
            raise TimeOrderError("times: must be strictly increasing")

    def at(self, times: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Latitude, longitude and heading (degrees) at `times` ((k,) UNIX seconds), linear in
        time between the two neighbouring positions (longitude and heading unwrapped, so the
        antimeridian and north are crossed the short way). NaN outside [times[0], times[-1]];
        heading is None when the track has none.
        """
        t = float_array("times", times)
        inside = (t >= self.times[0]) & (t <= self.times[-1])

        def interp(values: np.ndarray) -> np.ndarray:
            return np.where(inside, np.interp(t, self.times, values), np.nan)

        lat = interp(self.lat_deg)
        lon = wrap_deg(interp(unwrap_deg(self.lon_deg)))
        heading = None
        if self.heading_deg is not None:
            heading = wrap_360_deg(interp(unwrap_deg(self.heading_deg)))
        return lat, lon, heading


def reference_bearing_deg(times: Any, own: VesselTrack, target: VesselTrack) -> np.ndarray:
    """AIS reference bearing (eq. (2), degrees in (-180°, 180°], clockwise positive) of
    `target` from `own` at `times` ((k,) UNIX seconds), both tracks interpolated linearly in
    time. NaN where either track does not cover the time. `own` must carry headings.
    """
    instance("own", own, VesselTrack)
    instance("target", target, VesselTrack)
    if own.heading_deg is None:
        raise ValueError("own: the own-ship track needs heading_deg")
    lat_o, lon_o, heading = own.at(times)
    lat_t, lon_t, _ = target.at(times)
    ok = np.isfinite(lat_o) & np.isfinite(lat_t)
    out = np.full(lat_o.shape, np.nan)
    heading = cast(np.ndarray, heading)  # own has headings, so at() returned them
    out[ok] = relative_bearing_deg(lat_o[ok], lon_o[ok], heading[ok], lat_t[ok], lon_t[ok])
    return out
