"""Recordings: timestamped sensor streams described by a TOML file, replayed merged in time
order with the vessel pose at each item's time (the thesis's generators + scheduler, section
5.2.2, with the clock offsets of 5.2.3 made explicit).

A recording file (paths relative to it)::

    [recording]
    name = "harbour run"
    navigation = "gnss"        # optional: id of the stream the pose track comes from

    [[stream]]
    id = "gnss"                # unique
    type = "gpx"               # a stream type (usvfast.nav.stream_types.STREAM_TYPES)
    path = "track.gpx"
    clock_offset = 0.0         # seconds added to every timestamp of the stream
    sensor_id = 1              # optional, int or str

    [[stream]]
    id = "cam"
    type = "video"
    path = "cam.avi"
    start_time = 1675159200.0  # type-specific options (see the opener)
    fps = 4.0
    [stream.mount]             # optional: body <- sensor mount
    lever_arm = [1.2, 0.0, -0.8]   # metres, body FRD
    ypr_deg = [90.0, 0.0, 0.0]     # yaw, pitch, roll (ZYX), degrees

Replaying (`Replay`) merges the streams lazily with heapq (memory constant in the number of
items): items come in non-decreasing time, ties broken by stream order in the file, then by
order within the stream. A stream whose timestamps go back slightly is re-sorted within a
bounded window (`reorder_window` items); an item still out of order is skipped and counted.
"""

from __future__ import annotations

import heapq
import math
import sys
import warnings
from collections.abc import Callable, Generator, Iterable
from dataclasses import dataclass
from itertools import count
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from usvfast._core import DimensionError, NonFiniteError, NotPositiveDefiniteError, TimeOrderError
from usvfast.frames import Mount
from usvfast.nav._damage import DamagedRecordsWarning
from usvfast.nav.stream_types import (
    STREAM_TYPES,
    RecordingError,
    StreamSpec,
    open_stream,
    split_record,
)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # pyright: ignore[reportMissingImports]  # (Python 3.10 only)


# --- loading ---------------------------------------------------------------------------------


def _number(where: str, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise RecordingError(f"{where}: key '{key}': expected a finite number, got {value!r}")
    return float(value)


def _triple(where: str, key: str, value: Any) -> tuple[float, float, float]:
    if not isinstance(value, list) or len(value) != 3:
        raise RecordingError(f"{where}: key '{key}': expected 3 numbers, got {value!r}")
    a, b, c = (_number(where, key, v) for v in value)
    return a, b, c


def _mount(where: str, value: Any) -> Mount:
    if not isinstance(value, dict):
        raise RecordingError(f"{where}: key 'mount': expected a table, got {value!r}")
    unknown = set(value) - {"lever_arm", "ypr_deg"}
    if unknown:
        raise RecordingError(
            f"{where}: key 'mount.{sorted(unknown)[0]}': unknown (use lever_arm, ypr_deg)"
        )
    yaw, pitch, roll = _triple(where, "mount.ypr_deg", value.get("ypr_deg", [0.0, 0.0, 0.0]))
    return Mount(
        lever_arm=np.array(
            _triple(where, "mount.lever_arm", value.get("lever_arm", [0.0, 0.0, 0.0]))
        ),
        roll=math.radians(roll),
        pitch=math.radians(pitch),
        yaw=math.radians(yaw),
    )


_COMMON_KEYS = {"id", "type", "path", "topic", "clock_offset", "sensor_id", "mount"}


def _stream(file: Path, i: int, raw: Any) -> StreamSpec:
    where = f"{file}: stream[{i}]"
    if not isinstance(raw, dict):
        raise RecordingError(f"{where}: expected a table")
    sid = raw.get("id")
    if not isinstance(sid, str) or not sid:
        raise RecordingError(f"{where}: key 'id': expected a non-empty string, got {sid!r}")
    where = f"{file}: stream[{i}] (id {sid!r})"
    kind = raw.get("type")
    if kind not in STREAM_TYPES:
        raise RecordingError(
            f"{where}: key 'type': {kind!r} is not a stream type (known: {sorted(STREAM_TYPES)})"
        )
    st = STREAM_TYPES[kind]
    path = None
    if st.needs_path or "path" in raw:
        p = raw.get("path")
        if not isinstance(p, str) or not p:
            raise RecordingError(f"{where}: key 'path': expected a file path, got {p!r}")
        path = Path(p) if Path(p).is_absolute() else file.parent / p
    topic = raw.get("topic")
    if st.needs_topic and (not isinstance(topic, str) or not topic):
        raise RecordingError(f"{where}: key 'topic': expected a topic name, got {topic!r}")
    sensor_id = raw.get("sensor_id")
    if sensor_id is not None and (
        isinstance(sensor_id, bool) or not isinstance(sensor_id, (int, str))
    ):
        raise RecordingError(f"{where}: key 'sensor_id': expected an int or str, got {sensor_id!r}")
    options = {k: v for k, v in raw.items() if k not in _COMMON_KEYS}
    if st.options is not None:
        unknown = set(options) - st.options
        if unknown:
            raise RecordingError(
                f"{where}: key '{sorted(unknown)[0]}': not an option of type {kind!r} "
                f"(options: {sorted(st.options)})"
            )
    return StreamSpec(
        id=sid,
        type=kind,
        path=path,
        topic=topic,
        clock_offset=_number(where, "clock_offset", raw.get("clock_offset", 0.0)),
        sensor_id=sensor_id,
        mount=_mount(where, raw["mount"]) if "mount" in raw else None,
        options=options,
    )


@dataclass(frozen=True)
class Recording:
    """A recording: name, streams (in file order), navigation (id of the pose stream or
    None), reorder_window (items re-sorted per stream), path of the TOML file (or None),
    max_pose_gap (seconds: the pose track refuses to interpolate across longer gaps)."""

    name: str
    streams: tuple[StreamSpec, ...]
    navigation: str | None = None
    reorder_window: int = 16
    path: Path | None = None
    max_pose_gap: float = 2.0

    def stream(self, stream_id: str) -> StreamSpec:
        """The stream with this id (KeyError naming it otherwise)."""
        for s in self.streams:
            if s.id == stream_id:
                return s
        raise KeyError(f"stream_id: no stream {stream_id!r} in recording {self.name!r}")


def load_recording(path: Path | str) -> Recording:
    """Read a recording TOML file (see the module doc). Paths are relative to the file.

    Raises RecordingError (a ValueError) naming the file, the stream and the key on any
    invalid entry: unknown type or option, missing path/topic, duplicate id, bad numbers.
    """
    file = Path(path)
    try:
        data = tomllib.loads(file.read_text())
    except OSError as exc:
        raise RecordingError(f"recording: cannot read {file}: {exc.strerror}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise RecordingError(f"{file}: not valid TOML: {exc}") from exc
    unknown = set(data) - {"recording", "stream"}
    if unknown:
        raise RecordingError(
            f"{file}: key '{sorted(unknown)[0]}': unknown (use [recording] and [[stream]])"
        )
    head = data.get("recording", {})
    if not isinstance(head, dict):
        raise RecordingError(f"{file}: key 'recording': expected a table")
    bad = set(head) - {"name", "navigation", "reorder_window", "max_pose_gap"}
    if bad:
        raise RecordingError(f"{file}: key 'recording.{sorted(bad)[0]}': unknown")
    raw_streams = data.get("stream")
    if not isinstance(raw_streams, list) or not raw_streams:
        raise RecordingError(f"{file}: key 'stream': expected at least one [[stream]] table")
    streams = tuple(_stream(file, i, s) for i, s in enumerate(raw_streams))
    ids = [s.id for s in streams]
    dup = next((x for x in ids if ids.count(x) > 1), None)
    if dup is not None:
        raise RecordingError(f"{file}: key 'id': stream id {dup!r} is used twice")
    nav = head.get("navigation")
    if nav is not None and nav not in ids:
        raise RecordingError(
            f"{file}: key 'recording.navigation': {nav!r} is not a stream id (ids: {ids})"
        )
    window = head.get("reorder_window", 16)
    if isinstance(window, bool) or not isinstance(window, int) or window < 0:
        raise RecordingError(
            f"{file}: key 'recording.reorder_window': expected an int >= 0, got {window!r}"
        )
    gap = _number(f"{file}", "recording.max_pose_gap", head.get("max_pose_gap", 2.0))
    if gap <= 0:
        raise RecordingError(f"{file}: key 'recording.max_pose_gap': must be > 0, got {gap}")
    return Recording(str(head.get("name", file.stem)), streams, nav, window, file, gap)


# --- replay ----------------------------------------------------------------------------------


# usvfast's argument errors are ValueErrors too, but never mean "t is outside the coverage".
_NOT_A_GAP = (DimensionError, NonFiniteError, NotPositiveDefiniteError, TimeOrderError)


class PoseSource(Protocol):
    """Anything with `pose_at(t)` (the vessel pose at UNIX time t; None or a ValueError when t
    is outside its coverage), or with `at(times)` as usvfast.nav.pose.PoseTrack (its Pose of
    shape (1,) arrays; PoseGapError outside)."""

    def pose_at(self, t: float) -> Any:
        """The vessel pose at UNIX time `t` (seconds, the replay's clock), in any form the
        consumer understands; None, PoseGapError or a plain ValueError when `t` is outside the
        source's coverage (counted as `no_pose`). Other errors propagate."""
        ...


@dataclass(frozen=True)
class ReplayItem:
    """One replayed item: time (UNIX s, clock offset applied), stream (id), sensor_id, mount,
    data (the reader's record), pose (the vessel pose at `time`, or None), index (position
    of the record among the stream's good records, in reading order)."""

    time: float
    stream: str
    sensor_id: int | str | None
    mount: Mount | None
    data: Any
    pose: Any
    index: int


@dataclass
class StreamCounts:
    """Per-stream counts of a replay: yielded items, damaged records (from the reader, set
    when the stream ends),
    out_of_order (skipped: earlier than an item already emitted beyond the reorder window),
    no_pose (items whose time the pose track does not cover)."""

    yielded: int = 0
    damaged: int = 0
    out_of_order: int = 0
    no_pose: int = 0


class Replay:
    """Lazy time-ordered merge of a recording's streams; iterate for ReplayItems.

    pose_track: a PoseSource queried at each item's time (None: poses are None).
    skip_without_pose: leave out items the pose track does not cover (counted either way).
    streams: ids to replay (default all). decode: False for fast scans (images undecoded).
    start, end: replay only items with start <= time <= end (UNIX s; the merge stops at end).
    `counts` holds a StreamCounts per stream id, updated during iteration.
    """

    def __init__(
        self,
        recording: Recording,
        pose_track: PoseSource | None = None,
        *,
        skip_without_pose: bool = False,
        streams: Iterable[str] | None = None,
        decode: bool = True,
        start: float | None = None,
        end: float | None = None,
    ) -> None:
        for name, v in (("start", start), ("end", end)):
            if v is not None and (isinstance(v, bool) or not math.isfinite(v)):
                raise ValueError(f"{name}: expected a finite UNIX time, got {v!r}")
        self.start = -math.inf if start is None else float(start)
        self.end = math.inf if end is None else float(end)
        if self.start > self.end:
            raise ValueError(f"start, end: start {start} is after end {end}")
        self._pose_at: Callable[[float], Any] | None = None
        if pose_track is not None:
            if callable(getattr(pose_track, "pose_at", None)):
                self._pose_at = pose_track.pose_at
            elif callable(getattr(pose_track, "at", None)):
                self._pose_at = pose_track.at  # type: ignore[attr-defined]
            else:
                raise TypeError("pose_track: expected an object with pose_at(t) or at(times)")
        chosen = (
            list(recording.streams) if streams is None else [recording.stream(s) for s in streams]
        )
        self.recording = recording
        self.specs = chosen
        self.pose_track = pose_track
        self.skip_without_pose = skip_without_pose
        self.decode = decode
        self.counts: dict[str, StreamCounts] = {s.id: StreamCounts() for s in chosen}

    def _stream(self, k: int, spec: StreamSpec) -> Generator[tuple[float, int, int, Any]]:
        counts = self.counts[spec.id]
        source = open_stream(spec, self.decode)
        window = self.recording.reorder_window
        buf: list[tuple[float, int, Any]] = []  # heap of (time, seq, data)
        last = -math.inf
        seq = count()
        off = spec.clock_offset
        try:
            for rec in source:
                if type(rec) is tuple and len(rec) == 2:
                    t, data = float(rec[0]), rec[1]
                else:
                    t, data = split_record(rec)
                t += off
                if t < last:
                    counts.out_of_order += 1
                    continue
                item = (t, next(seq), data)
                if len(buf) < window:
                    heapq.heappush(buf, item)
                    continue
                # Full window: emit the earliest of the window and the new item.
                t0, s0, d0 = heapq.heappushpop(buf, item) if buf else item
                last = t0
                yield t0, k, s0, d0
            while buf:
                yield _pop(buf, k)
        finally:
            counts.damaged = int(getattr(source, "damaged", 0))

    def __iter__(self) -> Generator[ReplayItem]:
        gens = [self._stream(k, s) for k, s in enumerate(self.specs)]
        try:
            # (time, stream, seq) is unique: tuples never compare the data.
            for t, k, seq, data in heapq.merge(*gens):
                if t < self.start:
                    continue
                if t > self.end:
                    break
                spec = self.specs[k]
                counts = self.counts[spec.id]
                pose = None
                if self._pose_at is not None:
                    try:
                        pose = self._pose_at(t)
                    except _NOT_A_GAP:
                        raise  # bad data or a broken pose source: not a gap in coverage
                    except ValueError:  # PoseGapError, or a plain ValueError (PoseSource)
                        pose = None
                    if pose is None:
                        counts.no_pose += 1
                        if self.skip_without_pose:
                            continue
                counts.yielded += 1
                yield ReplayItem(t, spec.id, spec.sensor_id, spec.mount, data, pose, seq)
        finally:
            for g in gens:
                g.close()
            late = {sid: c.out_of_order for sid, c in self.counts.items() if c.out_of_order}
            if late:
                warnings.warn(
                    f"replay: skipped items whose time went back beyond the reorder window "
                    f"({late})",
                    DamagedRecordsWarning,
                    stacklevel=2,
                )


def _pop(buf: list[tuple[float, int, Any]], k: int) -> tuple[float, int, int, Any]:
    t, s, d = heapq.heappop(buf)
    return t, k, s, d
