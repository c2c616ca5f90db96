"""The pipeline end to end on a small simulated recording (tests/pipeline_recording.py: VLP-16
PointCloud2, NMEA sentences, IMU and rendered camera frames in one rosbag2): tracks against
the truth, Stone Soup's own tracker giving the same tracks, live `process`, the output files,
and bad input (missing topic, calibration, GNSS; wrong types; damaged messages)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import chi2

from usvfast.frames import Mount, sensor_to_ned
from usvfast.lidar import LidarDetector
from usvfast.nav.replay import Replay
from usvfast.pipeline import ConfigError, NavigationError, Pipeline, load_config
from usvfast.pipeline.config import preset_names
from usvfast.pipeline.lidar_chain import level_points
from usvfast.pipeline.orientation import imu_roll_pitch
from usvfast.pipeline.timing import StageTimer

import pipeline_recording as pr


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    return pr.build(tmp_path_factory.mktemp("rec"), duration=12.0, damaged_images=2)


@pytest.fixture(scope="module")
def run(rec):
    out = rec.root / "out"
    pipe = Pipeline(rec.config, detector=pr.disc_detector)
    with pytest.warns(UserWarning, match="skipped 2"):
        updates = list(pipe.run(out=out, truth=rec.truth))
    return pipe, updates, out


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_every_float_tracked_no_track_on_boats(rec, run):
    pipe, updates, out = run
    tracks = _rows(out / "tracks.csv")
    by_id: dict[int, list[tuple[float, float]]] = {}
    for r in tracks:
        by_id.setdefault(int(r["track_id"]), []).append((float(r["north"]), float(r["east"])))
    # Every float stays within the LiDAR's 10 m radius for > 5 s of the 12 s run.
    assert len(rec.floats) == 5
    errors = []
    for f in rec.floats:
        best = min(by_id.values(), key=lambda p: np.hypot(*(np.mean(p, axis=0) - f)))
        errors.append(np.sqrt(np.mean(np.sum((np.array(best) - f) ** 2, axis=1))))
    # Position RMSE of each float's track (all its states) below 0.3 m.
    assert max(errors) < 0.3, errors
    # One track per float: no track anywhere else (walls, moored boats, clutter).
    assert len(by_id) == len(rec.floats)
    for pts in by_id.values():
        d_boat = np.min(np.hypot(*(np.mean(pts, axis=0) - rec.boats).T))
        assert d_boat > 2.0
    assert pipe.summary["tracks"] == 5
    assert updates[-1].tracks.ids.size == 5
    # The same through usvfast.report (the thesis's metrics, section 4.3 / 7.3.1 matching).
    thesis = json.loads((out / "metrics.json").read_text())["thesis"]
    assert thesis["targets_tracked"] == thesis["n_targets"] == 5
    assert thesis["rmse"] < 0.3 and thesis["max_trf"] <= 1.5
    assert thesis["false_tracks"] == []
    assert (out / "map.png").stat().st_size > 10_000


def test_output_files_and_summary(rec, run):
    _, _, out = run
    header = {
        "tracks.csv": "time,track_id,north,east,v_north,v_east,lat,lon,cov_nn,cov_ne,cov_ee",
        "detections.csv": "time,sensor,north,east,lat,lon,cov_nn,cov_ne,cov_ee,score",
        "nav.csv": "time,north,east,lat,lon,heading_deg,roll_deg,pitch_deg",
        "innovations.csv": "time,track_id,sensor,nis,dof,gate",
    }
    for name, cols in header.items():
        assert (out / name).read_text().splitlines()[0] == cols
    dets = _rows(out / "detections.csv")
    assert {d["sensor"] for d in dets} == {"lidar", "camera"}
    innovations = _rows(out / "innovations.csv")
    nis = np.array([float(r["nis"]) for r in innovations])
    assert nis.size > 100 and np.all(nis >= 0)
    # every NIS comes from a detection inside the tracker's gate, which the file names
    prob_gate = load_config(rec.config).tracker["prob_gate"]
    assert {float(r["gate"]) for r in innovations} == {prob_gate}
    assert nis.max() <= chi2.ppf(prob_gate, 2) + 1e-4
    gj = json.loads((out / "tracks.geojson").read_text())
    assert len(gj["features"]) == 5
    lon, lat = gj["features"][0]["geometry"]["coordinates"][0]
    assert abs(lat - pr.ORIGIN[0]) < 1e-3 and abs(lon - pr.ORIGIN[1]) < 1e-3
    frames = _rows(out / "camera_frames" / "camera_frames.csv")
    assert 20 <= len(frames) <= 26  # ~2 Hz over 12 s
    assert (out / "camera_frames" / frames[0]["file"]).stat().st_size > 1000
    summary = json.loads((out / "summary.json").read_text())
    assert summary["streams"]["camera"]["damaged"] == 2
    assert summary["damaged_messages"] == 2
    assert summary["duration_s"] == pytest.approx(12.0, abs=0.1)
    for stage in ("reader", "pose", "lidar.prefilter", "lidar.mean_shift", "camera.detector"):
        assert summary["stages"][stage]["calls"] > 0
    assert summary["real_time_factor"] > 0
    lidar_range = load_config(rec.config).lidar["radius"]
    assert summary["coverage"]["lidar"] == [lidar_range, 360.0, 0.0]
    assert set(summary["coverage"]) == {"lidar", "camera"}


def test_stonesoup_backend_gives_the_same_tracks(rec):
    # Codes 5.7-5.8, every detection with its own covariance (Stone Soup: its own
    # LinearGaussian); the same again with each sensor's R.
    cfg = load_config(rec.config)
    assert Pipeline(cfg, detector=pr.disc_detector).tracker.uses_detection_covariance
    _same_tracks(cfg, 8.0)
    _same_tracks(load_config(rec.config, {"tracker.per_detection_covariance": False}), 5.0)


def _same_tracks(cfg, seconds):
    runs = []
    for backend in ("native", "stonesoup"):
        pipe = Pipeline(cfg.with_options(tracker={"backend": backend}), detector=pr.disc_detector)
        with pytest.warns(UserWarning, match="skipped 2"):
            runs.append(list(pipe.run(end=pr.EPOCH + seconds)))
    a, b = runs
    assert len(a) == len(b) > 30
    seen_a: set[int] = set()
    seen_b: set[int] = set()
    for x, y in zip(a, b, strict=True):
        assert x.time == y.time
        # Same births and deaths: the same number of tracks after every scan, new ids together.
        assert len(x.tracks.ids) == len(y.tracks.ids)
        assert len(set(x.tracks.ids) - seen_a) == len(set(y.tracks.ids) - seen_b)
        seen_a |= set(x.tracks.ids.tolist())
        seen_b |= set(y.tracks.ids.tolist())
        oa = np.lexsort(x.tracks.states.T[::-1])
        ob = np.lexsort(y.tracks.states.T[::-1])
        np.testing.assert_allclose(x.tracks.states[oa], y.tracks.states[ob], atol=1e-6, rtol=0)
        np.testing.assert_allclose(
            x.tracks.covariances[oa], y.tracks.covariances[ob], atol=1e-6, rtol=0
        )
    assert len(seen_a) >= 4


def test_camera_worker_thread_gives_the_same_updates(rec):
    # The detector on a worker thread (default) or inline: the same scans in the same order.
    runs, stages = [], []
    for worker in (True, False):
        cfg = load_config(rec.config, {"camera.worker_thread": worker})
        pipe = Pipeline(cfg, detector=pr.disc_detector)
        with pytest.warns(UserWarning, match="skipped 2"):
            runs.append(list(pipe.run(end=pr.EPOCH + 6.0)))
        stages.append(pipe.summary["stages"])
    a, b = runs
    assert [(u.time, u.sensor, u.detections) for u in a] == [
        (u.time, u.sensor, u.detections) for u in b
    ]
    assert {u.sensor for u in a} == {"lidar", "camera"}
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.tracks.ids, y.tracks.ids)
        np.testing.assert_array_equal(x.tracks.states, y.tracks.states)
    assert stages[0]["camera.detector"]["calls"] == stages[1]["camera.detector"]["calls"] > 0
    assert "camera.wait" in stages[0] and "camera.wait" not in stages[1]


def test_process_live_follows_navigation_messages(rec):
    cfg = load_config(rec.config)
    pipe = Pipeline(cfg, detector=pr.disc_detector)
    updates = []
    with pytest.warns(UserWarning, match="skipped 2"):
        for item in Replay(cfg.recording, end=pr.EPOCH + 8.0):  # no pose attached
            updates += pipe.process(item)
    assert pipe.counts["gnss"]["messages"] > 200
    assert updates and updates[-1].tracks.ids.size >= 4
    # The live pose (extrapolated from the latest fixes) matches the simulated path.
    poses = np.array([[u.time - pr.EPOCH, u.pose.north, u.pose.heading] for u in updates])
    np.testing.assert_allclose(poses[:, 1], pr.START_N + pr.SPEED * poses[:, 0], atol=0.05)


def test_level_points_equals_sensor_to_ned():
    rng = np.random.default_rng(1)
    from usvfast.lidar.frame import make_points

    xyz = rng.uniform(-8, 8, (50, 3))
    pts = make_points(xyz[:, 0], xyz[:, 1], xyz[:, 2])
    mount = Mount(lever_arm=[0.5, -0.2, -0.7], roll=0.02, pitch=-0.03, yaw=0.05)
    roll, pitch = 0.08, -0.05
    out = level_points(pts, mount, roll, pitch)
    # Peer: frames.sensor_to_ned with heading 0 (NED = level frame) on FRD sensor points.
    ned = sensor_to_ned(xyz * [1, -1, -1], mount, roll, pitch, 0.0, [0.0, 0.0, 0.0])
    np.testing.assert_allclose(out["x"], ned[:, 0] - 0.5, atol=1e-5)
    np.testing.assert_allclose(out["y"], -(ned[:, 1] + 0.2), atol=1e-5)
    np.testing.assert_allclose(out["z"], -ned[:, 2], atol=1e-5)


def test_timed_numpy_line_of_sight_detector_equals_the_plain_one(rec):
    # The thesis stack's numpy line-of-sight filter (the benchmark's peer), timed per stage,
    # gives the plain Rust detector's results.
    from usvfast.lidar import BagReader, LidarConfig
    from usvfast.lidar.line_of_sight import line_of_sight_filter_numpy

    cfg = LidarConfig(mount_height=1.2, lever_arm=(0.5, 0.0))
    timer = StageTimer()
    ref = LidarDetector(cfg)
    timed = LidarDetector(cfg, stage_timer=timer, line_of_sight=line_of_sight_filter_numpy)
    for k, frame in enumerate(BagReader(rec.bag, topic="/velodyne_points")):
        pose = pr.vessel(frame.stamp - pr.EPOCH)
        a, b = ref.process(frame, pose), timed.process(frame, pose)
        np.testing.assert_array_equal(a.keep, b.keep)
        np.testing.assert_array_equal(a.world, b.world)
        assert (a.cycle is None) == (b.cycle is None)
        if a.cycle is not None:
            assert len(a.cycle.detections) == len(b.cycle.detections)
        if k == 20:
            break
    assert timer.calls["lidar.line_of_sight"] == 21 and timer.calls["lidar.mean_shift"] >= 1


def test_imu_roll_pitch_from_rep103():
    from scipy.spatial.transform import Rotation

    # Body FLU in ENU: roll 5 deg (starboard down), nose up 3 deg, yaw 30 deg.
    q = Rotation.from_euler("ZYX", [30.0, -3.0, 5.0], degrees=True).as_quat()
    roll, pitch = imu_roll_pitch(q)
    assert math.degrees(roll[0]) == pytest.approx(5.0, abs=1e-9)
    assert math.degrees(pitch[0]) == pytest.approx(3.0, abs=1e-9)
    # Many random attitudes: scipy's Rotation is the peer for the quaternion algebra.
    rng = np.random.default_rng(2)
    ypr = rng.uniform([-180, -30, -30], [180, 30, 30], (100, 3))
    roll, pitch = imu_roll_pitch(Rotation.from_euler("ZYX", ypr, degrees=True).as_quat())
    np.testing.assert_allclose(np.degrees(roll), ypr[:, 2], atol=1e-9)
    np.testing.assert_allclose(np.degrees(pitch), -ypr[:, 1], atol=1e-9)


def test_thesis_preset_shipped_and_overrides(rec):
    root = Path(__file__).resolve().parents[1]
    assert "thesis" in preset_names()
    # One source: the packaged preset; no copy elsewhere in the repository, and the README
    # names the packaged file.
    shipped = root / "python/usvfast/pipeline/presets/thesis.toml"
    assert shipped.is_file()
    copies = [
        p
        for p in root.rglob("thesis.toml")
        if p != shipped and not {".venv", "target", "build"} & set(p.parts)
    ]
    assert copies == [], copies
    assert "python/usvfast/pipeline/presets/thesis.toml" in (root / "README.md").read_text()
    cfg = load_config(rec.config, {"tracker.prob_detect": 0.9, "lidar.radius": 12.0})
    assert cfg.tracker["prob_detect"] == 0.9 and cfg.lidar["radius"] == 12.0
    assert cfg.tracker["q"] == 0.001 and cfg.tracker["clutter_density"] == 0.125  # Code 5.7
    assert cfg.camera["min_confidence"] == 0.35  # Code 5.5


# --- bad input ---------------------------------------------------------------------------
def _edit(rec, tmp_path, old: str, new: str) -> Path:
    text = rec.config.read_text()
    assert old in text
    path = tmp_path / "edited.toml"
    path.write_text(text.replace(old, new).replace('path = "bag"', f'path = "{rec.bag}"'))
    (tmp_path / "camera_info.yaml").write_text((rec.root / "camera_info.yaml").read_text())
    return path


def test_bag_without_the_configured_topic(rec, tmp_path):
    path = _edit(rec, tmp_path, 'topic = "/velodyne_points"', 'topic = "/velodyne_packets"')
    pipe = Pipeline(path, detector=pr.disc_detector)
    with pytest.raises(ConfigError, match=r"stream 'lidar'.*'/velodyne_packets' is not in bag"):
        list(pipe.run())


def test_missing_calibration(rec, tmp_path):
    path = _edit(rec, tmp_path, 'calibration = "camera_info.yaml"\n', "")
    with pytest.raises(ConfigError, match=r"edited\.toml: key 'camera\.calibration': missing"):
        load_config(path)
    path = _edit(rec, tmp_path, 'calibration = "camera_info.yaml"', 'calibration = "nope.yaml"')
    with pytest.raises(ConfigError, match=r"camera\.calibration.*nope\.yaml does not exist"):
        load_config(path)


def test_config_key_of_the_wrong_type_or_unknown(rec, tmp_path):
    path = _edit(rec, tmp_path, "[lidar]\n", '[lidar]\nradius = "ten"\n')
    with pytest.raises(ConfigError, match=r"edited\.toml: key 'lidar\.radius': expected a finite"):
        load_config(path)
    path = _edit(rec, tmp_path, "[lidar]\n", "[lidar]\nradious = 10.0\n")
    with pytest.raises(ConfigError, match=r"key 'lidar\.radious': unknown"):
        load_config(path)
    path = _edit(rec, tmp_path, 'preset = "thesis"', 'preset = "nope"')
    with pytest.raises(ConfigError, match=r"key 'preset': 'nope' is not a preset"):
        load_config(path)


def test_recording_without_gnss(tmp_path):
    built = pr.build(tmp_path / "nognss", duration=1.0, camera=False, gnss=False)
    pipe = Pipeline(built.config)
    with pytest.raises(NavigationError, match=r"no GNSS position fix.*'gnss'"):
        list(pipe.run())


def test_nav_track_pose_equals_channel_interpolation(rec):
    from usvfast.pipeline.pose import NavTrack

    nav = NavTrack.from_config(load_config(rec.config))
    times = np.random.default_rng(0).uniform(nav.start, nav.end, 200)
    for t in times:
        pose = nav.pose_at(t)
        n, e = nav.position.at(np.array([t]))[0]
        assert (pose.north, pose.east) == pytest.approx((n, e), abs=1e-9)
        # The reference point is the antenna 0.94 m forward (heading north).
        assert pose.north == pytest.approx(pr.START_N + pr.SPEED * (t - pr.EPOCH), abs=1e-3)
    assert nav.pose_at(nav.end + 10.0) is None


def test_video_times_stream(tmp_path):
    import cv2

    from usvfast.nav.stream_types import StreamSpec, open_stream

    path = tmp_path / "cam.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 4.0, (64, 48))
    for k in range(6):
        w.write(np.full((48, 64, 3), 40 * k, np.uint8))
    w.release()
    # Frame 4 has no time (dropped and counted); times need not be evenly spaced.
    rows = "frame,time\n0,100.0\n1,100.26\n2,100.49\n3,100.77\n5,101.3\n"
    (tmp_path / "times.csv").write_text(rows)
    spec = StreamSpec("cam", "video_times", path, options={"times": "times.csv"})
    records = open_stream(spec)
    got = list(records)
    assert [t for t, _ in got] == [100.0, 100.26, 100.49, 100.77, 101.3]
    assert got[2][1].shape == (48, 64, 3) and abs(int(got[2][1].mean()) - 80) <= 3
    assert records.damaged == 1
    with pytest.raises(ValueError, match="times"):
        open_stream(StreamSpec("cam", "video_times", path, options={"times": "none.csv"}))


def test_level_points_deskews_the_rotation():
    from usvfast.lidar.frame import make_points

    # A fixed point at NED (10, 3) seen during a rotation in which the vessel moves 1 m north
    # and turns 0.1 rad: each firing sees it from the pose of its own time.
    mount = Mount(lever_arm=[0.4, 0.1, -0.6])
    frac = np.linspace(1.0, 0.0, 11)  # first firing ... stamp
    north, heading = 1.0 * (1 - frac), 0.3 + 0.1 * (1 - frac)
    target = np.array([10.0, 3.0])
    xyz = []
    for n, h in zip(north, heading, strict=True):
        c, s = np.cos(h), np.sin(h)
        d = target - [n, 0.0]
        body = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], 0.5]) - mount.lever_arm
        xyz.append(body * [1, -1, -1])  # FRD -> Velodyne FLU
    xyz = np.array(xyz)
    pts = make_points(xyz[:, 0], xyz[:, 1], xyz[:, 2])
    h1 = heading[-1]
    motion = (north - north[-1], np.zeros(11), heading - h1, h1)
    out = level_points(pts, mount, 0.0, 0.0, motion)
    c, s = np.cos(h1), np.sin(h1)
    d = target - [north[-1], 0.0]
    want = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]) - mount.lever_arm[:2]
    np.testing.assert_allclose(out["x"], want[0], atol=1e-5)
    np.testing.assert_allclose(out["y"], -want[1], atol=1e-5)
    skewed = level_points(pts, mount, 0.0, 0.0)
    assert np.ptp(skewed["x"]) > 0.5  # without de-skewing the point smears over the turn


def test_cli_run_prints_the_summary(rec, tmp_path):
    from typer.testing import CliRunner

    from usvfast.cli import app

    runner = CliRunner()
    out = tmp_path / "cli"
    args = ["run", str(rec.config), "--out", str(out), "--set", "outputs.report=false"]
    with pytest.warns(UserWarning, match="skipped 2"):  # the recording's damaged frames
        result = runner.invoke(app, [*args, "--set", "tracker.backend='native'"])
    assert result.exit_code == 0, result.output
    assert "real-time factor" in result.output and "lidar.mean_shift" in result.output
    assert json.loads((out / "summary.json").read_text())["tracks"] >= 4
    bad = runner.invoke(app, [*args, "--set", "lidar.radius='ten'"])
    assert bad.exit_code == 2 and "lidar.radius" in bad.output
