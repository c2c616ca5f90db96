"""Receive times of lines in NMEA/AIS logs, the way feeds deliver them.

Three sources, in order of precedence for each line:

1. an NMEA 4.10 tag block with a `c:` field (UNIX seconds; > 1e11 read as milliseconds):
   `\\c:1495196206*5A\\!AIVDM,...` (the tag-block checksum is checked when present);
2. a leading UNIX time column: `1495196206.25 !AIVDM,...` (space, tab, comma or semicolon);
3. the log's own clock: the latest valid `$--ZDA` or `$--RMC` (date and time of day, parsed by
   pynmea2) before the line.

Example::

    clock = LogClock()
    for line in open("feed.nmea", "rb"):
        t = clock.time_of(line)   # NaN before any clock is known
"""

from __future__ import annotations

import calendar
import math
import re
from functools import reduce
from operator import xor

import pynmea2

from usvfast.nav.ais_stream import receive_time

__all__ = ["LogClock", "line_time", "tag_block_ok"]

_TAG = re.compile(rb"^\\([^\\*]*)\*([0-9A-Fa-f]{2})\\")
_LEADING = re.compile(rb"^\s*(\d+(?:\.\d+)?)[\s,;]+(?=[!$\\])")


def line_time(line: bytes) -> float:
    """The line's own receive time, UNIX s: tag block `c:` or a leading time column before a
    `!`, `$` or tag block; NaN when it has none."""
    t = receive_time(line)
    if math.isfinite(t):
        return t
    m = _LEADING.match(line)
    return float(m.group(1)) if m else math.nan


def tag_block_ok(line: bytes) -> bool:
    """False when `line` starts with an NMEA 4.10 tag block whose checksum is wrong (a line
    without a tag block, or with one without a checksum, is OK)."""
    m = _TAG.match(line)
    if m is None:
        return True
    return reduce(xor, m.group(1), 0) == int(m.group(2), 16)


class LogClock:
    """The receive time of each line of a log (see the module docstring).

    `time_of(line)` returns UNIX seconds (float) or NaN when no time is known yet; ZDA/RMC lines
    with a valid checksum advance the clock (and get their own time). `n_clock` counts the
    ZDA/RMC sentences used."""

    def __init__(self) -> None:
        self.now = math.nan
        self.n_clock = 0

    def time_of(self, line: bytes) -> float:
        """Receive time of `line` (bytes, stripped), UNIX s; NaN when unknown."""
        t = line_time(line)
        if math.isfinite(t):
            return t
        if line[:1] == b"$" and line[3:6] in (b"ZDA", b"RMC"):
            t = _clock_sentence(line)
            if math.isfinite(t):
                self.now = t
                self.n_clock += 1
        return self.now


def _clock_sentence(line: bytes) -> float:
    """UNIX time of a ZDA or RMC sentence (pynmea2, checksum required), NaN when unusable."""
    try:
        msg = pynmea2.parse(line.decode("ascii"), check=True)
        dt = msg.datetime
    except (pynmea2.ParseError, UnicodeDecodeError, ValueError, TypeError, AttributeError):
        return math.nan
    if dt is None:
        return math.nan
    return calendar.timegm(dt.utctimetuple()) + dt.microsecond * 1e-6
