"""Position fixes of a recording's navigation stream as arrays, the input of a vessel pose
track: GPX points and `sensor_msgs/NavSatFix` bag messages (WGS84), with the stream's clock
offset applied."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from usvfast.nav.bags import NavSatFixSample
from usvfast.nav.replay import (
    GeoPoint,
    NmeaFix,
    NmeaHeading,
    NmeaRateOfTurn,
    NmeaVelocity,
    Recording,
    open_stream,
    split_record,
)


@dataclass(frozen=True)
class GeoFixes:
    """Fixes in time order: times (n,) UNIX s (clock offset applied), lat_deg (n,), lon_deg
    (n,) WGS84 degrees, alt_m (n,) metres as the source gives it (GPX elevation, NMEA height
    above mean sea level, NavSatFix ellipsoidal height; NaN when unknown); stream (its id);
    damaged (records the reader skipped); no_fix (fixes without a position: NavSatFix status
    -1, NMEA quality 0, or non-finite lat/lon; left out)."""

    stream: str
    times: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    alt_m: np.ndarray
    damaged: int
    no_fix: int


def navigation_fixes(recording: Recording, stream_id: str | None = None) -> GeoFixes:
    """Read the geodetic fixes of `stream_id` (default: the recording's navigation stream).

    The stream must be a `gpx` or `nmea` stream or a `bag` topic of NavSatFix messages; records are
    sorted by time (stable). Raises ValueError naming the stream when there is no navigation
    stream, it holds no position fixes, or no usable fix.
    """
    sid = stream_id if stream_id is not None else recording.navigation
    if sid is None:
        raise ValueError("stream_id: the recording names no navigation stream; give stream_id")
    spec = recording.stream(sid)
    source = open_stream(spec, decode=False)
    rows: list[tuple[float, float, float, float]] = []
    no_fix = 0
    for rec in source:
        t, data = split_record(rec)
        t += spec.clock_offset
        if isinstance(data, GeoPoint):
            rows.append((t, data.lat_deg, data.lon_deg, data.ele_m))
        elif isinstance(data, NmeaFix):
            if data.fix_quality == 0 or not (
                math.isfinite(data.lat_deg) and math.isfinite(data.lon_deg)
            ):
                no_fix += 1
                continue
            rows.append((t, data.lat_deg, data.lon_deg, data.altitude))
        elif isinstance(data, (NmeaHeading, NmeaVelocity, NmeaRateOfTurn)):
            continue  # the other records of an NMEA stream
        elif isinstance(data, NavSatFixSample):
            if data.status < 0 or not (math.isfinite(data.lat_deg) and math.isfinite(data.lon_deg)):
                no_fix += 1
                continue
            rows.append((t, data.lat_deg, data.lon_deg, data.alt_m))
        else:
            raise ValueError(
                f"stream_id: stream {sid!r} ({spec.type}) holds {type(data).__name__} records, "
                "not position fixes (use a gpx stream or a NavSatFix bag topic)"
            )
    if not rows:
        raise ValueError(f"stream_id: stream {sid!r} has no usable position fix ({no_fix} no-fix)")
    arr = np.asarray(rows, dtype=np.float64)
    arr = arr[np.argsort(arr[:, 0], kind="stable")]
    return GeoFixes(
        stream=sid,
        times=np.ascontiguousarray(arr[:, 0]),
        lat_deg=np.ascontiguousarray(arr[:, 1]),
        lon_deg=np.ascontiguousarray(arr[:, 2]),
        alt_m=np.ascontiguousarray(arr[:, 3]),
        damaged=int(getattr(source, "damaged", 0)),
        no_fix=no_fix,
    )
