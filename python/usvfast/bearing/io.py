"""CSV/JSON files of the bearing fusion: camera samples, AIS + own-ship positions, cameras,
and the fused output. Damaged rows are skipped and counted (a `SkippedRowsWarning` and the
`skipped` field); a file with no usable row raises ValueError naming the file.

Samples CSV (one row per detection; header required, column order free), either
  bearings: `source,t,bearing_deg[,confidence]`, or
  pixel boxes: `source,t,x_px,y_px[,confidence][,pan_deg][,tilt_deg][,zoom]` with the box
  centre in pixels (x right, y down), converted through eq. (1) with the camera of each source
  (`cameras.json`; default the paper's calibration: 1 visible, 2 thermal).
  `source` is an integer id, `t` UNIX seconds, `confidence` in [0, 1] (default 1).
AIS CSV: `vessel,t,lat_deg,lon_deg,heading_deg` where vessel is `own` (own-ship GNSS/AIS,
  heading required: degrees clockwise from true north) or `target` (the target's AIS position
  reports, heading may be empty). `lat`, `lon`, `heading` are accepted as column aliases.
Cameras JSON: `{"1": {"width_px": 1920, "height_px": 1200, "hfov_deg": 20.0, ...}, "2": ...}`
  with the fields of `BearingCamera` (vfov_deg may be omitted: square pixels).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast._damage import DamageCounter, DamagedRecordsWarning
from usvfast._files import MAX_LINE_BYTES, OVERLONG_LINE, bounded_lines, regular_file
from usvfast.bearing.ais import VesselTrack
from usvfast.bearing.camera import THERMAL_CAMERA, VISIBLE_CAMERA, BearingCamera, pixel_to_bearing
from usvfast.bearing.fusion import (
    PAPER_MEASUREMENT_STD_DEG,
    THERMAL,
    VISIBLE,
    BearingFusion,
    RmseRow,
)

PAPER_CAMERAS: Mapping[int, BearingCamera] = {VISIBLE: VISIBLE_CAMERA, THERMAL: THERMAL_CAMERA}
"""The paper's calibration per source id (used when no cameras file is given)."""


class SkippedRowsWarning(DamagedRecordsWarning):
    """Some rows of an input file were damaged and skipped (the count is on the result); a
    DamagedRecordsWarning like every reader's."""


class _BadRow(Exception):
    pass


def _cell(row: dict[str, Any], col: str) -> str:
    value = row.get(col)
    if value is None or value.strip() == "":
        raise _BadRow(f"{col} is missing")
    return value.strip()


def _number(row: dict[str, Any], col: str) -> float:
    text = _cell(row, col)
    try:
        value = float(text)
    except ValueError:
        raise _BadRow(f"{col}={text!r} is not a number") from None
    if not math.isfinite(value):
        raise _BadRow(f"{col}={text!r} is not finite")
    return value


def _integer(row: dict[str, Any], col: str) -> int:
    value = _number(row, col)
    if value != round(value):
        raise _BadRow(f"{col}={value!r} is not an integer")
    return int(value)


class _DamagedLine(dict):
    """The row of a line that could not be read as CSV text (`reason` says why)."""

    def __init__(self, reason: str) -> None:
        super().__init__()
        self.reason = reason


def _check_row(row: dict[str, Any]) -> None:
    """Raise _BadRow for an unreadable line or a row with more fields than the header."""
    if isinstance(row, _DamagedLine):
        raise _BadRow(row.reason)
    if None in row:
        raise _BadRow("too many fields")


def _csv_line(raw: bytes) -> list[str] | str:
    """The fields of one CSV line, or why it cannot be read (not UTF-8, over-long, bad CSV)."""
    if raw == OVERLONG_LINE:
        return f"line longer than {MAX_LINE_BYTES} bytes"
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        return "not UTF-8 text"
    try:
        return next(csv.reader([text]), [])
    except csv.Error as exc:
        return f"not CSV ({exc})"


def _open_rows(
    path: Path, label: str
) -> tuple[list[str], Iterable[tuple[int, dict[str, Any]]], Any]:
    """(header, rows, open file) of a CSV file read line by line, so that a line that is not
    UTF-8, too long or not CSV costs only its row (a `_DamagedLine`)."""
    try:
        f = regular_file(path, label).open("rb")
    except OSError as exc:
        raise ValueError(f"{label}: cannot open {path}: {exc.strerror}") from exc
    lines = bounded_lines(f)
    first = next(lines, b"").removeprefix(b"\xef\xbb\xbf")  # a UTF-8 byte-order mark
    fields = _csv_line(first)
    if isinstance(fields, str):
        f.close()
        raise ValueError(f"{label}: {path}: the header line is unreadable ({fields})")
    header = [h.strip() for h in fields]

    def rows() -> Iterable[tuple[int, dict[str, Any]]]:
        for line_num, raw in enumerate(lines, start=2):
            values = _csv_line(raw)
            if isinstance(values, str):
                yield line_num, _DamagedLine(values)
                continue
            if not values:
                continue  # blank line, as csv.DictReader skips it
            row: dict[Any, Any] = dict(zip(header, values, strict=False))
            if len(values) > len(header):
                row[None] = values[len(header) :]
            yield line_num, row

    return header, rows(), f


def _bad_rows(path: Path) -> DamageCounter:
    return DamageCounter(str(path), what="bad row(s)", category=SkippedRowsWarning)


@dataclass(frozen=True)
class BearingSamples:
    """Samples read from a CSV, sorted by time (stable).

    source (n,) int ids, times (n,) UNIX seconds, bearing_deg (n,) relative to own heading,
    elevation_deg (n,) (NaN when the file held bearings, not pixels), confidence (n,).
    skipped: number of damaged rows left out.
    """

    source: np.ndarray
    times: np.ndarray
    bearing_deg: np.ndarray
    elevation_deg: np.ndarray
    confidence: np.ndarray
    skipped: int


def read_cameras(path: Path | str) -> dict[int, BearingCamera]:
    """Read a cameras JSON file `{"<source id>": {BearingCamera fields}, ...}`.

    Raises ValueError naming the file and the entry when it cannot be read or is invalid.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"cameras: cannot read {path}: {exc}") from exc
    if not isinstance(data, dict) or not data:
        raise ValueError(f"cameras: {path} must hold an object of source id -> camera")
    cameras = {}
    for key, values in data.items():
        try:
            sid = int(key)
            if not isinstance(values, dict):
                raise ValueError("expected an object of camera fields")
            cameras[sid] = BearingCamera.from_dict(values)
        except ValueError as exc:
            raise ValueError(f"cameras: {path}, entry {key!r}: {exc}") from exc
    return cameras


def read_bearing_samples(
    path: Path | str,
    cameras: Mapping[int, BearingCamera] | None = None,
    *,
    sources: Iterable[int] | None = None,
) -> BearingSamples:
    """Read a samples CSV (bearings or pixel boxes; format in the module doc).

    cameras: calibration per source id for pixel files (default `PAPER_CAMERAS`). sources:
    the accepted source ids (default 1 and 2, the paper's). Rows with a missing/unparseable/
    non-finite value, an unknown source (or, for pixels, one without a camera), a confidence
    outside [0, 1] or a non-positive zoom are skipped and counted. Raises
    ValueError naming the file when a required column is missing or no row is usable.
    """
    path = Path(path)
    header, rows, f = _open_rows(path, "samples")
    with f:
        is_bearing = "bearing_deg" in header
        required = ["source", "t"] + (["bearing_deg"] if is_bearing else ["x_px", "y_px"])
        missing = [c for c in required if c not in header]
        if missing:
            raise ValueError(
                f"samples: {path} lacks column(s) {missing}; expected source,t,bearing_deg or "
                "source,t,x_px,y_px (plus optional confidence, pan_deg, tilt_deg, zoom)"
            )
        cams = dict(PAPER_CAMERAS if cameras is None else cameras)
        known = set(PAPER_MEASUREMENT_STD_DEG if sources is None else sources)
        optional = [c for c in ("confidence", "pan_deg", "tilt_deg", "zoom") if c in header]
        parsed: list[tuple[float, ...]] = []
        bad = _bad_rows(path)
        for line, row in rows:
            try:
                _check_row(row)
                sid = _integer(row, "source")
                if sid not in known:
                    raise _BadRow(f"unknown source {sid}")
                if not is_bearing and sid not in cams:
                    raise _BadRow(f"no camera for source {sid}")
                values = [float(sid), *(_number(row, c) for c in required[1:])]
                extra = {c: _number(row, c) for c in optional}
                conf = extra.get("confidence", 1.0)
                if not 0.0 <= conf <= 1.0:
                    raise _BadRow(f"confidence={conf} is outside [0, 1]")
                if extra.get("zoom", 1.0) <= 0.0:
                    raise _BadRow("zoom must be > 0")
                if not is_bearing:
                    cam = cams[sid]
                    values += [
                        extra.get("pan_deg", cam.pan_deg),
                        extra.get("tilt_deg", cam.tilt_deg),
                        extra.get("zoom", cam.zoom),
                    ]
                parsed.append((*values, conf))
            except _BadRow as exc:
                bad.add(f"line {line}: {exc}")
    if not parsed:
        raise ValueError(f"samples: no usable row in {path} ({bad.count} bad row(s))")
    bad.warn()
    table = np.array(parsed, dtype=np.float64)
    table = table[np.argsort(table[:, 1], kind="stable")]
    source = table[:, 0].astype(np.int64)
    if is_bearing:
        bearing, elevation = table[:, 2], np.full(len(table), np.nan)
    else:
        bearing, elevation = np.empty(len(table)), np.empty(len(table))
        for sid in np.unique(source):
            m = source == sid
            b, e = pixel_to_bearing(
                table[m, 2],
                table[m, 3],
                cams[int(sid)],
                pan_deg=table[m, 4],
                tilt_deg=table[m, 5],
                zoom=table[m, 6],
            )
            bearing[m], elevation[m] = b, e
    return BearingSamples(
        source, table[:, 1].copy(), bearing, elevation, table[:, -1].copy(), bad.count
    )


@dataclass(frozen=True)
class AisData:
    """Own-ship track (with headings) and target AIS track read from an AIS CSV;
    skipped: number of damaged or duplicate rows left out."""

    own: VesselTrack
    target: VesselTrack
    skipped: int


def read_ais(path: Path | str) -> AisData:
    """Read an AIS CSV (`vessel,t,lat_deg,lon_deg,heading_deg`; format in the module doc).

    Rows with an unknown vessel, a missing/unparseable value, |lat| > 90°, |lon| > 180°, a
    missing own-ship heading or a repeated time of the same vessel are skipped and counted.
    Raises ValueError naming the file when a column is missing or fewer than 2 usable rows of
    either vessel remain.
    """
    path = Path(path)
    header, rows, f = _open_rows(path, "ais")
    alias = {"lat": "lat_deg", "lon": "lon_deg", "heading": "heading_deg"}
    with f:
        cols = {alias.get(h, h): h for h in header}
        missing = [c for c in ("vessel", "t", "lat_deg", "lon_deg") if c not in cols]
        if missing:
            raise ValueError(
                f"ais: {path} lacks column(s) {missing}; "
                "expected vessel,t,lat_deg,lon_deg,heading_deg"
            )
        tracks: dict[str, dict[float, tuple[float, float, float]]] = {"own": {}, "target": {}}
        bad = _bad_rows(path)
        for line, raw in rows:
            row = {c: raw.get(h) for c, h in cols.items()}
            try:
                _check_row(raw)
                vessel = _cell(row, "vessel").lower()
                if vessel not in tracks:
                    raise _BadRow(f"vessel={vessel!r} is neither 'own' nor 'target'")
                t, lat, lon = (_number(row, c) for c in ("t", "lat_deg", "lon_deg"))
                if abs(lat) > 90.0 or abs(lon) > 180.0:
                    raise _BadRow(f"position ({lat}, {lon}) is out of range")
                if vessel == "own":
                    if "heading_deg" not in cols:
                        raise _BadRow("own-ship row without heading_deg")
                    heading = _number(row, "heading_deg")
                else:
                    heading = float("nan")
                if t in tracks[vessel]:
                    raise _BadRow(f"repeated time {t} for {vessel}")
                tracks[vessel][t] = (lat, lon, heading)
            except _BadRow as exc:
                bad.add(f"line {line}: {exc}")
    for vessel, points in tracks.items():
        if len(points) < 2:
            raise ValueError(
                f"ais: {path} has {len(points)} usable '{vessel}' row(s), need at least 2 "
                f"({bad.count} bad row(s))"
            )
    bad.warn()

    def track(points: dict[float, tuple[float, float, float]], with_heading: bool) -> VesselTrack:
        t = np.array(sorted(points))
        values = np.array([points[k] for k in t])
        return VesselTrack(t, values[:, 0], values[:, 1], values[:, 2] if with_heading else None)

    return AisData(track(tracks["own"], True), track(tracks["target"], False), bad.count)


FUSION_COLUMNS = (
    "t",
    "source",
    "measured_bearing_deg",
    "confidence",
    "bearing_deg",
    "bearing_std_deg",
    "bearing_rate_deg_s",
    "bearing_rate_std_deg_s",
    "ais_bearing_deg",
)


def write_fusion_csv(path: Path | str, fusion: BearingFusion, reference_deg: ArrayLike) -> Path:
    """Write the fused bearing per sample: columns `FUSION_COLUMNS` (ais_bearing_deg empty
    where AIS does not cover). Returns the path."""
    path = Path(path)
    ref = np.asarray(reference_deg, dtype=np.float64)
    with path.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(FUSION_COLUMNS)
        for k in range(len(fusion.times)):
            w.writerow(
                [
                    f"{fusion.times[k]:.3f}",
                    int(fusion.source[k]),
                    f"{fusion.measured_bearing_deg[k]:.4f}",
                    f"{fusion.confidence[k]:.3f}",
                    f"{fusion.bearing_deg[k]:.4f}",
                    f"{fusion.bearing_std_deg[k]:.4f}",
                    f"{fusion.bearing_rate_deg_s[k]:.5f}",
                    f"{fusion.bearing_rate_std_deg_s[k]:.5f}",
                    "" if not np.isfinite(ref[k]) else f"{ref[k]:.4f}",
                ]
            )
    return path


def write_rmse_csv(path: Path | str, rows: Iterable[RmseRow]) -> Path:
    """Write the RMSE table: columns label,rmse_deg,count. Returns the path."""
    path = Path(path)
    with path.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["label", "rmse_deg", "count"])
        for row in rows:
            w.writerow([row.label, f"{row.rmse_deg:.4f}", row.count])
    return path
