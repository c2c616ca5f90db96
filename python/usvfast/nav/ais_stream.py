"""AIS logs as a recording stream (type `ais`): receive times per line, decoded by
`usvfast.nav.ais.read_ais`, one item per position report.

AIS payloads carry only the UTC second, so each report needs a receive time: the line's NMEA
4.0 tag block `c:` field (`\\s:rx1,c:1686909600*5C\\!AIVDM,...`), a leading UNIX time
(`1686909600.25 !AIVDM,...`) or the log's own ZDA/RMC clock (see `usvfast.nav.linetime`).
Reports that cannot be placed in time are counted as damaged (with the reader's own damaged
and incomplete sentences); `usvfast inspect` still summarises a log with no time at all.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from usvfast.nav.stream_types import StreamSpec


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

        self.log = read_ais(path)
        p = self.log.positions
        self.timed = np.isfinite(p.time)
        log = self.log
        self.damaged = log.n_damaged + log.n_incomplete + log.n_bad_tag + int((~self.timed).sum())
        if not np.any(self.timed):
            raise ValueError(
                f"ais: {path} has no receive times (tag block c:, a leading UNIX time per line "
                "or ZDA/RMC sentences)"
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
