"""A first pipeline config for a bag (`usvfast init BAG [--out recording.toml]`): the bag's
topics sorted into the config's streams by message type, the camera calibration taken from its
CameraInfo topic, the Velodyne model read from the packets' factory byte; what only the user
can know (the sensors' mounts, the heights above the water, the camera detector) is written as
placeholders marked ``MEASURE`` or ``SET``. The draft starts from the thesis's preset, loads as
it is (`load_config` checks it) and its navigation is read once to say whether the bag holds
both position fixes and headings.

Topics by type (ROS 1 or ROS 2 names; topics without messages are left out):

- LiDAR: ``velodyne_msgs/VelodyneScan`` (packets) or ``sensor_msgs/PointCloud2``, every
  such topic a `lidar` stream;
- camera: one ``sensor_msgs/CompressedImage`` / ``Image`` topic (the one nearest in name to a
  ``sensor_msgs/CameraInfo`` topic, compressed first); the others are listed in a comment;
- navigation: every ``nmea_msgs/Sentence`` and ``sensor_msgs/NavSatFix`` topic, and every
  ``geometry_msgs/QuaternionStamped`` topic as a heading (its yaw convention to SET);
- attitude: the first ``sensor_msgs/Imu`` topic whose messages carry an orientation.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
import yaml

from usvfast.camera.calibration import CameraModel

__all__ = [
    "CALIBRATION_FILE",
    "VELODYNE_MODELS",
    "Draft",
    "draft_config",
    "init_command",
    "write_draft",
]

#: Velodyne factory byte (packet byte 1205) -> the `model` name of a `lidar` stream.
VELODYNE_MODELS = {
    0x21: "HDL-32E",
    0x22: "VLP-16",
    0x24: "VLP-16 Hi-Res",
    0x28: "VLP-32C",
    0xA1: "VLS-128",
}
_VELODYNE = "velodyne_msgs/msg/VelodyneScan"
_CLOUD = "sensor_msgs/msg/PointCloud2"
_COMPRESSED = "sensor_msgs/msg/CompressedImage"
_IMAGE = "sensor_msgs/msg/Image"
_INFO = "sensor_msgs/msg/CameraInfo"
_NAV = ("nmea_msgs/msg/Sentence", "sensor_msgs/msg/NavSatFix")
_HEADING = "geometry_msgs/msg/QuaternionStamped"
_IMU = "sensor_msgs/msg/Imu"
#: The calibration file written beside the config.
CALIBRATION_FILE = "camera_info.yaml"
_WATERLINE = "waterline_height = 0.3  # MEASURE: the body origin's height above the water, m"


@dataclass
class Draft:
    """A drafted config: `text` (TOML), the camera calibration read from a bag's CameraInfo
    (None without one; a folder's calibration file is named in the text instead), the streams
    chosen as (id, topic or file, message type or stream type), and `notes`: what the user
    still has to do or check."""

    text: str
    calibration: CameraModel | None
    streams: list[tuple[str, str, str]]
    notes: list[str] = field(default_factory=list)


def _relative(path: Path, config_dir: Path) -> str:
    """`path` as the config names it: relative to its folder when inside it, else absolute."""
    rel = Path(os.path.relpath(path.resolve(), config_dir.resolve())).as_posix()
    return path.resolve().as_posix() if rel.startswith("../") else rel


def _common_prefix(a: str, b: str) -> int:
    """Number of leading topic-name parts `a` and `b` share."""
    n = 0
    for x, y in zip(a.strip("/").split("/"), b.strip("/").split("/"), strict=False):
        if x != y:
            break
        n += 1
    return n


def _first_message(bag: Path, topic: str) -> Any:
    """The first deserialised message of `topic` (None when none can be read)."""
    from usvfast.nav.bags import BagTopic

    for m in BagTopic(bag, topic, decode_images=False):
        return m.data
    return None


def _has_orientation(imu: Any) -> bool:
    """Whether a sensor_msgs/Imu message (ImuSample) carries an orientation estimate."""
    from usvfast.pipeline.orientation import usable_orientations

    return imu is not None and bool(usable_orientations(imu.orientation_xyzw)[0])


def _model_of(packet: Any) -> str | None:
    """The model name of a Velodyne data packet's factory byte (None: unknown)."""
    data = np.frombuffer(bytes(packet), dtype=np.uint8)
    return VELODYNE_MODELS.get(int(data[1205])) if data.size == 1206 else None


def _bag_velodyne_model(bag: Path, topic: str) -> str | None:
    """The model of the first packet on a VelodyneScan topic."""
    packets = getattr(_first_message(bag, topic), "packets", None)
    return _model_of(np.asarray(packets[0].data, np.uint8)) if packets else None


def _pcap_velodyne_model(path: Path) -> str | None:
    """The model of the first 1206-byte UDP payload of a pcap capture (None without one, or
    when the file is not a libpcap capture); the capture is read by the core's record pass."""
    from usvfast._core import pcap_udp_datagrams

    if path.stat().st_size < 24:  # not even a libpcap header (numpy cannot map 0 bytes)
        return None
    data = np.memmap(path, dtype=np.uint8, mode="r")
    try:
        found = pcap_udp_datagrams(data)
    except ValueError:
        return None
    first = np.flatnonzero(found["lengths"] == 1206)
    if not first.size:
        return None
    start = int(found["offsets"][first[0]])
    return _model_of(data[start : start + 1206])


def _camera_model(msg: Any) -> CameraModel | None:
    """The CameraModel of a CameraInfo message (ROS 2 `k`/`d` or ROS 1 `K`/`D` fields), None
    when it holds no calibration (an all-zero K)."""

    def field_(name: str) -> Any:
        return getattr(msg, name, None) if hasattr(msg, name) else getattr(msg, name.upper())

    k = np.asarray(field_("k"), dtype=np.float64).reshape(3, 3)
    if k[0, 0] <= 0 or k[1, 1] <= 0:
        return None
    d = np.asarray(field_("d"), dtype=np.float64)
    return CameraModel.from_ros(
        {
            "image_width": int(msg.width),
            "image_height": int(msg.height),
            "camera_matrix": {"data": k.ravel().tolist()},
            "distortion_model": str(msg.distortion_model) or "plumb_bob",
            "distortion_coefficients": {"data": d.tolist() if d.size else [0.0] * 5},
        }
    )


def _mount_lines(what: str) -> list[str]:
    return [
        "[stream.mount]",
        f"lever_arm = [0.0, 0.0, 0.0]  # MEASURE: {what}, m from the body origin (FRD)",
        "ypr_deg = [0.0, 0.0, 0.0]  # MEASURE: its yaw, pitch, roll in the body frame, deg",
    ]


_GNSS_MOUNT = "the antenna the receiver reports"


@dataclass
class _Builder:
    """The parts of a draft as the sources are read; `text()` assembles the TOML."""

    source: str
    streams: list[tuple[str, str, str]] = field(default_factory=list)
    body: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    navigation: list[str] = field(default_factory=list)
    attitude: str | None = None
    lidars: int = 0
    camera: list[str] = field(default_factory=list)
    calibration: CameraModel | None = None

    def stream(self, sid: str, where: str, kind: str, lines: list[str]) -> None:
        self.streams.append((sid, where, kind))
        self.body += ["", "[[stream]]", f'id = "{sid}"', *lines]

    def lidar(
        self, sid: str, where: str, kind: str, lines: list[str], model: str | None = None
    ) -> None:
        """A LiDAR stream (`kind`: its message or stream type); Velodyne packets get their
        `model` (None: unknown, a placeholder), a PointCloud2 none."""
        if kind != _CLOUD and model is None:
            self.notes.append(f"{where}: unknown Velodyne model; SET the stream's model")
            lines.append('model = "VLP-16"  # SET: the sensor model')
        elif kind != _CLOUD:
            lines.append(f'model = "{model}"  # from the packets\' factory byte')
        self.lidars += 1
        self.stream(sid, where, kind, ['sensor = "lidar"', *lines, *_mount_lines("the LiDAR")])

    def camera_table(self, calibration: str | None) -> None:
        """The [camera] and [detector] tables; `calibration`: the line naming the file, None
        when there is no calibration (the camera is then off)."""
        self.camera = ["", "[camera]"]
        if calibration is not None:
            self.camera.append(calibration)
        else:
            self.notes.append(
                "no camera calibration found: the camera stays off until you give "
                "camera.calibration (a camera_info YAML) and set camera.enabled = true"
            )
            self.camera += [
                "enabled = false  # SET: true once calibrated",
                f'# calibration = "{CALIBRATION_FILE}"',
            ]
        self.camera += [
            _WATERLINE,
            "",
            "[detector]",
            'backend = "none"  # SET: "onnx" (OpenVINO / OpenCV DNN) or "torch" (YOLO weights)',
            '# weights = "my_detector.onnx"',
        ]
        self.notes.append("the camera runs no detector until you set detector.backend and weights")

    def text(self) -> str:
        nav = self.navigation
        head = [
            f"# Drafted by `usvfast init` from {self.source}. Edit every MEASURE and SET, then",
            "# `usvfast inspect` this file and `usvfast run` it.",
            'preset = "thesis"  # the thesis\'s camera filters and tracker (Codes 5.5, 5.7)',
            "",
            "[recording]",
            "navigation = " + (f'"{nav[0]}"' if len(nav) == 1 else str(nav).replace("'", '"')),
        ]
        if self.attitude is not None:
            head.append(f'attitude = "{self.attitude}"')
        head.append(
            "# fix_quality_std = [[5, 0.1], [2, 0.5]]  # SET: m per GGA quality beyond RTK fixed"
        )
        lidar = []
        if self.lidars:
            head.append(
                "# heading_calibration_s = 60.0  # the heading's error, from the LiDAR's quays"
            )
            lidar = ["", "[lidar]", _WATERLINE]
        return "\n".join(head + self.body + lidar + self.camera) + "\n"

    def draft(self) -> Draft:
        self.notes.insert(
            0, "measure every sensor's mount (lever_arm, ypr_deg) and the waterline heights"
        )
        return Draft(self.text(), self.calibration, self.streams, self.notes)


def _numbered(count: int, name: str) -> list[str]:
    """Stream ids `name` (one) or `name1`, `name2`, ... (several)."""
    return [f"{name}{i + 1}" if count > 1 else name for i in range(count)]


def _draft_bag(bag: Path, config_dir: Path) -> Draft:
    from usvfast.nav.bags import bag_topics

    topics = {name: info for name, info in bag_topics(bag).items() if info.count > 0}
    listing = ", ".join(f"{n} ({i.msgtype})" for n, i in sorted(topics.items())) or "none"

    def of(*types: str) -> list[str]:
        return sorted(n for n, i in topics.items() if i.msgtype in types)

    lidars, images, infos = of(_VELODYNE, _CLOUD), of(_COMPRESSED, _IMAGE), of(_INFO)
    navs, headings, imus = of(*_NAV), of(_HEADING), of(_IMU)
    if not navs:
        raise ValueError(
            f"source: {bag} has no navigation topic (nmea_msgs/Sentence or sensor_msgs/NavSatFix) "
            f"with messages; topics: {listing}"
        )
    if not lidars and not images:
        raise ValueError(
            f"source: {bag} has no LiDAR (VelodyneScan, PointCloud2) or camera (CompressedImage, "
            f"Image) topic with messages; topics: {listing}"
        )
    rel = _relative(bag, config_dir)
    b = _Builder(rel)

    def lines(topic: str) -> list[str]:
        return [
            'type = "bag"',
            f'path = "{rel}"',
            f'topic = "{topic}"  # {topics[topic].count} messages',
        ]

    b.navigation = _numbered(len(navs), "gnss")
    for sid, topic in zip(b.navigation, navs, strict=True):
        b.stream(sid, topic, topics[topic].msgtype, lines(topic) + _mount_lines(_GNSS_MOUNT))
    for sid, topic in zip(_numbered(len(headings), "heading"), headings, strict=True):
        b.navigation.append(sid)
        yaw = 'yaw_convention = "enu"  # SET: "north_clockwise" for nmea_navsat_driver\'s heading'
        b.stream(sid, topic, _HEADING, [*lines(topic), yaw])
    oriented = [t for t in imus if _has_orientation(_first_message(bag, t))]
    if oriented:
        b.attitude = "imu"
        b.stream("imu", oriented[0], _IMU, lines(oriented[0]))
    for topic in sorted(set(imus) - set(oriented)):
        b.body.append(f"# {topic}: an IMU without an orientation estimate (no roll, pitch)")
    for sid, topic in zip(_numbered(len(lidars), "lidar"), lidars, strict=True):
        kind = topics[topic].msgtype
        model = _bag_velodyne_model(bag, topic) if kind == _VELODYNE else None
        b.lidar(sid, topic, kind, lines(topic), model)
    if images:

        def rank(t: str) -> tuple:
            near = max((_common_prefix(t, i) for i in infos), default=0)
            return (-near, topics[t].msgtype != _COMPRESSED, -topics[t].count, t)

        image = min(images, key=rank)
        b.stream(
            "camera",
            image,
            topics[image].msgtype,
            ['sensor = "camera"', *lines(image), *_mount_lines("the camera's optical centre")],
        )
        if len(images) > 1:
            b.body.append(f"# other image topics: {', '.join(t for t in images if t != image)}")
        info = max(infos, key=lambda i: _common_prefix(image, i), default=None)
        msg = _first_message(bag, info) if info is not None else None
        b.calibration = _camera_model(msg) if msg is not None else None
        found = f'calibration = "{CALIBRATION_FILE}"  # from {info}'
        b.camera_table(found if b.calibration is not None else None)
    return b.draft()


_VIDEO = (".mp4", ".avi", ".mkv", ".mov", ".m4v")
_NMEA = (".nmea", ".log", ".txt")
_CALIBRATION = (".yaml", ".yml", ".json")


def _head(path: Path, lines: int = 50) -> list[str]:
    """The first `lines` lines of a text file, stripped."""
    with path.open(errors="replace") as fh:
        return [line.strip() for _, line in zip(range(lines), fh, strict=False)]


def _is_nmea(path: Path) -> bool:
    """Whether a text file holds NMEA sentences in its first lines."""
    return any(line[:1] in ("$", "!") and "," in line for line in _head(path))


def _times_csv(video: Path) -> Path | None:
    """The frame,time CSV of `video` in its folder (the one whose name starts with the
    video's, else the only one), None when there is none."""
    csvs = [
        p
        for p in sorted(video.parent.glob("*.csv"))
        if {"frame", "time"} <= set((_head(p, 1) or [""])[0].split(","))
    ]
    mine = [p for p in csvs if p.stem.startswith(video.stem)]
    if len(mine) == 1:
        return mine[0]
    return csvs[0] if len(csvs) == 1 else None


def _draft_folder(folder: Path, config_dir: Path) -> Draft:
    files = sorted(p for p in folder.iterdir() if p.is_file())
    pcaps = [p for p in files if p.suffix.lower() in (".pcap", ".cap")]
    videos = [p for p in files if p.suffix.lower() in _VIDEO]
    navs = [p for p in files if p.suffix.lower() in _NMEA and _is_nmea(p)]
    listing = ", ".join(p.name for p in files) or "none"
    if not navs:
        raise ValueError(
            f"source: {folder} is no bag and holds no NMEA log (.nmea, .log, .txt); "
            f"files: {listing}"
        )
    if not pcaps and not videos:
        raise ValueError(
            f"source: {folder} is no bag and holds no LiDAR .pcap or camera video; files: {listing}"
        )
    b = _Builder(_relative(folder, config_dir))
    b.navigation = _numbered(len(navs), "gnss")
    for sid, path in zip(b.navigation, navs, strict=True):
        rel = _relative(path, config_dir)
        b.stream(
            sid, path.name, "nmea", ['type = "nmea"', f'path = "{rel}"', *_mount_lines(_GNSS_MOUNT)]
        )
        if b.attitude is None and any("PASHR" in x or "XDR" in x for x in _head(path, 2000)):
            b.attitude = sid  # attitude sentences in the log
    for sid, path in zip(_numbered(len(pcaps), "lidar"), pcaps, strict=True):
        lines = ['type = "pcap"', f'path = "{_relative(path, config_dir)}"']
        b.lidar(sid, path.name, "pcap", lines, _pcap_velodyne_model(path))
    timed = [(v, _times_csv(v)) for v in videos]
    timed = [(v, t) for v, t in timed if t is not None]
    if videos and not timed:
        b.notes.append(
            f"no frame,time CSV beside {', '.join(v.name for v in videos)}: a video stream "
            "needs one (type video_times, times = CSV); no camera drafted"
        )
    if timed:
        video, times = timed[0]
        lines = [
            'sensor = "camera"',
            'type = "video_times"',
            f'path = "{_relative(video, config_dir)}"',
            f'times = "{os.path.relpath(times, video.parent)}"',
            *_mount_lines("the camera's optical centre"),
        ]
        b.stream("camera", video.name, "video_times", lines)
        calibs = [p for p in files if p.suffix.lower() in _CALIBRATION and _loads_camera(p)]
        found = f'calibration = "{_relative(calibs[0], config_dir)}"' if calibs else None
        b.camera_table(found)
    return b.draft()


def _loads_camera(path: Path) -> bool:
    """Whether `path` is a camera calibration `CameraModel.load` reads."""
    try:
        CameraModel.load(path)
    except (ValueError, OSError, TypeError, AttributeError, yaml.YAMLError):
        return False
    return True


def draft_config(source: Path | str, config_dir: Path | str) -> Draft:
    """Draft the config of `source` for a config file in `config_dir` (paths are written
    relative to it when inside it). `source`: a bag (ROS 1 `.bag` file, ROS 2 folder / `.db3`
    / `.mcap`) or a folder of recording files in the thesis's D1 layout (Velodyne `.pcap`,
    a video with its frame,time CSV, an NMEA log, a camera_info YAML/JSON). Raises ValueError
    naming the source when it is not readable or holds no LiDAR or camera, or no navigation."""
    source, config_dir = Path(source), Path(config_dir)
    if source.is_dir() and not (source / "metadata.yaml").exists():
        return _draft_folder(source, config_dir)
    return _draft_bag(source, config_dir)


def write_draft(source: Path | str, out: Path | str, *, force: bool = False) -> Draft:
    """Draft the config of `source` (:func:`draft_config`) into the file `out` and a bag's
    camera calibration into `camera_info.yaml` beside it; check that the config loads and read its
    navigation once (a missing position fix or heading becomes a note). Raises ValueError
    naming `out` when it (or the calibration file) exists and `force` is False."""
    from usvfast.pipeline.config import load_config
    from usvfast.pipeline.pose import NavigationError, NavTrack

    out = Path(out)
    calib = out.parent / CALIBRATION_FILE
    draft = draft_config(source, out.parent)
    for path in (out, calib) if draft.calibration is not None else (out,):
        if path.exists() and not force:
            raise ValueError(f"out: {path} exists (use --force to overwrite it)")
    out.parent.mkdir(parents=True, exist_ok=True)
    if draft.calibration is not None:
        draft.calibration.save(calib)
    out.write_text(draft.text)
    try:
        nav = NavTrack.from_config(load_config(out))
    except NavigationError as exc:
        draft.notes.append(f"navigation: {exc}")
    else:
        draft.notes.append(
            f"navigation: {len(nav.position.time)} position fixes and "
            f"{len(nav.heading.time)} headings"
        )
    return draft


def init_command(
    source: Annotated[
        Path,
        typer.Argument(
            help="ROS 1 .bag file, ROS 2 bag folder/.db3/.mcap, or a folder of .pcap + video "
            "+ frame-time CSV + NMEA log (the thesis's D1 layout)."
        ),
    ],
    out: Annotated[
        Path, typer.Option(help="The config file to write (camera_info.yaml goes beside it).")
    ] = Path("recording.toml"),
    force: Annotated[bool, typer.Option(help="Overwrite existing files.")] = False,
) -> None:
    """Draft a pipeline config for a bag or a D1 folder: its LiDAR, camera, GNSS and IMU as
    streams, the camera calibration, placeholders for the mounts to measure."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    draft = write_draft(source, out, force=force)
    console = Console()
    table = Table(title=f"streams drafted from {escape(str(source))}")
    for name in ("id", "topic or file", "type"):
        table.add_column(name)
    for sid, topic, msgtype in draft.streams:
        table.add_row(sid, escape(topic), msgtype)
    console.print(table)
    written = [str(out)] + ([str(out.parent / CALIBRATION_FILE)] if draft.calibration else [])
    console.print(f"wrote {escape(', '.join(written))}", soft_wrap=True)
    for note in draft.notes:
        console.print(f"- {escape(note)}", soft_wrap=True)
    console.print(f"then: usvfast inspect {escape(str(out))} && usvfast run {escape(str(out))}")
