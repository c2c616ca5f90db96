"""Write a simulated harbour recording: one rosbag2 with the VLP-16 packets, the camera's
JPEG frames and calibration, the GNSS/heading NMEA and the IMU; optionally the thesis's D1
layout (pcap + mp4 + NMEA log); the ground truth, the scene, and the pipeline configs.

Layout of DIR (see `simulate`):

    recording.toml       the pipeline config that runs the bag
    bag/                 rosbag2 (sqlite3, zstd-compressed messages)
    camera_info.yaml     the camera's calibration (ROS camera_info YAML)
    truth.csv            time,object_id,kind,north,east,lat,lon   (every object, every 0.1 s;
                         object_id an int, its name in scene.json "objects")
    visibility.csv       what the LiDAR and the camera physically saw of each object:
                         returns per rotation, visible pixels and box size per frame
                         (`usvfast.sim.visibility`)
    origin.json          {"lat", "lon", "height"} of the NED origin
    scene.json           walls, moored boats, the USV's true path (1 Hz)
    d1/lidar.pcap, d1/camera.mp4, d1/camera_times.csv, d1/gnss.nmea, recording-d1.toml

Everything is a function of the seed: the recording starts at a fixed UNIX time (`EPOCH`),
no wall-clock time or host name is written, so two runs give identical bytes.
"""

from __future__ import annotations

import csv
import heapq
import json
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from usvfast import geodesy
from usvfast.lidar.readers import lidar_typestore, make_header
from usvfast.nav.bags import EXTRA_MSG_DEFINITIONS
from usvfast.sim.camera import (
    HarbourRenderer,
    default_camera,
)
from usvfast.sim.configs import TOPICS, write_configs
from usvfast.sim.gnss import GnssErrors, simulate_gnss, simulate_imu
from usvfast.sim.scene import World, make_world
from usvfast.sim.velodyne import Vlp16Recorder, udp_frame
from usvfast.sim.visibility import VisibilityLog

#: UNIX time of the start of every simulated recording: 2023-06-16 10:00:00 UTC (the day the
#: thesis recorded its dataset D3 at Brattørkaia).
EPOCH = 1_686_909_600.0


@dataclass
class SimulationOptions:
    """What to simulate: seed, duration (s), camera frame size and JPEG quality (0–100),
    rates (Hz), whether to also write the D1 layout, whether the LiDAR sees the buildings
    behind the quays (`lidar_buildings`; off makes the bag much smaller), and the GNSS error
    model. `zstd_level` (1–22) compresses every bag message (rosbag2 message compression)."""

    seed: int = 0
    duration: float = 60.0
    width: int = 640
    height: int = 360
    jpeg_quality: int = 70
    camera_rate: float = 10.0
    imu_rate: float = 50.0
    d1: bool = False
    lidar_buildings: bool = True
    zstd_level: int = 9
    gnss: GnssErrors = field(default_factory=GnssErrors)

    def __post_init__(self) -> None:
        if not 0 < self.duration <= 3600:
            raise ValueError(f"duration: expected 0 < duration <= 3600 s, got {self.duration}")
        if not 1 <= self.jpeg_quality <= 100:
            raise ValueError(f"jpeg_quality: expected 1..100, got {self.jpeg_quality}")
        if not 1 <= self.zstd_level <= 22:
            raise ValueError(f"zstd_level: expected 1..22, got {self.zstd_level}")
        if not 1.0 <= self.camera_rate <= 30.0:
            raise ValueError(f"camera_rate: expected 1..30 Hz, got {self.camera_rate}")


@dataclass
class _Msg:
    record_time: float  # when the recorder received it (bag timestamp), UNIX s
    topic: str
    build: Callable[[], Any]  # -> the message (built lazily, in time order)
    raw: dict = field(default_factory=dict)


def _stamp(store, t: float):
    time_t = store.types["builtin_interfaces/msg/Time"]
    sec = int(np.floor(t))
    return time_t(sec=sec, nanosec=min(round((t - sec) * 1e9), 999_999_999))


def _typestore():
    from rosbags.typesys import get_types_from_msg

    store = lidar_typestore()
    name = "nmea_msgs/msg/Sentence"
    store.register(get_types_from_msg(EXTRA_MSG_DEFINITIONS[name], name))
    return store


class _Sim:
    """The sensors of one simulated world, as time-ordered message streams."""

    def __init__(self, opts: SimulationOptions, world: World) -> None:
        self.opts = opts
        self.world = world
        self.store = _typestore()
        self.camera = default_camera(opts.width, opts.height)
        self.renderer = HarbourRenderer(world, self.camera)
        self.lidar = Vlp16Recorder(
            world, start=EPOCH + 0.0123, seed=opts.seed, buildings=opts.lidar_buildings
        )
        self.gnss, self.gnss_truth = simulate_gnss(
            world, EPOCH, opts.duration, opts.gnss, seed=opts.seed
        )
        self.imu = simulate_imu(world, EPOCH, opts.duration, rate=opts.imu_rate, seed=opts.seed)
        self.end = EPOCH + opts.duration
        self.tee: Any = None  # a _D1Writer that also receives the scans and frames
        self.visibility = VisibilityLog(world.truth_ids())
        self._rmc = [r for r in self.gnss if r.kind == "RMC"]

    def last_rmc(self, t: float) -> str:
        """The last RMC sentence received before `t` (for the LiDAR's position packets)."""
        i = int(np.searchsorted([r.stamp for r in self._rmc], t)) - 1
        return self._rmc[max(i, 0)].sentence.replace("$GNRMC", "$GPRMC", 1) if self._rmc else ""

    # --- streams -----------------------------------------------------------------------
    def scans(self) -> Iterator[Any]:
        """VLP-16 scans with their stamps until the end of the recording."""
        while True:
            scan = self.lidar.next_scan()
            if scan.stamp > self.end:
                return
            self.visibility.lidar(scan.stamp, scan.object_ids)
            yield scan

    def frame_times(self) -> np.ndarray:
        """Exposure times of the camera frames, UNIX s."""
        n = int(np.floor((self.opts.duration - 0.05) * self.opts.camera_rate + 1e-9)) + 1
        return EPOCH + 0.05 + np.arange(n) / self.opts.camera_rate

    def frames(self) -> Iterator[tuple[float, np.ndarray]]:
        for t in self.frame_times():
            image, boxes = self.renderer.render(float(t - EPOCH), min_pixels=1)
            self.visibility.camera(float(t), boxes)
            yield float(t), image

    def bag_messages(self) -> Iterator[_Msg]:
        """Every bag message in record-time order."""
        return heapq.merge(
            self._lidar_msgs(),
            self._image_msgs(),
            self._info_msgs(),
            self._nmea_msgs(),
            self._imu_msgs(),
            key=lambda m: (m.record_time, m.topic),
        )

    def _lidar_msgs(self) -> Iterator[_Msg]:
        store = self.store
        scan_t = store.types["velodyne_msgs/msg/VelodyneScan"]
        pkt_t = store.types["velodyne_msgs/msg/VelodynePacket"]
        for scan in self.scans():
            if self.tee is not None:
                self.tee.scan(scan, self.last_rmc)

            def build(scan=scan):
                packets = [
                    pkt_t(stamp=_stamp(store, float(t)), data=row.copy())
                    for t, row in zip(scan.packet_times, scan.packets, strict=True)
                ]
                header = make_header(store, scan.stamp, "velodyne")
                return scan_t(header=header, packets=packets)  # pyright: ignore[reportArgumentType]

            yield _Msg(scan.stamp + 0.004, TOPICS["lidar"][0], build)

    def _image_msgs(self) -> Iterator[_Msg]:
        store = self.store
        img_t = store.types["sensor_msgs/msg/CompressedImage"]
        quality = [cv2.IMWRITE_JPEG_QUALITY, self.opts.jpeg_quality]
        for t, image in self.frames():
            if self.tee is not None:
                self.tee.frame(t, image)
            ok, buf = cv2.imencode(".jpg", image, quality)
            if not ok:  # pragma: no cover - OpenCV always encodes a uint8 BGR image
                raise RuntimeError("cv2.imencode failed")

            def build(t=t, buf=buf):
                header = make_header(store, t, "camera")
                return img_t(header=header, format="jpeg", data=buf.reshape(-1))

            yield _Msg(t + 0.03, TOPICS["image"][0], build)

    def _info_msgs(self) -> Iterator[_Msg]:
        store = self.store
        info_t = store.types["sensor_msgs/msg/CameraInfo"]
        roi_t = store.types["sensor_msgs/msg/RegionOfInterest"]
        cam = self.camera
        k = cam.camera_matrix
        p = np.hstack([k, np.zeros((3, 1))])
        for t in EPOCH + 0.05 + np.arange(int(np.floor(self.opts.duration - 0.05)) + 1):

            def build(t=float(t)):
                return info_t(
                    header=make_header(store, t, "camera"),
                    height=cam.image_size[1],
                    width=cam.image_size[0],
                    distortion_model="plumb_bob",
                    d=cam.dist_coeffs.astype(np.float64),
                    k=k.reshape(-1).astype(np.float64),
                    r=np.eye(3).reshape(-1),
                    p=p.reshape(-1),
                    binning_x=0,
                    binning_y=0,
                    roi=roi_t(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
                )

            yield _Msg(float(t) + 0.031, TOPICS["camera_info"][0], build)

    def _nmea_msgs(self) -> Iterator[_Msg]:
        store = self.store
        sent_t = store.types["nmea_msgs/msg/Sentence"]
        for rec in self.gnss:

            def build(rec=rec):
                return sent_t(header=make_header(store, rec.stamp, "gnss"), sentence=rec.sentence)

            yield _Msg(rec.stamp, TOPICS["nmea"][0], build)

    def _imu_msgs(self) -> Iterator[_Msg]:
        store = self.store
        imu_t = store.types["sensor_msgs/msg/Imu"]
        quat_t = store.types["geometry_msgs/msg/Quaternion"]
        vec_t = store.types["geometry_msgs/msg/Vector3"]
        imu = self.imu
        cov_q = np.diag([np.radians(0.05) ** 2] * 3).reshape(-1)
        cov_w = np.diag([0.002**2] * 3).reshape(-1)
        cov_a = np.diag([0.02**2] * 3).reshape(-1)
        for i, t in enumerate(imu.time):

            def build(i=i, t=float(t)):
                q = imu.orientation_xyzw[i]
                w = imu.angular_velocity[i]
                a = imu.linear_acceleration[i]
                return imu_t(
                    header=make_header(store, t, "imu"),
                    orientation=quat_t(x=q[0], y=q[1], z=q[2], w=q[3]),
                    orientation_covariance=cov_q,
                    angular_velocity=vec_t(x=w[0], y=w[1], z=w[2]),
                    angular_velocity_covariance=cov_w,
                    linear_acceleration=vec_t(x=a[0], y=a[1], z=a[2]),
                    linear_acceleration_covariance=cov_a,
                )

            yield _Msg(float(t) + 0.002, TOPICS["imu"][0], build)


# --------------------------------------------------------------------------------------
# writers
# --------------------------------------------------------------------------------------
def _writer(path: Path, level: int):
    """A rosbags rosbag2 Writer (version 8, sqlite3) compressing each message with zstd at
    `level` (rosbags itself uses zstd's default level)."""
    from rosbags.rosbag2 import Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

    try:
        from compression import zstd  # Python >= 3.14  # pyright: ignore[reportMissingImports]
    except ImportError:
        from backports import zstd  # rosbags' own dependency before 3.14

    class LevelWriter(Writer):
        def write(self, connection, timestamp: int, data) -> None:
            mode, self.compression_mode = self.compression_mode, CompressionMode.NONE
            try:
                super().write(connection, timestamp, zstd.compress(bytes(data), level=level))
            finally:
                self.compression_mode = mode

    writer = LevelWriter(path, version=8)
    writer.set_compression(CompressionMode.MESSAGE, CompressionFormat.ZSTD)
    return writer


def _write_bag(sim: _Sim, path: Path, progress: Callable[[float], None] | None) -> dict[str, int]:
    store = sim.store
    writer = _writer(path, sim.opts.zstd_level)
    counts: dict[str, int] = {}
    with writer:
        conns = {
            topic: writer.add_connection(topic, msgtype, typestore=store)
            for topic, msgtype in TOPICS.values()
        }
        types = {topic: msgtype for topic, msgtype in TOPICS.values()}
        for msg in sim.bag_messages():
            raw = store.serialize_cdr(msg.build(), types[msg.topic])
            writer.write(conns[msg.topic], round(msg.record_time * 1e9), raw)
            counts[msg.topic] = counts.get(msg.topic, 0) + 1
            if progress is not None:
                progress(msg.record_time - EPOCH)
    return counts


def write_truth(world: World, path: Path, duration: float) -> int:
    """truth.csv: every truth object every 0.1 s from the start; returns the row count."""
    k = np.arange(int(np.floor(duration * 10 + 1e-9)) + 1)
    rel = k / 10.0
    lat0, lon0, h0 = world.origin
    rows = 0
    with open(path, "w", newline="") as fh:
        out = csv.writer(fh, lineterminator="\n")
        out.writerow(["time", "object_id", "kind", "north", "east", "lat", "lon"])
        per = world.truth_at(rel)
        ids = world.truth_ids()
        geo = [geodesy.ned2geodetic(n, e, np.zeros_like(n), lat0, lon0, h0) for _, _, n, e in per]
        for i, t in enumerate(rel):
            for (oid, kind, n, e), (lat, lon, _) in zip(per, geo, strict=True):
                out.writerow(
                    [
                        f"{EPOCH + t:.1f}",
                        ids[oid],
                        kind,
                        f"{n[i]:.4f}",
                        f"{e[i]:.4f}",
                        f"{lat[i]:.9f}",
                        f"{lon[i]:.9f}",
                    ]
                )
                rows += 1
    return rows


def write_scene(world: World, path: Path, duration: float) -> None:
    """scene.json: walls (polylines, NED m), moored boats, the USV's true path at 1 Hz
    ([UNIX s, north m, east m, heading deg]), and the moving objects (id = truth.csv
    object_id, name, kind, size: length, width, top above the water m)."""
    rel = np.arange(int(np.floor(duration + 1e-9)) + 1, dtype=np.float64)
    n, e, h = world.usv.pose(rel)
    data = {
        "walls": [np.round(w, 4).tolist() for w in world.walls],
        "moored": [
            {
                "id": world.truth_ids()[b.object_id],
                "name": b.object_id,
                "north": round(float(b.box.center[0]), 4),
                "east": round(float(b.box.center[1]), 4),
                "length": round(float(b.box.length), 4),
                "width": round(float(b.box.width), 4),
                "heading_deg": round(float(np.degrees(b.box.yaw)), 4),
            }
            for b in world.moored
        ],
        "usv": [
            [
                EPOCH + float(t),
                round(float(a), 4),
                round(float(b), 4),
                round(float(np.degrees(c)), 4),
            ]
            for t, a, b, c in zip(rel, n, e, h, strict=True)
        ],
        "objects": [
            {
                "id": world.truth_ids()[m.object_id],
                "name": m.object_id,
                "kind": m.kind,
                "size": [round(float(v), 4) for v in m.size],
            }
            for m in world.movers
        ],
        "seed": world.seed,
        "epoch": EPOCH,
    }
    path.write_text(json.dumps(data, indent=1) + "\n")


class _D1Writer:
    """The thesis's D1 layout: Velodyne pcap (Ethernet/IPv4/UDP as captured on the laptop),
    mp4 video with a frame,time CSV, and the NMEA log as text."""

    def __init__(self, folder: Path, size: tuple[int, int], fps: float) -> None:
        try:
            import dpkt
        except ImportError as exc:  # pragma: no cover - dpkt ships with the sim/lidar extras
            raise RuntimeError(
                "d1: writing the pcap needs dpkt (pip install usvfast[sim])"
            ) from exc

        folder.mkdir(parents=True, exist_ok=False)
        self.folder = folder
        self._pcap_fh = open(folder / "lidar.pcap", "wb")
        self.pcap = dpkt.pcap.Writer(self._pcap_fh, snaplen=1600, linktype=dpkt.pcap.DLT_EN10MB)
        fourcc = cv2.VideoWriter_fourcc(*"mp4v")  # pyright: ignore[reportAttributeAccessIssue]
        self.video = cv2.VideoWriter(str(folder / "camera.mp4"), fourcc, fps, size)
        if not self.video.isOpened():  # pragma: no cover - OpenCV builds without a writer
            raise RuntimeError("OpenCV cannot write mp4 (mp4v) video here")
        self._times = open(folder / "camera_times.csv", "w", newline="")
        self._times.write("frame,time\n")
        self.frames = 0
        self._ip_id = 0
        self._next_position = EPOCH + 0.5

    def _udp(self, payload: bytes, port: int) -> bytes:
        frame = udp_frame(payload, port, self._ip_id)
        self._ip_id += 1
        return frame

    def scan(self, scan: Any, gnss_text: Callable[[float], str]) -> None:
        """Write a scan's packets, stamped when the laptop received them (the packet's last
        firing + 0.1 ms), and a position packet each second."""
        for t, row in zip(scan.packet_times, scan.packets, strict=True):
            t_rx = float(t) + 24 * 55.296e-6 + 1e-4
            while self._next_position <= t_rx:
                self.pcap.writepkt(
                    self._udp(_position_packet(self._next_position, gnss_text), 8308),
                    ts=self._next_position,
                )
                self._next_position += 1.0
            self.pcap.writepkt(self._udp(bytes(row), 2368), ts=t_rx)

    def frame(self, t: float, image: np.ndarray) -> None:
        self.video.write(image)
        self._times.write(f"{self.frames},{t:.6f}\n")
        self.frames += 1

    def nmea(self, sentences: list[str]) -> None:
        (self.folder / "gnss.nmea").write_text("".join(s + "\r\n" for s in sentences))

    def close(self) -> None:
        self.video.release()
        self._times.close()
        self.pcap.close()


def _position_packet(t: float, gnss_text: Callable[[float], str]) -> bytes:
    """A 512-byte VLP-16 position packet: timestamp (µs past the hour) at byte 198, PPS locked
    at 202, the last $GPRMC sentence at 206 (VLP-16 manual, "Position Packet")."""
    out = bytearray(512)
    us = round((t % 3600.0) * 1e6) % 3_600_000_000
    out[198:202] = int(us).to_bytes(4, "little")
    out[202] = 2
    text = gnss_text(t).encode("ascii")[:72]
    out[206 : 206 + len(text)] = text
    return bytes(out)


@dataclass
class SimulationResult:
    """What `simulate` wrote: the output folder, message counts per bag topic, truth rows, the
    world, the per-epoch GNSS truth, and the rows of visibility.csv."""

    out: Path
    counts: dict[str, int]
    truth_rows: int
    world: World
    gnss_truth: Any
    visibility_rows: int = 0


def simulate(
    out: Path | str,
    options: SimulationOptions | None = None,
    *,
    progress: Callable[[float], None] | None = None,
) -> SimulationResult:
    """Simulate a harbour recording into the new folder `out` (see the module doc).

    `progress(seconds_done)` is called as messages are written. Raises ValueError when `out`
    exists and is not an empty folder.
    """
    opts = options or SimulationOptions()
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"out: {out} exists and is not an empty folder")
    out.mkdir(parents=True, exist_ok=True)
    world = make_world(opts.seed, opts.duration)
    sim = _Sim(opts, world)
    d1 = None
    if opts.d1:
        d1 = _D1Writer(out / "d1", sim.camera.image_size, opts.camera_rate)
        d1.nmea([r.sentence for r in sim.gnss])
        sim.tee = d1
    try:
        counts = _write_bag(sim, out / "bag", progress)
    finally:
        if d1 is not None:
            d1.close()
    sim.camera.save(out / "camera_info.yaml")
    lat, lon, h = world.origin
    (out / "origin.json").write_text(json.dumps({"lat": lat, "lon": lon, "height": h}) + "\n")
    write_scene(world, out / "scene.json", opts.duration)
    rows = write_truth(world, out / "truth.csv", opts.duration)
    seen = sim.visibility.write(out / "visibility.csv")
    write_configs(out, world, opts.seed, opts.d1)
    return SimulationResult(out, counts, rows, world, sim.gnss_truth, seen)
