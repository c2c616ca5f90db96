"""LiDAR readers, one frame per rotation: ROS1/ROS2 bags (`BagReader`: VelodyneScan or
PointCloud2) and `open_lidar` for any LiDAR file (Velodyne `.pcap` captures:
`usvfast.lidar.pcap`).

Packets are decoded by usvfast's own decoder for the VLP-16, VLP-16 Hi-Res and HDL-32E and by
velodyne-decoder for the other models (`usvfast.lidar.packets`), bags are read by rosbags;
these modules add the robustness layer field data needs. Damaged input (a record header that
does not parse, a truncated record, a Velodyne packet whose structure is wrong, a message that
does not deserialise) is skipped and counted in `reader.stats`; a `LidarDataWarning`
summarises the count at the end of the stream. Good records before and after a damaged one
are kept: the pcap record stream resynchronises on the next plausible record header. Nothing
usable in a file raises ValueError.

Payload bytes that are corrupted but still structurally valid (a flipped distance byte)
cannot be detected: Velodyne sensors send UDP checksums of zero.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from usvfast._time import ros_stamp_seconds
from usvfast._validate import integer
from usvfast.lidar.frame import POINT_DTYPE, LidarFrame
from usvfast.lidar.packets import (
    ReadStats,
    VelodyneScanDecoder,
    decoded_to_points,
    finish_read,
    packet_problems,
)
from usvfast.lidar.pcap import VelodynePcapReader

VELODYNE_SCAN_MSG = """\
std_msgs/Header header
velodyne_msgs/VelodynePacket[] packets
"""
VELODYNE_PACKET_MSG = """\
builtin_interfaces/Time stamp
uint8[1206] data
"""


LIDAR_MSGTYPES = ("velodyne_msgs/msg/VelodyneScan", "sensor_msgs/msg/PointCloud2")


def lidar_typestore(ros1: bool = False):
    """A rosbags typestore with the ROS 2 Humble (or ROS 1 Noetic) types plus velodyne_msgs."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    types = {}
    types.update(get_types_from_msg(VELODYNE_PACKET_MSG, "velodyne_msgs/msg/VelodynePacket"))
    types.update(get_types_from_msg(VELODYNE_SCAN_MSG, "velodyne_msgs/msg/VelodyneScan"))
    store.register(types)
    return store


_PC2_DTYPES = {1: "i1", 2: "u1", 3: "<i2", 4: "<u2", 5: "<i4", 6: "<u4", 7: "<f4", 8: "<f8"}


def pointcloud2_to_points(msg: Any) -> tuple[float, np.ndarray]:
    """Convert a sensor_msgs/PointCloud2 message to (stamp s, (n,) `POINT_DTYPE`).

    `msg`: any object with PointCloud2's fields (rosbags, rclpy or rospy messages alike).
    Needs float fields x, y, z; takes intensity, ring (or Livox's `line`) and a per-point
    time when present (`time`/`t`/`timestamp`/`time_stamp`: float seconds relative to the
    header stamp, or integer nanoseconds for `t` (Ouster); absolute float seconds (Hesai) and
    absolute float nanoseconds (Livox) are made relative). Points with a non-finite
    coordinate (organised clouds) are dropped. Raises ValueError on a message whose layout
    does not match its data.
    """
    stamp = ros_stamp_seconds(msg.header.stamp)
    if msg.is_bigendian:
        raise ValueError("PointCloud2: big-endian clouds are not supported")
    fields = {f.name: f for f in msg.fields}
    if not {"x", "y", "z"} <= fields.keys():
        raise ValueError("PointCloud2: fields x, y, z are required")
    names, formats, offsets = [], [], []
    for f in msg.fields:
        if f.datatype not in _PC2_DTYPES or f.count != 1:
            continue
        names.append(f.name)
        formats.append(_PC2_DTYPES[f.datatype])
        offsets.append(f.offset)
    step = int(msg.point_step)
    n = int(msg.width) * int(msg.height)
    data = np.asarray(msg.data, dtype=np.uint8)
    ends = [o + np.dtype(t).itemsize for o, t in zip(offsets, formats, strict=True)]
    if step <= 0 or max(ends) > step:
        raise ValueError("PointCloud2: point_step smaller than its fields")
    if data.size < n * step or int(msg.row_step) * int(msg.height) != data.size:
        raise ValueError("PointCloud2: data size does not match width*height*point_step")
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": step})
    if int(msg.row_step) == int(msg.width) * step:
        raw = data[: n * step].view(dtype)
    else:  # padded rows
        rows = data.reshape(int(msg.height), int(msg.row_step))[:, : int(msg.width) * step]
        raw = np.ascontiguousarray(rows).view(dtype).reshape(-1)
    out = np.empty(n, dtype=POINT_DTYPE)
    for name in ("x", "y", "z"):
        out[name] = raw[name]
    out["intensity"] = raw["intensity"] if "intensity" in fields else 0.0
    ring = "ring" if "ring" in fields else "line" if "line" in fields else None
    out["ring"] = raw[ring] if ring is not None else 0
    time = np.zeros(n)
    for name in ("time", "t", "timestamp", "time_stamp"):
        if name in fields:
            t = raw[name].astype(np.float64)
            if name == "t" and raw[name].dtype.kind in "iu":
                t = t * 1e-9
            typical = np.nanmedian(np.abs(t)) if n else 0.0
            if typical > 1e15:  # absolute nanoseconds (UNIX seconds are ~1.7e9)
                t = t * 1e-9
            if typical > 1e6:  # absolute times
                t = t - stamp
            time = t
            break
    out["time"] = time
    finite = np.isfinite(out["x"]) & np.isfinite(out["y"]) & np.isfinite(out["z"])
    return stamp, out[finite]


def make_header(typestore, stamp: float, frame_id: str):
    """A std_msgs/msg/Header of `typestore` (ROS 1 headers get seq = 0) at `stamp` UNIX s."""
    header_t = typestore.types["std_msgs/msg/Header"]
    time_t = typestore.types["builtin_interfaces/msg/Time"]
    sec = int(np.floor(stamp))
    nanosec = min(round((stamp - sec) * 1e9), 999_999_999)
    extra = {"seq": 0} if "seq" in header_t.__dataclass_fields__ else {}
    return header_t(stamp=time_t(sec=sec, nanosec=nanosec), frame_id=frame_id, **extra)


def points_to_pointcloud2(stamp: float, points: np.ndarray, frame_id: str, typestore):
    """Build a sensor_msgs/msg/PointCloud2 (rosbags class) holding `POINT_DTYPE` points.

    Layout follows the ROS velodyne driver: x, y, z, intensity (float32), ring (uint16),
    time (float32, s relative to the header stamp), dense, one row.
    """
    pc2 = typestore.types["sensor_msgs/msg/PointCloud2"]
    pf = typestore.types["sensor_msgs/msg/PointField"]
    packed = np.ascontiguousarray(points, dtype=POINT_DTYPE)
    names = POINT_DTYPE.names or ()
    offsets = [(POINT_DTYPE.fields or {})[n][1] for n in names]
    kinds = [7, 7, 7, 7, 4, 7]
    fields = [
        pf(name=n, offset=o, datatype=k, count=1)
        for n, o, k in zip(names, offsets, kinds, strict=True)
    ]
    return pc2(
        header=make_header(typestore, stamp, frame_id),
        height=1,
        width=packed.shape[0],
        fields=fields,
        is_bigendian=False,
        point_step=POINT_DTYPE.itemsize,
        row_step=POINT_DTYPE.itemsize * packed.shape[0],
        data=packed.view(np.uint8).copy(),
        is_dense=True,
    )


def write_pointcloud2_bag(
    path: str | Path,
    frames: list[LidarFrame],
    *,
    topic: str = "/velodyne_points",
    frame_id: str = "velodyne",
    ros1: bool = False,
) -> Path:
    """Write frames as sensor_msgs/PointCloud2 to a new rosbag2 directory (or a ROS1 `.bag`).

    The message time of each record is the frame stamp. Raises if `path` exists.
    """
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2

    path = Path(path)
    store = lidar_typestore(ros1)
    msgtype = "sensor_msgs/msg/PointCloud2"
    if ros1:
        with Writer1(path) as writer:
            conn = writer.add_connection(topic, msgtype, typestore=store)
            for fr in frames:
                msg = points_to_pointcloud2(fr.stamp, fr.points, frame_id, store)
                raw = store.serialize_ros1(msg, msgtype)
                writer.write(conn, round(fr.stamp * 1e9), raw)
    else:
        with Writer2(path, version=8) as writer:
            conn = writer.add_connection(topic, msgtype, typestore=store)
            for fr in frames:
                msg = points_to_pointcloud2(fr.stamp, fr.points, frame_id, store)
                writer.write(conn, round(fr.stamp * 1e9), store.serialize_cdr(msg, msgtype))
    return path


class BagReader:
    """Stream LiDAR frames from a ROS1 `.bag` or a ROS2 bag directory (rosbags).

    Reads `velodyne_msgs/VelodyneScan` messages (one rotation of raw packets each, decoded by
    `VelodyneScanDecoder` as velodyne-decoder decodes them; `model` is a
    `velodyne_decoder.Model` or None to take it from the packets) and `sensor_msgs/PointCloud2`
    messages (one rotation each). `topic` selects one topic; None takes every topic of those
    two types. Messages that fail to deserialise or convert, and malformed packets inside a
    scan, are skipped and counted.
    A damaged bag (cut short, damaged sqlite pages, no metadata.yaml, MCAP without summary) is
    recovered first (`usvfast._bagsalvage`): what cannot be read is counted as "bag container".
    `every` > 1 yields only every `every`-th LiDAR message's rotation; the others are skipped
    unread (not deserialised or decoded, so not checked for damage either).
    Raises ValueError when the bag holds no LiDAR topic or no usable frame.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        topic: str | None = None,
        model: object | None = None,
        device_time: bool = False,
        every: int = 1,
    ) -> None:
        self.path = Path(path)
        self.topic = topic
        self.model = model
        self.device_time = device_time
        self.every = integer("every", every, low=1)
        self.stats = ReadStats()

    def __iter__(self) -> Iterator[LidarFrame]:
        from usvfast._bagsalvage import open_bag

        self.stats = stats = ReadStats()
        source = str(self.path)
        store = lidar_typestore(ros1=self.path.suffix == ".bag")
        with _bag_errors(source), open_bag(self.path, store) as reader:
            if reader.salvage is not None and reader.salvage.lost:
                stats.damage("bag container", reader.salvage.lost)
            # Bags that embed definitions bring their own store; make sure velodyne_msgs is there.
            for name, fdef in store.fielddefs.items():
                if name.startswith("velodyne_msgs/") and name not in reader.typestore.fielddefs:
                    reader.typestore.register({name: fdef})
            conns = [
                c
                for c in reader.connections
                if c.msgtype in LIDAR_MSGTYPES and (self.topic is None or c.topic == self.topic)
            ]
            if not conns:
                raise ValueError(
                    f"{source}: no VelodyneScan/PointCloud2 topic (topic={self.topic})"
                )
            decoder = None
            for conn, raw in _guarded(reader.messages(connections=conns), stats):
                stats.records += 1
                if (stats.records - 1) % self.every:
                    continue
                try:
                    msg = reader.deserialize(raw, conn.msgtype)
                except Exception:  # rosbags raises several types on bad bytes
                    stats.damage("message")
                    continue
                if conn.msgtype.endswith("PointCloud2"):
                    try:
                        stamp, points = pointcloud2_to_points(msg)
                    except (ValueError, TypeError, KeyError):
                        stats.damage("message")
                        continue
                else:
                    if decoder is None:
                        decoder = VelodyneScanDecoder(self.model)
                    decoded = self._decode_scan(msg, decoder, stats)
                    if decoded is None:
                        continue
                    stamp, points = decoded
                frame = LidarFrame(stamp, points, source=f"{source}:{conn.topic}")
                frame.index = stats.frames
                stats.frames += 1
                yield frame
        finish_read(stats, source)

    def _decode_scan(
        self, msg, decoder: VelodyneScanDecoder, stats: ReadStats
    ) -> tuple[float, np.ndarray] | None:
        good: list[bytes] = []
        times: list[float] = []
        model_id = None
        payloads = [np.asarray(pkt.data, dtype=np.uint8).tobytes() for pkt in msg.packets]
        problems = packet_problems(payloads)
        for pkt, payload, problem in zip(msg.packets, payloads, problems, strict=True):
            if problem is None and model_id is not None and payload[1205] != model_id:
                problem = "model id"
            if problem is not None:
                stats.damage(problem)
                continue
            model_id = payload[1205]
            good.append(payload)
            times.append(ros_stamp_seconds(pkt.stamp))
        if not good:
            stats.damage("empty scan")
            return None
        stats.packets += len(good)
        try:
            (host, device), arr = decoder.decode(good, times)
        except RuntimeError:
            stats.damage("decoder")
            return None
        return float(device if self.device_time else host), decoded_to_points(arr)


@contextmanager
def _bag_errors(source: str) -> Iterator[None]:
    """Turn rosbags' container errors (AnyReaderError and its storage errors) into ValueError
    naming the bag, the one error type the readers document."""
    from rosbags.highlevel import AnyReaderError

    try:
        yield
    except AnyReaderError as exc:
        raise ValueError(f"{source}: cannot read the bag: {exc}") from exc


def _guarded(messages, stats: ReadStats):
    """Yield (connection, raw bytes) until the bag's storage fails; a failure ends the
    stream (counted as damage) without losing what was read before it."""
    it = iter(messages)
    while True:
        try:
            conn, _, raw = next(it)
        except StopIteration:
            return
        except Exception:  # storage errors of sqlite3 / mcap / rosbag1 chunks
            stats.damage("bag storage")
            return
        yield conn, raw


def open_lidar(path: str | Path, *, topic: str | None = None, **kwargs):
    """Open a LiDAR recording by its kind: `.pcap` -> VelodynePcapReader, `.bag` or a rosbag2
    directory / `.db3` / `.mcap` -> BagReader. Extra keyword arguments go to the reader."""
    p = Path(path)
    if p.suffix.lower() in (".pcap", ".cap"):
        if topic is not None:
            raise ValueError("topic: not used for pcap files")
        return VelodynePcapReader(p, **kwargs)
    if p.suffix.lower() in (".db3", ".mcap"):
        p = p.parent
    if p.suffix.lower() == ".bag" or p.is_dir():
        return BagReader(p, topic=topic, **kwargs)
    raise ValueError(f"path: unknown LiDAR recording kind: {path}")
