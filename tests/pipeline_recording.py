"""A small multi-sensor recording for the pipeline tests and bench, built from existing pieces:
the VLP-16 simulator in a harbour scene (PointCloud2), NMEA GGA/RMC/HDT sentences
(nmea_msgs/Sentence), an IMU (sensor_msgs/Imu, level) and camera frames rendered through a
distorted pinhole model (CompressedImage jpeg; floating objects drawn as orange discs), all in
one rosbag2, plus the config that runs it and the ground truth.

Nothing here is part of the library. `build(dir)` returns a `Built` with the paths and the
truth; `disc_detector` is the matching camera detector (colour threshold -> boxes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import reduce
from operator import xor
from pathlib import Path

import cv2
import numpy as np

from usvfast import geodesy
from usvfast.camera.calibration import CameraModel
from usvfast.camera.georef import mount_rotation
from usvfast.lidar.readers import lidar_typestore, make_header, points_to_pointcloud2
from usvfast.lidar.simulator import FLOAT, Cylinder, VLP16Simulator, harbour_scene

EPOCH = 1_700_000_000.0
ORIGIN = (63.44, 10.40, 0.0)
SPEED = 0.5  # m/s north
START_N = -6.0
WATERLINE = 0.5  # vessel reference point above the water, m
LIDAR_LEVER = (0.5, 0.0, -0.7)  # sensor 1.2 m above the water
CAMERA_LEVER = (0.6, 0.0, -1.0)  # camera 1.5 m above the water
CAMERA_YPR = (0.0, -12.0, 0.0)
GNSS_LEVER = (-0.94, 0.0, 0.0)
ORANGE = (0, 128, 255)  # BGR


def camera_model() -> CameraModel:
    """640x360 pinhole, f = 400 px, mild barrel distortion."""
    k = np.array([[400.0, 0.0, 320.0], [0.0, 400.0, 180.0], [0.0, 0.0, 1.0]])
    return CameraModel(k, np.array([-0.05, 0.01, 0.0, 0.0, 0.0]), (640, 360))


def _nmea(body: str) -> str:
    return f"${body}*{reduce(xor, body.encode(), 0):02X}"


def _hms(t: float) -> str:
    s = t % 86400
    return f"{int(s // 3600):02d}{int(s % 3600 // 60):02d}{s % 60:05.2f}"


def _ddmm(value: float, lat: bool) -> str:
    hemi = ("N" if value >= 0 else "S") if lat else ("E" if value >= 0 else "W")
    v = abs(value)
    d = int(v)
    m = (v - d) * 60
    return f"{d:02d}{m:09.6f},{hemi}" if lat else f"{d:03d}{m:09.6f},{hemi}"


def nmea_sentences(t: float, lat: float, lon: float, heading_deg: float) -> list[str]:
    """GGA, RMC and HDT sentences of one fix at UNIX time t."""
    import datetime as dt

    day = dt.datetime.fromtimestamp(t, dt.timezone.utc).strftime("%d%m%y")
    return [
        _nmea(f"GPGGA,{_hms(t)},{_ddmm(lat, True)},{_ddmm(lon, False)},1,12,0.8,10.0,M,40.0,M,,"),
        _nmea(f"GPRMC,{_hms(t)},A,{_ddmm(lat, True)},{_ddmm(lon, False)},0.97,0.0,{day},,,A"),
        _nmea(f"GPHDT,{heading_deg:.2f},T"),
    ]


def vessel(t: float) -> np.ndarray:
    """(north, east, heading) of the reference point at t seconds after EPOCH."""
    return np.array([START_N + SPEED * t, 0.0, 0.0])


def render(model: CameraModel, pose: np.ndarray, floats: list[Cylinder]) -> np.ndarray:
    """Sky, sea and orange discs standing on the water at each float's position."""
    w, h = model.image_size
    img = np.empty((h, w, 3), np.uint8)
    img[:] = (120, 80, 40)
    img[: h // 4] = (230, 200, 170)
    r_bc = mount_rotation(CAMERA_YPR)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    for f in floats:
        dn, de = f.center[0] - pose[0], f.center[1] - pose[1]
        body = np.array([c * dn + s * de, -s * dn + c * de, WATERLINE]) - np.array(CAMERA_LEVER)
        cam = r_bc.T @ body
        if cam[2] < 1.0:
            continue
        (u, v) = model.project(cam.reshape(1, 3))[0]
        r = max(2.0, 400.0 * f.radius / cam[2])
        if not (0 <= u < w and r < v < h):
            continue
        cv2.circle(img, (round(u), round(v - r)), round(r), ORANGE, -1)
    return img


def disc_detector(images: list[np.ndarray]) -> list[tuple[np.ndarray, np.ndarray]]:
    """Boxes (k, 4) xyxy and scores (k,) of the orange discs of each image."""
    out = []
    for im in images:
        mask = cv2.inRange(im, (0, 100, 200), (40, 160, 255))
        n, _, stats, _ = cv2.connectedComponentsWithStats(mask)
        boxes = [[x, y, x + bw, y + bh] for x, y, bw, bh, area in stats[1:n].tolist() if area >= 4]
        b = np.array(boxes, float).reshape(-1, 4)
        out.append((b, np.full(len(b), 0.9)))
    return out


@dataclass
class Built:
    """Paths of a built recording and its truth: floats (k, 2) NED positions (static),
    boats (m, 2) centres of the moored boats, duration s."""

    root: Path
    config: Path
    bag: Path
    truth: Path
    floats: np.ndarray
    boats: np.ndarray
    duration: float


def build(
    root: Path,
    *,
    duration: float = 12.0,
    seed: int = 3,
    camera: bool = True,
    gnss: bool = True,
    damaged_images: int = 0,
) -> Built:
    """Write the recording into `root`: bag/, camera_info.yaml, recording.toml, truth.csv."""
    from rosbags.rosbag2 import Writer

    root.mkdir(parents=True, exist_ok=True)
    scene = harbour_scene(seed=seed, floats=5, boats=2, near=3.5, far=9.0)
    floats = [o for o in scene.objects if getattr(o, "kind", "") == FLOAT]
    boats = [o for o in scene.objects if getattr(o, "kind", "") == "boat"]
    # Floats from the simulator are boxes or cylinders; draw them all as discs.
    discs = [
        o if isinstance(o, Cylinder) else Cylinder(o.center, 0.2, 0.0, o.top, FLOAT) for o in floats
    ]
    sim = VLP16Simulator(
        scene, mount_height=WATERLINE - LIDAR_LEVER[2], lever_arm=LIDAR_LEVER[:2], seed=seed
    )
    store = lidar_typestore(ros1=False)
    from usvfast.nav.bags import bag_typestore

    nav_store = bag_typestore()
    model = camera_model()
    model.save(root / "camera_info.yaml")
    bag = root / "bag"
    with Writer(bag, version=8) as w:
        c_lidar = w.add_connection(
            "/velodyne_points", "sensor_msgs/msg/PointCloud2", typestore=store
        )
        c_nmea = w.add_connection("/gnss/nmea", "nmea_msgs/msg/Sentence", typestore=nav_store)
        c_imu = w.add_connection("/imu/data", "sensor_msgs/msg/Imu", typestore=nav_store)
        c_cam = w.add_connection(
            "/camera/image_raw/compressed", "sensor_msgs/msg/CompressedImage", typestore=nav_store
        )
        types = nav_store.types
        bad_left = damaged_images
        for k in range(int(duration * 10) + 1):
            t_rel = k * 0.1
            t = EPOCH + t_rel
            pose = vessel(t_rel)
            ns = round(t * 1e9)
            if gnss:
                lever = np.array(GNSS_LEVER)
                ant_n = pose[0] + math.cos(pose[2]) * lever[0] - math.sin(pose[2]) * lever[1]
                ant_e = pose[1] + math.sin(pose[2]) * lever[0] + math.cos(pose[2]) * lever[1]
                lat, lon, _ = geodesy.ned2geodetic(ant_n, ant_e, 0.0, *ORIGIN)
                for sentence in nmea_sentences(t, float(lat), float(lon), math.degrees(pose[2])):
                    msg = types["nmea_msgs/msg/Sentence"](
                        header=make_header(nav_store, t, "gnss"), sentence=sentence
                    )
                    w.write(c_nmea, ns, nav_store.serialize_cdr(msg, "nmea_msgs/msg/Sentence"))
            for j in range(5):  # IMU at 50 Hz, level (quaternion identity)
                ti = t + j * 0.02
                q = types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
                v3 = types["geometry_msgs/msg/Vector3"]
                imu = types["sensor_msgs/msg/Imu"](
                    header=make_header(nav_store, ti, "imu"),
                    orientation=q,
                    orientation_covariance=np.zeros(9),
                    angular_velocity=v3(x=0.0, y=0.0, z=0.0),
                    angular_velocity_covariance=np.zeros(9),
                    linear_acceleration=v3(x=0.0, y=0.0, z=9.81),
                    linear_acceleration_covariance=np.zeros(9),
                )
                w.write(c_imu, round(ti * 1e9), nav_store.serialize_cdr(imu, "sensor_msgs/msg/Imu"))
            frame = sim.scan(pose, t).frame
            pc = points_to_pointcloud2(t, frame.points, "velodyne", store)
            w.write(c_lidar, ns, store.serialize_cdr(pc, "sensor_msgs/msg/PointCloud2"))
            if camera:
                tc = t + 0.05
                img = render(model, vessel(t_rel + 0.05), discs)
                data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].ravel()
                if bad_left and k % 7 == 3:
                    data = np.frombuffer(b"not a jpeg", np.uint8)
                    bad_left -= 1
                ci = types["sensor_msgs/msg/CompressedImage"](
                    header=make_header(nav_store, tc, "camera"), format="jpeg", data=data
                )
                w.write(
                    c_cam,
                    round(tc * 1e9),
                    nav_store.serialize_cdr(ci, "sensor_msgs/msg/CompressedImage"),
                )
    config = root / "recording.toml"
    config.write_text(
        f"""
preset = "thesis"
[recording]
name = "pipeline test seed {seed}"
navigation = "gnss"
attitude = "imu"
origin = [{ORIGIN[0]}, {ORIGIN[1]}, 0.0]

[[stream]]
id = "gnss"
type = "bag"
path = "bag"
topic = "/gnss/nmea"
[stream.mount]
lever_arm = {list(GNSS_LEVER)}

[[stream]]
id = "imu"
type = "bag"
path = "bag"
topic = "/imu/data"

[[stream]]
id = "lidar"
type = "bag"
path = "bag"
topic = "/velodyne_points"
sensor = "lidar"
[stream.mount]
lever_arm = {list(LIDAR_LEVER)}
ypr_deg = [0.0, 0.0, 0.0]

[[stream]]
id = "camera"
type = "bag"
path = "bag"
topic = "/camera/image_raw/compressed"
sensor = "camera"
[stream.mount]
lever_arm = {list(CAMERA_LEVER)}
ypr_deg = {list(CAMERA_YPR)}

[lidar]
waterline_height = {WATERLINE}
# A cluster's centroid is that of the face the LiDAR sees: up to half an object (0.15 m) off.
min_position_std = 0.2

[camera]
calibration = "camera_info.yaml"
waterline_height = {WATERLINE}
max_range = 15.0

[tracker]
delete_after_s = 5.0

[outputs]
frames_hz = 2.0
"""
    )
    centres = np.array([o.center for o in floats], float).reshape(-1, 2)
    boat_c = np.array([o.center for o in boats], float).reshape(-1, 2)
    rows = ["time,object_id,kind,north,east,lat,lon"]
    for k in range(int(duration * 10) + 1):
        t = EPOCH + k * 0.1
        for i, (n, e) in enumerate(centres):
            lat, lon, _ = geodesy.ned2geodetic(n, e, 0.0, *ORIGIN)
            rows.append(f"{t:.3f},{i},bottle,{n:.4f},{e:.4f},{lat:.9f},{lon:.9f}")
        for i, (n, e) in enumerate(boat_c):
            lat, lon, _ = geodesy.ned2geodetic(n, e, 0.0, *ORIGIN)
            rows.append(f"{t:.3f},{100 + i},moored_boat,{n:.4f},{e:.4f},{lat:.9f},{lon:.9f}")
    truth = root / "truth.csv"
    truth.write_text("\n".join(rows) + "\n")
    return Built(root, config, bag, truth, centres, boat_c, duration)
