"""LiDAR readers: Velodyne `.pcap` captures and ROS1/ROS2 bags, one frame per rotation.

Packets are decoded by velodyne-decoder, bags are read by rosbags; this module adds the
robustness layer field data needs. Damaged input (a record header that does not parse, a
truncated record, a Velodyne packet whose structure is wrong, a message that does not
deserialise) is skipped and counted in `reader.stats`; a `LidarDataWarning` summarises the
count at the end of the stream. Good records before and after a damaged one are kept: the
pcap record stream resynchronises on the next plausible record header. Nothing usable in a
file raises ValueError.

Payload bytes that are corrupted but still structurally valid (a flipped distance byte)
cannot be detected: Velodyne sensors send UDP checksums of zero.
"""

from __future__ import annotations

import mmap
import os
import struct
import warnings
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from usvfast._damage import DamagedRecordsWarning
from usvfast._extras import require
from usvfast._files import regular_file
from usvfast._time import ros_stamp_seconds
from usvfast.lidar.frame import POINT_DTYPE, LidarFrame

#: Size of the UDP payload of a Velodyne data packet, bytes.
VELODYNE_PACKET_SIZE = 1206
#: Model ids (factory byte) known to velodyne-decoder's packet format.
_KNOWN_MODEL_IDS = {0x21, 0x22, 0x24, 0x28, 0x31, 0xA1}
_BLOCK_FLAGS = {0xEEFF, 0xDDFF}  # upper / lower block (HDL-64E uses both)
_RETURN_MODES = {0x37, 0x38, 0x39}

VELODYNE_SCAN_MSG = """\
std_msgs/Header header
velodyne_msgs/VelodynePacket[] packets
"""
VELODYNE_PACKET_MSG = """\
builtin_interfaces/Time stamp
uint8[1206] data
"""


class LidarDataWarning(DamagedRecordsWarning):
    """Damaged LiDAR records were skipped while reading (count in the message); a
    DamagedRecordsWarning like every reader's."""


@dataclass
class ReadStats:
    """Counts kept by a reader while it streams.

    `records` counts pcap records or bag messages seen, `packets` Velodyne data packets
    decoded, `frames` frames produced, `damaged` skipped damaged records/packets/messages;
    `reasons` breaks `damaged` down by cause.
    """

    records: int = 0
    packets: int = 0
    frames: int = 0
    damaged: int = 0
    reasons: Counter = field(default_factory=Counter)

    def damage(self, reason: str, count: int = 1) -> None:
        """Count `count` damaged items for `reason`."""
        self.damaged += count
        self.reasons[reason] += count


def _finish(stats: ReadStats, source: str) -> None:
    if stats.damaged:
        detail = ", ".join(f"{k}: {v}" for k, v in sorted(stats.reasons.items()))
        warnings.warn(
            f"{source}: skipped {stats.damaged} damaged record(s) ({detail})",
            LidarDataWarning,
            stacklevel=3,
        )
    if stats.frames == 0:
        raise ValueError(f"{source}: no usable LiDAR frame (damaged: {stats.damaged})")


def velodyne_packet_problem(payload: bytes, model_id: int | None = None) -> str | None:
    """Return why a 1206-byte Velodyne data packet is malformed, or None if it looks valid.

    Checks the block flags, the azimuths (< 36000 hundredths of a degree), the factory bytes
    (return mode, model id, and the model id against `model_id` when given).
    """
    if len(payload) != VELODYNE_PACKET_SIZE:
        return "packet length"
    blocks = np.frombuffer(payload, dtype="<u2", count=600).reshape(12, 50)
    flags = blocks[:, 0].tolist()  # 12 values: plain Python is faster than np.isin here
    if not all(f in _BLOCK_FLAGS for f in flags):
        return "block flag"
    if max(blocks[:, 1].tolist()) >= 36000:
        return "azimuth"
    return_mode, model = payload[1204], payload[1205]
    if return_mode not in _RETURN_MODES or model not in _KNOWN_MODEL_IDS:
        return "factory bytes"
    if model_id is not None and model != model_id:
        return "model id"
    return None


_FLAG_ARRAY = np.array(sorted(_BLOCK_FLAGS), dtype=np.uint16)
_RETURN_ARRAY = np.array(sorted(_RETURN_MODES), dtype=np.uint8)
_MODEL_ARRAY = np.array(sorted(_KNOWN_MODEL_IDS), dtype=np.uint8)


def _packet_problems(payloads: list[bytes]) -> list[str | None]:
    """`velodyne_packet_problem(p)` (without the model-id check) of many packets at once: one
    numpy pass over the packets of full length, the others one by one."""
    full = [k for k, p in enumerate(payloads) if len(p) == VELODYNE_PACKET_SIZE]
    out: list[str | None] = [None] * len(payloads)
    for k in set(range(len(payloads))) - set(full):
        out[k] = velodyne_packet_problem(payloads[k])
    if not full:
        return out
    raw = np.frombuffer(b"".join(payloads[k] for k in full), dtype=np.uint8)
    raw = raw.reshape(len(full), VELODYNE_PACKET_SIZE)
    blocks = raw[:, :1200].copy().view("<u2").reshape(len(full), 12, 50)
    bad_flag = ~np.all(np.isin(blocks[:, :, 0], _FLAG_ARRAY), axis=1)
    bad_azimuth = (blocks[:, :, 1] >= 36000).any(axis=1)
    bad_factory = ~np.isin(raw[:, 1204], _RETURN_ARRAY) | ~np.isin(raw[:, 1205], _MODEL_ARRAY)
    for j, k in enumerate(full):
        if bad_flag[j]:
            out[k] = "block flag"
        elif bad_azimuth[j]:
            out[k] = "azimuth"
        elif bad_factory[j]:
            out[k] = "factory bytes"
    return out


def _decoded_to_points(arr: np.ndarray) -> np.ndarray:
    """velodyne-decoder's (n, 8) float32 columns -> (n,) `POINT_DTYPE`."""
    out = np.empty(arr.shape[0], dtype=POINT_DTYPE)
    out["x"], out["y"], out["z"] = arr[:, 0], arr[:, 1], arr[:, 2]
    out["intensity"] = arr[:, 3]
    out["time"] = arr[:, 4]
    out["ring"] = arr[:, 6].astype(np.uint16)
    return out


# --------------------------------------------------------------------------------------
# pcap
# --------------------------------------------------------------------------------------
_PCAP_MAGICS = {
    b"\xd4\xc3\xb2\xa1": ("<", 1e-6),
    b"\xa1\xb2\xc3\xd4": (">", 1e-6),
    b"\x4d\x3c\xb2\xa1": ("<", 1e-9),
    b"\xa1\xb2\x3c\x4d": (">", 1e-9),
}


def _close_in_time(ref_sec: int, sec: int) -> bool:
    """True when `sec` can follow `ref_sec` in one capture stream (1 s of reordering back,
    up to a minute of silence forward)."""
    return -1 <= sec - ref_sec <= 60


def _iter_pcap_records(
    data: bytes, stats: ReadStats, source: str
) -> Iterator[tuple[float, int, bytes]]:
    """Yield (timestamp s, link type, frame bytes) of every readable pcap record.

    A record whose header is implausible (length beyond the snap length, a timestamp far
    from its neighbours) is counted as damaged and the stream resynchronises on the next
    position holding a plausible header followed by another plausible header (or the end
    of the file). A record cut by the end of the file is counted as damaged.

    A header's timestamp is judged by both neighbours, not by the last accepted record
    alone: a record whose seconds disagree with the previous record while the next record
    agrees with the previous one is the single outlier (a damaged `ts_sec`), so it is
    skipped and counted ("record timestamp") and the reference time stays; a jump that the
    next record confirms is a real clock step and is adopted (an unconfirmed jump, as in the
    last record, is damage).
    """
    if len(data) < 24 or data[:4] not in _PCAP_MAGICS:
        raise ValueError(f"{source}: not a libpcap file (pcapng is not supported)")
    endian, tick = _PCAP_MAGICS[data[:4]]
    snaplen, linktype = struct.unpack(endian + "II", data[16:24])
    snaplen = min(snaplen or 262144, 262144)
    hdr = struct.Struct(endian + "IIII")
    n = len(data)
    last_sec: int | None = None

    def plausible(pos: int, ref_sec: int | None) -> bool:
        if pos + 16 > n:
            return False
        sec, frac, incl, orig = hdr.unpack_from(data, pos)
        if incl == 0 or incl > snaplen or incl > orig or orig > 262144:
            return False
        if frac >= (1_000_000 if tick == 1e-6 else 1_000_000_000):
            return False
        return ref_sec is None or -3600 <= sec - ref_sec <= 86400

    def header_sec(pos: int) -> int | None:
        return hdr.unpack_from(data, pos)[0] if plausible(pos, None) else None

    def resync(start: int, ref_sec: int | None) -> int:
        pos = start
        while pos + 16 <= n:
            if plausible(pos, ref_sec):
                incl = hdr.unpack_from(data, pos)[2]
                nxt = pos + 16 + incl
                if nxt == n or plausible(nxt, ref_sec):
                    return pos
            pos += 1
        return n

    pos = 24
    while pos < n:
        if pos + 16 > n:
            stats.records += 1
            stats.damage("truncated record")
            return
        if not plausible(pos, last_sec):
            stats.records += 1
            stats.damage("record header")
            pos = resync(pos + 1, last_sec)
            continue
        sec, frac, incl, _ = hdr.unpack_from(data, pos)
        stats.records += 1
        if pos + 16 + incl > n:
            stats.damage("truncated record")
            return
        nxt = pos + 16 + incl
        next_sec = header_sec(nxt)
        if last_sec is None and next_sec is not None:
            # the first record: judged by the next two (is it or the next one the outlier?)
            after = header_sec(nxt + 16 + hdr.unpack_from(data, nxt)[2])
            judge = next_sec if after is None or _close_in_time(next_sec, after) else None
        else:
            judge = last_sec
        if judge is not None and not _close_in_time(judge, sec):
            if next_sec is None or _close_in_time(judge, next_sec):
                # the one outlier between agreeing neighbours (or a jump nothing confirms)
                stats.damage("record timestamp")
                pos = nxt
                continue
        last_sec = sec
        yield sec + frac * tick, linktype, data[pos + 16 : pos + 16 + incl]
        pos += 16 + incl


def _udp_payload(linktype: int, frame: bytes) -> tuple[int, bytes] | None:
    """(destination port, payload) of a UDP/IPv4 frame, None for anything else.

    Raises ValueError when the frame claims to be IPv4/UDP but its headers are broken
    (IP header checksum, lengths).
    """
    dpkt = require("dpkt", "lidar", "pcap files")

    try:
        if linktype == 1:
            eth = dpkt.ethernet.Ethernet(frame)
            ip = eth.data
        elif linktype in (101, 12):
            ip = dpkt.ip.IP(frame)
        elif linktype == 113:
            ip = dpkt.sll.SLL(frame).data
        else:
            return None
    except (dpkt.dpkt.UnpackError, struct.error) as exc:
        raise ValueError("link/IP header") from exc
    if not isinstance(ip, dpkt.ip.IP):
        return None
    # the header as stored (pack_hdr keeps the received checksum): sums to 0 when intact
    if dpkt.in_cksum(ip.pack_hdr() + bytes(ip.opts)) != 0:
        raise ValueError("IP checksum")
    udp = ip.data
    if not isinstance(udp, dpkt.udp.UDP):
        return None
    if udp.ulen != 8 + len(udp.data):
        raise ValueError("UDP length")
    return int(udp.dport), bytes(udp.data)


class VelodynePcapReader:
    """Stream the rotations of a Velodyne `.pcap` capture (libpcap format).

    Parameters
    ----------
    path : path of the capture.
    model : velodyne_decoder.Model or None
        Sensor model; None lets velodyne-decoder detect it from the packets.
    data_port : int or None
        UDP destination port of data packets; None accepts any port (position/telemetry
        packets are recognised by their size and ignored).
    device_time : bool
        Stamp frames with the sensor's own clock (top-of-hour packet stamps, only right
        when the sensor is GPS-synchronised) instead of the capture host's clock (default).

    Iterating yields `LidarFrame`s; `stats` counts records, packets, frames and damage.
    Raises ValueError at the end of iteration if no frame could be decoded.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        model: object | None = None,
        data_port: int | None = None,
        device_time: bool = False,
    ) -> None:
        self.path = Path(path)
        self.model = model
        self.data_port = data_port
        self.device_time = device_time
        self.stats = ReadStats()

    def __iter__(self) -> Iterator[LidarFrame]:
        vd = require("velodyne_decoder", "lidar", "Velodyne packets")

        with regular_file(self.path, "path").open("rb") as fh:
            size = os.fstat(fh.fileno()).st_size
            # memory-mapped: captures of several GB are streamed, not loaded
            data = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) if size else b""
            try:
                yield from self._frames(data, vd)
            finally:
                if isinstance(data, mmap.mmap):
                    data.close()

    def _frames(self, data, vd) -> Iterator[LidarFrame]:
        self.stats = stats = ReadStats()
        source = str(self.path)
        decoder = vd.StreamDecoder(vd.Config(model=self.model))
        model_id: int | None = None

        def emit(result: tuple) -> LidarFrame:
            stamp_pair, arr = result
            stamp = stamp_pair.device if self.device_time else stamp_pair.host
            frame = LidarFrame(
                float(stamp), _decoded_to_points(arr), source=source, index=stats.frames
            )
            stats.frames += 1
            return frame

        for stamp, linktype, frame_bytes in _iter_pcap_records(data, stats, source):
            try:
                udp = _udp_payload(linktype, frame_bytes)
            except ValueError as exc:
                stats.damage(str(exc))
                continue
            if udp is None:
                continue
            port, payload = udp
            if self.data_port is not None and port != self.data_port:
                continue
            if len(payload) != VELODYNE_PACKET_SIZE:
                if self.data_port is not None:
                    stats.damage("packet length")
                continue  # position / telemetry packet
            problem = velodyne_packet_problem(payload, model_id)
            if problem is not None:
                stats.damage(problem)
                continue
            model_id = payload[1205]
            stats.packets += 1
            try:
                result = decoder.decode(stamp, payload)
            except RuntimeError:
                stats.damage("decoder")
                decoder = vd.StreamDecoder(vd.Config(model=self.model))
                continue
            if result is not None:
                yield emit(result)
        result = decoder.finish()
        if result is not None:
            yield emit(result)
        _finish(stats, source)


# --------------------------------------------------------------------------------------
# ROS bags
# --------------------------------------------------------------------------------------
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
    Needs float fields x, y, z; takes intensity, ring and a per-point time when present
    (`time`/`t`/`timestamp`/`time_stamp`: float seconds relative to the header stamp, or
    integer nanoseconds for `t`; absolute float seconds are made relative). Points with a
    non-finite coordinate (organised clouds) are dropped. Raises ValueError on a message
    whose layout does not match its data.
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
    out["ring"] = raw["ring"] if "ring" in fields else 0
    time = np.zeros(n)
    for name in ("time", "t", "timestamp", "time_stamp"):
        if name in fields:
            t = raw[name].astype(np.float64)
            if name == "t" and raw[name].dtype.kind in "iu":
                t = t * 1e-9
            if np.nanmedian(np.abs(t)) > 1e6 if n else False:  # absolute times
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
    velodyne-decoder) and `sensor_msgs/PointCloud2` messages (one rotation each). `topic`
    selects one topic; None takes every topic of those two types. Messages that fail to
    deserialise or convert, and malformed packets inside a scan, are skipped and counted.
    A damaged bag (cut short, damaged sqlite pages, no metadata.yaml, MCAP without summary) is
    recovered first (`usvfast._bagsalvage`): what cannot be read is counted as "bag container".
    Raises ValueError when the bag holds no LiDAR topic or no usable frame.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        topic: str | None = None,
        model: object | None = None,
        device_time: bool = False,
    ) -> None:
        self.path = Path(path)
        self.topic = topic
        self.model = model
        self.device_time = device_time
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
                        vd = require("velodyne_decoder", "lidar", "Velodyne scans")

                        decoder = vd.ScanDecoder(vd.Config(model=self.model))
                    decoded = self._decode_scan(msg, decoder, stats)
                    if decoded is None:
                        continue
                    stamp, points = decoded
                frame = LidarFrame(stamp, points, source=f"{source}:{conn.topic}")
                frame.index = stats.frames
                stats.frames += 1
                yield frame
        _finish(stats, source)

    def _decode_scan(self, msg, decoder, stats: ReadStats) -> tuple[float, np.ndarray] | None:
        vd = require("velodyne_decoder", "lidar", "Velodyne packets")

        packets = []
        model_id = None
        payloads = [bytes(np.asarray(pkt.data, dtype=np.uint8)) for pkt in msg.packets]
        problems = _packet_problems(payloads)
        for pkt, payload, problem in zip(msg.packets, payloads, problems, strict=True):
            if problem is None and model_id is not None and payload[1205] != model_id:
                problem = "model id"
            if problem is not None:
                stats.damage(problem)
                continue
            model_id = payload[1205]
            t = ros_stamp_seconds(pkt.stamp)
            packets.append(vd.VelodynePacket(t, payload))
        if not packets:
            stats.damage("empty scan")
            return None
        stats.packets += len(packets)
        try:
            stamp_pair, arr = decoder.decode(vd.PacketVector(packets))
        except RuntimeError:
            stats.damage("decoder")
            return None
        stamp = stamp_pair.device if self.device_time else stamp_pair.host
        return float(stamp), _decoded_to_points(arr)


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
