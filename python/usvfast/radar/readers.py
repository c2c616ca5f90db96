"""Radar plots from files: (range, bearing) CSV, NMEA ARPA target sentences (TTM, TLL) and
plots already in a local NED plane (the Joyride recording).

All readers return :class:`RadarPlots`, one row per plot in time order. Positions are given
either polar from the own ship (`range_m`, `bearing_deg`) or geodetic (`lat_deg`, `lon_deg`,
TLL) or NED (`north`, `east`, metres of the caller's tangent plane); the fields that do not
apply are NaN. :func:`plots_to_ned` places every plot in one NED plane from the own-ship track.

Damaged records (bad checksum, unparsable fields, unknown radar sentences, untimed lines,
rows out of time order) are skipped and counted, with one `DamagedRecordsWarning`.

Example::

    from usvfast.radar import read_radar_nmea
    plots = read_radar_nmea("arpa.nmea")
    plots.time, plots.range_m, plots.bearing_deg, plots.target_number, plots.n_unknown
"""

from __future__ import annotations

import bisect
import csv
import datetime as _dt
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pynmea2
from numpy.typing import ArrayLike

from usvfast._damage import DamageCounter
from usvfast.nav._damage import iter_lines
from usvfast.nav._fields import DAY, day_start, degrees, nearest_day, seconds_of_day
from usvfast.nav.linetime import LogClock, line_time, tag_block_ok
from usvfast.nav.nmea import KNOT

__all__ = [
    "RadarPlots",
    "plots_from_ned",
    "read_radar_csv",
    "read_radar_nmea",
]

NAUTICAL_MILE = 1852.0
#: TTM distance units -> metres.
_DIST_UNITS = {"N": NAUTICAL_MILE, "K": 1000.0, "S": 1609.344}
#: NMEA sentence types of the radar talker (RA) that are read or known and ignored.
_RADAR_READ = {"TTM", "TLL"}
_RADAR_KNOWN = {"OSD", "RSD", "ZDA", "RMC"}


@dataclass(frozen=True)
class RadarPlots:
    """Radar plots in time order, shape (n,) per array.

    time: UNIX s; range_m (m) and bearing_deg (clockwise from `bearing_true` north, else from
    the bow) from the own ship, NaN when not polar; lat_deg, lon_deg (WGS84, TLL), NaN when
    not geodetic; north, east (m, NED of the caller's plane), NaN until placed; target_number:
    the radar's own target number (ARPA), -1 when none; speed (m/s) and course_deg (true, over
    ground) as the radar reported them, NaN when not given. Counts: n_read (records seen),
    n_damaged (skipped: checksum, fields, time order, no time), n_unknown (radar sentences of
    an unknown type, skipped), n_ignored (other sentences)."""

    time: np.ndarray
    range_m: np.ndarray
    bearing_deg: np.ndarray
    bearing_true: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    north: np.ndarray
    east: np.ndarray
    target_number: np.ndarray
    speed: np.ndarray
    course_deg: np.ndarray
    n_read: int = 0
    n_damaged: int = 0
    n_unknown: int = 0
    n_ignored: int = 0

    def __len__(self) -> int:
        return len(self.time)

    def scans(self) -> tuple[np.ndarray, np.ndarray]:
        """(scan times (s,), scan index of each plot (n,)): plots with one time form one scan."""
        times, index = np.unique(self.time, return_inverse=True)
        return times, index.astype(np.int64)


_COLUMNS = (
    "time",
    "range_m",
    "bearing_deg",
    "bearing_true",
    "lat_deg",
    "lon_deg",
    "north",
    "east",
    "target_number",
    "speed",
    "course_deg",
)
_NAN_ROW = {c: math.nan for c in _COLUMNS} | {"bearing_true": True, "target_number": -1}


def _in_time_order(times: list[float]) -> list[int]:
    """Indices of the longest run of `times` in non-decreasing order (a longest
    non-decreasing subsequence, O(n log n)), the earliest rows among equally long runs: the
    fewest rows dropped to restore time order, so one damaged time, early or late, costs its
    own row and not the rows after it."""
    # longest[i]: the longest non-decreasing run starting at row i (from the end, backwards)
    longest = [0] * len(times)
    tails: list[float] = []
    for i in range(len(times) - 1, -1, -1):
        k = bisect.bisect_right(tails, -times[i])
        if k == len(tails):
            tails.append(-times[i])
        else:
            tails[k] = -times[i]
        longest[i] = k + 1
    out: list[int] = []
    need, last = len(tails), -math.inf
    for i, t in enumerate(times):
        if need and longest[i] == need and t >= last:
            out.append(i)
            need, last = need - 1, t
    return out


def _build(rows: list[dict], counter: DamageCounter, **counts: int) -> RadarPlots:
    """Rows in time order -> RadarPlots; the fewest rows out of time order are skipped."""
    keep = set(_in_time_order([r["time"] for r in rows]))
    kept: list[dict] = []
    for i, r in enumerate(rows):
        if i not in keep:
            counter.add(f"time {r['time']:.3f} out of time order")
            continue
        kept.append(r)
    arrays: dict[str, np.ndarray] = {}
    for c in _COLUMNS:
        dtype = np.bool_ if c == "bearing_true" else np.int64 if c == "target_number" else float
        arrays[c] = np.array([r[c] for r in kept], dtype=dtype)
    return RadarPlots(**arrays, n_damaged=counter.count, **counts)  # pyright: ignore[reportArgumentType]  # (arrays by field name)


def read_radar_csv(path: str | os.PathLike) -> RadarPlots:
    """Plots from a CSV with a header: `time` (UNIX s) and either `range` (m) + `bearing` (deg,
    true, clockwise from north) or `north` + `east` (m, NED); optional `target` (int).

    Rows with missing or non-numeric values, or a time before the previous row's, are skipped
    and counted. Raises ValueError when the columns are missing or no row is usable."""
    counter = DamageCounter(str(path), what="radar plot(s)")
    with open(path, newline="") as fh:
        reader = csv.DictReader(fh)
        fields = {f.strip().lower(): f for f in (reader.fieldnames or [])}
        polar = {"range", "bearing"} <= fields.keys()
        cart = {"north", "east"} <= fields.keys()
        if "time" not in fields or not (polar or cart):
            raise ValueError(
                f"path: {path} needs a header with time and range,bearing or north,east "
                f"(got {list(fields)})"
            )
        rows: list[dict] = []
        n_read = 0
        for lineno, rec in enumerate(reader, start=2):
            n_read += 1
            try:
                row = dict(_NAN_ROW, time=float(rec[fields["time"]]))
                if polar:
                    row["range_m"] = float(rec[fields["range"]])
                    row["bearing_deg"] = float(rec[fields["bearing"]]) % 360.0
                else:
                    row["north"] = float(rec[fields["north"]])
                    row["east"] = float(rec[fields["east"]])
                if "target" in fields and rec[fields["target"]]:
                    row["target_number"] = int(rec[fields["target"]])
                vals = (row["time"], row["range_m"] if polar else row["north"])
                if not all(math.isfinite(v) for v in vals) or (polar and row["range_m"] < 0):
                    raise ValueError("non-finite or negative value")
            except (TypeError, ValueError, KeyError) as e:
                counter.add(f"line {lineno}: {e}")
                continue
            rows.append(row)
    plots = _build(rows, counter, n_read=n_read)
    counter.warn()
    if len(plots) == 0:
        raise ValueError(f"path: no usable radar plot in {path} ({counter.count} damaged)")
    return plots


def read_radar_nmea(
    source: str | os.PathLike | Iterable[Any], *, date: _dt.date | None = None
) -> RadarPlots:
    """ARPA target sentences from an NMEA log (a path or an iterable of lines), parsed by
    pynmea2 with the checksum required: `$--TTM` (target number, distance, bearing true or
    relative, speed, course; distance units N/K/S) and `$--TLL` (target number, latitude,
    longitude). Times: the line's tag block `c:` or leading UNIX time, else the TTM/TLL time
    of day on the date of the log's ZDA/RMC clock (or `date`), else the log's clock itself.

    Radar-talker (`$RA`) sentences of other types are counted in `n_unknown` and skipped, like
    damaged lines; other sentences are counted in `n_ignored`. Targets with status `L` (lost)
    are skipped. Raises ValueError when no target sentence could be read."""
    label = str(source) if isinstance(source, str | os.PathLike) else "radar NMEA lines"
    counter = DamageCounter(label, what="radar sentence(s)")
    clock = LogClock()
    rows: list[dict] = []
    n_read = n_unknown = n_ignored = 0
    for lineno, raw in enumerate(iter_lines(source), start=1):
        line = (raw if isinstance(raw, bytes) else str(raw).encode("ascii", "replace")).strip()
        if not line or line.startswith(b"#"):
            continue
        clock.time_of(line)  # advances the log's ZDA/RMC clock
        t_line = line_time(line)  # the line's own tag block or leading time, else NaN
        start = line.find(b"$")
        kind = line[start + 3 : start + 6] if start >= 0 else b""
        talker = line[start + 1 : start + 3] if start >= 0 else b""
        if kind.decode("ascii", "replace") not in _RADAR_READ:
            if talker == b"RA" and kind.decode("ascii", "replace") not in _RADAR_KNOWN:
                n_unknown += 1
                counter.add(f"line {lineno}: unknown radar sentence {line[start : start + 6]!r}")
            else:
                n_ignored += 1
            continue
        n_read += 1
        if not tag_block_ok(line):
            counter.add(f"line {lineno}: bad tag block checksum")
            continue
        try:
            msg = pynmea2.parse(line[start:].decode("ascii"), check=True)
            row = _target_row(msg, t_line, clock.now, date)
        except (pynmea2.ParseError, UnicodeDecodeError, ValueError, TypeError, KeyError) as e:
            counter.add(f"line {lineno}: {type(e).__name__}")
            continue
        if row is not None:
            rows.append(row)
    plots = _build(rows, counter, n_read=n_read, n_unknown=n_unknown, n_ignored=n_ignored)
    # Unknown radar sentences are counted apart from damaged ones but reported together.
    counter.warn()
    if len(plots) == 0:
        raise ValueError(
            f"source: no usable TTM/TLL sentence ({n_read} read, {plots.n_damaged} damaged, "
            f"{n_unknown} unknown radar sentences)"
        )
    return replace(plots, n_damaged=plots.n_damaged - n_unknown)


def _time_of_day(stamp: _dt.time | None, t_line: float, t_clock: float, date: Any) -> float:
    """UNIX time of a TTM/TLL time of day: the line's own receive time wins; else the time of
    day on the clock's (or `date`'s) day, moved by whole days to within 12 h of the clock."""
    if math.isfinite(t_line):
        return t_line  # tag block or leading column
    if stamp is None:
        if math.isfinite(t_clock):
            return t_clock
        raise ValueError("no time")
    tod = seconds_of_day(stamp)
    if math.isfinite(t_clock):
        return nearest_day(math.floor(t_clock / DAY) * DAY + tod, t_clock)
    if date is None:
        raise ValueError("time of day without a date (no ZDA/RMC in the log and no date=)")
    return day_start(date.year, date.month, date.day) + tod


def _target_row(sentence: Any, t_line: float, t_clock: float, date: Any) -> dict | None:
    msg: Any = sentence  # pynmea2 fields are typed by the sentence's field table, not here
    if type(sentence).__name__ == "TTM":
        if msg.status == "L":
            return None
        unit = _DIST_UNITS[msg.dist_unit or "N"]
        if msg.distance is None or msg.bearing is None:
            raise ValueError("TTM without distance or bearing")
        speed = float(msg.speed) * unit / 3600.0 if msg.speed is not None else math.nan
        if msg.dist_unit == "N":
            speed = float(msg.speed) * KNOT if msg.speed is not None else math.nan
        return dict(
            _NAN_ROW,
            time=_time_of_day(msg.timestamp, t_line, t_clock, date),
            range_m=float(msg.distance) * unit,
            bearing_deg=float(msg.bearing) % 360.0,
            bearing_true=(msg.brg_ref or "T") == "T",
            target_number=int(msg.target_number),
            speed=speed,
            course_deg=float(msg.cog) % 360.0 if msg.cog is not None else math.nan,
        )
    if msg.target_status == "L":
        return None
    lat, lon = degrees(msg.lat, msg.lat_dir), degrees(msg.lon, msg.lon_dir)
    if not (math.isfinite(lat) and math.isfinite(lon)) or abs(lat) > 90 or abs(lon) > 180:
        raise ValueError("TLL without a valid position")
    return dict(
        _NAN_ROW,
        time=_time_of_day(msg.timestamp, t_line, t_clock, date),
        lat_deg=lat,
        lon_deg=lon,
        target_number=int(msg.target_number),
    )


def plots_from_ned(times: ArrayLike, measurements: Iterable[Any]) -> RadarPlots:
    """Plots already in NED (e.g. `load_joyride(...).times, .measurements`): scan i at times[i]
    (UNIX s) holds the (k_i, 2) array (north, east) of metres."""
    rows: list[dict] = []
    for t, m in zip(np.asarray(times, float), measurements, strict=True):
        for n, e in np.asarray(m, float).reshape(-1, 2):
            rows.append(dict(_NAN_ROW, time=float(t), north=float(n), east=float(e)))
    counter = DamageCounter("plots", what="radar plot(s)")
    plots = _build(rows, counter, n_read=len(rows))
    counter.warn()
    return plots
