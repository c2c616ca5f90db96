"""NMEA 0183 field conversions shared by the NMEA, AIS-clock and radar readers: latitude and
longitude `ddmm.mmmm` + hemisphere, times of day, dates, midnight rollover, checksums.

(pynmea2 parses the sentences; its `latitude`/`longitude` read an empty field or a missing
hemisphere as 0°, which would be a silent wrong position, hence `degrees`.)"""

from __future__ import annotations

import datetime as _dt
import math
from functools import reduce
from operator import xor

DAY = 86400.0


def checksum(body: bytes) -> int:
    """The NMEA checksum of `body` (the bytes between `$`/`!`/`\\` and `*`): XOR of all."""
    return reduce(xor, body, 0)


def checksum_ok(body: str, given: str) -> bool:
    """Whether `given` (hex text) is the checksum of the sentence `body` (text between `$` and
    `*`); False for non-ASCII text or a malformed checksum."""
    try:
        return checksum(body.encode("ascii")) == int(given, 16)
    except (ValueError, UnicodeEncodeError):
        return False


def degrees(value: str, hemisphere: str) -> float:
    """`ddmm.mmmm` (or `dddmm.mmmm`) + N/S/E/W → signed degrees; NaN when `value` is empty;
    ValueError for another hemisphere letter or a malformed number."""
    if not value:
        return math.nan
    v = float(value)
    d = math.floor(v / 100.0)
    out = d + (v - 100.0 * d) / 60.0
    if hemisphere in ("S", "W"):
        return -out
    if hemisphere not in ("N", "E"):
        raise ValueError(f"bad hemisphere {hemisphere!r}")
    return out


def seconds_of_day(value: str | _dt.time) -> float:
    """`hhmmss(.ss)` (or a datetime.time, as pynmea2 gives it) → seconds since 00:00 UTC;
    ValueError for a malformed or out-of-range time."""
    if isinstance(value, _dt.time):
        return value.hour * 3600.0 + value.minute * 60.0 + value.second + value.microsecond * 1e-6
    if len(value) < 6:
        raise ValueError(f"bad time {value!r}")
    h, m, s = int(value[0:2]), int(value[2:4]), float(value[4:])
    if h > 23 or m > 59 or s >= 61:
        raise ValueError(f"bad time {value!r}")
    return h * 3600.0 + m * 60.0 + s


def day_start(year: int, month: int, day: int) -> float:
    """UNIX seconds of 00:00 UTC on that date."""
    return (_dt.date(year, month, day) - _dt.date(1970, 1, 1)).days * DAY


def nearest_day(candidate: float, reference: float) -> float:
    """`candidate` (UNIX s) moved by whole days to within half a day of `reference` (the
    midnight rollover of a time of day read against a known clock)."""
    return candidate + DAY * round((reference - candidate) / DAY)
