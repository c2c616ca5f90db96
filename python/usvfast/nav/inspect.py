"""`usvfast inspect`: what is in a recording (or a single NMEA/GPX/bag/video file): per stream
the type, source, item count, time span, mean rate, largest gaps and damaged-record counts,
and the time span all streams overlap; an AIS log is also decoded and summarised (messages by
type, MMSIs, positions), with or without receive times. One pass over each stream, memory
constant in the number of items (images are not decoded)."""

from __future__ import annotations

import heapq
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from usvfast._time import unix_to_iso
from usvfast.nav.replay import Recording, load_recording
from usvfast.nav.stream_types import NMEA_RECORDS, StreamSpec, open_stream, split_record

VIDEO_SUFFIXES = frozenset({".avi", ".mp4", ".mkv", ".mov", ".m4v", ".webm"})
BAG_SUFFIXES = frozenset({".bag", ".db3", ".mcap"})
AIS_SUFFIXES = frozenset({".aivdm", ".aivdo", ".ais"})


@dataclass(frozen=True)
class StreamSummary:
    """One stream of an inspection: id, type, source (path, `path topic` for bags), count of
    good items, start/end (UNIX s, clock offset applied; NaN when empty), mean_rate_hz
    ((count - 1) / span; NaN below two items), gaps: largest [(time before the gap, gap s)],
    damaged (records skipped by the reader), backwards (items earlier than their predecessor),
    error (why the stream could not be read, else None)."""

    id: str
    type: str
    source: str
    count: int
    start: float
    end: float
    mean_rate_hz: float
    gaps: list[tuple[float, float]]
    damaged: int
    backwards: int
    error: str | None = None

    @property
    def span(self) -> float:
        """end - start in seconds (NaN when empty)."""
        return self.end - self.start


@dataclass(frozen=True)
class Inspection:
    """The streams of a recording and the span all of them cover: overlap (start, end) UNIX s,
    or None when some stream is empty or they do not overlap."""

    name: str
    streams: list[StreamSummary]
    overlap: tuple[float, float] | None

    @property
    def span(self) -> tuple[float, float] | None:
        """(earliest start, latest end) over the non-empty streams, or None."""
        ok = [s for s in self.streams if s.count]
        if not ok:
            return None
        return min(s.start for s in ok), max(s.end for s in ok)


def _source(spec: StreamSpec) -> str:
    src = str(spec.path) if spec.path is not None else "-"
    return f"{src} {spec.topic}" if spec.topic else src


def summarize_stream(spec: StreamSpec, top_gaps: int = 3) -> StreamSummary:
    """Scan one stream (images undecoded) into a StreamSummary; a stream that cannot be opened
    or read gives a summary with `error` set instead of raising."""
    n = 0
    first = last = math.nan
    prev = -math.inf
    backwards = 0
    gaps: list[tuple[float, float]] = []  # min-heap of (gap, time before)
    source = None
    try:
        source = open_stream(spec, decode=False)
        for rec in source:
            t = split_record(rec)[0] + spec.clock_offset
            if n == 0:
                first = t
            elif t < prev:
                backwards += 1
            else:
                item = (t - prev, prev)
                if len(gaps) < top_gaps:
                    heapq.heappush(gaps, item)
                elif top_gaps and item > gaps[0]:
                    heapq.heapreplace(gaps, item)
            last = t if n == 0 else max(last, t)
            prev = t
            n += 1
        error = None
    except (ValueError, OSError, KeyError) as exc:
        error = str(exc)
    damaged = int(getattr(source, "damaged", 0)) if source is not None else 0
    span = last - first
    rate = (n - 1) / span if n >= 2 and span > 0 else math.nan
    return StreamSummary(
        id=spec.id,
        type=spec.type,
        source=_source(spec),
        count=n,
        start=first,
        end=last,
        mean_rate_hz=rate,
        gaps=[(t, g) for g, t in sorted(gaps, reverse=True)],
        damaged=damaged,
        backwards=backwards,
        error=error,
    )


def inspect_recording(recording: Recording, top_gaps: int = 3) -> Inspection:
    """Summarize every stream of a recording and their common overlap."""
    with warnings.catch_warnings():
        # The counts are in the summary; no need for one warning per damaged stream.
        warnings.simplefilter("ignore")
        streams = [summarize_stream(s, top_gaps) for s in recording.streams]
    overlap = None
    if streams and all(s.count for s in streams):
        lo, hi = max(s.start for s in streams), min(s.end for s in streams)
        if lo <= hi:
            overlap = (lo, hi)
    return Inspection(recording.name, streams, overlap)


def recording_for_path(path: Path | str) -> Recording:
    """A Recording for `path`: a recording TOML file, or a single data file as a recording of
    its own (GPX; ROS1 `.bag` or ROS2 bag folder/`.db3`/`.mcap`: one stream per topic; video:
    timed from the file's write time; `.aivdm`/`.ais`: AIS with receive times; anything else:
    NMEA text, one stream per kind of record found: positions, headings, velocities,
    rates_of_turn). Raises ValueError naming the path when it cannot be read."""
    from usvfast.nav.bags import bag_topics

    p = Path(path)
    if not p.exists():
        raise ValueError(f"path: no such file or directory: {p}")
    suffix = p.suffix.lower()
    if suffix == ".toml":
        return load_recording(p)
    if suffix == ".gpx":
        return Recording(p.name, (StreamSpec(p.stem, "gpx", p),), path=None)
    if p.is_dir() or suffix in BAG_SUFFIXES:
        topics = bag_topics(p)
        specs = tuple(
            StreamSpec(topic, "bag", p, topic=topic)
            for topic in sorted(topics)
            if topics[topic].count
        )
        if not specs:
            raise ValueError(f"path: bag {p} holds no message")
        return Recording(p.name, specs)
    if suffix in VIDEO_SUFFIXES:
        return Recording(p.name, (StreamSpec(p.stem, "video", p),))
    if suffix in AIS_SUFFIXES:
        return Recording(p.name, (StreamSpec(p.stem, "ais", p),))
    from usvfast.nav.nmea import read_nmea

    # NMEA text: one stream per kind of record the log holds.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        log = read_nmea(p)
    kinds = [k for k in NMEA_RECORDS if getattr(log, k).time.size]
    specs = tuple(StreamSpec(f"{p.stem}:{k}", "nmea", p, options={"records": [k]}) for k in kinds)
    return Recording(p.name, specs)


@dataclass(frozen=True)
class AisContent:
    """What an AIS log holds, with or without receive times: sentences (AIS sentences seen),
    messages (decoded), by_type {AIS message type: count}, mmsis (distinct MMSIs of the position
    and static reports), named (MMSIs
    with a name from static reports), positions (position reports), with_position (reports
    with a latitude and longitude), timed (reports with a receive time), own_ship (!AIVDO
    reports), lat_range/lon_range ((min, max) degrees, None without positions), damaged (bad
    checksum, undecodable or wrong tag block), incomplete (fragments never completed)."""

    sentences: int
    messages: int
    by_type: dict[int, int]
    mmsis: int
    named: int
    positions: int
    with_position: int
    timed: int
    own_ship: int
    lat_range: tuple[float, float] | None
    lon_range: tuple[float, float] | None
    damaged: int
    incomplete: int


def summarize_ais(path: Path | str) -> AisContent:
    """Decode an AIS log (`usvfast.nav.ais.read_ais`) into an AisContent. Raises ValueError
    naming the path when nothing decodes."""
    import numpy as np

    from usvfast.nav.ais import read_ais

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the damage counts are in the summary
        log = read_ais(path)
    p = log.positions
    located = np.isfinite(p.lat_deg) & np.isfinite(p.lon_deg)
    lat, lon = p.lat_deg[located], p.lon_deg[located]
    return AisContent(
        sentences=log.n_sentences,
        messages=log.n_messages,
        by_type=dict(log.by_type),
        mmsis=len(set(p.mmsi.tolist()) | set(log.static)),
        named=sum(1 for s in log.static.values() if s.name),
        positions=len(p.time),
        with_position=int(located.sum()),
        timed=int(np.isfinite(p.time).sum()),
        own_ship=int(p.own_ship.sum()),
        lat_range=(float(lat.min()), float(lat.max())) if lat.size else None,
        lon_range=(float(lon.min()), float(lon.max())) if lon.size else None,
        damaged=log.n_damaged + log.n_bad_tag,
        incomplete=log.n_incomplete,
    )


#: Names of the AIS message types (ITU-R M.1371) for the summary table.
AIS_TYPE_NAMES = {
    1: "position report class A",
    2: "position report class A (assigned)",
    3: "position report class A (interrogated)",
    4: "base station report",
    5: "static and voyage data",
    6: "binary addressed",
    7: "binary acknowledge",
    8: "binary broadcast",
    9: "SAR aircraft position",
    10: "UTC/date inquiry",
    11: "UTC/date response",
    12: "addressed safety",
    13: "safety acknowledge",
    14: "safety broadcast",
    15: "interrogation",
    16: "assignment mode command",
    17: "DGNSS broadcast",
    18: "position report class B",
    19: "extended position report class B",
    20: "data link management",
    21: "aid-to-navigation report",
    22: "channel management",
    23: "group assignment",
    24: "static data report",
    25: "single slot binary",
    26: "multiple slot binary",
    27: "long-range position report",
}


def render_ais(name: str, c: AisContent, console: Console) -> None:
    """Print an AisContent: messages by type, then MMSIs, positions and their extent."""
    table = Table(title=escape(f"AIS: {name}"))
    table.add_column("type", justify="right")
    table.add_column("message", justify="left")
    table.add_column("count", justify="right")
    for kind, count in c.by_type.items():
        table.add_row(str(kind), AIS_TYPE_NAMES.get(kind, "-"), str(count))
    console.print(table)
    lines = [
        f"{c.messages} messages from {c.sentences} sentences ({c.damaged} damaged, "
        f"{c.incomplete} incomplete fragments); {c.mmsis} MMSIs with positions or static "
        f"data ({c.named} named)",
        f"{c.positions} position reports ({c.own_ship} own ship), {c.with_position} with a "
        f"position, {c.timed} with a receive time",
    ]
    if c.lat_range is not None and c.lon_range is not None:
        lines.append(
            f"positions: latitude {c.lat_range[0]:.5f} to {c.lat_range[1]:.5f}°, "
            f"longitude {c.lon_range[0]:.5f} to {c.lon_range[1]:.5f}°"
        )
    if c.positions and not c.timed:
        lines.append(
            "no receive times: the reports cannot be placed in time (tag block c:, a leading "
            "UNIX time per line or ZDA/RMC sentences give them)"
        )
    for line in lines:
        console.print(line, soft_wrap=True)


def _utc(t: float) -> str:
    if not math.isfinite(t):
        return "-"
    return unix_to_iso(t)


def _secs(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{x:.3f}"


def render_inspection(ins: Inspection, console: Console) -> None:
    """Print an Inspection as a rich table plus the overlap line."""
    table = Table(title=escape(f"recording: {ins.name}"), show_lines=False)
    for col, just in [
        ("stream", "left"),
        ("type", "left"),
        ("source", "left"),
        ("items", "right"),
        ("start (UTC)", "left"),
        ("span s", "right"),
        ("rate Hz", "right"),
        ("largest gaps s", "left"),
        ("damaged", "right"),
    ]:
        table.add_column(col, justify=just, overflow="fold")  # type: ignore[arg-type]
    for s in ins.streams:
        gaps = ", ".join(f"{g:.3f}" for _, g in s.gaps) or "-"
        damaged = str(s.damaged) + (f" (+{s.backwards} backwards)" if s.backwards else "")
        table.add_row(
            escape(s.id),
            s.type,
            escape(s.source),
            str(s.count),
            _utc(s.start),
            _secs(s.span),
            "-" if math.isnan(s.mean_rate_hz) else f"{s.mean_rate_hz:.3f}",
            gaps,
            damaged,
        )
    console.print(table)
    for s in ins.streams:
        if s.error:
            console.print(f"[red]{escape(s.id)}: {escape(s.error)}[/red]", soft_wrap=True)
    total = ins.span
    if ins.overlap is None:
        console.print("overlap of all streams: none")
    else:
        lo, hi = ins.overlap
        length = hi - lo
        frac = length / (total[1] - total[0]) if total and total[1] > total[0] else 1.0
        console.print(
            f"overlap of all streams: {_utc(lo)} to {_utc(hi)} UTC "
            f"({length:.3f} s, {100 * frac:.1f}% of the recording)",
            soft_wrap=True,
        )


def inspect_command(
    path: Annotated[
        Path,
        typer.Argument(help="Recording TOML, or a single NMEA/GPX/video file or ROS bag."),
    ],
    gaps: Annotated[int, typer.Option(help="How many of the largest gaps to list.", min=0)] = 3,
) -> None:
    """Show the streams of a recording: counts, time spans, rates, gaps, damage, overlap."""
    console = Console(width=200)
    if path.suffix.lower() in AIS_SUFFIXES and path.exists():
        # An AIS log is decoded and summarised even when it has no receive times.
        try:
            content = summarize_ais(path)
        except ValueError as exc:
            console.print(f"[red]error:[/red] {escape(str(exc))}", soft_wrap=True)
            raise typer.Exit(1) from None
        render_ais(path.name, content, console)
        if not content.timed:
            return
    try:
        recording = recording_for_path(path)
    except ValueError as exc:
        console.print(f"[red]error:[/red] {escape(str(exc))}", soft_wrap=True)
        raise typer.Exit(1) from None
    ins = inspect_recording(recording, gaps)
    render_inspection(ins, console)
    if not any(s.count for s in ins.streams):
        raise typer.Exit(1)
