"""`Pipeline`: the thesis's whole flow (section 5.3, Figures 3.6 and 5.4) as one streaming
object. Streams merged in time order (usvfast.nav.replay) -> vessel pose at each sensor
timestamp -> the LiDAR chain or the camera chain -> the two-sensor tracker -> track updates,
written to the output files as they happen.

    from usvfast.pipeline import Pipeline
    pipe = Pipeline("recording.toml")
    for update in pipe.run(out="out/run"):      # a whole recording
        print(update.time, update.tracks.ids)
    pipe.summary                                # counts, damaged messages, time per stage

Live use: `pipe.process(message)` for each message (anything with `time` (UNIX s), `stream`
(a stream id of the config) and `data`: an NMEA sentence / NmeaFix / NmeaHeading for the
navigation stream, an ImuSample for the attitude stream, a LidarFrame or an image for the
sensor streams; a QuaternionSample or ImuSample on a navigation stream is a heading);
it returns the track updates that message caused (a list, usually of 0 or 1).
"""

from __future__ import annotations

import json
import math
import time
import warnings
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from usvfast.camera.agc import to_uint8
from usvfast.nav.heading_offset import HeadingOffset
from usvfast.nav.replay import Replay
from usvfast.pipeline.camera_chain import CameraChain, load_detector
from usvfast.pipeline.config import ConfigError, PipelineConfig, load_config
from usvfast.pipeline.gyro_bridge import heading_rates
from usvfast.pipeline.heading import HeadingCalibrator, calibrate_heading
from usvfast.pipeline.lidar_chain import LidarChain
from usvfast.pipeline.live_pose import LivePose, parse_sentence, sentence_utc
from usvfast.pipeline.orientation import imu_roll_pitch, quaternion_heading, usable_orientations
from usvfast.pipeline.outputs import OutputWriter
from usvfast.pipeline.pose import NavTrack, VesselPose, yaw_convention
from usvfast.pipeline.timing import StageTimer
from usvfast.pipeline.tracker import (
    SENSORS,
    VESSEL_IDS,
    Snapshot,
    join_snapshots,
    make_tracker,
    make_vessel_tracker,
)

__all__ = ["Pipeline", "TrackUpdate"]


@dataclass(frozen=True)
class TrackUpdate:
    """The tracker's state after one scan: time (UNIX s), sensor ("lidar" | "camera"), stream
    id, detections (number handed to the tracker), tracks (the confirmed tracks: ids, states
    [n, v_n, e, v_e] NED, covariances), pose (the vessel at `time`)."""

    time: float
    sensor: str
    stream: str
    detections: int
    tracks: Snapshot
    pose: VesselPose


class Pipeline:
    """The pipeline of one config (a PipelineConfig or the path of a TOML/YAML file).

    detector: a camera detector callable overriding the config's [detector] (see
    usvfast.pipeline.camera_chain); None builds it from the config.
    """

    def __init__(self, config: PipelineConfig | str | Path, *, detector: Any = None) -> None:
        self.config = config if isinstance(config, PipelineConfig) else load_config(config)
        cfg = self.config
        self.timer = StageTimer()
        self.chains: dict[str, LidarChain | CameraChain] = {}
        if cfg.lidar["enabled"]:
            for spec in cfg.streams_of("lidar"):
                self.chains[spec.id] = LidarChain(cfg.lidar, spec.mount, self.timer)
        cameras = cfg.streams_of("camera") if cfg.camera["enabled"] else []
        #: the camera network's inference back-end ("opencv", "openvino"), None without one
        self.detector_runtime: str | None = None
        if cameras:
            det = detector
            if det is None:
                base = cfg.path.parent if cfg.path is not None else None
                det = load_detector(cfg.detector, base)
            self.detector_runtime = getattr(det, "runtime", None)
            for spec in cameras:
                self.chains[spec.id] = CameraChain(cfg.camera, det, spec.mount, self.timer)
        self.tracker = make_tracker(cfg.tracker)
        self.vessel_tracker = make_vessel_tracker(cfg.tracker)
        nav = cfg.recording.stream(cfg.navigation[0])
        self.live = LivePose(
            cfg.origin,
            nav.mount.lever_arm if nav.mount is not None else (0.0, 0.0, 0.0),
            cfg.recording.max_pose_gap,
            math.radians(cfg.heading_offset_deg),
            cfg.nav_errors,
            cfg.gyro_heading_bridge,
        )
        self.origin = cfg.origin
        self.epoch: float | None = None
        self.writer: OutputWriter | None = None
        self.counts: dict[str, dict[str, int]] = {
            s.id: {"messages": 0, "no_pose": 0, "damaged": 0} for s in cfg.recording.streams
        }
        self.detections = dict.fromkeys(SENSORS, 0)
        self.scans = 0
        self.track_ids: set[int] = set()
        self.summary: dict[str, Any] = {}
        self._nav: NavTrack | None = None
        self.heading_calibration: HeadingOffset | None = None
        # process(): each NMEA stream's receive delay (s), from its latest timed fix
        self._nav_delay: dict[str, float] = {}
        # process(): the live frames' heading calibration, until it has given its estimate
        self._live_calibrator = (
            HeadingCalibrator(cfg.heading_calibration_s)
            if cfg.heading_calibration_s is not None
            else None
        )

    # --- live -----------------------------------------------------------------------------
    def _live_nav(self, t: float, stream: str, data: Any) -> None:
        from usvfast.nav.stream_types import NmeaFix, NmeaHeading

        if isinstance(data, str):
            parsed = parse_sentence(data)
            if parsed is None:
                return
            kind, values = parsed
            if kind == "fix":
                # A fix is timed by its own UTC time; the stream's other sentences by their
                # receive time less the receive delay of its latest fix.
                utc = sentence_utc(data, t)
                if utc is not None:
                    self._nav_delay[stream] = t - utc
            t -= self._nav_delay.get(stream, 0.0)
            if kind == "fix":
                self.live.add_fix(t, *values)
            elif kind == "attitude":
                self.live.add_attitude(t, *values)
            else:
                self.live.add_heading(t, math.radians(values[0]))
        elif isinstance(data, NmeaFix):
            if data.fix_quality > 0:
                self.live.add_fix(t, data.lat_deg, data.lon_deg, data.fix_quality)
        elif isinstance(data, NmeaHeading):
            self.live.add_heading(t, math.radians(data.heading_deg))
        elif hasattr(data, "lat_deg") and hasattr(data, "status"):  # NavSatFixSample
            if data.status >= 0:
                self.live.add_fix(t, data.lat_deg, data.lon_deg)
        elif hasattr(data, "orientation_xyzw"):  # ImuSample, QuaternionSample
            if not usable_orientations(data.orientation_xyzw)[0]:
                self.counts[stream]["damaged"] += 1  # no orientation estimate
                return
            if stream in self.config.navigation:  # a GNSS heading
                spec = self.config.recording.stream(stream)
                heading = quaternion_heading(data.orientation_xyzw, yaw_convention(spec))
                self.live.add_heading(t, float(heading[0]))
            if stream == self.config.attitude:
                roll, pitch = imu_roll_pitch(data.orientation_xyzw)
                self.live.add_attitude(t, float(roll[0]), float(pitch[0]))
                if self.config.gyro_heading_bridge and hasattr(data, "angular_velocity"):
                    gyro = np.asarray(data.angular_velocity, dtype=np.float64)
                    if gyro.shape == (3,) and np.isfinite(gyro).all():
                        rate = heading_rates(gyro[None], roll, pitch)
                        self.live.add_heading_rate(t, float(rate[0]))
        if self.origin is None and self.live.origin is not None:
            self.origin = self.live.origin

    def process(self, message: Any) -> list[TrackUpdate]:
        """Process one message (see the module doc); returns the track updates it caused.

        A message's own `pose` (a VesselPose, as `run` attaches) is used when present;
        otherwise the pose follows the navigation messages given so far. Sensor messages
        without a pose are counted (`no_pose`) and skipped. Raises ConfigError for a stream
        id the config does not have.
        """
        scan = self._begin(message)
        if scan is None:
            return []
        raw = None
        if isinstance(scan.chain, CameraChain):
            with self.timer("camera.detector"):
                raw = scan.chain.detect(scan.image)
        return self._end(scan, raw)

    def _begin(self, message: Any) -> _Scan | None:
        """The part of `process` that must run in message order: counts, pose, epoch, the
        whole LiDAR chain (it keeps state between rotations), the camera image's checks.
        None when the message gives no scan."""
        t = float(message.time)
        stream = message.stream
        data: Any = getattr(message, "data", None)
        if stream not in self.counts:
            raise ConfigError(
                f"message.stream: {stream!r} is not a stream of the config "
                f"(streams: {sorted(self.counts)})"
            )
        self.counts[stream]["messages"] += 1
        if stream not in self.chains:
            if stream in self.config.navigation or stream == self.config.attitude:
                self._live_nav(t, stream, data)
            return None
        pose = getattr(message, "pose", None)
        live = not isinstance(pose, VesselPose)
        if live:
            pose = self.live.at(t)
        if pose is None:
            self.counts[stream]["no_pose"] += 1
            return None
        if self.epoch is None:
            self.epoch = math.floor(t)
        chain = self.chains[stream]
        if isinstance(chain, LidarChain):
            if live and self._live_calibrator is not None:
                self._calibrate_live(data, pose, chain)
            dets = chain.process(data, pose, self._pose_source(message))
            if dets is None:
                return None
            z = np.array([d.position for d in dets], dtype=np.float64).reshape(-1, 2)
            covs = np.array([d.covariance for d in dets], dtype=np.float64).reshape(-1, 2, 2)
            scores = np.array([d.n_points for d in dets], dtype=np.float64)
            vessel = np.array([bool(d.extended) for d in dets], dtype=bool)
            return _Scan(t, stream, chain, pose, None, (z, covs, scores), vessel)
        image = data.image if hasattr(data, "image") else data
        if not isinstance(image, np.ndarray) or image.ndim not in (2, 3):
            self.counts[stream]["damaged"] += 1
            return None
        if image.dtype != np.uint8:  # e.g. a thermal camera's mono16 counts
            with self.timer("camera.agc"):
                image = to_uint8(image, self.config.camera["agc_percentiles"])
        if image.ndim == 2:
            import cv2

            image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        return _Scan(t, stream, chain, pose, image, None)

    def _end(self, scan: _Scan, raw: Any) -> list[TrackUpdate]:
        """The rest of `process`, in message order: the camera chain after its detector (on
        the detector's result `raw`), the tracker, the outputs."""
        t, pose = scan.time, scan.pose
        assert self.epoch is not None  # set by _begin
        if isinstance(scan.chain, LidarChain):
            sensor = "lidar"
            assert scan.lidar is not None
            z, covs, scores = scan.lidar
            vessel, starts = scan.vessel, None
        else:
            sensor = "camera"
            res = scan.chain.finish(raw, pose)
            z, covs, scores = res.positions, res.covariances, res.scores
            vessel = res.vessel
            start = scan.chain.settings.get("start_confidence")
            starts = None if start is None else np.asarray(scores) >= start
            if self.writer is not None:
                with self.timer("outputs"):
                    self.writer.write_frame(t, scan.image)
        nav_cov = pose.covariance_at(z)  # the navigation's errors reach every detection
        if nav_cov is not None:
            covs = covs + nav_cov
        sid = SENSORS.index(sensor)
        with self.timer("tracker"):
            snap = self._track(round(t - self.epoch, 6), z, sid, covs, vessel, starts)
        self.scans += 1
        self.detections[sensor] += len(z)
        self.track_ids.update(snap.ids.tolist())
        if self.writer is not None:
            with self.timer("outputs"):
                self.writer.write_nav(pose)
                self.writer.write_detections(t, sensor, z, covs, scores)
                self.writer.write_tracks(t, snap)
        return [TrackUpdate(t, sensor, scan.stream, len(z), snap, pose)]

    def _track(
        self,
        t: float,
        z: np.ndarray,
        sid: int,
        covs: np.ndarray,
        vessel: np.ndarray | None,
        starts: np.ndarray | None,
    ) -> Any:
        """One scan through the tracker; with a vessel tracker (tracker.vessels) the `vessel`
        detections go to it, the rest to the floats' tracker, and the snapshots are joined.
        `starts`: which detections may start tracks (None: all)."""
        sensors = np.full(len(z), sid, dtype=np.int64)
        if self.vessel_tracker is None:
            return self.tracker.step(t, z, sensors, covs, starts)
        v = np.zeros(len(z), bool) if vessel is None else vessel
        st = np.ones(len(z), bool) if starts is None else starts
        snap = self.tracker.step(t, z[~v], sensors[~v], covs[~v], st[~v])
        ves = self.vessel_tracker.step(t, z[v], sensors[v], covs[v], st[v])
        return join_snapshots(snap, ves, VESSEL_IDS)

    def _collect(self, scan: _Scan, fut: Future[tuple[Any, float]] | None) -> list[TrackUpdate]:
        """`_end` of a scan whose camera network ran on the worker (`fut`); the network's
        time counts as camera.detector, this thread's wait for it as camera.wait."""
        raw = None
        if fut is not None:
            with self.timer("camera.wait"):
                raw, seconds = fut.result()
            self.timer.add("camera.detector", seconds)
        return self._end(scan, raw)

    def _pose_source(self, message: Any) -> Any:
        """The pose at any time for de-skewing a LiDAR rotation: the recording's track in
        `run`, the live pose otherwise."""
        if isinstance(getattr(message, "pose", None), VesselPose) and self._nav is not None:
            return self._nav.pose_at
        return self.live.at

    # --- whole recording ------------------------------------------------------------------
    def _pose_at(self, t: float) -> VesselPose | None:
        t0 = time.perf_counter()
        try:
            assert self._nav is not None
            return self._nav.pose_at(t)
        finally:
            self._pose_seconds += time.perf_counter() - t0

    def _calibrate_live(self, frame: Any, pose: VesselPose, chain: LidarChain) -> None:
        """Feed a live LiDAR frame to the heading calibration; once it has its estimate, an
        observable correction turns every later pose (the frames before it keep theirs)."""
        assert self._live_calibrator is not None
        with self.timer("calibration.heading"):
            est = self._live_calibrator.add(frame, pose, self.live.at, chain)
        if est is None:
            return
        self._live_calibrator = None
        self.heading_calibration = est
        if est.observable:
            self.live.heading_offset += math.radians(est.offset_deg)

    def _calibrate_heading(self, seconds: float) -> None:
        """Estimate the heading correction from the first `seconds` of LiDAR and, when it is
        observable, add it to the navigation's headings (`usvfast.pipeline.heading`)."""
        assert self._nav is not None
        lidar = {k: c for k, c in self.chains.items() if isinstance(c, LidarChain)}
        with self.timer("calibration.heading"):
            est = calibrate_heading(self.config, self._nav, lidar, seconds)
            if est.observable:
                total = self._nav.heading_offset_deg + est.offset_deg
                self._nav = self._nav.with_heading_offset(total)
        self.heading_calibration = est

    def run(
        self,
        *,
        out: str | Path | None = None,
        truth: str | Path | None = None,
        scene: str | Path | None = None,
        progress: Callable[[float, float], None] | None = None,
        start: float | None = None,
        end: float | None = None,
    ) -> Iterator[TrackUpdate]:
        """Replay the whole recording (optionally from `start` to `end`, UNIX s); yields track
        updates as they happen. With `out`, writes the output files there and, at the end,
        summary.json and (when `outputs.report` and usvfast.report is installed) the report:
        metrics.json against `truth` (truth.csv), map/NIS/error plots and the animation.
        progress(t, span) is called per message with the seconds since the start and the
        recording's span.

        Raises NavigationError when the navigation streams give no GNSS fix or heading, and
        ConfigError (naming the stream and topic) when a bag lacks a configured topic.
        """
        cfg = self.config
        wall0 = time.perf_counter()
        with self.timer("navigation"):
            self._nav = NavTrack.from_config(cfg)
        self.heading_calibration = None
        if cfg.heading_calibration_s is not None:
            self._calibrate_heading(cfg.heading_calibration_s)
        self.origin = self._nav.origin
        self._check_topics()
        sensors = [s.id for s in cfg.recording.streams if s.id in self.chains]
        if not sensors:
            raise ConfigError(
                f"{cfg.path}: no sensor stream: mark LiDAR/camera streams with "
                'sensor = "lidar" or "camera"'
            )
        self._pose_seconds = 0.0
        replay = Replay(
            cfg.recording,
            pose_track=SimpleNamespace(pose_at=self._pose_at),  # type: ignore[arg-type]
            skip_without_pose=True,
            streams=sensors,
            start=start,
            end=end,
        )
        if out is not None:
            self.writer = OutputWriter(
                out,
                self.origin,
                frames_hz=cfg.outputs["frames_hz"] if cfg.outputs["animation"] else 0.0,
                frame_width=cfg.outputs["frame_width"],
                nis_gate=self.tracker.nis_gate,
            )
        first: float | None = None
        last = 0.0
        span = self._nav.end - self._nav.start
        it = replay.__iter__()
        # The camera network on a worker thread while this thread reads, runs the LiDAR chain
        # and the tracker; scans still reach the tracker in message order.
        worker = (
            ThreadPoolExecutor(1, thread_name_prefix="usvfast-camera")
            if cfg.camera["worker_thread"]
            and any(
                isinstance(c, CameraChain) and c.detector is not None for c in self.chains.values()
            )
            else None
        )
        pending: deque[tuple[_Scan, Future[tuple[Any, float]] | None]] = deque()
        try:
            while True:
                t0 = time.perf_counter()
                p0 = self._pose_seconds
                try:
                    item = next(it)
                except StopIteration:
                    break
                dt = time.perf_counter() - t0
                dp = self._pose_seconds - p0
                self.timer.add("reader", dt - dp)
                self.timer.add("pose", dp)
                first = item.time if first is None else first
                last = item.time
                if worker is None:
                    yield from self.process(item)
                else:
                    scan = self._begin(item)
                    if scan is not None:
                        fut = None
                        if isinstance(scan.chain, CameraChain):
                            fut = worker.submit(_timed, scan.chain.detect, scan.image)
                        pending.append((scan, fut))
                    while len(pending) > _LOOKAHEAD:
                        yield from self._collect(*pending.popleft())
                if progress is not None:
                    progress(item.time - self._nav.start, span)
            while pending:
                yield from self._collect(*pending.popleft())
        finally:
            if worker is not None:
                worker.shutdown(wait=True, cancel_futures=True)
            it.close()
            if self.writer is not None:
                self.writer.close()
        for sid, c in replay.counts.items():
            self.counts[sid]["no_pose"] += c.no_pose
            self.counts[sid]["damaged"] += c.damaged + c.out_of_order
        for sid, bad in self._nav.damaged.items():
            self.counts[sid]["damaged"] += bad
        wall = time.perf_counter() - wall0
        duration = 0.0 if first is None else float(last - first)
        self.summary = {
            "recording": cfg.recording.name,
            "config": str(cfg.path),
            "origin": list(self.origin),
            "tracker_backend": cfg.tracker["backend"],
            "detector_runtime": self.detector_runtime,
            "per_detection_covariance": bool(
                getattr(self.tracker, "uses_detection_covariance", self.tracker.per_detection)
            ),
            "start_time": first,
            "end_time": last,
            "duration_s": duration,
            "wall_s": wall,
            "real_time_factor": duration / wall if wall > 0 else math.inf,
            "scans": self.scans,
            "detections": dict(self.detections),
            "tracks": len(self.track_ids),
            "streams": self.counts,
            "damaged_messages": sum(c["damaged"] for c in self.counts.values()),
            "stages": self.timer.as_dict(),
            "heading_offset_deg": cfg.heading_offset_deg,
            "heading_calibration": (
                None if self.heading_calibration is None else self.heading_calibration.as_dict()
            ),
            "coverage": {k: list(v) for k, v in self.coverage().items()},
        }
        if out is not None:
            Path(out, "summary.json").write_text(json.dumps(self.summary, indent=2))
            if cfg.outputs["report"]:
                self.summary["metrics"] = _report(
                    Path(out), truth, scene, self.origin, self.coverage()
                )

    def coverage(self) -> dict[str, tuple[float, float, float]]:
        """What each sensor chain sees: {"lidar" | "camera": (range m, horizontal field of
        view deg, axis yaw deg clockwise from the heading)} (LiDAR: its radius all round;
        camera: its max_range within the calibrated image width). The report counts an
        object as a target while it lies within some sensor's coverage."""
        out: dict[str, tuple[float, float, float]] = {}
        for chain in self.chains.values():
            if isinstance(chain, LidarChain):
                out["lidar"] = (float(chain.config.radius), 360.0, 0.0)
            elif "camera" not in out:
                out["camera"] = chain.coverage()
        return out

    def _check_topics(self) -> None:
        from usvfast.pipeline.streams import check_topic

        for spec in self.config.recording.streams:
            if spec.topic is None or spec.path is None or spec.type not in ("bag", "lidar"):
                continue
            if spec.path.suffix.lower() in (".pcap", ".cap"):
                continue
            try:
                check_topic(spec.path, spec.topic)
            except ValueError as exc:
                raise ConfigError(f"{self.config.path}: stream {spec.id!r}: {exc}") from None


#: Scans read ahead of the tracker while the camera network runs on its worker thread.
_LOOKAHEAD = 3


@dataclass(frozen=True)
class _Scan:
    """A sensor message past `Pipeline._begin`: time (UNIX s), stream id, its chain, the pose,
    the camera image (camera) or the LiDAR detections (z, covariances, scores) and which of
    them are vessels."""

    time: float
    stream: str
    chain: LidarChain | CameraChain
    pose: VesselPose
    image: Any
    lidar: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    vessel: np.ndarray | None = None


def _timed(fn: Callable[[Any], Any], arg: Any) -> tuple[Any, float]:
    """fn(arg) and its wall-clock seconds."""
    t0 = time.perf_counter()
    return fn(arg), time.perf_counter() - t0


def _report(
    out: Path, truth: Any, scene: Any, origin: Any, coverage: dict[str, Any] | None = None
) -> dict[str, Any]:
    """usvfast.report.write_report when it is installed (metrics and pictures), else {}."""
    try:
        from usvfast.report import write_report  # type: ignore[import-not-found]
    except ImportError:
        return {}
    try:
        return (
            write_report(out, truth=truth, scene=scene, origin=tuple(origin), coverage=coverage)
            or {}
        )
    except (ValueError, TypeError, KeyError, OSError) as exc:
        # The run's files are written; a report failure must not lose them.
        warnings.warn(f"report: not written ({type(exc).__name__}: {exc})", stacklevel=3)
        return {"error": f"{type(exc).__name__}: {exc}"}
