"""Receive times of the lines of NMEA/AIS logs, the way feeds and loggers deliver them.

Three sources, in order of precedence for each line:

1. an NMEA 4.10 tag block with a `c:` field (UNIX seconds; values above 1e11 are read as
   milliseconds): `\\s:rx1,c:1495196206*5A\\!AIVDM,...` (`tag_block_ok` checks its checksum);
2. a leading UNIX time column before the sentence or tag block, separated by a space, tab,
   comma or semicolon: `1495196206.25 !AIVDM,...`;
3. the log's own clock: the latest valid `$--ZDA` or `$--RMC` (date and time of day, parsed by
   pynmea2 with the checksum required) before the line (`LogClock`).

Used by the AIS reader (`usvfast.nav.ais.read_ais`), the radar NMEA reader and the AIS feed of
the fusion.

Example::

    clock = LogClock()
    for line in open("feed.nmea", "rb"):
        t = clock.time_of(line.strip())   # NaN before any time is known
"""

from __future__ import annotations

import calendar
import math
import re
from typing import Any

import pynmea2

from usvfast._validate import instance
from usvfast.nav._fields import checksum

__all__ = ["LogClock", "clock_time", "line_time", "tag_block_ok"]

_TAG_TIME = re.compile(rb"^\s*\\[^\\]*?\bc:(\d+(?:\.\d+)?)[^\\]*\\")
_LEADING = re.compile(rb"^\s*(\d+(?:\.\d+)?)[\s,;]+(?=[!$\\])")
_TAG = re.compile(rb"^\s*\\([^\\*]*)\*([0-9A-Fa-f]{2})\\")


def line_time(line: bytes) -> float:
    """The line's own receive time, UNIX s: its tag block `c:` (milliseconds above 1e11) or a
    leading time column before a `!`, `$` or tag block; NaN when it has none."""
    instance("line", line, bytes)
    m = _TAG_TIME.match(line)
    if m is not None:
        t = float(m.group(1))
        return t / 1000.0 if t > 1e11 else t
    m = _LEADING.match(line)
    return float(m.group(1)) if m else math.nan


def tag_block_ok(line: bytes) -> bool:
    """False when `line` starts with an NMEA 4.10 tag block whose checksum is wrong (a line
    without a tag block, or with one without a checksum, is OK)."""
    instance("line", line, bytes)
    m = _TAG.match(line)
    if m is None:
        return True
    return checksum(m.group(1)) == int(m.group(2), 16)


def clock_time(line: bytes) -> float:
    """UNIX time of a `$--ZDA` or `$--RMC` sentence (date and time of day; pynmea2 with the
    checksum required), NaN for any other line or an unusable one."""
    instance("line", line, bytes)
    start = line.find(b"$")
    if start < 0 or line[start + 3 : start + 6] not in (b"ZDA", b"RMC"):
        return math.nan
    try:
        msg = pynmea2.parse(line[start:].decode("ascii"), check=True)
        stamp: Any = msg.datetime  # pyright: ignore[reportAttributeAccessIssue]  # ZDA, RMC
    except (pynmea2.ParseError, UnicodeDecodeError, ValueError, TypeError, AttributeError):
        return math.nan
    if stamp is None:
        return math.nan
    return calendar.timegm(stamp.utctimetuple()) + stamp.microsecond * 1e-6


class LogClock:
    """The receive time of each line of a log (see the module docstring).

    `time_of(line)` returns UNIX seconds or NaN when no time is known yet; ZDA/RMC lines with a
    valid checksum and no time of their own advance the clock (and get its new time). `now`:
    the clock (UNIX s, NaN before the first ZDA/RMC); `n_clock`: ZDA/RMC sentences used."""

    def __init__(self) -> None:
        self.now = math.nan
        self.n_clock = 0

    def time_of(self, line: bytes) -> float:
        """Receive time of `line` (bytes), UNIX s; NaN when unknown."""
        t = line_time(line)
        if math.isfinite(t):
            return t
        t = clock_time(line)
        if math.isfinite(t):
            self.now = t
            self.n_clock += 1
        return self.now
