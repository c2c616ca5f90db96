"""The GNSS heading's constant error from the LiDAR's view of the static world
(`usvfast.nav.heading_offset`, `usvfast.pipeline.heading`, recording.heading_offset_deg /
heading_calibration_s)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from usvfast.nav.heading_offset import estimate_heading_offset, sharpness
from usvfast.pipeline.config import ConfigError, load_config
from usvfast.pipeline.live_pose import LivePose
from usvfast.pipeline.pose import NavTrack

BUNDLED = Path(__file__).resolve().parents[1] / "python" / "usvfast" / "data" / "harbour"


def _harbour(rng: np.random.Generator) -> np.ndarray:
    """Static structure (m, NED): two quays and a pier as dense point lines, boxes of boats."""
    lines = [((-5.0, 12.0), (45.0, 12.0)), ((-5.0, -14.0), (45.0, -16.0)), ((30, -16), (30, -4))]
    pts = []
    for (n0, e0), (n1, e1) in lines:
        f = rng.uniform(0, 1, 4000)
        pts.append(np.column_stack([n0 + f * (n1 - n0), e0 + f * (e1 - e0)]))
    for n, e in ((10.0, 9.0), (22.0, -11.0)):  # moored boats: rectangles' outlines
        f = rng.uniform(0, 1, 600)
        pts.append(np.column_stack([n + 6 * f - 3, np.full(600, e + rng.choice([-1.1, 1.1]))]))
    return np.concatenate(pts)


def _frames(bias_deg: float, seed: int, moving: bool = True):
    """Body FRD points and biased poses of a vessel running 30 m up the harbour, turning."""
    rng = np.random.default_rng(seed)
    world = _harbour(rng)
    points, poses = [], []
    for k in range(40):
        s = k / 39
        north = 2.0 + 30.0 * s if moving else 2.0
        east = 3.0 * math.sin(4 * s) if moving else 0.0
        heading = 0.3 * math.sin(6 * s) + (0.0 if moving else 2.0 * s)  # turns, rad
        d = world - [north, east]
        c, sn = math.cos(heading), math.sin(heading)
        x, y = c * d[:, 0] + sn * d[:, 1], -sn * d[:, 0] + c * d[:, 1]  # NED -> body FRD
        seen = np.hypot(x, y) < 40
        body = np.column_stack([x[seen], y[seen]]) + rng.normal(0, 0.02, (int(seen.sum()), 2))
        points.append(body)
        poses.append((north, east, heading + math.radians(bias_deg)))
    return points, np.array(poses)


@pytest.mark.parametrize("seed", range(4))
def test_a_heading_bias_is_found_from_the_static_world(seed):
    bias = float(np.random.default_rng(100 + seed).uniform(-2.0, 2.0))
    est = estimate_heading_offset(*_frames(bias, seed))
    assert est.observable
    assert est.offset_deg == pytest.approx(-bias, abs=0.03)
    assert est.baseline_m > 25 and est.contrast > 1.5 and est.frames == 40
    # the corrected map is sharper than the uncorrected one
    assert est.scores.max() > est.scores[np.argmin(np.abs(est.angles_deg))]


def test_turning_on_the_spot_leaves_the_offset_unobservable():
    est = estimate_heading_offset(*_frames(1.0, 0, moving=False))
    assert not est.observable and math.isnan(est.offset_deg)
    assert est.baseline_m < 1.0
    assert est.as_dict()["offset_deg"] is None


def _sharpness_numpy(xy, north, east, heading, cell):
    """The score written plainly (the oracle of the Rust loop)."""
    c, s = np.cos(heading), np.sin(heading)
    pn = (north + c * xy[:, 0] - s * xy[:, 1]) / cell
    pe = (east + s * xy[:, 0] + c * xy[:, 1]) / cell
    total = 0.0
    for shift in (0.0, 0.5):
        keys = np.floor(np.column_stack([pn, pe]) + shift).astype(np.int64)
        _, counts = np.unique(keys, axis=0, return_counts=True)
        total += float((counts.astype(float) ** 2).sum())
    return total / (2.0 * len(xy) ** 2)


def test_sharpness_is_highest_for_coincident_points():
    xy = np.array([[1.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    zero = np.zeros(3)
    tight = sharpness(xy, zero, zero, zero, np.array([0.0]), 0.1)
    spread = sharpness(xy + np.array([[0, 0], [0.5, 0], [0, 0]]), zero, zero, zero, [0.0], 0.1)
    assert tight[0] == pytest.approx(5 / 9) and spread[0] == pytest.approx(3 / 9)


@pytest.mark.parametrize("seed", range(3))
def test_the_rust_score_equals_the_plain_one(seed):
    points, poses = _frames(0.7, seed)
    counts = [len(p) for p in points]
    xy = np.concatenate(points)
    frame = np.repeat(np.arange(len(points)), counts)
    n, e, h = poses[frame, 0], poses[frame, 1], poses[frame, 2]
    offsets = np.array([-1.0, -0.7, 0.0, 0.35])
    ours = sharpness(xy, n, e, h, offsets, 0.1)
    plain = [_sharpness_numpy(xy, n, e, h + np.radians(d), 0.1) for d in offsets]
    assert ours == pytest.approx(plain, rel=1e-12)


def test_sharpness_refuses_bad_input():
    xy, one = np.ones((2, 2)), np.zeros(2)
    with pytest.raises(ValueError, match="cell"):
        sharpness(xy, one, one, one, [0.0], 0.0)
    with pytest.raises(ValueError, match="north"):
        sharpness(xy, np.zeros(3), one, one, [0.0], 0.1)
    with pytest.raises(ValueError, match="offsets"):
        sharpness(xy, one, one, one, [float("nan")], 0.1)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"poses": np.zeros((2, 3))}, "poses"),
        ({"poses": np.zeros(3)}, "poses"),
        ({"points": [np.zeros((3, 3))]}, "points[0]"),
        ({"points": [np.full((2, 2), np.nan)]}, "points[0]"),
        ({"points": [np.zeros((0, 2))]}, "points"),
        ({"cell": 0.0}, "cell"),
        ({"span_deg": -1.0}, "span_deg"),
        ({"fine_step_deg": float("nan")}, "fine_step_deg"),
        ({"min_contrast": 0.5}, "min_contrast"),
    ],
)
def test_bad_input_names_the_argument(kwargs, name):
    args = {"points": [np.ones((4, 2))], "poses": np.zeros((1, 3))}
    args.update(kwargs)
    with pytest.raises((ValueError, TypeError), match=name.replace("[", r"\[")):
        estimate_heading_offset(args.pop("points"), args.pop("poses"), **args)


def test_the_offset_turns_every_heading():
    cfg = load_config(BUNDLED / "recording.toml")
    plain = NavTrack.from_config(cfg)
    turned = plain.with_heading_offset(1.5)
    assert turned.with_heading_offset(0.0).pose_at(plain.start + 1.0) == plain.pose_at(
        plain.start + 1.0
    )
    t = 0.5 * (plain.start + plain.end)
    a, b = plain.pose_at(t), turned.pose_at(t)
    assert a is not None and b is not None
    diff = (b.heading - a.heading + math.pi) % (2 * math.pi) - math.pi
    assert diff == pytest.approx(math.radians(1.5), abs=1e-9)
    live = LivePose(heading_offset=math.radians(-2.0))
    live.add_fix(0.0, 63.0, 10.0)
    live.add_heading(0.0, 1.0)
    pose = live.at(0.0)
    assert pose is not None and pose.heading == pytest.approx(1.0 - math.radians(2.0))


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("heading_offset_deg", 200.0, "heading_offset_deg"),
        ("heading_offset_deg", "1", "heading_offset_deg"),
        ("heading_calibration_s", 0.0, "heading_calibration_s"),
        ("heading_calibration_s", -3.0, "heading_calibration_s"),
    ],
)
def test_bad_heading_keys_are_config_errors(key, value, message):
    with pytest.raises(ConfigError, match=message):
        load_config(BUNDLED / "recording.toml", {f"recording.{key}": value})


def test_the_bundled_recordings_heading_bias_is_found():
    """On the demo recording (seed 7) the calibration finds the simulator's heading bias
    (drawn from the seed, unknown to the pipeline) to within 0.15 degrees."""
    from usvfast.pipeline import Pipeline
    from usvfast.sim.gnss import GnssErrors, simulate_gnss
    from usvfast.sim.recording import EPOCH
    from usvfast.sim.scene import make_world

    cfg = load_config(BUNDLED / "recording.toml")
    assert cfg.heading_calibration_s == 30.0
    _, truth = simulate_gnss(make_world(7, 30.0), EPOCH, 30.0, GnssErrors(), seed=7)
    pipe = Pipeline(cfg)
    pipe._nav = NavTrack.from_config(cfg)
    pipe._calibrate_heading(cfg.heading_calibration_s)
    est = pipe.heading_calibration
    assert est is not None and est.observable
    assert est.offset_deg == pytest.approx(-math.degrees(truth.heading_bias), abs=0.15)
    assert abs(truth.heading_bias) > math.radians(0.3)  # so the test could fail


def test_the_summary_table_shows_the_heading_correction():
    from rich.console import Console

    from usvfast.pipeline.command import summary_tables

    summary = {
        "recording": "r",
        "duration_s": 30.0,
        "wall_s": 5.0,
        "real_time_factor": 6.0,
        "scans": 1,
        "detections": {"lidar": 1, "camera": 0},
        "tracks": 1,
        "damaged_messages": 0,
        "tracker_backend": "native",
        "stages": {},
        "heading_calibration": {"offset_deg": 0.947, "baseline_m": 32.1, "observable": True},
    }
    console = Console(width=120, record=True)
    console.print(summary_tables(summary)[0])
    assert "+0.95 deg (over 32 m)" in console.export_text()
    summary["heading_calibration"] = {"offset_deg": None, "baseline_m": 0.4, "observable": False}
    console.print(summary_tables(summary)[0])
    assert "not observable (0 m travelled)" in console.export_text()


def test_a_heading_calibration_without_lidar_is_a_config_error():
    with pytest.raises(ConfigError, match=r"heading_calibration_s.*LiDAR"):
        load_config(BUNDLED / "recording.toml", {"lidar.enabled": False})


def test_process_calibrates_the_heading_on_live_frames():
    """Fed live (no pose attached), the pipeline takes the first 25 s of LiDAR, then turns
    every later pose by its estimate: Pipeline.run's estimate over the same 25 s to within
    0.06 deg (the live pose extrapolates its newest samples to each frame's stamp, the
    recording's interpolates; both time the NMEA fixes by their own UTC times)."""
    from usvfast.nav.replay import Replay
    from usvfast.pipeline import Pipeline

    cfg = load_config(
        BUNDLED / "recording.toml",
        {"camera.enabled": False, "recording.heading_calibration_s": 25.0},
    )
    batch = Pipeline(cfg)
    batch._nav = NavTrack.from_config(cfg)
    batch._calibrate_heading(25.0)
    assert batch.heading_calibration is not None
    pipe = Pipeline(cfg)
    for message in Replay(cfg.recording):
        pipe.process(message)
    est = pipe.heading_calibration
    assert est is not None and est.observable
    assert abs(est.frames - batch.heading_calibration.frames) <= 1
    assert est.offset_deg == pytest.approx(batch.heading_calibration.offset_deg, abs=0.06)
    # the live pose now carries the correction
    assert pipe.live.heading_offset == pytest.approx(math.radians(est.offset_deg))
    t = message.time
    turned = pipe.live.at(t)
    pipe.live.heading_offset = 0.0
    plain = pipe.live.at(t)
    assert turned is not None and plain is not None
    diff = (turned.heading - plain.heading + math.pi) % (2 * math.pi) - math.pi
    assert diff == pytest.approx(math.radians(est.offset_deg), abs=1e-9)


def test_sentence_utc_takes_the_day_of_the_receive_time():
    from usvfast.pipeline.live_pose import sentence_utc

    gga = "$GPGGA,235959.50,6326.3820,N,01024.1500,E,4,12,0.8,40.0,M,0.0,M,,*"
    body = gga[1:-1]
    checksum = 0
    for ch in body:
        checksum ^= ord(ch)
    gga += f"{checksum:02X}"
    day = 1686873600.0  # 2023-06-16 00:00 UTC
    # received 0.1 s after midnight: the fix belongs to the day before
    assert sentence_utc(gga, day + 0.05) == pytest.approx(day - 0.5)
    assert sentence_utc(gga, day - 0.45) == pytest.approx(day - 0.5)
    assert sentence_utc(gga, day + 3600.0) is None  # a clock that does not agree
    assert sentence_utc("$GPHDT,10.0,T*00", day) is None
    assert sentence_utc("garbage", day) is None
