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
- navigation: every ``nmea_msgs/Sentence`` and ``sensor_msgs/NavSatFix`` topic;
- attitude: the first ``sensor_msgs/Imu`` topic.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

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
_IMU = "sensor_msgs/msg/Imu"
#: The calibration file written beside the config.
CALIBRATION_FILE = "camera_info.yaml"
_WATERLINE = "waterline_height = 0.3  # MEASURE: the body origin's height above the water, m"


@dataclass
class Draft:
    """A drafted config: `text` (TOML), the camera calibration read from the bag (None
    without a CameraInfo topic or camera), the streams chosen as (id, topic, message type),
    and `notes`: what the user still has to do or check."""

    text: str
    calibration: CameraModel | None
    streams: list[tuple[str, str, str]]
    notes: list[str] = field(default_factory=list)


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


def _velodyne_model(bag: Path, topic: str) -> str | None:
    """The model name of the first packet's factory byte on a VelodyneScan topic."""
    msg = _first_message(bag, topic)
    packets = getattr(msg, "packets", None)
    if not packets:
        return None
    data = np.asarray(packets[0].data, dtype=np.uint8)
    return VELODYNE_MODELS.get(int(data[1205])) if data.size > 1205 else None


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


def _stream_lines(sid: str, bag: str, topic: str, count: int, extra: list[str]) -> list[str]:
    return [
        "",
        "[[stream]]",
        f'id = "{sid}"',
        'type = "bag"',
        f'path = "{bag}"',
        f'topic = "{topic}"  # {count} messages',
        *extra,
    ]


def draft_config(bag: Path | str, config_dir: Path | str) -> Draft:
    """Draft the config of the bag at `bag` for a config file in `config_dir` (the bag's path
    is written relative to it). Raises ValueError naming the bag when it is not a readable
    bag or holds neither a LiDAR nor a camera topic, or no navigation topic."""
    from usvfast.nav.bags import bag_topics

    bag = Path(bag)
    topics = {name: info for name, info in bag_topics(bag).items() if info.count > 0}
    listing = ", ".join(f"{n} ({i.msgtype})" for n, i in sorted(topics.items())) or "none"

    def of(*types: str) -> list[str]:
        return sorted(n for n, i in topics.items() if i.msgtype in types)

    lidars, images, infos = of(_VELODYNE, _CLOUD), of(_COMPRESSED, _IMAGE), of(_INFO)
    navs, imus = of(*_NAV), of(_IMU)
    if not navs:
        raise ValueError(
            f"bag: {bag} has no navigation topic (nmea_msgs/Sentence or sensor_msgs/NavSatFix) "
            f"with messages; topics: {listing}"
        )
    if not lidars and not images:
        raise ValueError(
            f"bag: {bag} has no LiDAR (VelodyneScan, PointCloud2) or camera (CompressedImage, "
            f"Image) topic with messages; topics: {listing}"
        )
    # relative to the config when the bag lies in its folder, else absolute
    rel = Path(os.path.relpath(bag.resolve(), Path(config_dir).resolve())).as_posix()
    if rel.startswith("../"):
        rel = bag.resolve().as_posix()
    notes: list[str] = []
    streams: list[tuple[str, str, str]] = []
    body: list[str] = []

    def add(sid: str, topic: str, extra: list[str]) -> None:
        streams.append((sid, topic, topics[topic].msgtype))
        body.extend(_stream_lines(sid, rel, topic, topics[topic].count, extra))

    nav_ids = [f"gnss{i + 1}" if len(navs) > 1 else "gnss" for i in range(len(navs))]
    for sid, topic in zip(nav_ids, navs, strict=True):
        add(sid, topic, _mount_lines("the antenna the receiver reports"))
    if imus:
        add("imu", imus[0], [])
    for i, topic in enumerate(lidars):
        extra = ['sensor = "lidar"']
        if topics[topic].msgtype == _VELODYNE:
            model = _velodyne_model(bag, topic)
            if model is None:
                notes.append(f"{topic}: unknown Velodyne model; SET the stream's model")
                extra.append('model = "VLP-16"  # SET: the sensor model')
            else:
                extra.append(f'model = "{model}"  # from the packets\' factory byte')
        sid = f"lidar{i + 1}" if len(lidars) > 1 else "lidar"
        add(sid, topic, extra + _mount_lines("the LiDAR"))
    calibration = None
    camera: list[str] = []
    if images:

        def rank(t: str) -> tuple:
            near = max((_common_prefix(t, i) for i in infos), default=0)
            return (-near, topics[t].msgtype != _COMPRESSED, -topics[t].count, t)

        image = min(images, key=rank)
        add("camera", image, ['sensor = "camera"', *_mount_lines("the camera's optical centre")])
        if len(images) > 1:
            body.append(f"# other image topics: {', '.join(t for t in images if t != image)}")
        info = max(infos, key=lambda i: _common_prefix(image, i), default=None)
        msg = _first_message(bag, info) if info is not None else None
        calibration = _camera_model(msg) if msg is not None else None
        camera = ["", "[camera]"]
        if calibration is not None:
            camera.append(f'calibration = "{CALIBRATION_FILE}"  # from {info}')
        else:
            notes.append(
                "no usable CameraInfo in the bag: the camera stays off until you give "
                "camera.calibration (a camera_info YAML) and set camera.enabled = true"
            )
            camera.append("enabled = false  # SET: true once calibrated")
            camera.append('# calibration = "camera_info.yaml"')
        camera += [
            _WATERLINE,
            "",
            "[detector]",
            'backend = "none"  # SET: "onnx" (OpenVINO / OpenCV DNN) or "torch" (YOLO weights)',
            '# weights = "my_detector.onnx"',
        ]
        notes.append("the camera runs no detector until you set detector.backend and weights")
    nav_value = f'"{nav_ids[0]}"' if len(nav_ids) == 1 else str(nav_ids).replace("'", '"')
    head = [
        f"# Drafted by `usvfast init` from {rel}. Edit every MEASURE and SET, then",
        "# `usvfast inspect` this file and `usvfast run` it.",
        'preset = "thesis"  # the thesis\'s camera filters and tracker (Codes 5.5, 5.7)',
        "",
        "[recording]",
        f"navigation = {nav_value}",
    ]
    if imus:
        head.append('attitude = "imu"')
    if lidars:
        head.append("# heading_calibration_s = 60.0  # the heading's error, from the LiDAR's quays")
    lidar = []
    if lidars:
        lidar = ["", "[lidar]", _WATERLINE]
    notes.insert(0, "measure every sensor's mount (lever_arm, ypr_deg) and the waterline heights")
    text = "\n".join(head + body + lidar + camera) + "\n"
    return Draft(text, calibration, streams, notes)


def write_draft(bag: Path | str, out: Path | str, *, force: bool = False) -> Draft:
    """Draft the config of `bag` (:func:`draft_config`) into the file `out` and its camera
    calibration into `camera_info.yaml` beside it; check that the config loads and read its
    navigation once (a missing position fix or heading becomes a note). Raises ValueError
    naming `out` when it (or the calibration file) exists and `force` is False."""
    from usvfast.pipeline.config import load_config
    from usvfast.pipeline.pose import NavigationError, NavTrack

    out = Path(out)
    calib = out.parent / CALIBRATION_FILE
    draft = draft_config(bag, out.parent)
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
    bag: Annotated[Path, typer.Argument(help="ROS 1 .bag file or ROS 2 bag folder/.db3/.mcap.")],
    out: Annotated[
        Path, typer.Option(help="The config file to write (camera_info.yaml goes beside it).")
    ] = Path("recording.toml"),
    force: Annotated[bool, typer.Option(help="Overwrite existing files.")] = False,
) -> None:
    """Draft a pipeline config for a bag: its LiDAR, camera, GNSS and IMU topics as streams,
    the camera calibration from its CameraInfo, placeholders for the mounts to measure."""
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    draft = write_draft(bag, out, force=force)
    console = Console()
    table = Table(title=f"streams drafted from {escape(str(bag))}")
    for name in ("id", "topic", "message type"):
        table.add_column(name)
    for sid, topic, msgtype in draft.streams:
        table.add_row(sid, escape(topic), msgtype)
    console.print(table)
    written = [str(out)] + ([str(out.parent / CALIBRATION_FILE)] if draft.calibration else [])
    console.print(f"wrote {escape(', '.join(written))}", soft_wrap=True)
    for note in draft.notes:
        console.print(f"- {escape(note)}", soft_wrap=True)
    console.print(f"then: usvfast inspect {escape(str(out))} && usvfast run {escape(str(out))}")
