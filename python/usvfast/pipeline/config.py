"""Pipeline configuration: one TOML (or YAML) file naming the recording's streams, the mounts,
the camera calibration, the detector, the LiDAR chain and the tracker.

Layout (paths relative to the file; every table optional except the streams)::

    preset = "thesis"            # start from a shipped preset (usvfast/pipeline/presets/)
    [recording]                  # usvfast.nav.replay's table, plus navigation/attitude/origin
    navigation = "gnss"          # stream id (or a list of ids) giving position and heading
    attitude = "imu"             # stream id giving roll/pitch (sensor_msgs/Imu)
    origin = [59.91, 10.75, 0.0] # NED origin (deg, deg, m); default: the first fix
    [[stream]]                   # replay streams plus `sensor = "lidar" | "camera"`
    [mounts]                     # default mounts by role (lidar, camera, navigation) for
                                 # streams without their own [stream.mount]
    [lidar] [camera] [detector] [tracker] [outputs]   (keys: see SCHEMA)

Unknown keys, wrong types and missing files are `ConfigError`s (a ValueError) naming the key
and the file. Values are SI (metres, seconds); names ending in `_deg` are degrees.
"""

from __future__ import annotations

import copy
import math
import sys
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from usvfast._validate import instance
from usvfast.frames import Mount
from usvfast.nav.replay import Recording, _stream
from usvfast.nav.stream_types import STREAM_TYPES, RecordingError, StreamSpec
from usvfast.pipeline import streams as _streams  # noqa: F401  (registers lidar, video_times)
from usvfast.pipeline.pose import NavErrors

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib  # pyright: ignore[reportMissingImports]  # (Python 3.10 only)

__all__ = [
    "SCHEMA",
    "ConfigError",
    "PipelineConfig",
    "apply_overrides",
    "config_from_dict",
    "load_config",
    "preset_names",
]


class ConfigError(ValueError):
    """A pipeline configuration is invalid; the message names the file and the key."""


# Value kinds: "float", "int", "bool", "str", "path", "floats:N" (N numbers; N=0 any length),
# "points" (list of at least 3 [u, v] pairs), "pairs" (list of [a, b] number pairs),
# "strs" (str or list of str), "any".
_LIDAR = {
    "enabled": ("bool", True),
    "model": ("str", "VLP-16"),
    "waterline_height": ("float", None),
    "mount_height": ("float", None),
    "radius": ("float", 10.0),
    "line_margin": ("float", 2.0),
    "slice_min": ("float", -0.5),
    "slice_max": ("float", 0.5),
    "min_intensity": ("float", None),
    "pixel": ("float", 0.2),
    "min_segment_length": ("float", 1.0),
    "line_memory_frames": ("int", 3),
    "cover_tolerance": ("float", 0.2),
    "segment_extension": ("float", 0.4),
    "los_tolerance": ("float", 0.4),
    "buffer_frames": ("int", 4),
    "bandwidth": ("float", 2.0),
    "bin_seeding": ("bool", False),
    "cluster_all": ("bool", False),
    "backend": ("str", "rust"),
    "los_backend": ("str", "rust"),
    "covariance": ("str", "spread"),
    "surface_offset": ("float", 0.0),
    "range_std": ("float", 0.1),
    "cross_range_std": ("float", 0.065),
    "reference_points": ("int", 0),
    "surface_offset_share": ("float", 0.0),
    "low_profile_std": ("float", 0.0),
    "low_profile_width": ("float", 0.3),
    "low_profile_height": ("float", 0.15),
    "min_cluster_points": ("int", 15),
    "small_cluster_points": ("int", None),
    "small_cluster_radius": ("float", 0.1),
    "small_cluster_variance": ("float", 1.0),
    "core_radius": ("float", None),
    "min_position_std": ("float", 0.1),
    "vessels": ("bool", False),
    "vessel_beam": ("float", 2.2),
    "vessel_length": ("float", 6.0),
    "vessel_max_length": ("float", 9.0),
    "vessel_min_speed": ("float", 0.8),
}
_CAMERA = {
    "enabled": ("bool", True),
    "calibration": ("path", None),
    "image_size": ("floats:2", None),
    "fov_deg": ("floats:2", None),
    "waterline_height": ("float", None),
    "pixel_sigma": ("float", 2.0),
    "pixel_sigma_uv": ("floats:2", None),
    "box_pixel_offset": ("float", 0.5),
    "object_depth_factor": ("float", 0.0),
    # Classes whose centre lies a known distance beyond the near waterline (m), with the
    # standard deviation of that centre (m, added to the covariance), e.g. vessels: half the
    # beam, since a long hull's seen width is no measure of its depth.
    "depth_classes": ("floats:0", None),
    "class_depth_m": ("floats:0", None),
    "class_depth_std_m": ("floats:0", None),
    # The error of a floating object's centre placed from its box (its unknown shape and yaw,
    # the box's fit about it), m along / across the line of sight: the same at every range,
    # added to each of its detections' covariance (the pixel terms grow with the range).
    "centre_along_std": ("float", 0.0),
    "centre_across_std": ("float", 0.0),
    # Boat classes (usvfast.camera.vessels): their boxes are fused per hull and kept only
    # while the boat moves (median speed over vessel_history_s s >= vessel_min_speed m/s);
    # the hull's centre lies half its depth along the line of sight beyond the box bottom
    # (vessel_length x vessel_beam m, heading from the velocity), with vessel_along_std /
    # vessel_across_std m added along / across the line of sight; of the moving boats within
    # vessel_separation m of each other only the best-scoring one is kept; a boat box must
    # span vessel_min_height m above the water (a hull and cabin, not a float) and give a
    # velocity from vessel_min_frames earlier frames, and lie vessel_edge_margin_px from the
    # image's side edges.
    "moving_classes": ("floats:0", None),
    "vessel_min_speed": ("float", 1.0),
    "vessel_history_s": ("float", 2.0),
    "vessel_min_frames": ("int", 5),
    "vessel_min_height": ("float", 1.2),
    # Boxes of these moving classes that span less than vessel_min_height m above the water
    # are floating objects the network called boats: the float path takes them.
    "low_boat_classes": ("floats:0", None),
    "vessel_edge_margin_px": ("float", 16.0),
    "vessel_length": ("float", 6.0),
    "vessel_beam": ("float", 2.2),
    "vessel_along_std": ("float", 1.0),
    "vessel_across_std": ("float", 0.6),
    "vessel_separation": ("float", 9.0),
    "attitude_sigma_deg": ("float", 0.5),
    "height_sigma": ("float", 0.0),
    "heading_sigma_deg": ("float", 0.0),
    "min_depression_deg": ("float", 0.0),
    "max_range": ("float", 40.0),
    "min_confidence": ("float", 0.0),
    # Boxes scored under start_confidence (and at least min_confidence and the detector's
    # conf_threshold) update tracks, tentative ones included, but start none (the
    # two-threshold association of ByteTrack, Zhang et al. 2022); None: every box may.
    "start_confidence": ("float", None),
    "own_vessel_polygon": ("points", None),
    "horizon": ("str", "attitude"),
    "horizon_margin_deg": ("float", 0.5),
    "horizon_line": ("floats:2", None),
    # Pipeline.run: the detector network on a worker thread, overlapping the other stages
    # (the scans reach the tracker in message order: the same tracks either way).
    "worker_thread": ("bool", True),
    # 16-bit and float frames (a thermal camera's raw counts) reach the detector as 8 bits:
    # these percentiles (low, high) of each frame become 0 and 255 (usvfast.camera.agc).
    "agc_percentiles": ("floats:2", (1.0, 99.0)),
}
_DETECTOR = {
    "backend": ("str", "none"),
    "weights": ("str", None),
    "conf_threshold": ("float", 0.25),
    "iou_threshold": ("float", 0.45),
    "input_size": ("floats:2", None),
    "classes": ("floats:0", None),
    # backend "onnx": the inference back-end (usvfast.camera.dnn.RUNTIMES); "auto" is OpenVINO
    # when the openvino extra is installed (OpenCV DNN's boxes, 1.6x faster), else OpenCV DNN.
    "runtime": ("str", "auto"),
}
_TRACKER = {
    "backend": ("str", "native"),
    "association": ("str", "jpda"),
    "q": ("float", 0.001),
    "prob_detect": ("float", 0.85),
    "prob_gate": ("float", 0.95),
    "clutter_density": ("float", 0.125),
    "method": ("str", "ehm"),
    "gnn_missed_distance": ("float", 3.0),
    "lidar_noise_std": ("float", 0.25),
    "camera_noise_std": ("float", 0.5),
    "per_detection_covariance": ("bool", True),
    "missed_distance": ("float", 0.3),
    "prior_velocity_var": ("float", 0.3),
    # Per-track offsets of the LiDAR's and the camera's detections in the state ([n, v_n, e,
    # v_e, then (b_n, b_e) of each sensor with one]): prior std (m, 0: none) and random-walk
    # diffusion (m²/s). The camera and the LiDAR each place an object with an offset of their
    # own that changes slowly.
    "camera_offset_std": ("float", 0.0),
    "camera_offset_q": ("float", 0.001),
    "lidar_offset_std": ("float", 0.0),
    "lidar_offset_q": ("float", 0.001),
    "min_points": ("int", 2),
    "init_delete_steps": ("int", 3),
    "delete_steps": ("int", 35),
    "deletion": ("str", "steps"),
    "init_delete_after_s": ("float", None),
    "delete_after_s": ("float", None),
    "covariance_trace": ("float", 1.5),
    "initiate_in_gates": ("bool", True),
    # A second tracker for moving vessels (the LiDAR's vessel detections and the camera's
    # moving boats), apart from the floating objects: a vessel under way at 1.5-2.5 m/s
    # starts far outside a float's velocity prior and manoeuvres (process noise vessel_q,
    # velocity prior variance vessel_prior_velocity_var m²/s², tracks deleted
    # vessel_delete_after_s s after their last update; no covariance-trace deletion unless
    # vessel_covariance_trace). Its track ids start at 100000.
    "vessels": ("bool", False),
    "vessel_q": ("float", 0.05),
    "vessel_prior_velocity_var": ("float", 6.25),
    "vessel_delete_after_s": ("float", 2.0),
    "vessel_covariance_trace": ("float", None),
    # The vessel tracker's per-track camera offset (as camera_offset_std / camera_offset_q for
    # the floats; m, 0: none): a hull's camera detections err by a slowly changing offset.
    "vessel_camera_offset_std": ("float", 0.0),
}
_OUTPUTS = {
    "animation": ("bool", True),
    "frames_hz": ("float", 2.0),
    "frame_width": ("int", 480),
    "report": ("bool", True),
}
_RECORDING = {
    "name": ("str", None),
    "navigation": ("strs", None),
    "attitude": ("str", None),
    "origin": ("floats:3", None),
    "reorder_window": ("int", 16),
    "max_pose_gap": ("float", 2.0),
    # A constant correction of the GNSS heading (degrees clockwise, added to every heading),
    # and the seconds of LiDAR at the recording's start from which Pipeline.run estimates a
    # further one (usvfast.nav.heading_offset; None: no estimate).
    "heading_offset_deg": ("float", 0.0),
    "heading_calibration_s": ("float", None),
    # The navigation's errors, added to every detection's covariance (usvfast.pipeline.pose
    # .NavErrors): [[GGA fix quality, horizontal std m], ...] beyond the measurement models'
    # own, and the unmodelled accelerations that interpolation between samples misses.
    "fix_quality_std": ("pairs", None),
    "pose_acceleration_std": ("float", 0.0),
    "heading_acceleration_std": ("float", 0.0),
    # Carry the GNSS heading across its gaps with the attitude IMU's gyro
    # (usvfast.pipeline.gyro_bridge; the attitude stream must be a sensor_msgs/Imu topic).
    "gyro_heading_bridge": ("bool", False),
}
SCHEMA: dict[str, dict[str, tuple[str, Any]]] = {
    "recording": _RECORDING,
    "lidar": _LIDAR,
    "camera": _CAMERA,
    "detector": _DETECTOR,
    "tracker": _TRACKER,
    "outputs": _OUTPUTS,
}
"""Every table's keys: {table: {key: (kind, default)}}."""

_CHOICES = {
    ("lidar", "backend"): ("rust", "sklearn"),
    ("lidar", "los_backend"): ("rust", "numpy"),
    ("lidar", "covariance"): ("spread", "centroid", "model"),
    ("camera", "horizon"): ("attitude", "none", "line"),
    ("detector", "backend"): ("none", "onnx", "torch"),
    ("detector", "runtime"): ("auto", "opencv", "openvino"),
    ("tracker", "backend"): ("native", "stonesoup"),
    ("tracker", "association"): ("jpda", "gnn"),
    ("tracker", "method"): ("ehm", "brute_force"),
    ("tracker", "deletion"): ("steps", "time"),
}
_ROLES = ("lidar", "camera", "navigation")


@dataclass(frozen=True)
class PipelineConfig:
    """A validated configuration: recording (the replay streams, mounts filled in), sensors
    ({stream id: "lidar" | "camera"}), navigation (stream ids for position/heading), attitude
    (stream id or None), origin ((lat, lon, h) or None), and one dict per table with every key
    of SCHEMA (defaults filled in; paths absolute). `path` is the file it came from.
    heading_offset_deg: correction added to the GNSS heading (degrees clockwise);
    heading_calibration_s: seconds of LiDAR from which `Pipeline.run` estimates a further
    correction (None: none); nav_errors: the navigation's errors that reach every detection
    (`usvfast.pipeline.pose.NavErrors`; none by default); gyro_heading_bridge: whether the
    attitude IMU's gyro carries the heading across its gaps."""

    recording: Recording
    sensors: dict[str, str]
    navigation: tuple[str, ...]
    attitude: str | None
    origin: tuple[float, float, float] | None
    lidar: dict[str, Any]
    camera: dict[str, Any]
    detector: dict[str, Any]
    tracker: dict[str, Any]
    outputs: dict[str, Any]
    path: Path | None = None
    raw: dict[str, Any] = field(default_factory=dict)
    heading_offset_deg: float = 0.0
    heading_calibration_s: float | None = None
    nav_errors: NavErrors = field(default_factory=NavErrors)
    gyro_heading_bridge: bool = False

    def streams_of(self, sensor: str) -> list[StreamSpec]:
        """The streams consumed by `sensor` ("lidar" or "camera"), in file order."""
        return [s for s in self.recording.streams if self.sensors.get(s.id) == sensor]

    def with_options(self, **tables: dict[str, Any]) -> PipelineConfig:
        """A copy with some table keys replaced, e.g. `with_options(tracker={"backend":
        "stonesoup"})`; values are validated like the file's."""
        raw = copy.deepcopy(self.raw)
        for table, values in tables.items():
            raw.setdefault(table, {}).update(values)
        return _build(raw, self.path or Path("<config>"))


def preset_names() -> list[str]:
    """Names of the shipped presets (`preset = "..."`)."""
    folder = resources.files("usvfast.pipeline") / "presets"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def _read(path: Path) -> dict[str, Any]:
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"config: cannot read {path}: {exc.strerror}") from exc
    try:
        if path.suffix.lower() in (".yaml", ".yml"):
            data = yaml.safe_load(text)
        else:
            data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(f"{path}: not valid {path.suffix.lstrip('.').upper()}: {exc}") from exc
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a table at the top level")
    return data


def _preset(name: Any, where: Path) -> dict[str, Any]:
    if not isinstance(name, str) or name not in preset_names():
        raise ConfigError(f"{where}: key 'preset': {name!r} is not a preset ({preset_names()})")
    res = resources.files("usvfast.pipeline") / "presets" / f"{name}.toml"
    data = tomllib.loads(res.read_text())
    data.pop("preset", None)
    return data


def _merge(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out


def _value(where: str, key: str, kind: str, v: Any, base: Path) -> Any:
    def bad(expected: str) -> ConfigError:
        return ConfigError(
            f"{where}: key '{key}': expected {expected}, got {v!r} ({type(v).__name__})"
        )

    if kind == "any":
        return v
    if kind == "bool":
        if not isinstance(v, bool):
            raise bad("true or false")
        return v
    if kind == "int":
        if isinstance(v, bool) or not isinstance(v, int):
            raise bad("an integer")
        return v
    if kind == "float":
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise bad("a finite number")
        return float(v)
    if kind == "str":
        if not isinstance(v, str):
            raise bad("a string")
        return v
    if kind == "strs":
        if isinstance(v, str):
            return (v,)
        if not isinstance(v, list) or not v or not all(isinstance(x, str) for x in v):
            raise bad("a stream id or a list of them")
        return tuple(v)
    if kind == "path":
        if not isinstance(v, str) or not v:
            raise bad("a file path")
        p = Path(v)
        return p if p.is_absolute() else base / p
    if kind.startswith("floats:"):
        n = int(kind.split(":")[1])
        if not isinstance(v, list) or (n and len(v) != n) or not v:
            raise bad(f"a list of {n or 'some'} numbers")
        return tuple(_value(where, key, "float", x, base) for x in v)
    if kind in ("points", "pairs"):
        if kind == "points" and (not isinstance(v, list) or len(v) < 3):
            raise bad("a list of at least 3 [u, v] pixel pairs")
        if not isinstance(v, list) or not v:
            raise bad("a list of [a, b] number pairs")
        return tuple(_value(where, key, "floats:2", x, base) for x in v)
    raise AssertionError(kind)  # pragma: no cover - schema typo


def _table(file: Path, name: str, raw: Any) -> dict[str, Any]:
    schema = SCHEMA[name]
    if raw is None:
        raw = {}
    if not isinstance(raw, dict):
        raise ConfigError(f"{file}: key '{name}': expected a table, got {raw!r}")
    unknown = sorted(set(raw) - set(schema))
    if unknown:
        raise ConfigError(
            f"{file}: key '{name}.{unknown[0]}': unknown (known: {', '.join(sorted(schema))})"
        )
    out = {}
    for key, (kind, default) in schema.items():
        if key in raw and raw[key] is not None:
            out[key] = _value(str(file), f"{name}.{key}", kind, raw[key], file.parent)
            choices = _CHOICES.get((name, key))
            if choices and out[key] not in choices:
                raise ConfigError(
                    f"{file}: key '{name}.{key}': {out[key]!r} is not one of {list(choices)}"
                )
        else:
            out[key] = default
    return out


def _mount_table(file: Path, role: str, raw: Any) -> Mount:
    spec = _stream(
        file, 0, {"id": f"mounts.{role}", "type": "gpx", "path": "-", "mount": raw}
    ).mount
    assert spec is not None
    return spec


_TOP = {"preset", "recording", "stream", "mounts", *SCHEMA}


def _build(data: dict[str, Any], file: Path) -> PipelineConfig:
    raw = copy.deepcopy(data)
    if "preset" in data:
        data = _merge(
            _preset(data["preset"], file), {k: v for k, v in data.items() if k != "preset"}
        )
    unknown = sorted(set(data) - _TOP)
    if unknown:
        raise ConfigError(f"{file}: key '{unknown[0]}': unknown (known: {', '.join(sorted(_TOP))})")
    tables = {name: _table(file, name, data.get(name)) for name in SCHEMA}
    rec = tables["recording"]
    mounts_raw = data.get("mounts", {})
    if not isinstance(mounts_raw, dict):
        raise ConfigError(f"{file}: key 'mounts': expected a table")
    bad = sorted(set(mounts_raw) - set(_ROLES))
    if bad:
        raise ConfigError(f"{file}: key 'mounts.{bad[0]}': unknown (roles: {list(_ROLES)})")
    mounts = {role: _mount_table(file, role, m) for role, m in mounts_raw.items()}
    raw_streams = data.get("stream")
    if not isinstance(raw_streams, list) or not raw_streams:
        raise ConfigError(f"{file}: key 'stream': expected at least one [[stream]] table")
    streams, sensors = [], {}
    navigation = rec["navigation"] or ()
    for i, s in enumerate(raw_streams):
        if not isinstance(s, dict):
            raise ConfigError(f"{file}: stream[{i}]: expected a table")
        s = dict(s)
        sensor = s.pop("sensor", None)
        if sensor is not None and sensor not in ("lidar", "camera"):
            raise ConfigError(
                f"{file}: stream[{i}]: key 'sensor': expected 'lidar' or 'camera', got {sensor!r}"
            )
        if sensor == "lidar" and s.get("type") in ("bag", "pcap"):
            s["type"] = "lidar"  # LiDAR bags and pcaps are decoded into frames
        try:
            spec = _stream(file, i, s)
        except RecordingError as exc:
            raise ConfigError(str(exc)) from None
        role = sensor or ("navigation" if spec.id in navigation else None)
        if spec.mount is None and role in mounts:
            spec = StreamSpec(**{**spec.__dict__, "mount": mounts[role]})
        if spec.path is not None and not spec.path.exists() and STREAM_TYPES[spec.type].needs_path:
            raise ConfigError(f"{file}: stream {spec.id!r}: key 'path': {spec.path} does not exist")
        streams.append(spec)
        if sensor is not None:
            sensors[spec.id] = sensor
    ids = [s.id for s in streams]
    dup = next((x for x in ids if ids.count(x) > 1), None)
    if dup is not None:
        raise ConfigError(f"{file}: key 'stream.id': stream id {dup!r} is used twice")
    if not navigation:
        raise ConfigError(
            f"{file}: key 'recording.navigation': missing; name the GNSS stream(s) giving "
            "position and heading"
        )
    for key, value in (("navigation", navigation), ("attitude", (rec["attitude"],))):
        for sid in value:
            if sid is not None and sid not in ids:
                raise ConfigError(
                    f"{file}: key 'recording.{key}': {sid!r} is not a stream id (ids: {ids})"
                )
    if rec["max_pose_gap"] <= 0:
        raise ConfigError(f"{file}: key 'recording.max_pose_gap': must be > 0")
    if not abs(rec["heading_offset_deg"]) <= 180.0:
        raise ConfigError(
            f"{file}: key 'recording.heading_offset_deg': expected degrees in [-180, 180], "
            f"got {rec['heading_offset_deg']}"
        )
    calibration = rec["heading_calibration_s"]
    if calibration is not None and calibration <= 0:
        raise ConfigError(
            f"{file}: key 'recording.heading_calibration_s': expected seconds > 0, got "
            f"{calibration}"
        )
    nav_errors = _nav_errors(file, rec)
    recording = Recording(
        rec["name"] or file.stem,
        tuple(streams),
        navigation[0],
        rec["reorder_window"],
        file,
        rec["max_pose_gap"],
    )
    cam = tables["camera"]
    if any(v == "camera" for v in sensors.values()) and cam["enabled"]:
        if cam["calibration"] is None and (cam["image_size"] is None or cam["fov_deg"] is None):
            raise ConfigError(
                f"{file}: key 'camera.calibration': missing; give a camera_info YAML/JSON file "
                "(or camera.image_size and camera.fov_deg for the thesis's FOV model)"
            )
        if cam["calibration"] is not None and not cam["calibration"].exists():
            raise ConfigError(
                f"{file}: key 'camera.calibration': {cam['calibration']} does not exist"
            )
    if calibration is not None and not (tables["lidar"]["enabled"] and "lidar" in sensors.values()):
        raise ConfigError(
            f"{file}: key 'recording.heading_calibration_s': the heading calibration needs a "
            'LiDAR stream (sensor = "lidar", lidar.enabled = true)'
        )
    low, high = cam["agc_percentiles"]
    if not 0.0 <= low < high <= 100.0:
        raise ConfigError(
            f"{file}: key 'camera.agc_percentiles': expected 0 <= low < high <= 100, "
            f"got {[low, high]}"
        )
    start = cam["start_confidence"]
    if start is not None and not 0.0 <= start <= 1.0:
        raise ConfigError(
            f"{file}: key 'camera.start_confidence': expected a score in [0, 1], got {start}"
        )
    trk = tables["tracker"]
    if trk["deletion"] == "time":
        for key in ("init_delete_after_s", "delete_after_s"):
            if trk[key] is None or trk[key] <= 0:
                raise ConfigError(
                    f"{file}: key 'tracker.{key}': a number of seconds > 0 is needed with "
                    'tracker.deletion = "time"'
                )
    offset_keys = ("camera_offset_std", "lidar_offset_std", "vessel_camera_offset_std")
    for key in (*offset_keys, "camera_offset_q", "lidar_offset_q"):
        if trk[key] < 0:
            raise ConfigError(f"{file}: key 'tracker.{key}': must be >= 0, got {trk[key]}")
    for key in ("centre_along_std", "centre_across_std"):
        if tables["camera"][key] < 0:
            value = tables["camera"][key]
            raise ConfigError(f"{file}: key 'camera.{key}': must be >= 0, got {value}")
    offset = next((k for k in offset_keys if trk[k] > 0), None)
    if offset is not None and trk["backend"] == "stonesoup":
        raise ConfigError(
            f"{file}: key 'tracker.{offset}': a sensor-offset state needs backend "
            '"native" (Stone Soup\'s initiator would split a detection between position and offset)'
        )
    det = tables["detector"]
    if det["backend"] in ("onnx", "torch") and det["weights"] is None:
        raise ConfigError(f"{file}: key 'detector.weights': missing for backend {det['backend']!r}")
    if det["runtime"] != "auto" and det["backend"] != "onnx":
        raise ConfigError(
            f"{file}: key 'detector.runtime': {det['runtime']!r} runs ONNX files only "
            f"(backend {det['backend']!r})"
        )
    for name in ("lidar", "camera"):
        if tables[name]["waterline_height"] is None:
            other = tables["camera" if name == "lidar" else "lidar"]["waterline_height"]
            tables[name]["waterline_height"] = other
    return PipelineConfig(
        recording=recording,
        sensors=sensors,
        navigation=tuple(navigation),
        attitude=rec["attitude"],
        origin=rec["origin"],
        lidar=tables["lidar"],
        camera=cam,
        detector=det,
        tracker=tables["tracker"],
        outputs=tables["outputs"],
        path=file,
        raw=raw,
        heading_offset_deg=rec["heading_offset_deg"],
        heading_calibration_s=calibration,
        nav_errors=nav_errors,
        gyro_heading_bridge=rec["gyro_heading_bridge"],
    )


def _nav_errors(file: Path, rec: dict[str, Any]) -> NavErrors:
    """The [recording] table's navigation errors, validated (ConfigError naming the key)."""
    fix_std: dict[int, float] = {}
    for quality, std in rec["fix_quality_std"] or ():
        if not (0 <= quality <= 9 and quality == int(quality) and 0 <= std < math.inf):
            raise ConfigError(
                f"{file}: key 'recording.fix_quality_std': expected [GGA fix quality 0-9, "
                f"std m >= 0] pairs, got {[quality, std]}"
            )
        if int(quality) in fix_std:
            raise ConfigError(
                f"{file}: key 'recording.fix_quality_std': fix quality {int(quality)} is given "
                "twice"
            )
        fix_std[int(quality)] = std
    for key in ("pose_acceleration_std", "heading_acceleration_std"):
        if not 0 <= rec[key] < math.inf:
            raise ConfigError(f"{file}: key 'recording.{key}': must be >= 0, got {rec[key]}")
    return NavErrors(
        fix_std, rec["pose_acceleration_std"], math.radians(rec["heading_acceleration_std"])
    )


def apply_overrides(data: dict[str, Any], overrides: dict[str, Any] | None) -> dict[str, Any]:
    """A copy of the parsed config with dotted-key overrides applied, e.g.
    {"tracker.prob_detect": 0.9, "lidar.radius": 12.0} (tables are created as needed)."""
    if not isinstance(data, dict) or not (overrides is None or isinstance(overrides, dict)):
        raise ConfigError(
            f"data, overrides: expected dicts, got {type(data).__name__}, "
            f"{type(overrides).__name__}"
        )
    out = copy.deepcopy(data)
    for key, value in (overrides or {}).items():
        if not isinstance(key, str) or not key:
            raise ConfigError(f"overrides: expected dotted string keys, got {key!r}")
        *tables, last = key.split(".")
        node = out
        for t in tables:
            nxt = node.setdefault(t, {})
            if not isinstance(nxt, dict):
                raise ConfigError(f"overrides: key {key!r}: {t!r} is not a table")
            node = nxt
        node[last] = copy.deepcopy(value)
    return out


def load_config(path: Path | str, overrides: dict[str, Any] | None = None) -> PipelineConfig:
    """Read and validate a pipeline config (TOML, or YAML for `.yaml`/`.yml`); `overrides`
    are dotted keys applied over the file (and its preset) before validation, e.g.
    `load_config("run.toml", {"tracker.prob_detect": 0.9})`.

    Raises ConfigError naming the file and the key on: unknown keys or tables, values of the
    wrong type, unknown presets, stream types or choices, missing files (stream paths,
    camera.calibration), a camera stream without calibration, a missing
    `recording.navigation`.
    """
    file = Path(path)
    return _build(apply_overrides(_read(file), overrides), file)


def config_from_dict(data: dict[str, Any], base: Path | str = ".") -> PipelineConfig:
    """Validate a config given as a dict (the parsed TOML); relative paths are taken from
    `base` (a directory)."""
    if not isinstance(data, dict):
        raise ConfigError(f"data: expected a dict (the parsed TOML), got {type(data).__name__}")
    instance("base", base, str, Path)
    return _build(copy.deepcopy(data), Path(base) / "<config>")
