"""The navigation stream of a recording: its position fixes as arrays (GPX points, NMEA fixes,
`sensor_msgs/NavSatFix` bag messages; WGS84, the stream's clock offset applied) and the vessel
pose track built from them (usvfast.nav.pose.PoseTrack)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from usvfast.nav.bags import NavSatFixSample
from usvfast.nav.pose import PoseTrack
from usvfast.nav.replay import Recording
from usvfast.nav.stream_types import (
    GeoPoint,
    NmeaFix,
    NmeaHeading,
    NmeaRateOfTurn,
    NmeaVelocity,
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


def recording_pose_track(recording: Recording, *, max_gap: float | None = None) -> PoseTrack:
    """The vessel pose track (usvfast.nav.pose.PoseTrack) from the recording's navigation stream:
    an `nmea` stream gives positions and true headings (PoseTrack.from_nmea), a `gpx` or
    NavSatFix `bag` stream positions only; the stream's clock offset is applied. max_gap
    (seconds) defaults to the recording's max_pose_gap. Pass it to `Replay` to attach the pose
    at each item's time. Raises ValueError when there is no usable navigation stream.
    """
    gap = recording.max_pose_gap if max_gap is None else max_gap
    if recording.navigation is None:
        raise ValueError("recording: names no navigation stream ([recording] navigation = ...)")
    spec = recording.stream(recording.navigation)
    if spec.type == "nmea":
        from usvfast.nav.nmea import read_nmea

        assert spec.path is not None
        return PoseTrack.from_nmea(
            read_nmea(spec.path),
            max_gap=gap,
            position_offset=spec.clock_offset,
            heading_offset=spec.clock_offset,
        )
    fixes = navigation_fixes(recording)
    alt = fixes.alt_m if np.all(np.isfinite(fixes.alt_m)) else None
    return PoseTrack(fixes.times, fixes.lat_deg, fixes.lon_deg, alt, max_gap=gap)
