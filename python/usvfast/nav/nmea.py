"""NMEA 0183 logs and streams → numpy arrays of positions, headings, velocities, turn rates.

Parsing is pynmea2's; this module adds what a tracker needs on top: checksum validation, any
talker id (GP, GN, GL, HE, IN, ...), absolute UNIX times for sentences that carry only a time of
day (GGA, GLL) from the date of RMC/ZDA with midnight rollover, time stamps for sentences with
no time at all (HDT, THS, VTG, ROT get the time of the fix epoch they arrive in), and damaged
lines skipped and counted.

Example::

    from usvfast.nav.nmea import read_nmea
    log = read_nmea("ublox-zed-f9p-nmea.log")
    log.positions.time, log.positions.lat_deg, log.positions.lon_deg, log.n_damaged

Sentences read: GGA, RMC, GLL (positions), ZDA (date/time), VTG and RMC (speed over ground,
course), HDT and THS (true heading), ROT (rate of turn), and the headings of dual-antenna GNSS
compasses, which carry their own time of day: Hemisphere `$PSAT,HPR` and Ashtech/Spectra
`$PASHR,HPR` (true heading), Trimble `$PTNL,AVR` (the yaw of the antenna baseline, primary to
secondary antenna: the heading when the antennas are mounted aft to fore along the keel; else
correct it with the pipeline's `heading_offset_deg`). Their pitch and roll are not read:
which of the two a two-antenna baseline measures depends on its mounting. Other proprietary
(`$P...`), AIS (`!...`) and other sentence types are ignored and counted in `n_ignored`;
lines with a bad or missing checksum, garbage or unparsable fields are skipped and counted in
`n_damaged` (with a `DamagedRecordsWarning`). A ValueError is raised only when no usable
sentence is left, or when no date is found anywhere and none is given.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pynmea2

from usvfast._damage import DamagedRecordsWarning
from usvfast.nav._damage import iter_lines
from usvfast.nav._fields import DAY, checksum_ok, day_start, degrees, nearest_day, seconds_of_day

__all__ = [
    "MODE_QUALITY",
    "DamagedRecordsWarning",
    "Headings",
    "NmeaLog",
    "Positions",
    "RatesOfTurn",
    "Velocities",
    "compass_heading",
    "read_nmea",
]

KNOT = 1852.0 / 3600.0  # m/s
HALF_DAY = 43200.0
_POSITION_TYPES = {"GGA": 0, "RMC": 1, "GLL": 2}  # priority when several share one time
_WANTED = {"GGA", "RMC", "GLL", "ZDA", "VTG", "HDT", "THS", "ROT"}
#: Proprietary GNSS-compass heading sentences (address → the Headings' sentence name).
COMPASS_SENTENCES = {"PSAT,HPR": "HPR", "PASHR,HPR": "HPR", "PTNL,AVR": "AVR"}
#: FAA mode indicator → GGA-style fix quality.
MODE_QUALITY = {"A": 1, "D": 2, "P": 3, "R": 4, "F": 5, "E": 6, "M": 7, "S": 8, "N": 0}


@dataclass(frozen=True)
class Positions:
    """Position fixes, one per distinct time (GGA preferred over RMC over GLL).

    All arrays have shape (n,). time: UNIX seconds (UTC); lat_deg, lon_deg: WGS84 degrees
    (NaN when the sentence had no position); altitude: metres above mean sea level (GGA only,
    else NaN); fix_quality: GGA quality (0 no fix, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float,
    6 dead reckoning; RMC/GLL mapped from their status and mode); num_satellites (-1 unknown);
    hdop (NaN unknown); sentence: "GGA" | "RMC" | "GLL"; talker: e.g. "GP", "GN".
    """

    time: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    altitude: np.ndarray
    fix_quality: np.ndarray
    num_satellites: np.ndarray
    hdop: np.ndarray
    sentence: np.ndarray
    talker: np.ndarray


@dataclass(frozen=True)
class Headings:
    """True headings (HDT, THS, HPR, AVR): time (UNIX s), heading_deg (clockwise from true
    north, [0, 360) for HPR and AVR), talker (e.g. "HE"; the maker "SAT", "ASH" or "TNL" of a
    proprietary sentence), sentence ("HDT" | "THS" | "HPR" | "AVR"); shape (n,) each."""

    time: np.ndarray
    heading_deg: np.ndarray
    talker: np.ndarray
    sentence: np.ndarray


@dataclass(frozen=True)
class Velocities:
    """Speed and course over ground (RMC, VTG): time (UNIX s), speed (m/s), course_deg
    (clockwise from true north, NaN when not given), sentence; shape (n,) each."""

    time: np.ndarray
    speed: np.ndarray
    course_deg: np.ndarray
    sentence: np.ndarray


@dataclass(frozen=True)
class RatesOfTurn:
    """Rate of turn (ROT): time (UNIX s), rate_deg_per_min (negative = turning to port),
    valid (status A); shape (n,) each."""

    time: np.ndarray
    rate_deg_per_min: np.ndarray
    valid: np.ndarray


@dataclass(frozen=True)
class NmeaLog:
    """What `read_nmea` found. Counts: n_lines (non-blank, non-comment lines), n_used (lines
    that produced data), n_ignored (valid but proprietary, AIS or unread types), n_damaged
    (bad/missing checksum, garbage, unparsable), n_untimed (time-less sentences before the
    first time of day, dropped). `damaged_lines` holds up to 100 1-based line numbers."""

    positions: Positions
    headings: Headings
    velocities: Velocities
    rates_of_turn: RatesOfTurn
    n_lines: int
    n_used: int
    n_ignored: int
    n_damaged: int
    n_untimed: int
    damaged_lines: list[int] = field(default_factory=list)


def compass_heading(body: str) -> tuple[str, str, float, float] | None:
    """(sentence "HPR" | "AVR", maker "SAT" | "ASH" | "TNL", UTC time of day s, heading deg in
    [0, 360)) of a GNSS compass's proprietary heading sentence (`body`: the text between `$`
    and `*`, see :data:`COMPASS_SENTENCES`); None for any other sentence. ValueError when it
    holds no valid heading (an empty or malformed field, AVR's GPS quality 0)."""
    f = body.split(",")
    kind = COMPASS_SENTENCES.get(",".join(f[:2]))
    if kind is None:
        return None
    if len(f) < 4 or (kind == "AVR" and (len(f) < 11 or f[10] in ("", "0"))):
        raise ValueError(f"{f[0]},{f[1]} without a valid heading")
    heading = float(f[3])
    if not math.isfinite(heading):
        raise ValueError(f"{f[0]},{f[1]} heading {f[3]!r}")
    return kind, f[0][1:4], seconds_of_day(f[2]), heading % 360.0


def _float(value: str) -> float:
    return float(value) if value else math.nan


def read_nmea(
    source: str | os.PathLike | Iterable[str | bytes],
    *,
    date: _dt.date | None = None,
    require_checksum: bool = True,
) -> NmeaLog:
    """Read an NMEA 0183 log (a path, or any iterable of lines such as an open file or a serial
    stream) into arrays; see the module docstring for what is read and how time is assigned.

    date: the UTC date of the first time of day, used only when the log has no RMC/ZDA date.
    require_checksum: lines without `*hh` count as damaged (default), else they are accepted.
    Raises ValueError when no usable sentence is found or no date is available.
    """
    # Pass 1: parse into events (kind, time-of-day or None, values...), in order.
    events: list[tuple] = []
    n_lines = n_ignored = n_damaged = 0
    damaged_lines: list[int] = []

    def damaged(lineno: int) -> None:
        nonlocal n_damaged
        n_damaged += 1
        if len(damaged_lines) < 100:
            damaged_lines.append(lineno)

    for lineno, raw in enumerate(iter_lines(source), start=1):
        if isinstance(raw, bytes):
            try:
                line = raw.decode("ascii").strip()
            except UnicodeDecodeError:
                n_lines += 1
                damaged(lineno)
                continue
        else:
            line = raw.strip()
        if not line or line.startswith("#"):
            continue
        n_lines += 1
        if line[0] not in "$!" or len(line) < 6:
            damaged(lineno)
            continue
        star = line.rfind("*")
        if star >= 0:
            if not checksum_ok(line[1:star], line[star + 1 : star + 3]) or len(line) != star + 3:
                damaged(lineno)
                continue
        elif require_checksum:
            damaged(lineno)
            continue
        body = line[1:star] if star >= 0 else line[1:]
        if line[0] == "!" or body[0] == "P":
            try:
                compass = compass_heading(body) if line[0] == "$" else None
            except (ValueError, IndexError):
                damaged(lineno)
                continue
            if compass is None:
                n_ignored += 1
            else:
                kind, maker, tod, heading = compass
                events.append((kind, maker, tod, None, (heading,)))
            continue
        address = body.split(",", 1)[0]
        talker, kind = address[:2], address[2:]
        if kind not in _WANTED:
            n_ignored += 1
            continue
        try:
            events.append(_event(kind, talker, line, body))
        except (ValueError, IndexError, TypeError, pynmea2.ParseError):
            damaged(lineno)
    return _assemble(events, date, n_lines, n_ignored, n_damaged, damaged_lines, str(source)[:80])


def _event(kind: str, talker: str, line: str, body: str) -> tuple:
    """One parsed sentence as (kind, talker, tod | None, date_unix | None, values)."""
    if kind == "THS":  # not in pynmea2: heading, mode
        f = body.split(",")
        if f[2] == "V":
            raise ValueError("invalid heading")
        return ("THS", talker, None, None, (_float(f[1]),))
    msg = pynmea2.parse(line, check=False)
    d = msg.data
    if kind == "GGA":
        # time, lat, N, lon, E, quality, sats, hdop, alt, M, ...
        return (
            "GGA",
            talker,
            seconds_of_day(d[0]),
            None,
            (
                degrees(d[1], d[2]),
                degrees(d[3], d[4]),
                _float(d[8]),
                int(d[5]) if d[5] else 0,
                int(d[6]) if d[6] else -1,
                _float(d[7]),
            ),
        )
    if kind == "RMC":
        # time, status, lat, N, lon, E, knots, course, ddmmyy, magvar, E/W, mode
        status = d[1]
        mode = d[11] if len(d) > 11 and d[11] else ("A" if status == "A" else "N")
        quality = MODE_QUALITY.get(mode, 1) if status == "A" else 0
        ddmmyy = d[8]
        day = None
        if len(ddmmyy) == 6:
            yy = int(ddmmyy[4:6])
            day = day_start(2000 + yy if yy < 80 else 1900 + yy, int(ddmmyy[2:4]), int(ddmmyy[0:2]))
        return (
            "RMC",
            talker,
            seconds_of_day(d[0]),
            day,
            (degrees(d[2], d[3]), degrees(d[4], d[5]), quality, _float(d[6]) * KNOT, _float(d[7])),
        )
    if kind == "GLL":
        status = d[5] if len(d) > 5 else "A"
        mode = d[6] if len(d) > 6 and d[6] else ("A" if status == "A" else "N")
        quality = MODE_QUALITY.get(mode, 1) if status == "A" else 0
        return (
            "GLL",
            talker,
            seconds_of_day(d[4]),
            None,
            (degrees(d[0], d[1]), degrees(d[2], d[3]), quality),
        )
    if kind == "ZDA":
        return ("ZDA", talker, seconds_of_day(d[0]), day_start(int(d[3]), int(d[2]), int(d[1])), ())
    if kind == "VTG":
        # true course, T, magnetic, M, knots, N, km/h, K, mode
        knots, kmh = _float(d[4]), _float(d[6]) if len(d) > 6 else math.nan
        speed = knots * KNOT if not math.isnan(knots) else kmh / 3.6
        if math.isnan(speed):
            raise ValueError("VTG without speed")
        return ("VTG", talker, None, None, (speed, _float(d[0])))
    if kind == "HDT":
        heading = _float(d[0])
        if math.isnan(heading):
            raise ValueError("empty heading")
        return ("HDT", talker, None, None, (heading,))
    # ROT: rate (deg/min), status
    return ("ROT", talker, None, None, (_float(d[0]), len(d) > 1 and d[1] == "A"))


def _assemble(
    events: list[tuple],
    date: _dt.date | None,
    n_lines: int,
    n_ignored: int,
    n_damaged: int,
    damaged_lines: list[int],
    name: str,
) -> NmeaLog:
    # Pass 2: absolute times. Dated sentences (RMC with a date, ZDA) are exact; a time of day is
    # put on the current date and moved by whole days to within 12 h of the previous time, which
    # handles midnight rollover before the next RMC/ZDA. Events before the first date are
    # resolved backwards from it.
    times = [math.nan] * len(events)
    first_dated = next((i for i, e in enumerate(events) if e[3] is not None), None)
    if first_dated is None:
        first_tod = next((i for i, e in enumerate(events) if e[2] is not None), None)
        if first_tod is None:
            anchor_i, anchor_t = None, math.nan
        elif date is None:
            raise ValueError(
                f"source: no RMC/ZDA date in {name!r}; pass date= (the UTC date of the first fix)"
            )
        else:
            anchor_i = first_tod
            anchor_t = day_start(date.year, date.month, date.day) + events[first_tod][2]
    else:
        anchor_i = first_dated
        anchor_t = events[first_dated][3] + events[first_dated][2]
    if anchor_i is not None:
        last = anchor_t
        for i in range(anchor_i - 1, -1, -1):  # backwards from the anchor
            tod = events[i][2]
            if tod is not None:
                last = nearest_day(last - last % DAY + tod, last)
            times[i] = last if tod is not None else math.nan
        last = anchor_t
        for i in range(anchor_i, len(events)):
            e = events[i]
            if e[2] is not None:
                last = (
                    e[3] + e[2] if e[3] is not None else nearest_day(last - last % DAY + e[2], last)
                )
                times[i] = last
    # Time-less sentences take the time of the latest timed sentence before them.
    n_untimed = 0
    current = math.nan
    for i, e in enumerate(events):
        if e[2] is not None:
            current = times[i]
        else:
            times[i] = current
            if math.isnan(current):
                n_untimed += 1

    pos: dict[float, tuple] = {}
    heads, vels, rots = [], [], []
    n_used = 0
    for t, e in zip(times, events, strict=True):
        if math.isnan(t):
            continue
        kind, talker, _, _, v = e
        n_used += 1
        if kind in _POSITION_TYPES:
            if kind == "GGA":
                rec = (t, v[0], v[1], v[2], v[3], v[4], v[5], kind, talker)
            else:
                rec = (t, v[0], v[1], math.nan, v[2], -1, math.nan, kind, talker)
            old = pos.get(t)
            if old is None or _POSITION_TYPES[kind] < _POSITION_TYPES[old[7]]:
                pos[t] = rec
            if kind == "RMC":
                vels.append((t, v[3], v[4], kind))
        elif kind in ("HDT", "THS", "HPR", "AVR"):
            heads.append((t, v[0], talker, kind))
        elif kind == "VTG":
            vels.append((t, v[0], v[1], kind))
        elif kind == "ROT":
            rots.append((t, v[0], v[1]))
    if n_used == 0:
        raise ValueError(
            f"source: no usable NMEA sentence in {name!r} ({n_lines} lines, "
            f"{n_damaged} damaged, {n_ignored} ignored)"
        )
    if n_damaged or n_untimed:
        warnings.warn(
            f"read_nmea({name!r}): skipped {n_damaged} damaged line(s) and {n_untimed} "
            f"sentence(s) before the first time of day; counts are on the result",
            DamagedRecordsWarning,
            stacklevel=3,
        )
    p = list(pos.values())
    return NmeaLog(
        positions=Positions(
            time=_col(p, 0, np.float64),
            lat_deg=_col(p, 1, np.float64),
            lon_deg=_col(p, 2, np.float64),
            altitude=_col(p, 3, np.float64),
            fix_quality=_col(p, 4, np.int64),
            num_satellites=_col(p, 5, np.int64),
            hdop=_col(p, 6, np.float64),
            sentence=_col(p, 7, np.str_),
            talker=_col(p, 8, np.str_),
        ),
        headings=Headings(
            time=_col(heads, 0, np.float64),
            heading_deg=_col(heads, 1, np.float64),
            talker=_col(heads, 2, np.str_),
            sentence=_col(heads, 3, np.str_),
        ),
        velocities=Velocities(
            time=_col(vels, 0, np.float64),
            speed=_col(vels, 1, np.float64),
            course_deg=_col(vels, 2, np.float64),
            sentence=_col(vels, 3, np.str_),
        ),
        rates_of_turn=RatesOfTurn(
            time=_col(rots, 0, np.float64),
            rate_deg_per_min=_col(rots, 1, np.float64),
            valid=_col(rots, 2, np.bool_),
        ),
        n_lines=n_lines,
        n_used=n_used,
        n_ignored=n_ignored,
        n_damaged=n_damaged,
        n_untimed=n_untimed,
        damaged_lines=damaged_lines,
    )


def _col(rows: list[tuple], k: int, dtype: Any) -> np.ndarray:
    if dtype is np.str_:
        return np.array([r[k] for r in rows], dtype="U3")
    return np.array([r[k] for r in rows], dtype=dtype)
