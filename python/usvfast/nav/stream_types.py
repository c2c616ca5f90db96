"""Stream types of a recording (see usvfast.nav.replay): the registry that maps a `type` key
to its reader, the built-in readers (GPX, NMEA, AIS, rosbag topics, video) and the records they
yield, and `open_stream`.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from usvfast.frames import Mount


class RecordingError(ValueError):
    """A recording file is invalid; the message names the file, the stream and the key."""


@dataclass(frozen=True)
class StreamSpec:
    """One stream of a recording: id, type, path (absolute; None for types without a file),
    topic (bag streams), clock_offset (s, added to every timestamp), sensor_id, mount, and
    options (the remaining, type-specific keys)."""

    id: str
    type: str
    path: Path | None
    topic: str | None = None
    clock_offset: float = 0.0
    sensor_id: int | str | None = None
    mount: Mount | None = None
    options: Mapping[str, Any] = field(default_factory=dict)


Opener = Callable[[StreamSpec, bool], Iterable[Any]]
"""A stream reader: `opener(spec, decode)` returns an iterable of records, each an object with
a `time` attribute (UNIX s, before the clock offset; the record itself is the item's data,
or its `data` attribute when it has one) or a `(time, data)` tuple, in time order. decode=False
asks for a fast scan (e.g. images undecoded). The iterable may expose `damaged` (int)."""


@dataclass(frozen=True)
class StreamType:
    """A registered stream type: its opener, whether it needs `path`/`topic`, and its option
    keys (None: any key is passed through)."""

    opener: Opener
    needs_path: bool = True
    needs_topic: bool = False
    options: frozenset[str] | None = frozenset()


STREAM_TYPES: dict[str, StreamType] = {}
"""Stream types by name; add one with `register_stream_type`."""


def register_stream_type(
    name: str,
    opener: Opener,
    *,
    needs_path: bool = True,
    needs_topic: bool = False,
    options: Iterable[str] | None = (),
) -> None:
    """Register (or replace) a stream type, e.g. the LiDAR pcap reader:
    `register_stream_type("lidar_pcap", open_pcap, options=["model"])`."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"name: expected a non-empty string, got {name!r}")
    if not callable(opener):
        raise TypeError(f"opener: expected a callable, got {type(opener).__name__}")
    STREAM_TYPES[name] = StreamType(
        opener, needs_path, needs_topic, None if options is None else frozenset(options)
    )


# --- built-in stream types -------------------------------------------------------------------


@dataclass(frozen=True)
class GeoPoint:
    """A GPX track point: lat_deg, lon_deg (WGS84), ele_m (NaN when absent)."""

    lat_deg: float
    lon_deg: float
    ele_m: float


class _Records:
    """Iterable adapter exposing the reader's damaged count."""

    def __init__(self, it: Callable[[], Iterator[Any]], damaged: Callable[[], int]) -> None:
        self._it = it
        self._damaged = damaged

    def __iter__(self) -> Iterator[Any]:
        return self._it()

    @property
    def damaged(self) -> int:
        return self._damaged()


def _open_gpx(spec: StreamSpec, decode: bool) -> Iterable[Any]:
    from usvfast.nav.gpx import read_gpx

    assert spec.path is not None
    track = read_gpx(spec.path)

    def it() -> Iterator[tuple[float, GeoPoint]]:
        for t, la, lo, el in zip(
            track.times.tolist(),
            track.lat_deg.tolist(),
            track.lon_deg.tolist(),
            track.ele_m.tolist(),
            strict=True,
        ):
            yield t, GeoPoint(la, lo, el)

    return _Records(it, lambda: track.skipped)


def _open_bag(spec: StreamSpec, decode: bool) -> Iterable[Any]:
    from usvfast.nav.bags import BagTopic

    assert spec.path is not None and spec.topic is not None
    return BagTopic(
        spec.path,
        spec.topic,
        time_source=spec.options.get("time_source", "header"),
        decode_images=bool(spec.options.get("decode_images", True)) and decode,
    )


class _VideoRecords:
    def __init__(self, reader: Any, decode: bool) -> None:
        self.reader, self.decode = reader, decode

    def __iter__(self) -> Iterator[Any]:
        return self.reader.frames(decode=self.decode)

    @property
    def damaged(self) -> int:
        return self.reader.damaged


def _open_video(spec: StreamSpec, decode: bool) -> Iterable[Any]:
    from usvfast.nav.video import VideoReader

    assert spec.path is not None
    return _VideoRecords(VideoReader(spec.path, **dict(spec.options)), decode)


@dataclass(frozen=True)
class NmeaFix:
    """An NMEA position fix (GGA/RMC/GLL): lat_deg, lon_deg (WGS84), altitude (m above mean
    sea level, NaN unknown), fix_quality (GGA quality)."""

    lat_deg: float
    lon_deg: float
    altitude: float
    fix_quality: int


@dataclass(frozen=True)
class NmeaHeading:
    """An NMEA true heading (HDT/THS): heading_deg clockwise from true north."""

    heading_deg: float


@dataclass(frozen=True)
class NmeaVelocity:
    """NMEA speed (m/s) and course over ground (course_deg, NaN when not given)."""

    speed: float
    course_deg: float


@dataclass(frozen=True)
class NmeaRateOfTurn:
    """NMEA rate of turn (ROT): rate_deg_per_min (negative: to port), valid."""

    rate_deg_per_min: float
    valid: bool


NMEA_RECORDS = ("positions", "headings", "velocities", "rates_of_turn")


def _open_nmea(spec: StreamSpec, decode: bool) -> Iterable[Any]:
    from usvfast.nav.nmea import read_nmea

    assert spec.path is not None
    kinds = spec.options.get("records", list(NMEA_RECORDS))
    if not isinstance(kinds, list) or not set(kinds) <= set(NMEA_RECORDS) or not kinds:
        raise RecordingError(
            f"stream {spec.id!r}: key 'records': expected a list of {list(NMEA_RECORDS)}, "
            f"got {kinds!r}"
        )
    log = read_nmea(spec.path)
    p, h, v, r = log.positions, log.headings, log.velocities, log.rates_of_turn
    parts = {
        "positions": lambda: (
            (t, NmeaFix(la, lo, al, q))
            for t, la, lo, al, q in zip(
                p.time.tolist(),
                p.lat_deg.tolist(),
                p.lon_deg.tolist(),
                p.altitude.tolist(),
                p.fix_quality.tolist(),
                strict=True,
            )
        ),
        "headings": lambda: (
            (t, NmeaHeading(x))
            for t, x in zip(h.time.tolist(), h.heading_deg.tolist(), strict=True)
        ),
        "velocities": lambda: (
            (t, NmeaVelocity(s, c))
            for t, s, c in zip(
                v.time.tolist(), v.speed.tolist(), v.course_deg.tolist(), strict=True
            )
        ),
        "rates_of_turn": lambda: (
            (t, NmeaRateOfTurn(x, bool(ok)))
            for t, x, ok in zip(
                r.time.tolist(), r.rate_deg_per_min.tolist(), r.valid.tolist(), strict=True
            )
        ),
    }
    chosen = [parts[k] for k in NMEA_RECORDS if k in kinds]

    def it() -> Iterator[tuple[float, Any]]:
        # Each kind is in time order; ties keep the order positions, headings, velocities, ROT.
        keyed = [((t, i, d) for t, d in part()) for i, part in enumerate(chosen)]
        for t, _, d in heapq.merge(*keyed, key=lambda x: (x[0], x[1])):
            yield t, d

    return _Records(it, lambda: log.n_damaged)


def _open_ais(spec: StreamSpec, decode: bool) -> Iterable[Any]:
    from usvfast.nav.ais_stream import open_ais_stream

    return open_ais_stream(spec, decode)


register_stream_type("gpx", _open_gpx)
register_stream_type("ais", _open_ais)
register_stream_type("nmea", _open_nmea, options=["records"])
register_stream_type(
    "bag", _open_bag, needs_topic=True, options=["time_source", "decode_images", "yaw_convention"]
)
register_stream_type(
    "video", _open_video, options=["start_time", "end_time", "fps", "time_base", "skip_until"]
)


def split_record(rec: Any) -> tuple[float, Any]:
    """(time, data) of a stream record: a `(time, data)` tuple or an object with `.time`
    (data: its `.data` attribute, or the object itself). Raises TypeError otherwise."""
    if isinstance(rec, tuple) and len(rec) == 2:
        return float(rec[0]), rec[1]
    t = getattr(rec, "time", None)
    if t is None:
        raise TypeError(
            "stream record: expected (time, data) or an object with .time, "
            f"got {type(rec).__name__}"
        )
    return float(t), getattr(rec, "data", rec)


def open_stream(spec: StreamSpec, decode: bool = True) -> Iterable[Any]:
    """Open a stream with its registered reader (records before the clock offset).

    Raises RecordingError naming the stream when the reader rejects the file or an option.
    """
    try:
        st = STREAM_TYPES[spec.type]
    except KeyError:
        raise ValueError(f"type: {spec.type!r} is not a registered stream type") from None
    try:
        return st.opener(spec, decode)
    except RecordingError:
        raise
    except (TypeError, ValueError) as exc:
        raise RecordingError(f"stream {spec.id!r} ({spec.type}): {exc}") from exc
