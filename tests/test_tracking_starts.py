"""`Sensor.starts_tracks = False`: the sensor's detections update tracks (tentative ones
included) but never start one — the two-threshold association of ByteTrack (Zhang et al.
2022) that the pipeline uses for a detector's low-score boxes (camera.start_confidence)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import usvfast.tracking as tk
from usvfast.kalman import constant_velocity_2d


def _tracker(second_starts: bool, association=None) -> tk.Tracker:
    lidar = tk.Sensor.position(0.1)
    camera = tk.Sensor(lidar.measurement_matrix, np.eye(2) * 0.04, starts_tracks=second_starts)
    return tk.Tracker(
        motion_model=constant_velocity_2d(0.01),
        sensors=[lidar, camera],
        association=association or tk.JPDA(clutter_density=0.05),
        deleter=tk.StepsSinceUpdate(4),
        initiator=tk.MultiMeasurementInitiator(
            prior_state=np.zeros(4),
            prior_covariance=np.diag([0.0, 1.0, 0.0, 1.0]),
            min_points=3,
            deleter=tk.StepsSinceUpdate(3),
            missed_distance=3.0,
        ),
    )


def test_a_non_starting_sensor_starts_nothing_but_confirms_a_tentative_track():
    scans = [(0.1 * k, [[0.05 * k, 5.0]]) for k in range(6)]
    for starts, expected in ((True, 1), (False, 0)):
        tr = _tracker(starts)
        for t, z in scans:
            out = tr.step(t, z, [1])
        assert len(out.ids) == expected
    # One LiDAR detection starts the track; the camera's confirm and update it.
    tr = _tracker(False)
    tr.step(0.0, [[0.0, 5.0]], [0])
    for t, z in scans[1:]:
        out = tr.step(t, z, [1])
    assert len(out.ids) == 1
    hist = tr.history(int(out.ids[0]))
    assert hist.sensor[0] == 0 and (hist.sensor[1:] == 1).all() and hist.is_update.all()


def test_starts_tracks_must_be_a_bool():
    with pytest.raises(TypeError, match="starts_tracks"):
        tk.Sensor(np.eye(2), np.eye(2), starts_tracks=1)


@given(
    seed=st.integers(0, 2**31 - 1),
    gnn=st.booleans(),
)
def test_every_track_starts_from_a_starting_sensor(seed, gnn):
    """Random targets, clutter and a random share of non-starting detections: every track,
    tentative or confirmed, begins with a detection of sensor 0; sensor 1's detections still
    update tracks; with sensor 1 starting too, the tracks differ (it does start some)."""
    rng = np.random.default_rng(seed)
    targets = rng.uniform(-10, 10, (3, 2))
    vel = rng.normal(0, 0.3, (3, 2))
    assoc = tk.GNN(missed_distance=3.0) if gnn else None
    runs = {s: _tracker(s, assoc) for s in (True, False)}
    ids_seen = {True: set(), False: set()}
    for k in range(40):
        t = 0.1 * k
        pos = targets + t * vel
        z = pos + rng.normal(0, 0.1, pos.shape)
        z = np.vstack([z, rng.uniform(-12, 12, (rng.poisson(1.0), 2))])
        sensors = (rng.random(len(z)) < 0.6).astype(np.int64)
        for s, tr in runs.items():
            ids_seen[s] |= set(tr.step(t, z, sensors).ids.tolist())
    tr = runs[False]
    firsts, updates_by_1 = [], 0
    for i in ids_seen[False]:
        h = tr.history(i)
        firsts.append(int(h.sensor[0]))
        updates_by_1 += int(np.sum((h.sensor == 1) & h.is_update))
    assert all(f == 0 for f in firsts)
    if ids_seen[False]:
        assert updates_by_1 > 0
    starts_from_1 = [int(runs[True].history(i).sensor[0]) == 1 for i in ids_seen[True]]
    if any(starts_from_1):
        assert ids_seen[True] != ids_seen[False] or any(
            not np.array_equal(runs[True].history(i).states, runs[False].history(i).states)
            for i in ids_seen[True] & ids_seen[False]
        )


def test_pipeline_camera_start_confidence():
    """The bundled recording's first 8 s, camera only: with every box starting tracks the
    camera confirms some; with camera.start_confidence above every score it confirms none,
    while the same detections still reach the tracker."""
    import warnings
    from importlib import resources

    from usvfast.pipeline import ConfigError, Pipeline, load_config

    path = resources.files("usvfast") / "data" / "harbour" / "recording.toml"
    cfg = load_config(path).with_options(
        lidar={"enabled": False}, recording={"heading_calibration_s": None}
    )
    with pytest.raises(ConfigError, match=r"camera\.start_confidence.*\[0, 1\]"):
        cfg.with_options(camera={"start_confidence": 1.5})
    counts, tracks = [], []
    for start in (None, 1.0):
        pipe = Pipeline(cfg.with_options(camera={"start_confidence": start}))
        seen: set[int] = set()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            first = None
            for u in pipe.run():
                first = u.time if first is None else first
                if u.time - first > 8.0:
                    break
                seen |= set(u.tracks.ids.tolist())
        counts.append(pipe.detections["camera"])
        tracks.append(seen)
    assert counts[0] == counts[1] > 20
    assert len(tracks[0]) >= 2 and not tracks[1]
