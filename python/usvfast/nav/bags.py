"""ROS bag readers (ROS1 `.bag`, ROS2 sqlite3 or mcap folders) via rosbags, with no ROS
installation.

`BagTopic(path, topic)` iterates one topic lazily as `BagMessage`s whose `data` is converted:
- `sensor_msgs/NavSatFix` -> `NavSatFixSample`
- `sensor_msgs/Imu` -> `ImuSample`
- `geometry_msgs/QuaternionStamped` -> `QuaternionSample`
- `geometry_msgs/PoseStamped`, `geometry_msgs/PoseWithCovarianceStamped`, `nav_msgs/Odometry`
  -> `PoseSample`
- `sensor_msgs/Image`, `sensor_msgs/CompressedImage` -> numpy image decoded with OpenCV
  (colour in OpenCV's BGR(A) order; mono and depth images 2-D in their own dtype)
- `nmea_msgs/Sentence` -> the sentence text (str)
- anything else -> the message object deserialized by rosbags.

Message definitions come from the bag; for ROS2 bags without embedded definitions the ROS2
Humble store plus `nmea_msgs` and `velodyne_msgs` (registered from their .msg text) is used.
A message that cannot be deserialized or converted is skipped and counted (`damaged`, with a
`DamagedRecordsWarning` at the end of the iteration); good messages are never lost.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import AbstractContextManager
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from usvfast._bagsalvage import open_bag
from usvfast._time import ros_stamp_seconds
from usvfast.nav._damage import DamageCounter, check_file

# Message definitions of the common driver packages that rosbags' stores do not ship.
EXTRA_MSG_DEFINITIONS: dict[str, str] = {
    "nmea_msgs/msg/Sentence": "std_msgs/Header header\nstring sentence\n",
    "velodyne_msgs/msg/VelodynePacket": "time stamp\nuint8[1206] data\n",
    "velodyne_msgs/msg/VelodyneScan": (
        "std_msgs/Header header\nvelodyne_msgs/VelodynePacket[] packets\n"
    ),
}

TimeSource = Literal["header", "record"]


def bag_typestore(ros2: bool = True) -> Typestore:
    """A rosbags typestore with the standard messages (ROS1 Noetic or ROS2 Humble) plus
    `nmea_msgs/Sentence`, `velodyne_msgs/VelodynePacket` and `velodyne_msgs/VelodyneScan`.

    Use it to write bags (`typestore.serialize_ros1/serialize_cdr`) or to read ROS2 bags that
    carry no message definitions.
    """
    store = get_typestore(Stores.ROS2_HUMBLE if ros2 else Stores.ROS1_NOETIC)
    types: dict[str, Any] = {}
    for name, text in EXTRA_MSG_DEFINITIONS.items():
        types.update(get_types_from_msg(text, name))
    store.register(types)
    return store


@dataclass(frozen=True)
class NavSatFixSample:
    """One `sensor_msgs/NavSatFix`: WGS84 lat_deg, lon_deg, alt_m (ellipsoidal metres),
    status (-1 no fix, 0 fix, 1 SBAS, 2 GBAS), covariance (3, 3) m² in ENU, covariance_type."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    status: int
    covariance: np.ndarray
    covariance_type: int


@dataclass(frozen=True)
class ImuSample:
    """One `sensor_msgs/Imu`: orientation_xyzw (4,) quaternion, angular_velocity (3,) rad/s,
    linear_acceleration (3,) m/s², all in the message's frame_id (ROS: body FLU)."""

    orientation_xyzw: np.ndarray
    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray
    frame_id: str


@dataclass(frozen=True)
class QuaternionSample:
    """One `geometry_msgs/QuaternionStamped` (e.g. a GNSS driver's heading): orientation_xyzw
    (4,) in the message's frame_id."""

    orientation_xyzw: np.ndarray
    frame_id: str


@dataclass(frozen=True)
class PoseSample:
    """A pose from PoseStamped / PoseWithCovarianceStamped / Odometry: position (3,) metres
    and orientation_xyzw (4,) in frame_id (ROS: ENU world, FLU body), covariance (6, 6) over
    (x, y, z, rot x, rot y, rot z) or None, child_frame_id ('' unless Odometry)."""

    position: np.ndarray
    orientation_xyzw: np.ndarray
    frame_id: str
    child_frame_id: str
    covariance: np.ndarray | None


@dataclass(frozen=True)
class BagMessage:
    """One converted message: time (UNIX s; the header stamp, or the bag's record time when
    the message has no header, its stamp is zero, or time_source='record'), record_time (UNIX
    s, when the recorder received it), topic, msgtype (`pkg/msg/Name`), data (see module doc),
    index (position within the topic, damaged messages included)."""

    time: float
    record_time: float
    topic: str
    msgtype: str
    data: Any
    index: int


@dataclass(frozen=True)
class BagTopicInfo:
    """A topic of a bag: msgtype (`pkg/msg/Name`) and message count from the bag's index."""

    msgtype: str
    count: int


class DamagedMessage(ValueError):
    """A message that cannot be deserialized or converted (skipped and counted by readers)."""


def _open(path: Path) -> AbstractContextManager[AnyReader]:
    # ROS1 bags always embed their definitions; ROS2 bags may not (before Iron).
    return open_bag(path, bag_typestore(ros2=True))  # recovers damaged bags


def bag_topics(path: Path | str) -> dict[str, BagTopicInfo]:
    """Topics of a bag (ROS1 `.bag` file, or ROS2 folder / `.db3` / `.mcap`), by name. A bag
    is opened for this once per process while its files are unchanged (an open costs ~30 ms:
    rosbags parses the metadata and the message definitions).

    Raises ValueError naming the path when it is missing or not a readable bag.
    """
    p = _bag_path(path)
    return dict(_topics(str(p), _file_stamp(p)))


def _file_stamp(path: Path) -> tuple:
    """(name, size, modification time ns) of the bag file, or of a bag folder and its files."""
    entries = sorted(path.iterdir()) if path.is_dir() else []
    return tuple((q.name, q.stat().st_size, q.stat().st_mtime_ns) for q in [path, *entries])


@lru_cache(maxsize=16)
def _topics(path: str, stamp: tuple) -> dict[str, BagTopicInfo]:
    """The topics of the bag at `path` as it was at `stamp` (`_file_stamp`)."""
    try:
        with _open(Path(path)) as reader:
            return {
                name: BagTopicInfo(info.msgtype or "", info.msgcount)
                for name, info in reader.topics.items()
            }
    except (AnyReaderError, OSError) as exc:
        raise ValueError(f"bag: cannot read {path}: {exc}") from exc


def _bag_path(path: Path | str) -> Path:
    p = check_file(path, "bag", directory=True)
    # A ROS2 storage file given directly: read its folder (holds metadata.yaml).
    if p.is_file() and p.suffix in (".db3", ".mcap") and (p.parent / "metadata.yaml").exists():
        return p.parent
    return p


def _vec3(v: Any) -> np.ndarray:
    return np.array([v.x, v.y, v.z], dtype=np.float64)


def _quat(q: Any) -> np.ndarray:
    return np.array([q.x, q.y, q.z, q.w], dtype=np.float64)


def _pose(pose: Any, frame_id: str, child: str, cov: np.ndarray | None) -> PoseSample:
    if cov is not None:
        cov = np.asarray(cov, dtype=np.float64)
        if cov.size != 36:
            raise DamagedMessage(f"pose covariance has {cov.size} values, expected 36")
        cov = cov.reshape(6, 6)
    return PoseSample(_vec3(pose.position), _quat(pose.orientation), frame_id, child, cov)


_RAW_ENCODINGS: dict[str, tuple[np.dtype, int, int | None]] = {
    # encoding: (dtype, channels, cv2 conversion to BGR(A) or None)
    "mono8": (np.dtype(np.uint8), 1, None),
    "8UC1": (np.dtype(np.uint8), 1, None),
    "mono16": (np.dtype(np.uint16), 1, None),
    "16UC1": (np.dtype(np.uint16), 1, None),
    "32FC1": (np.dtype(np.float32), 1, None),
    "bgr8": (np.dtype(np.uint8), 3, None),
    "8UC3": (np.dtype(np.uint8), 3, None),
    "rgb8": (np.dtype(np.uint8), 3, cv2.COLOR_RGB2BGR),
    "bgra8": (np.dtype(np.uint8), 4, None),
    "8UC4": (np.dtype(np.uint8), 4, None),
    "rgba8": (np.dtype(np.uint8), 4, cv2.COLOR_RGBA2BGRA),
    "bgr16": (np.dtype(np.uint16), 3, None),
    "rgb16": (np.dtype(np.uint16), 3, cv2.COLOR_RGB2BGR),
    "bayer_rggb8": (np.dtype(np.uint8), 1, cv2.COLOR_BayerRGGB2BGR),
    "bayer_bggr8": (np.dtype(np.uint8), 1, cv2.COLOR_BayerBGGR2BGR),
    "bayer_gbrg8": (np.dtype(np.uint8), 1, cv2.COLOR_BayerGBRG2BGR),
    "bayer_grbg8": (np.dtype(np.uint8), 1, cv2.COLOR_BayerGRBG2BGR),
    "uyvy": (np.dtype(np.uint8), 2, cv2.COLOR_YUV2BGR_UYVY),
    "yuv422": (np.dtype(np.uint8), 2, cv2.COLOR_YUV2BGR_UYVY),
    "yuyv": (np.dtype(np.uint8), 2, cv2.COLOR_YUV2BGR_YUY2),
    "yuv422_yuy2": (np.dtype(np.uint8), 2, cv2.COLOR_YUV2BGR_YUY2),
}


def decode_image(msg: Any) -> np.ndarray:
    """Decode a `sensor_msgs/Image` (row stride `step`, endianness) to a numpy image.

    Returns (h, w) for one channel, (h, w, c) otherwise; colour in BGR(A) order (rgb, Bayer
    and YUV 4:2:2 encodings are converted with OpenCV). Raises DamagedMessage for an unknown
    encoding or a data size that does not match height × step.
    """
    enc = str(msg.encoding)
    if enc not in _RAW_ENCODINGS:
        raise DamagedMessage(f"unsupported image encoding {enc!r}")
    dtype, channels, conversion = _RAW_ENCODINGS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    row_bytes = w * channels * dtype.itemsize
    data = np.asarray(msg.data, dtype=np.uint8)
    if h <= 0 or w <= 0 or step < row_bytes or data.size < h * step:
        raise DamagedMessage(f"image {w}x{h} {enc} step {step} does not fit {data.size} data bytes")
    rows = data[: h * step].reshape(h, step)[:, :row_bytes]
    order = ">" if msg.is_bigendian else "<"
    img = np.ascontiguousarray(rows).view(dtype.newbyteorder(order)).astype(dtype, copy=False)
    shape = (h, w) if channels == 1 else (h, w, channels)
    img = img.reshape(shape)
    if conversion is not None:
        img = cv2.cvtColor(img, conversion)
    return img


def decode_compressed_image(msg: Any) -> np.ndarray:
    """Decode a `sensor_msgs/CompressedImage` (jpeg, png, ...; also image_transport's
    `compressedDepth` PNG with its 12-byte header) with cv2.imdecode, unchanged depth and
    channels (colour BGR). Raises DamagedMessage when OpenCV cannot decode it."""
    data = np.asarray(msg.data, dtype=np.uint8)
    if "compresseddepth" in str(msg.format).lower().replace(" ", "") and data.size > 12:
        data = data[12:]
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise DamagedMessage(f"cannot decode compressed image (format {msg.format!r})")
    return img


def convert_message(msgtype: str, msg: Any, decode_images: bool = True) -> Any:
    """Convert a deserialized message to the `data` of a BagMessage (see module doc).

    With decode_images=False image messages are returned undecoded (fast scans).
    Raises DamagedMessage when the content is unusable.
    """
    if msgtype == "sensor_msgs/msg/NavSatFix":
        cov = np.asarray(msg.position_covariance, dtype=np.float64)
        if cov.size != 9:
            raise DamagedMessage(f"NavSatFix covariance has {cov.size} values, expected 9")
        return NavSatFixSample(
            float(msg.latitude),
            float(msg.longitude),
            float(msg.altitude),
            int(msg.status.status),
            cov.reshape(3, 3),
            int(msg.position_covariance_type),
        )
    if msgtype == "sensor_msgs/msg/Imu":
        return ImuSample(
            _quat(msg.orientation),
            _vec3(msg.angular_velocity),
            _vec3(msg.linear_acceleration),
            str(msg.header.frame_id),
        )
    if msgtype == "geometry_msgs/msg/QuaternionStamped":
        return QuaternionSample(_quat(msg.quaternion), str(msg.header.frame_id))
    if msgtype == "geometry_msgs/msg/PoseStamped":
        return _pose(msg.pose, str(msg.header.frame_id), "", None)
    if msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
        return _pose(msg.pose.pose, str(msg.header.frame_id), "", msg.pose.covariance)
    if msgtype == "nav_msgs/msg/Odometry":
        return _pose(
            msg.pose.pose, str(msg.header.frame_id), str(msg.child_frame_id), msg.pose.covariance
        )
    if msgtype == "nmea_msgs/msg/Sentence":
        return str(msg.sentence)
    if decode_images and msgtype == "sensor_msgs/msg/Image":
        return decode_image(msg)
    if decode_images and msgtype == "sensor_msgs/msg/CompressedImage":
        return decode_compressed_image(msg)
    return msg


class BagTopic:
    """Lazy reader of one topic of a bag; iterate it for BagMessages in record order.

    path: ROS1 `.bag` file or ROS2 bag folder (sqlite3 or mcap); topic: exact topic name.
    time_source: 'header' (default; header stamp when present and non-zero, else record time)
    or 'record'. decode_images: decode Image/CompressedImage to numpy (default True).
    After (or during) iteration, `damaged` counts skipped messages and `yielded` good ones.
    Raises ValueError naming the bag and the available topics when the topic is absent.
    """

    def __init__(
        self,
        path: Path | str,
        topic: str,
        *,
        time_source: TimeSource = "header",
        decode_images: bool = True,
    ) -> None:
        if time_source not in ("header", "record"):
            raise ValueError(f"time_source: expected 'header' or 'record', got {time_source!r}")
        self.path = _bag_path(path)
        topics = bag_topics(self.path)
        if topic not in topics:
            raise ValueError(
                f"topic: {topic!r} is not in bag {self.path} (topics: {sorted(topics)})"
            )
        self.topic = topic
        self.msgtype = topics[topic].msgtype
        self.count = topics[topic].count
        self.time_source = time_source
        self.decode_images = decode_images
        self.damaged = 0
        self.yielded = 0

    def __iter__(self) -> Iterator[BagMessage]:
        damage = DamageCounter(f"{self.path} {self.topic}")
        self.damaged = 0
        self.yielded = 0
        index = -1
        try:
            with _open(self.path) as reader:
                conns = [c for c in reader.connections if c.topic == self.topic]
                messages = reader.messages(connections=conns)
                while True:
                    try:
                        conn, ts_ns, raw = next(messages)
                    except StopIteration:
                        break
                    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
                        # The container itself is damaged: nothing after this is reachable.
                        damage.add(f"bag unreadable after message {index}: {exc}")
                        self.damaged = damage.count
                        break
                    index += 1
                    record_time = ts_ns * 1e-9
                    try:
                        msg = reader.deserialize(raw, conn.msgtype)
                        data = convert_message(conn.msgtype, msg, self.decode_images)
                    except (AnyReaderError, DamagedMessage, cv2.error) as exc:
                        damage.add(f"message {index}: {exc}")
                        self.damaged = damage.count
                        continue
                    t = record_time
                    header = getattr(msg, "header", None)
                    if self.time_source == "header" and header is not None:
                        stamp = ros_stamp_seconds(header.stamp)
                        if stamp != 0.0:
                            t = stamp
                    self.yielded += 1
                    yield BagMessage(t, record_time, self.topic, conn.msgtype, data, index)
        except AnyReaderError as exc:
            raise ValueError(f"bag: cannot read {self.path}: {exc}") from exc
        finally:
            damage.warn(stacklevel=2)


@dataclass(frozen=True)
class NavSatFixTrack:
    """NavSatFix messages of a topic as arrays: times (n,) UNIX s, lat_deg (n,), lon_deg (n,),
    alt_m (n,), status (n,) int; skipped damaged messages."""

    times: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    alt_m: np.ndarray
    status: np.ndarray
    skipped: int


@dataclass(frozen=True)
class PoseSamples:
    """Pose messages of a topic as arrays: times (n,) UNIX s, position (n, 3) m,
    orientation_xyzw (n, 4); skipped damaged messages."""

    times: np.ndarray
    position: np.ndarray
    orientation_xyzw: np.ndarray
    skipped: int


@dataclass(frozen=True)
class ImuSamples:
    """Imu messages of a topic as arrays: times (n,) UNIX s, orientation_xyzw (n, 4),
    angular_velocity (n, 3) rad/s, linear_acceleration (n, 3) m/s²; skipped damaged."""

    times: np.ndarray
    orientation_xyzw: np.ndarray
    angular_velocity: np.ndarray
    linear_acceleration: np.ndarray
    skipped: int


def _collect(path: Path | str, topic: str, msgtypes: tuple[str, ...], time_source: TimeSource):
    reader = BagTopic(path, topic, time_source=time_source)
    if reader.msgtype not in msgtypes:
        raise ValueError(
            f"topic: {topic!r} in {reader.path} holds {reader.msgtype}, "
            f"expected {' or '.join(msgtypes)}"
        )
    items = list(reader)
    if not items:
        raise ValueError(
            f"bag: topic {topic!r} in {reader.path} has no usable message "
            f"({reader.damaged} damaged)"
        )
    return items, reader.damaged


_POSE_TYPES = (
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "nav_msgs/msg/Odometry",
)


def read_bag_navsatfix(
    path: Path | str, topic: str, *, time_source: TimeSource = "header"
) -> NavSatFixTrack:
    """All `sensor_msgs/NavSatFix` messages of `topic` as a NavSatFixTrack (record order).

    Raises ValueError when the topic is missing, of another type, or has no usable message.
    """
    items, skipped = _collect(path, topic, ("sensor_msgs/msg/NavSatFix",), time_source)
    return NavSatFixTrack(
        times=np.array([m.time for m in items]),
        lat_deg=np.array([m.data.lat_deg for m in items]),
        lon_deg=np.array([m.data.lon_deg for m in items]),
        alt_m=np.array([m.data.alt_m for m in items]),
        status=np.array([m.data.status for m in items], dtype=np.int64),
        skipped=skipped,
    )


def read_bag_poses(
    path: Path | str, topic: str, *, time_source: TimeSource = "header"
) -> PoseSamples:
    """All PoseStamped / PoseWithCovarianceStamped / Odometry messages of `topic` as arrays.

    Raises ValueError when the topic is missing, of another type, or has no usable message.
    """
    items, skipped = _collect(path, topic, _POSE_TYPES, time_source)
    return PoseSamples(
        times=np.array([m.time for m in items]),
        position=np.array([m.data.position for m in items]).reshape(-1, 3),
        orientation_xyzw=np.array([m.data.orientation_xyzw for m in items]).reshape(-1, 4),
        skipped=skipped,
    )


@dataclass(frozen=True)
class BagNmeaLog:
    """NMEA sentences of a bag topic decoded by `usvfast.nav.nmea.read_nmea`: log (its
    NmeaLog, times from the sentences themselves), skipped_messages (bag messages that could not
    be deserialized)."""

    log: Any
    skipped_messages: int


def read_bag_nmea(
    path: Path | str, topic: str, *, date: Any = None, require_checksum: bool = True
) -> BagNmeaLog:
    """Feed the `nmea_msgs/Sentence` messages of `topic` (lazily, in record order) to
    `usvfast.nav.nmea.read_nmea` (date, require_checksum: as there).

    Raises ValueError when the topic is missing or of another type, or read_nmea finds no
    usable sentence.
    """
    from usvfast.nav.nmea import read_nmea

    reader = BagTopic(path, topic)
    if reader.msgtype != "nmea_msgs/msg/Sentence":
        raise ValueError(
            f"topic: {topic!r} in {reader.path} holds {reader.msgtype}, "
            "expected nmea_msgs/msg/Sentence"
        )
    log = read_nmea((m.data for m in reader), date=date, require_checksum=require_checksum)
    return BagNmeaLog(log, reader.damaged)


def read_bag_orientations(
    path: Path | str, topic: str, *, time_source: TimeSource = "header"
) -> tuple[np.ndarray, np.ndarray, int]:
    """(times (n,) UNIX s, orientation_xyzw (n, 4), skipped damaged messages) of a topic of
    `sensor_msgs/Imu` or `geometry_msgs/QuaternionStamped`. Raises ValueError when the topic
    is missing, of another type, or has no usable message."""
    msgtypes = ("sensor_msgs/msg/Imu", "geometry_msgs/msg/QuaternionStamped")
    items, skipped = _collect(path, topic, msgtypes, time_source)
    q = np.array([m.data.orientation_xyzw for m in items]).reshape(-1, 4)
    return np.array([m.time for m in items]), q, skipped


def read_bag_imu(path: Path | str, topic: str, *, time_source: TimeSource = "header") -> ImuSamples:
    """All `sensor_msgs/Imu` messages of `topic` as arrays.

    Raises ValueError when the topic is missing, of another type, or has no usable message.
    """
    items, skipped = _collect(path, topic, ("sensor_msgs/msg/Imu",), time_source)
    return ImuSamples(
        times=np.array([m.time for m in items]),
        orientation_xyzw=np.array([m.data.orientation_xyzw for m in items]).reshape(-1, 4),
        angular_velocity=np.array([m.data.angular_velocity for m in items]).reshape(-1, 3),
        linear_acceleration=np.array([m.data.linear_acceleration for m in items]).reshape(-1, 3),
        skipped=skipped,
    )
