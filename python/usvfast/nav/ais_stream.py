"""AIS logs as a recording stream (type `ais`): receive times per line, decoded by
`usvfast.nav.ais.read_ais`, one item per position report.

AIS payloads carry only the UTC second, so each line needs a receive time. Two common logger
formats are recognised:
- an NMEA 4.0 tag block with a `c:` (UNIX time) field: `\\s:rx1,c:1686909600*5C\\!AIVDM,...`
  (seconds; values above 1e11 are taken as milliseconds);
- a leading UNIX time before the sentence, separated by a space, tab, comma or semicolon:
  `1686909600.25 !AIVDM,...`.
Reports from lines without a receive time cannot be placed in time: they are counted as damaged
(with the reader's own damaged and incomplete sentences).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from usvfast.nav.replay import StreamSpec

_TAG_TIME = re.compile(rb"^\\[^\\]*?\bc:(\d+(?:\.\d+)?)[^\\]*\\")
_PREFIX_TIME = re.compile(rb"^\s*(\d{9,}(?:\.\d+)?)[\s,;]+(?=[!\\])")


def receive_time(line: bytes) -> float:
    """UNIX receive time of an AIS log line (tag block `c:` or a leading number), NaN if none."""
    m = _TAG_TIME.match(line) or _PREFIX_TIME.match(line)
    if m is None:
        return math.nan
    t = float(m.group(1))
    return t / 1000.0 if t > 1e11 else t


@dataclass(frozen=True)
class AisReport:
    """One AIS position report (types 1-3, 18, 19, 27): mmsi, msg_type, own_ship (!AIVDO),
    lat_deg, lon_deg (NaN unavailable), speed (m/s), course_deg, heading_deg (NaN unavailable),
    status (navigational status, -1 unknown), name (from static reports in the log, or None)."""

    mmsi: int
    msg_type: int
    own_ship: bool
    lat_deg: float
    lon_deg: float
    speed: float
    course_deg: float
    heading_deg: float
    status: int
    name: str | None


class _AisRecords:
    def __init__(self, path: Path) -> None:
        from usvfast.nav.ais import read_ais

        with path.open("rb") as fh:
            self.log = read_ais((receive_time(line), line) for line in fh)
        p = self.log.positions
        self.timed = np.isfinite(p.time)
        self.damaged = self.log.n_damaged + self.log.n_incomplete + int((~self.timed).sum())
        if not np.any(self.timed):
            raise ValueError(
                f"ais: {path} has no receive times (tag block c: or a leading UNIX time per line)"
            )

    def __iter__(self) -> Iterator[tuple[float, AisReport]]:
        p = self.log.positions
        idx = np.flatnonzero(self.timed)
        idx = idx[np.argsort(p.time[idx], kind="stable")]
        static = self.log.static
        for i in idx.tolist():
            mmsi = int(p.mmsi[i])
            s = static.get(mmsi)
            yield (
                float(p.time[i]),
                AisReport(
                    mmsi,
                    int(p.msg_type[i]),
                    bool(p.own_ship[i]),
                    float(p.lat_deg[i]),
                    float(p.lon_deg[i]),
                    float(p.speed[i]),
                    float(p.course_deg[i]),
                    float(p.heading_deg[i]),
                    int(p.status[i]),
                    s.name if s is not None else None,
                ),
            )


def open_ais_stream(spec: StreamSpec, decode: bool = True) -> Iterable[Any]:
    """The reader of the `ais` stream type: (receive time, AisReport) in time order, with
    `damaged` (bad, incomplete or untimed). Raises ValueError when no line has a time."""
    assert spec.path is not None
    if not spec.path.exists():
        raise ValueError(f"ais: no such file: {spec.path}")
    return _AisRecords(spec.path)
