"""Replay stream types the pipeline adds to `usvfast.nav.replay`: the LiDAR as a first-class
stream (VelodyneScan packets, PointCloud2, Velodyne pcap) and video with a per-frame timestamp
file (the D1 layout: mp4 + `frame,time` CSV). Camera images from bags (CompressedImage, Image)
and GNSS (NMEA text, nmea_msgs/Sentence, NavSatFix) use the built-in `bag` / `nmea` types.

Registered on import:
- `lidar`: path = a `.pcap` capture, a ROS1 `.bag` or a rosbag2 folder; topic (bags) = a
  VelodyneScan or PointCloud2 topic; options `model` ("VLP-16", ...), `device_time`, `every`
  (an integer >= 1: only every `every`-th rotation; a bag's others are skipped unread).
  Records are `(stamp, LidarFrame)`; `damaged` counts skipped messages/packets.
- `video_times`: path = a video file, `times` = a CSV with columns frame,time (UNIX s);
  records `(time, image BGR)`; frames without a time are counted as damaged.
"""

from __future__ import annotations

import csv
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from usvfast.nav.stream_types import StreamSpec, register_stream_type

__all__ = ["LidarRecords", "check_topic", "open_lidar_stream", "open_video_times"]

#: The `lidar` stream's `model` names -> velodyne-decoder's Model members.
_MODELS = {
    "VLP-16": "VLP16",
    "VLP16": "VLP16",
    "VLP-16 Hi-Res": "PuckHiRes",
    "VLP-32C": "VLP32C",
    "HDL-32E": "HDL32E",
    "HDL-64E S2": "HDL64E_S2",
    "HDL-64E S3": "HDL64E_S3",
    "VLS-128": "VLS128",
}


def check_topic(path: Path, topic: str, msgtypes: Iterable[str] | None = None) -> str:
    """The message type of `topic` in the bag at `path`; ValueError naming the bag, the topic
    and the topics it holds when it is absent (or not of one of `msgtypes`)."""
    from usvfast.nav.bags import bag_topics

    topics = bag_topics(path)
    if topic not in topics:
        listing = ", ".join(f"{k} ({v.msgtype})" for k, v in sorted(topics.items()))
        raise ValueError(f"topic: {topic!r} is not in bag {path} (topics: {listing})")
    msgtype = topics[topic].msgtype
    wanted = list(msgtypes or [])
    if wanted and msgtype not in wanted:
        raise ValueError(f"topic: {topic!r} in {path} holds {msgtype}, expected {wanted}")
    return msgtype


class LidarRecords:
    """A LiDAR reader as replay records `(stamp, LidarFrame)`; `damaged` from its stats."""

    def __init__(self, reader: Any) -> None:
        self.reader = reader

    def __iter__(self) -> Iterator[tuple[float, Any]]:
        for frame in self.reader:
            yield frame.stamp, frame

    @property
    def damaged(self) -> int:
        return int(self.reader.stats.damaged)


def _model(name: Any) -> Any:
    if name is None:
        return None
    import velodyne_decoder as vd

    if not isinstance(name, str) or name not in _MODELS:
        raise ValueError(f"model: expected one of {sorted(_MODELS)}, got {name!r}")
    return getattr(vd.Model, _MODELS[name])


def open_lidar_stream(spec: StreamSpec, decode: bool = True) -> LidarRecords:
    """Open a `lidar` stream (see the module doc). Raises ValueError naming the topic when a
    bag lacks it or holds no LiDAR type."""
    from usvfast.lidar.pcap import VelodynePcapReader
    from usvfast.lidar.readers import LIDAR_MSGTYPES, BagReader

    assert spec.path is not None
    model = _model(spec.options.get("model"))
    device_time = bool(spec.options.get("device_time", False))
    every = spec.options.get("every", 1)
    p = spec.path
    if p.suffix.lower() in (".pcap", ".cap"):
        return LidarRecords(
            VelodynePcapReader(p, model=model, device_time=device_time, every=every)
        )
    if p.suffix.lower() in (".db3", ".mcap"):
        p = p.parent
    if spec.topic is None:
        raise ValueError("topic: required for a LiDAR bag stream")
    check_topic(p, spec.topic, LIDAR_MSGTYPES)
    return LidarRecords(
        BagReader(p, topic=spec.topic, model=model, device_time=device_time, every=every)
    )


class _VideoTimes:
    def __init__(self, path: Path, times: dict[int, float], decode: bool) -> None:
        from usvfast.nav.video import VideoReader

        self.reader = VideoReader(path, start_time=0.0, fps=1.0, time_base="rate")
        self.times = times
        self.decode = decode
        self.missing = 0

    def __iter__(self) -> Iterator[tuple[float, Any]]:
        self.missing = 0
        for fr in self.reader.frames(decode=self.decode):
            t = self.times.get(fr.index)
            if t is None:
                self.missing += 1
                continue
            yield t, fr.image

    @property
    def damaged(self) -> int:
        return int(self.reader.damaged) + self.missing


def open_video_times(spec: StreamSpec, decode: bool = True) -> Iterable[Any]:
    """Open a `video_times` stream (see the module doc). Raises ValueError naming `times` when
    the CSV is missing or has no `frame,time` columns."""
    assert spec.path is not None
    times_opt = spec.options.get("times")
    if not isinstance(times_opt, str):
        raise ValueError(f"times: expected the path of a frame,time CSV, got {times_opt!r}")
    tpath = Path(times_opt)
    if not tpath.is_absolute():
        tpath = spec.path.parent / tpath
    try:
        with open(tpath, newline="") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as exc:
        raise ValueError(f"times: cannot read {tpath}: {exc.strerror}") from exc
    times: dict[int, float] = {}
    for row in rows:
        try:
            times[int(row["frame"])] = float(row["time"])
        except (KeyError, TypeError, ValueError):
            continue
    if not times:
        raise ValueError(f"times: {tpath} has no usable frame,time row")
    return _VideoTimes(spec.path, times, decode)


register_stream_type("lidar", open_lidar_stream, options=["model", "device_time", "every"])
register_stream_type("video_times", open_video_times, options=["times"])
