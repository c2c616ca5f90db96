"""A short simulated recording read back through the library's own readers (usvfast.nav,
usvfast.lidar) and peers (pymap3d, OpenCV, velodyne-decoder): topics, LiDAR frames from the
bag and from the D1 pcap, camera frames and calibration, NMEA checksums and noise, IMU
attitude, truth against the scene, the configs, and byte-for-byte reproducibility through
the CLI."""

from __future__ import annotations

import csv
import json
import sys
from functools import reduce
from operator import xor
from pathlib import Path

import cv2
import numpy as np
import pymap3d
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from usvfast.camera.calibration import CameraModel
from usvfast.cli import app
from usvfast.frames import rotation_matrix
from usvfast.lidar.pcap import VelodynePcapReader
from usvfast.lidar.readers import BagReader
from usvfast.nav.bags import BagTopic, bag_topics, read_bag_imu, read_bag_nmea
from usvfast.nav.nmea import read_nmea
from usvfast.sim.camera import default_camera
from usvfast.sim.gnss import GNSS_LEVER_ARM, GnssErrors, simulate_gnss
from usvfast.sim.recording import EPOCH, TOPICS, SimulationOptions, simulate
from usvfast.sim.scene import HALF_WIDTH, NORTH, SOUTH, TRUTH_KINDS, make_world

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

SEED, DURATION = 11, 2.0
# outages are rare in 2 s; make one certain so that the test sees the gap
GNSS = GnssErrors(outages_per_minute=40.0)


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim") / "rec"
    opts = SimulationOptions(seed=SEED, duration=DURATION, d1=True, gnss=GNSS)
    return simulate(out, opts)


def test_bag_topics(rec):
    topics = bag_topics(rec.out / "bag")
    assert {t: i.msgtype for t, i in topics.items()} == dict(TOPICS.values())
    counts = {t: i.count for t, i in topics.items()}
    assert counts[TOPICS["image"][0]] == 20  # 10 Hz
    assert counts[TOPICS["imu"][0]] == 101  # 50 Hz
    assert counts[TOPICS["camera_info"][0]] == 2  # 1 Hz
    assert 19 <= counts[TOPICS["lidar"][0]] <= 21  # 10 Hz rotations
    meta = (rec.out / "bag" / "metadata.yaml").read_text()
    assert "compression_mode: message" in meta and "compression_format: zstd" in meta


def test_lidar_from_the_bag_and_the_pcap_agree(rec):
    bag = list(BagReader(rec.out / "bag", topic=TOPICS["lidar"][0]))
    assert len(bag) == rec.counts[TOPICS["lidar"][0]]
    full = bag[1]
    assert len(full) > 1000
    assert np.all(np.diff([f.stamp for f in bag]) > 0.09)
    pcap = list(VelodynePcapReader(rec.out / "d1" / "lidar.pcap", device_time=True))
    a = np.concatenate([f.points for f in bag])
    b = np.concatenate([f.points for f in pcap])
    assert a.shape == b.shape
    for name in ("x", "y", "z", "intensity", "ring"):
        assert np.array_equal(a[name], b[name]), name


def test_camera_frames_and_calibration(rec):
    cam = CameraModel.load(rec.out / "camera_info.yaml")
    ref = default_camera()
    assert np.allclose(cam.camera_matrix, ref.camera_matrix)
    assert np.allclose(cam.dist_coeffs, ref.dist_coeffs) and cam.image_size == (640, 360)
    msgs = list(BagTopic(rec.out / "bag", TOPICS["image"][0]))
    assert len(msgs) == 20 and msgs[0].data.shape == (360, 640, 3)
    times = np.array([m.time for m in msgs])
    assert np.allclose(np.diff(times), 0.1, atol=1e-6)
    info = list(BagTopic(rec.out / "bag", TOPICS["camera_info"][0]))
    assert np.allclose(np.reshape(info[0].data.k, (3, 3)), ref.camera_matrix)
    # the D1 video holds the same frames (mp4v-compressed) at the times of its CSV
    cap = cv2.VideoCapture(str(rec.out / "d1" / "camera.mp4"))
    frames = []
    while True:
        ok, img = cap.read()
        if not ok:
            break
        frames.append(img)
    with open(rec.out / "d1" / "camera_times.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(frames) == len(rows) == 20
    assert np.allclose([float(r["time"]) for r in rows], times, atol=1e-6)
    diff = np.abs(frames[5].astype(float) - msgs[5].data.astype(float)).mean()
    assert diff < 6.0  # grey levels: two lossy codecs of one image


def _sentences(rec):
    return [m.data for m in BagTopic(rec.out / "bag", TOPICS["nmea"][0])]


def test_nmea_checksums_rates_and_latency(rec):
    sentences = _sentences(rec)
    for s in sentences:
        body, given = s[1:].split("*")
        assert int(given, 16) == reduce(xor, body.encode("ascii"), 0)
    kinds = [s[3:6] for s in sentences]
    assert set(kinds) == {"GGA", "RMC", "HDT"}
    log = read_bag_nmea(rec.out / "bag", TOPICS["nmea"][0]).log
    assert log.n_damaged == 0
    # 10 Hz epochs minus the outage (no sentence at all while it lasts)
    epochs = np.round((log.positions.time - EPOCH) * 10).astype(int)
    up = np.flatnonzero(rec.gnss_truth.quality > 0)
    assert (rec.gnss_truth.quality == 0).sum() >= 5, "an outage of at least 0.5 s"
    assert set(epochs) <= set(up) and epochs.size >= up.size - 1
    # header stamps trail the fix time by the receiver latency
    msgs = list(BagTopic(rec.out / "bag", TOPICS["nmea"][0]))
    gga = [(m.time, m.data) for m in msgs if m.data[3:6] == "GGA"]
    for stamp, text in gga:
        hms = text.split(",")[1]
        tod = int(hms[:2]) * 3600 + int(hms[2:4]) * 60 + float(hms[4:])
        lat = (stamp - tod) % 86400
        assert GNSS.latency[0] - 1e-6 <= lat <= GNSS.latency[1] + 0.01


def test_nmea_positions_and_heading_within_the_stated_noise(rec):
    """A minute of the receiver model (no rendering), read back by read_nmea."""
    world = rec.world
    errors = GnssErrors()
    records, truth = simulate_gnss(world, EPOCH, 60.0, errors, seed=3)
    log = read_nmea([r.sentence for r in records])
    assert log.n_damaged == 0
    pos = log.positions
    rel = pos.time - EPOCH
    n, e, h = world.usv.pose(rel)
    roll, pitch, _ = world.waves.at(rel)
    lever = np.asarray(GNSS_LEVER_ARM)
    arm = np.array(
        [rotation_matrix(a, b, c) @ lever for a, b, c in zip(roll, pitch, h, strict=True)]
    )
    lat0, lon0, h0 = world.origin
    mn, me, _ = pymap3d.geodetic2ned(pos.lat_deg, pos.lon_deg, h0, lat0, lon0, h0)
    err = np.column_stack([mn - n - arm[:, 0], me - e - arm[:, 1]])
    fixed = pos.fix_quality == 4
    sigma = errors.horizontal_sigma
    assert fixed.sum() > 400 and (pos.fix_quality == 5).sum() > 0
    assert np.abs(err[fixed]).max() < 5 * sigma
    # white part: epoch-to-epoch differences have std sqrt(2) * position_sigma
    d = np.diff(err[fixed], axis=0)
    assert 0.8 < d.std() / (np.sqrt(2) * errors.position_sigma) < 1.25
    assert np.abs(err[~fixed]).max() < 5 * np.hypot(sigma, errors.float_sigma)
    assert np.allclose(
        truth.measured_ne[truth.quality > 0][:, 0],
        truth.true_ne[truth.quality > 0][:, 0],
        atol=5 * np.hypot(sigma, errors.float_sigma),
    )
    hd = log.headings
    _, _, true_h = world.usv.pose(hd.time - EPOCH)
    dh = np.degrees(np.angle(np.exp(1j * (np.radians(hd.heading_deg) - true_h))))
    bias = np.degrees(truth.heading_bias)
    assert 0.3 <= abs(bias) <= 1.0
    assert np.abs(dh - bias).max() < 5 * errors.heading_sigma_deg
    assert abs(np.mean(dh) - bias) < 4 * errors.heading_sigma_deg / np.sqrt(dh.size)


def test_imu_attitude_is_the_wave_motion(rec):
    imu = read_bag_imu(rec.out / "bag", TOPICS["imu"][0])
    assert np.allclose(np.diff(imu.times), 0.02, atol=1e-6)
    # ENU <- FLU to NED <- FRD, then ZYX angles
    enu_flu = Rotation.from_quat(imu.orientation_xyzw).as_matrix()
    swap = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    ned_frd = swap @ enu_flu @ np.diag([1.0, -1.0, -1.0])
    ypr = Rotation.from_matrix(ned_frd).as_euler("ZYX")
    roll, pitch, _ = rec.world.waves.at(imu.times - EPOCH)
    assert np.degrees(np.abs(ypr[:, 2] - roll)).max() < 0.3
    assert np.degrees(np.abs(ypr[:, 1] - pitch)).max() < 0.3
    assert np.degrees(np.abs(roll)).max() > 0.2  # the sea does move the USV
    assert np.allclose(np.linalg.norm(imu.linear_acceleration, axis=1), 9.81, atol=0.1)


def test_truth_is_consistent_with_the_scene(rec):
    out = rec.out
    origin = json.loads((out / "origin.json").read_text())
    scene = json.loads((out / "scene.json").read_text())
    with open(out / "truth.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == ["time", "object_id", "kind", "north", "east", "lat", "lon"]
    times = sorted({float(r["time"]) for r in rows})
    assert np.allclose(np.diff(times), 0.1) and times[0] == EPOCH and len(times) == 21
    ids = {r["object_id"] for r in rows}
    assert len(rows) == len(ids) * len(times)
    assert {r["kind"] for r in rows} <= set(TRUTH_KINDS)
    floats = [r for r in rows if r["kind"] in ("bottle", "bag", "box")]
    assert 5 <= len({r["object_id"] for r in floats}) <= 15
    n = np.array([float(r["north"]) for r in rows])
    e = np.array([float(r["east"]) for r in rows])
    lat = np.array([float(r["lat"]) for r in rows])
    lon = np.array([float(r["lon"]) for r in rows])
    pn, pe, _ = pymap3d.geodetic2ned(
        lat, lon, origin["height"], origin["lat"], origin["lon"], origin["height"]
    )
    assert np.abs(pn - n).max() < 2e-3 and np.abs(pe - e).max() < 2e-3
    assert np.all((n > SOUTH) & (n < NORTH) & (np.abs(e) < HALF_WIDTH))
    moored = {str(m["id"]): (m["north"], m["east"]) for m in scene["moored"]}
    assert all(r["object_id"].isdigit() for r in rows)
    names = {str(o["id"]): o["kind"] for o in scene["objects"]}
    for r in rows:
        assert names.get(r["object_id"], "moored_boat") == r["kind"]
    for r in rows:
        if r["kind"] == "moored_boat":
            assert (float(r["north"]), float(r["east"])) == pytest.approx(
                moored[r["object_id"]], abs=1e-3
            )
    # floats keep clear of the walls; the USV path starts at the origin
    assert scene["usv"][0][1:3] == [0.0, 0.0] and scene["usv"][0][0] == EPOCH
    fe = np.array([float(r["east"]) for r in floats])
    assert np.abs(fe).max() < HALF_WIDTH - 1.0


def test_configs_name_what_the_recording_holds(rec):
    cfg = tomllib.loads((rec.out / "recording.toml").read_text())
    topics = bag_topics(rec.out / "bag")
    streams = {s["id"]: s for s in cfg["stream"]}
    assert set(streams) == {"gnss", "imu", "lidar", "camera"}
    for s in streams.values():
        assert (rec.out / s["path"]).exists() and s["topic"] in topics
    assert cfg["recording"]["navigation"] == "gnss" and cfg["recording"]["attitude"] == "imu"
    assert streams["lidar"]["sensor"] == "lidar" and streams["camera"]["sensor"] == "camera"
    assert (rec.out / cfg["camera"]["calibration"]).exists()
    d1 = tomllib.loads((rec.out / "recording-d1.toml").read_text())
    for s in d1["stream"]:
        assert (rec.out / s["path"]).exists()
    nmea = read_nmea(rec.out / "d1" / "gnss.nmea")
    bag = read_bag_nmea(rec.out / "bag", TOPICS["nmea"][0]).log
    assert nmea.n_damaged == 0 and nmea.positions.time.size > 0
    assert np.array_equal(nmea.positions.lat_deg, bag.positions.lat_deg)
    assert np.array_equal(nmea.headings.heading_deg, bag.headings.heading_deg)


def test_cli_reproduces_the_recording_byte_for_byte(rec, tmp_path):
    out = tmp_path / "again"
    common = ["simulate", "--seed", str(SEED), "--duration", str(DURATION), "--d1"]
    args = [*common, "--out", str(out)]
    # the fixture used a custom outage rate; the CLI has the default one, so compare a CLI
    # run with another CLI run and the fixture's files that the GNSS model does not touch
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    assert "wrote" in res.output
    res2 = CliRunner().invoke(app, [*common, "--out", str(tmp_path / "third")])
    assert res2.exit_code == 0, res2.output
    files = sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file())
    assert len(files) >= 12
    for f in files:
        assert (out / f).read_bytes() == (tmp_path / "third" / f).read_bytes(), f
    for f in ("truth.csv", "scene.json", "d1/camera.mp4", "camera_info.yaml"):
        assert (out / f).read_bytes() == (rec.out / f).read_bytes(), f


def test_cli_bad_arguments(tmp_path):
    res = CliRunner().invoke(app, ["simulate", "--duration", "-1", "--out", str(tmp_path / "x")])
    assert res.exit_code != 0 and "duration" in res.output
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("x")
    res = CliRunner().invoke(app, ["simulate", "--duration", "1", "--out", str(tmp_path / "full")])
    assert res.exit_code != 0 and "out" in res.output
    assert not Path(tmp_path / "x").exists()


def test_the_bundled_recording_is_the_current_simulator_s(rec):
    """The demo bundle (seed 7, 30 s) reads back, its truth is make_world(7, 30)'s and its
    sensor models and tracker settings are the ones the simulator writes now."""
    folder = Path(__file__).resolve().parents[1] / "python" / "usvfast" / "data" / "harbour"
    bundled = tomllib.loads((folder / "recording.toml").read_text())
    fresh = tomllib.loads((rec.out / "recording.toml").read_text())
    for table in ("lidar", "camera", "detector", "tracker"):
        assert bundled[table] == fresh[table], table
    key = "heading_calibration_s"
    assert bundled["recording"][key] == fresh["recording"][key]
    topics = bag_topics(folder / "bag")
    assert {t: i.count for t, i in topics.items()}[TOPICS["image"][0]] == 300
    assert {t: i.count for t, i in topics.items()}[TOPICS["lidar"][0]] >= 299
    cfg = tomllib.loads((folder / "recording.toml").read_text())
    assert {s["topic"] for s in cfg["stream"]} <= set(topics)
    with open(folder / "truth.csv") as fh:
        rows = list(csv.DictReader(fh))
    world = make_world(7, 30.0)
    names = {v: k for k, v in world.truth_ids().items()}
    for r in rows[:: len(rows) // 50]:
        oid = names[int(r["object_id"])]
        t = float(r["time"]) - EPOCH
        n, e = next((n, e) for i, _, n, e in world.truth_at(np.array([t])) if i == oid)
        assert (float(r["north"]), float(r["east"])) == pytest.approx((n[0], e[0]), abs=1e-4)
    # its visibility.csv (what each sensor saw, for the report's detectable rule) is this
    # recording's: every object a truth object, every row inside the recording's 30 s
    from usvfast.report.detectable import read_visibility

    vis = read_visibility(folder / "visibility.csv")
    assert vis.skipped == 0 and set(vis.sensor) == {"lidar", "camera"}
    assert set(vis.object_id) <= {int(r["object_id"]) for r in rows}
    assert EPOCH <= vis.time.min() and vis.time.max() <= EPOCH + 30.0
    lidar = vis.sensor == "lidar"
    assert (
        len(np.unique(vis.time[lidar]))
        <= {t: i.count for t, i in topics.items()}[TOPICS["lidar"][0]]
    )
