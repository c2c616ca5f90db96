"""GPX track reader (via gpxpy): track points as numpy arrays of UNIX time, latitude,
longitude and elevation.

Damaged points (unparseable numbers, latitude/longitude out of range, missing or unreadable
time) are skipped and counted (`GpxTrack.skipped`, a `DamagedRecordsWarning`). When gpxpy
rejects the document as a whole (a bad number anywhere, or a file cut off mid-write, common
for loggers that lost power), every complete `<trkpt>` element is parsed on its own with gpxpy
so that one bad point never loses the good ones.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import gpxpy
import gpxpy.gpx
import numpy as np

from usvfast.nav._damage import DamageCounter, check_file

_TRKPT = re.compile(rb"<trkpt\b[^>]*?(?:/>|>.*?</trkpt\s*>)", re.DOTALL)
_TRKPT_OPEN = re.compile(rb"<trkpt\b")
_VERSION = re.compile(rb"<gpx\b[^>]*\bversion=[\"']([0-9.]+)[\"']")


@dataclass(frozen=True)
class GpxTrack:
    """Track points of a GPX file, sorted by time (stable; file order for equal times).

    times (n,) float64 UNIX seconds (UTC; a time without a zone is taken as UTC, as GPX
    specifies), lat_deg (n,) and lon_deg (n,) WGS84 degrees, ele_m (n,) metres (NaN when the
    point has no elevation), segment (n,) int index of the track segment over the whole file.
    skipped: number of damaged points left out.
    """

    times: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    ele_m: np.ndarray
    segment: np.ndarray
    skipped: int

    def __len__(self) -> int:
        return int(self.times.size)


def _unix(t: datetime) -> float:
    if t.tzinfo is None or t.utcoffset() is None:
        t = t.replace(tzinfo=timezone.utc)
    return t.timestamp()


def _point_row(p: gpxpy.gpx.GPXTrackPoint) -> tuple[float, float, float, float] | str:
    """(time, lat, lon, ele) of a point, or the reason it is damaged."""
    lat, lon = p.latitude, p.longitude
    if lat is None or lon is None or not (math.isfinite(lat) and math.isfinite(lon)):
        return "missing or non-finite lat/lon"
    if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        return f"lat/lon out of range ({lat}, {lon})"
    if p.time is None:
        return "missing or unreadable time"
    ele = p.elevation
    ele = float(ele) if ele is not None and math.isfinite(ele) else math.nan
    return _unix(p.time), float(lat), float(lon), ele


def _rows_whole(gpx: gpxpy.gpx.GPX, damage: DamageCounter) -> list[tuple[float, ...]]:
    rows: list[tuple[float, ...]] = []
    seg = 0
    for track in gpx.tracks:
        for segment in track.segments:
            for p in segment.points:
                row = _point_row(p)
                if isinstance(row, str):
                    damage.add(row)
                else:
                    rows.append((*row, seg))
            seg += 1
    return rows


def _rows_pointwise(raw: bytes, damage: DamageCounter) -> list[tuple[float, ...]]:
    """Parse each complete <trkpt> on its own (segment boundaries are not recovered: 0)."""
    m = _VERSION.search(raw)
    version = m.group(1).decode() if m else "1.1"
    rows: list[tuple[float, ...]] = []
    end = 0
    for match in _TRKPT.finditer(raw):
        end = match.end()
        doc = (
            f'<?xml version="1.0"?><gpx version="{version}"><trk><trkseg>'.encode()
            + match.group(0)
            + b"</trkseg></trk></gpx>"
        )
        try:
            points = gpxpy.parse(doc.decode("utf-8", errors="replace")).tracks[0].segments[0].points
        except (gpxpy.gpx.GPXException, IndexError, ValueError) as exc:
            damage.add(f"unreadable point ({exc})")
            continue
        row = _point_row(points[0])
        if isinstance(row, str):
            damage.add(row)
        else:
            rows.append((*row, 0))
    if _TRKPT_OPEN.search(raw, end):
        damage.add("point cut off at the end of the file")
    return rows


def read_gpx(path: Path | str) -> GpxTrack:
    """Read the track points of a GPX 1.0/1.1 file (routes and waypoints are ignored).

    Returns a GpxTrack sorted by time. Damaged points are skipped and counted with a
    DamagedRecordsWarning; raises ValueError naming the file when it cannot be read or holds
    no usable track point.
    """
    path = check_file(path, "gpx")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"gpx: cannot read {path}: {exc.strerror}") from exc
    damage = DamageCounter(str(path))
    try:
        rows = _rows_whole(gpxpy.parse(raw.decode("utf-8", errors="replace")), damage)
    except gpxpy.gpx.GPXException:
        # Damaged document: recover point by point.
        damage = DamageCounter(str(path))
        rows = _rows_pointwise(raw, damage)
    if not rows:
        raise ValueError(
            f"gpx: {path} holds no usable track point ({damage.count} damaged point(s))"
        )
    damage.warn()
    arr = np.asarray(rows, dtype=np.float64)
    order = np.argsort(arr[:, 0], kind="stable")
    arr = arr[order]
    return GpxTrack(
        times=np.ascontiguousarray(arr[:, 0]),
        lat_deg=np.ascontiguousarray(arr[:, 1]),
        lon_deg=np.ascontiguousarray(arr[:, 2]),
        ele_m=np.ascontiguousarray(arr[:, 3]),
        segment=arr[:, 4].astype(np.int64),
        skipped=damage.count,
    )
