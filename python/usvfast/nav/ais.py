"""AIS (`!AIVDM` other vessels, `!AIVDO` own ship) → per-report arrays and per-MMSI static data,
decoded by pyais, plus dead-reckoned target positions at arbitrary times.

Multi-fragment messages are assembled here (by fragment count, sequence id and channel);
sentences with a bad checksum, undecodable payloads and orphan fragments are skipped and
counted. AIS payloads carry only the UTC second of the report, so each line needs a receive
time (`usvfast.nav.linetime`): the caller's, passing `(unix_time, line)` pairs; else the line's
own NMEA 4.10 tag block `c:` (a tag block with a wrong checksum skips the line, counted in
`n_bad_tag`) or leading UNIX time column; else the log's own ZDA/RMC clock (the latest one
before the AIS sentence, or the first one for reports before it) with the report's UTC second.
With none of these, times are NaN.

Example::

    from usvfast.nav.ais import read_ais, dead_reckon
    ais = read_ais(open("sample.aivdm"))
    ais.positions.mmsi, ais.positions.lat_deg, ais.static[351759000].name
"""

from __future__ import annotations

import math
import os
import re
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from pyais import NMEAMessage
from pyais.exceptions import AISBaseException

from usvfast import geodesy
from usvfast._damage import DamagedRecordsWarning
from usvfast._files import OVERLONG_LINE
from usvfast._validate import as_float_array, instance
from usvfast.nav._damage import iter_lines
from usvfast.nav.linetime import LogClock, line_time, tag_block_ok
from usvfast.nav.nmea import KNOT

__all__ = ["AisLog", "AisPositions", "StaticData", "dead_reckon", "read_ais"]

POSITION_TYPES = {1, 2, 3, 18, 19, 27}
STATIC_TYPES = {5, 19, 24}


@dataclass(frozen=True)
class AisPositions:
    """Position reports (types 1–3, 18, 19, 27) in arrival order, shape (n,) each.

    time: receive time, UNIX s (NaN when not given); mmsi; msg_type; own_ship (from !AIVDO);
    lat_deg, lon_deg (NaN when not available); speed (m/s over ground, NaN n/a); course_deg
    (over ground, clockwise from true north, NaN n/a); heading_deg (true, NaN n/a); second
    (UTC second of the report, 60+ = n/a); status (navigation status, -1 for class B)."""

    time: np.ndarray
    mmsi: np.ndarray
    msg_type: np.ndarray
    own_ship: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    speed: np.ndarray
    course_deg: np.ndarray
    heading_deg: np.ndarray
    second: np.ndarray
    status: np.ndarray


@dataclass
class StaticData:
    """Static and voyage data of one MMSI (types 5, 19, 24 merged; None = not received).
    Dimensions in metres from the position reference: to_bow, to_stern, to_port,
    to_starboard; length = to_bow + to_stern, beam = to_port + to_starboard."""

    mmsi: int
    name: str | None = None
    callsign: str | None = None
    ship_type: int | None = None
    imo: int | None = None
    to_bow: int | None = None
    to_stern: int | None = None
    to_port: int | None = None
    to_starboard: int | None = None

    @property
    def length(self) -> float:
        """Overall length (m), NaN when unknown."""
        if self.to_bow is None or self.to_stern is None:
            return math.nan
        return float(self.to_bow + self.to_stern)

    @property
    def beam(self) -> float:
        """Beam (m), NaN when unknown."""
        if self.to_port is None or self.to_starboard is None:
            return math.nan
        return float(self.to_port + self.to_starboard)


@dataclass(frozen=True)
class AisLog:
    """What `read_ais` found: positions, static data by MMSI, and counts — n_sentences (AIS
    sentences seen), n_messages (decoded messages), n_damaged (bad checksum / undecodable),
    n_incomplete (fragments whose message never completed), n_other (decoded messages of
    other types), n_ignored (non-AIS lines), n_bad_tag (lines skipped for a wrong tag-block
    checksum), n_clock (ZDA/RMC sentences of the log that set its clock), by_type (decoded
    messages by AIS message type)."""

    positions: AisPositions
    static: dict[int, StaticData]
    n_sentences: int
    n_messages: int
    n_damaged: int
    n_incomplete: int
    n_other: int
    n_ignored: int
    n_bad_tag: int = 0
    n_clock: int = 0
    by_type: dict[int, int] = field(default_factory=dict)


def _nan_if(value: Any, *sentinels: float) -> float:
    if value is None:
        return math.nan
    v = float(value)
    return math.nan if any(abs(v - s) < 1e-9 for s in sentinels) else v


def read_ais(source: str | os.PathLike | Iterable[Any]) -> AisLog:
    """Read AIS sentences from a path or an iterable of lines (str/bytes) or (time, line)
    pairs, timed as the module docstring says; non-AIS lines are counted and skipped. Raises
    ValueError when no AIS message could be decoded at all."""
    rows: list[tuple] = []
    static: dict[int, StaticData] = {}
    pending: dict[tuple, list[NMEAMessage]] = {}
    n_sentences = n_messages = n_damaged = n_incomplete = n_other = n_ignored = n_bad_tag = 0
    by_type: dict[int, int] = {}
    pending_msgs: list[tuple[float, NMEAMessage]] = []
    clock = LogClock()  # the log's own UTC clock (ZDA/RMC) when AIS lines carry no time
    before_clock: list[int] = []
    for item in iter_lines(source):
        t, raw = item if isinstance(item, tuple) else (math.nan, item)
        line = raw if isinstance(raw, bytes) else raw.encode("ascii", "replace")
        line = line.strip()
        if not line:
            continue
        if line == OVERLONG_LINE.strip():
            n_damaged += 1
            continue
        if math.isnan(t):
            t = line_time(line)
        if math.isnan(t) and math.isfinite(clock.time_of(line)) and before_clock:
            for i in before_clock:  # the first clock of the log times what came before
                rows[i] = (_ais_time(clock.now, rows[i][9]), *rows[i][1:])
            before_clock.clear()
        sentences = _split_sentences(line)
        if not sentences:
            n_ignored += int(not line.startswith(b"#"))
            continue
        if not tag_block_ok(line):
            n_bad_tag += 1
            continue
        for sentence in sentences:
            n_sentences += 1
            try:
                msg = NMEAMessage(sentence)
                if not msg.is_valid:
                    raise ValueError("bad checksum")
            except (AISBaseException, ValueError, IndexError, UnicodeDecodeError):
                n_damaged += 1
                continue
            pending_msgs.append((t, msg))
        while pending_msgs:
            t, msg = pending_msgs.pop(0)
            if msg.frag_cnt > 1:
                key = (msg.frag_cnt, msg.seq_id, msg.channel, msg.type)
                frags = pending.setdefault(key, [])
                if msg.frag_num != len(frags) + 1:
                    # Out of order or a lost fragment: drop what was collected, maybe restart.
                    n_incomplete += len(frags)
                    frags.clear()
                    if msg.frag_num != 1:
                        n_incomplete += 1
                        continue
                frags.append(msg)
                if len(frags) < msg.frag_cnt:
                    continue
                try:
                    msg = NMEAMessage.assemble_from_iterable(list(frags))
                except AISBaseException:
                    n_damaged += len(frags)
                    frags.clear()
                    continue
                frags.clear()
            try:
                d: dict[str, Any] = msg.decode().asdict()
            except (AISBaseException, ValueError, IndexError, KeyError, TypeError):
                n_damaged += 1
                continue
            n_messages += 1
            kind = int(d["msg_type"])
            by_type[kind] = by_type.get(kind, 0) + 1
            mmsi = int(d["mmsi"])
            if kind in STATIC_TYPES:
                _merge_static(static.setdefault(mmsi, StaticData(mmsi)), d)
            if kind in POSITION_TYPES:
                status = d.get("status")
                second = int(d["second"]) if d.get("second") is not None else 60
                if math.isnan(t) and not math.isnan(clock.now):
                    t = _ais_time(clock.now, second)
                elif math.isnan(t):
                    before_clock.append(len(rows))  # heard before the log's first clock
                rows.append(
                    (
                        float(t),
                        mmsi,
                        kind,
                        msg.type == "VDO",
                        _nan_if(d.get("lat"), 91.0),
                        _nan_if(d.get("lon"), 181.0),
                        _nan_if(d.get("speed"), 102.3, 63.0 if kind == 27 else -1.0) * KNOT,
                        _nan_if(d.get("course"), 360.0, 511.0 if kind == 27 else -1.0),
                        _nan_if(d.get("heading"), 511.0),
                        second,
                        int(status) if status is not None else -1,
                    )
                )
            elif kind not in STATIC_TYPES:
                n_other += 1
    n_incomplete += sum(len(f) for f in pending.values())
    if n_messages == 0:
        raise ValueError(
            f"source: no decodable AIS message ({n_sentences} AIS sentences, "
            f"{n_damaged} damaged, {n_incomplete} incomplete)"
        )
    if n_damaged or n_incomplete:
        warnings.warn(
            f"read_ais: skipped {n_damaged} damaged and {n_incomplete} incomplete AIS "
            "sentence(s); counts are on the result",
            DamagedRecordsWarning,
            stacklevel=2,
        )
    cols = list(zip(*rows, strict=True)) if rows else [()] * 11
    dtypes = [np.float64, np.int64, np.int64, np.bool_] + [np.float64] * 5 + [np.int64] * 2
    arrays = [np.array(c, dtype=dt) for c, dt in zip(cols, dtypes, strict=True)]
    return AisLog(
        positions=AisPositions(*arrays),
        static=static,
        n_sentences=n_sentences,
        n_messages=n_messages,
        n_damaged=n_damaged,
        n_incomplete=n_incomplete,
        n_other=n_other,
        n_ignored=n_ignored,
        n_bad_tag=n_bad_tag,
        n_clock=clock.n_clock,
        by_type=dict(sorted(by_type.items())),
    )


#: The start of an AIS sentence: `!` + a two-letter talker + VDM/VDO and its first comma.
_AIS_START = re.compile(rb"![A-Z]{2}VD[MO],")


def _split_sentences(line: bytes) -> list[bytes]:
    """The AIS sentences of one line, up to each one's checksum: two or more glued on one
    line (a lost newline, or a `#` comment glued to the next sentence) come out one by one;
    receiver metadata after a checksum (",s36310,d-081,...") is dropped."""
    starts = [m.start() for m in _AIS_START.finditer(line)]
    if line.startswith(b"#"):
        # a comment may quote sentences ("# !AIVDM,..."); only one glued straight onto it
        # (a lost newline: no space or quote before the `!`) is a real sentence
        starts = [a for a in starts if line[a - 1 : a] not in (b" ", b"\t", b'"')]
    out = []
    for k, a in enumerate(starts):
        end = starts[k + 1] if k + 1 < len(starts) else len(line)
        star = line.find(b"*", a, end)
        out.append(line[a : star + 3] if star >= 0 else line[a:end])
    return out


def _ais_time(clock: float, second: int) -> float:
    """The UNIX time of an AIS report heard when the log's clock read `clock`: its own UTC
    second (0-59) placed in the minute nearest `clock`; `clock` itself when the report has
    no second (60-63: not available, manual, dead reckoning, inoperative)."""
    if not 0 <= second <= 59:
        return clock
    t = clock - clock % 60 + second
    if t - clock > 30:
        t -= 60
    elif clock - t > 30:
        t += 60
    return t


def _merge_static(s: StaticData, d: dict) -> None:
    name = d.get("shipname")
    if name:
        s.name = str(name).strip() or s.name
    if d.get("callsign"):
        s.callsign = str(d["callsign"]).strip() or s.callsign
    if d.get("ship_type") is not None and (d["msg_type"] != 24 or d.get("partno") == 1):
        s.ship_type = int(d["ship_type"])
    if d.get("imo"):
        s.imo = int(d["imo"])
    if d.get("to_bow") is not None:
        s.to_bow, s.to_stern = int(d["to_bow"]), int(d["to_stern"])
        s.to_port, s.to_starboard = int(d["to_port"]), int(d["to_starboard"])


def dead_reckon(
    positions: AisPositions, mmsi: int, times: ArrayLike, *, max_age: float = math.inf
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions of one target at `times` (UNIX s, any shape) by dead reckoning from its
    latest report at or before each time: straight line at the reported speed over ground
    along the course over ground (the radar/AIS paper's interpolation), exact on the WGS84
    ellipsoid via the local NED plane at the report.

    Returns (lat_deg, lon_deg, age_s) of the shape of `times`; age_s = time since the report
    used. Times before the first report, or with age beyond `max_age`, give NaN positions
    (age still reported, NaN before the first report). A report without speed or course
    extrapolates as stationary; reports without latitude or longitude are not used. Raises
    ValueError when the MMSI has no timed report, NonFiniteError when `times` holds NaN/inf.
    """
    t_query = as_float_array("times", times)
    instance("positions", positions, AisPositions)
    sel = (
        (positions.mmsi == mmsi)
        & np.isfinite(positions.time)
        & np.isfinite(positions.lat_deg)
        & np.isfinite(positions.lon_deg)
    )
    if not np.any(sel):
        raise ValueError(f"mmsi: no timed position report for {mmsi}")
    t_rep = positions.time[sel]
    order = np.argsort(t_rep, kind="stable")
    t_rep = t_rep[order]
    lat = positions.lat_deg[sel][order]
    lon = positions.lon_deg[sel][order]
    speed = positions.speed[sel][order]
    course_deg = positions.course_deg[sel][order]
    # Without both speed and course the motion is unknown: hold the reported position.
    moving = np.isfinite(speed) & np.isfinite(course_deg)
    speed = np.where(moving, speed, 0.0)
    course = np.radians(np.where(moving, course_deg, 0.0))
    idx = np.searchsorted(t_rep, t_query, side="right") - 1
    valid = idx >= 0
    i = np.where(valid, idx, 0)
    age = np.where(valid, t_query - t_rep[i], np.nan)
    dist = speed[i] * np.where(valid, age, 0.0)
    north, east = dist * np.cos(course[i]), dist * np.sin(course[i])
    out_lat, out_lon, _ = geodesy.ned2geodetic(north, east, 0.0, lat[i], lon[i], 0.0)
    bad = ~valid | (age > max_age)
    out_lat = np.where(bad, np.nan, out_lat)
    out_lon = np.where(bad, np.nan, out_lon)
    return out_lat, out_lon, age
