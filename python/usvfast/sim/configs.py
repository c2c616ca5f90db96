"""The pipeline configs of a simulated recording: recording.toml (the bag) and
recording-d1.toml (the thesis's D1 layout), with the simulated sensors' measurement models
and tracker settings."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

from usvfast.sim.camera import CAMERA_LEVER_ARM, CAMERA_YPR_DEG, WATERLINE_HEIGHT
from usvfast.sim.gnss import GNSS_LEVER_ARM
from usvfast.sim.scene import World
from usvfast.sim.velodyne import LIDAR_LEVER_ARM

#: Bag topics and message types of a simulated recording.
TOPICS = {
    "lidar": ("/velodyne_packets", "velodyne_msgs/msg/VelodyneScan"),
    "image": ("/camera/image_raw/compressed", "sensor_msgs/msg/CompressedImage"),
    "camera_info": ("/camera/camera_info", "sensor_msgs/msg/CameraInfo"),
    "nmea": ("/gnss/nmea", "nmea_msgs/msg/Sentence"),
    "imu": ("/imu/data", "sensor_msgs/msg/Imu"),
}


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list | tuple):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, float) else str(v)


#: The measurement models and tracker settings of the simulated sensors, calibrated on
#: held-out simulator seeds 4, 5, 6 and 8, 9, 10 (30 s each; never on the scored seeds 1, 2,
#: 3 and the bundled 7): detection errors against the truth split into the per-object mean
#: (bias) and the scan-to-scan part, then the per-sensor ANIS. See docs/harbour-system.md.
_SENSOR_MODELS = {
    "lidar": """\
# A cluster counts only its core (0.5 m about its densest point): sparse water returns
# gathered by the 2 m mean-shift window neither pull a float's detection nor make up a
# clutter cluster's count, so a bottle that one beam grazes (6-15 points per 4-frame cycle
# at 8-10 m) is kept. Centroid of the visible surface -> object centre: 0.03 m plus 0.32 of
# the cluster's seen half-width (sqrt(3) x its spread across the line of sight; fitted to
# the cores' offsets from the truth). The random error of one cycle along / across the
# line of sight, growing as sqrt(12 / n) below 12 points, plus along it a low-profile term,
# 0.097 m x (seen width / 0.3 m)^2 x (1 - top / 0.145 m): the rings reach a low, wide
# float's top at grazing incidence and the vessel's heave slides its hits along the line of
# sight (set from the innovations of held-out seeds: LiDAR NIS by object kind 1.7-2.1, was
# 1.2-2.9 with one error for all).
covariance = "model"
core_radius = 0.5
min_cluster_points = 6
# A core under 6 points is kept too when at least 4 of its points lie within 0.1 m of their
# median, and is then made of those: one ring grazing a 5 cm high bottle for a single
# rotation gives 4-5 returns within a few cm (a stray water return may share its 0.5 m
# core), and a tentative track needs three detections within 4.5 s. Its covariance is 3x
# the model's: a ring's partial hit lies anywhere on the float's seen outline (held-out
# seeds: against the same float's next many-point detection, NEES 3.8 for 4 points where
# many-point pairs give 2.4). Held-out seeds 4-6, 8-14: of 10,941 cores under 6 points, the
# 41 this keeps all lie on floats (within 0.15 m: 47, and one that does not).
small_cluster_points = 4
small_cluster_radius = 0.1
small_cluster_variance = 3.0
surface_offset = 0.03
surface_offset_share = 0.32
range_std = 0.035
cross_range_std = 0.019
reference_points = 12
low_profile_std = 0.097
low_profile_width = 0.3
low_profile_height = 0.145
# A moving vessel's hull is removed by the line-of-sight filter like a quay: find it among
# the removed points (a vessel-sized group whose ends move >= 0.8 m/s) and give it one
# detection at its centre (the seen side + half the 2.2 m beam).
vessels = true
""",
    "camera": """\
# Beyond 20 m one pixel is more than 1 m of range (1.2 m above the water, f = 300 px).
max_range = 20.0
# Box bottom = near waterline; the centre lies half the seen width beyond it.
object_depth_factor = 0.5
# Pixel error (u, v): between the scan-to-scan part (0.8 / 0.35 px) and the error about
# each object's mean (1.1 / 0.75 px: the camera's errors vary slowly and cancel in the
# innovations), set from the innovations (camera ANIS 1.8-2.4 on held-out seeds); and the
# IMU's attitude noise.
pixel_sigma_uv = [1.05, 0.52]
attitude_sigma_deg = 0.05
# Moving boats: the demo network boxes a vessel under way as "vessel" (4) or "moored boat"
# (5); boxes of both that span >= 1.2 m above the water are fused per hull and passed to the
# vessel tracker only while their own trail moves >= 1 m/s (moored boats stay out), at the
# hull's centre (the box bottom's waterline point + half the hull's depth along the line of
# sight) with 0.5 / 0.3 m added along / across it. The detections err about the truth by
# 1.24 / 0.50 m rms, but mostly as a slowly changing offset of each hull that cancels in the
# innovations: with 1.0 / 0.6 m no held-out seed's vessel ANIS reached its band, with 0.5 /
# 0.3 two do (benches/vessel_noise_heldout.py, protocol 2). Lower class-4 boxes are floats the
# network called vessels: the float path keeps them. Held-out seeds: vessels tracked 6 -> 8
# of 8, the floating objects' figures unchanged.
moving_classes = [4, 5]
low_boat_classes = [4]
vessel_along_std = 0.5
vessel_across_std = 0.3
""",
    "tracker": """\
# Small floats are hit by the VLP-16 beams in bursts 2-4 s apart (the waves roll and
# pitch the USV): tentative tracks wait 4.5 s for their detections. A tentative track takes
# a detection within Mahalanobis 2 of it (the thesis's 0.3 holds no target moving faster
# than ~0.3 m/s: a vessel at 1.5-2.5 m/s moves 0.6-1 m between LiDAR cycles) and is
# confirmed at its third (camera clutter rarely repeats 3 times). A detection in a
# confirmed track's gate (P_G 0.99) starts no track (no duplicates from the 10 Hz camera).
# A track not updated for 3 s is deleted (a coasting track drifts with its velocity error).
# Floats drift with the harbour's current, well below 0.1 m/s: a velocity prior of
# 0.01 m^2/s^2 (the thesis's 0.3 lets one far camera detection, metres off in range, set a
# track moving at 0.3-0.5 m/s). Held-out seeds 4-6, 8-14: float RMSE 0.15-0.30 m (with the
# heading calibration; 0.15-0.35 m with 0.3).
prior_velocity_var = 0.01
initiate_in_gates = false
missed_distance = 2.0
min_points = 3
prob_gate = 0.99
init_delete_after_s = 4.5
delete_after_s = 3.0
# Moving vessels (the LiDAR's vessel detections) go to a tracker of their own: a vessel
# under way at 1.5-2.5 m/s lies far outside a float's velocity prior (0.3 m^2/s^2) and
# manoeuvres (process noise 0.05 m^2/s^3, velocity prior 6.25 m^2/s^2, deleted 2 s after
# its last update). Held-out seeds 5, 6, 8: vessel RMSE 0.71 / 0.59 / 2.3 -> 0.43 / 0.23 / 0.86 m.
vessels = true
""",
}


def _config_text(name: str, origin: tuple, streams: list[dict], attitude: bool) -> str:
    """The pipeline config (contract: `usvfast.pipeline.load_config` schema)."""
    out = io.StringIO()
    out.write('preset = "thesis"\n\n[recording]\n')
    out.write(f"name = {_toml_value(name)}\n")
    out.write('navigation = "gnss"\n')
    if attitude:
        out.write('attitude = "imu"\n')
    out.write(f"origin = {_toml_value(list(origin))}\n")
    out.write(
        "# The GNSS heading's constant error (the antennas' baseline is not exactly along the\n"
        "# hull) is estimated from the LiDAR's view of the quays in the first 30 s\n"
        "# (usvfast.nav.heading_offset).\n"
        "heading_calibration_s = 30.0\n"
        "# After an outage the receiver reports RTK float (GGA quality 5) for 3 s, 0.10 m of\n"
        "# extra white noise per fix; interpolation between fixes and the LiDAR's four-rotation\n"
        "# clusters average part of it away: 0.05 m is what reaches the detections (chosen on\n"
        "# held-out seeds, benches/nav_errors_heldout.py).\n"
        "fix_quality_std = [[5, 0.05]]\n"
    )
    for s in streams:
        out.write("\n[[stream]]\n")
        mount = s.pop("mount", None)
        for k, v in s.items():
            out.write(f"{k} = {_toml_value(v)}\n")
        if mount is not None:
            out.write("[stream.mount]\n")
            out.write(f"lever_arm = {_toml_value(list(mount[0]))}\n")
            out.write(f"ypr_deg = {_toml_value(list(mount[1]))}\n")
    out.write("\n[lidar]\n")
    out.write(f"waterline_height = {WATERLINE_HEIGHT!r}\n")
    out.write(_SENSOR_MODELS["lidar"])
    out.write("\n[camera]\n")
    out.write('calibration = "camera_info.yaml"\n')
    out.write(f"waterline_height = {WATERLINE_HEIGHT!r}\n")
    out.write(_SENSOR_MODELS["camera"])
    out.write(_CAMERA_START)
    out.write('\n[detector]\nbackend = "onnx"\nweights = "models/harbour-demo.onnx"\n')
    out.write(
        "# the demo network's trash kinds, vessels and moored boats (camera.moving_classes)\n"
    )
    out.write("classes = [0, 1, 2, 4, 5]\n")
    out.write(_DETECTOR_THRESHOLD)
    out.write('\n[tracker]\nbackend = "native"\n')
    out.write(_SENSOR_MODELS["tracker"])
    out.write("\n[outputs]\nanimation = true\n")
    return out.getvalue()


#: The demo network's score gates (over the thesis preset's 0.25; camera.min_confidence 0.35
#: stays): chosen for it on held-out seeds 4-6, 8-14 (benches/demo_detector_heldout.py,
#: protocols 2 and 3).
_DETECTOR_THRESHOLD = """\
# Boxes scored >= 0.45 reach the tracker; only those >= 0.5 start tracks
# (camera.start_confidence). Held-out seeds 4-6, 8-14: at the preset's 0.35 gate the demo
# network's repeated 0.35-0.5 boxes started 5 false tracks in open water and on a quay; at 0.5
# none (103 / 103 detectable floats, mean float RMSE 0.171 m); boxes from 0.45 updating the
# tracks started at 0.5: none either, mean float RMSE 0.162 m.
conf_threshold = 0.45
"""
_CAMERA_START = """\
# Boxes under 0.5 only update tracks (the detector's conf_threshold lets them through).
start_confidence = 0.5
"""

_NAV_MOUNT = (list(GNSS_LEVER_ARM), [0.0, 0.0, 0.0])
_LIDAR_MOUNT = (list(LIDAR_LEVER_ARM), [0.0, 0.0, 0.0])
_CAMERA_MOUNT = (list(CAMERA_LEVER_ARM), list(CAMERA_YPR_DEG))


def write_configs(out: Path, world: World, seed: int, d1: bool) -> None:
    """recording.toml (the bag) and, with `d1`, recording-d1.toml (the D1 files)."""
    name = f"simulated harbour, seed {seed}"
    bag = [
        {
            "id": "gnss",
            "type": "bag",
            "path": "bag",
            "topic": TOPICS["nmea"][0],
            "mount": _NAV_MOUNT,
        },
        {"id": "imu", "type": "bag", "path": "bag", "topic": TOPICS["imu"][0]},
        {
            "id": "lidar",
            "type": "bag",
            "path": "bag",
            "topic": TOPICS["lidar"][0],
            "sensor": "lidar",
            "mount": _LIDAR_MOUNT,
        },
        {
            "id": "camera",
            "type": "bag",
            "path": "bag",
            "topic": TOPICS["image"][0],
            "sensor": "camera",
            "mount": _CAMERA_MOUNT,
        },
    ]
    (out / "recording.toml").write_text(_config_text(name, world.origin, bag, True))
    if d1:
        files = [
            {"id": "gnss", "type": "nmea", "path": "d1/gnss.nmea", "mount": _NAV_MOUNT},
            {
                "id": "lidar",
                "type": "pcap",
                "path": "d1/lidar.pcap",
                "sensor": "lidar",
                "mount": _LIDAR_MOUNT,
            },
            {
                "id": "camera",
                "type": "video_times",
                "path": "d1/camera.mp4",
                "times": "camera_times.csv",
                "sensor": "camera",
                "mount": _CAMERA_MOUNT,
            },
        ]
        text = _config_text(name + " (D1 layout)", world.origin, files, False)
        (out / "recording-d1.toml").write_text(text)
