"""Moving boats in the camera chain (usvfast.camera.vessels) and the vessel tracker's joined
snapshots (usvfast.pipeline.tracker)."""

from pathlib import Path

import numpy as np
import pytest

import usvfast
from usvfast.camera.vessels import MovingBoats, fuse_boxes, hull_centre, hull_covariance, separate
from usvfast.pipeline.tracker import Snapshot, join_snapshots


def test_fuse_boxes_unions_overlapping_groups_only():
    boxes = np.array(
        [
            [100, 50, 180, 80],  # bow
            [150, 45, 220, 82],  # stern, overlaps the bow
            [205, 60, 240, 81],  # overlaps the stern only: same hull through it
            [400, 60, 420, 70],  # another object
        ],
        float,
    )
    scores = np.array([0.4, 0.7, 0.3, 0.9])
    fused, best = fuse_boxes(boxes, scores, min_overlap=0.3)
    assert best.tolist() == [0.9, 0.7]
    np.testing.assert_array_equal(fused, [[400, 60, 420, 70], [100, 45, 240, 82]])
    # a slight touch (below min_overlap of the smaller box) does not fuse
    two = np.array([[0, 0, 10, 10], [9, 0, 30, 10]], float)
    assert len(fuse_boxes(two, np.array([0.5, 0.6]), min_overlap=0.3)[0]) == 2
    with pytest.raises(ValueError, match="scores"):
        fuse_boxes(two, np.array([0.5]))


def test_moving_boats_tells_a_vessel_from_a_moored_boat():
    rng = np.random.default_rng(3)
    boats = MovingBoats(history_s=2.0, min_speed=1.0, min_frames=5)
    moored = np.array([30.0, 10.0])
    start = np.array([40.0, -5.0])
    velocity = np.array([-2.0, 0.3])
    moving_flags, still_flags, est = [], [], []
    for k in range(40):
        t = 0.1 * k
        p = np.vstack([start + velocity * t, moored]) + rng.normal(0, 0.3, (2, 2))
        vel, moving = boats.update(t, p)
        if t >= 1.5:  # min_dt + history_s / 2: the first frames that can tell
            moving_flags.append(moving[0])
            still_flags.append(moving[1])
            est.append(vel[0])
    assert np.mean(moving_flags) >= 0.9 and not any(still_flags)
    np.testing.assert_allclose(np.mean(est, axis=0), velocity, atol=0.15)


def test_moving_boats_rejects_a_box_appearing_beside_another_boats_trail():
    boats = MovingBoats(history_s=2.0, min_speed=1.0, min_frames=3, gate=1.5)
    for k in range(15):  # a vessel sails east for 1.5 s
        boats.update(0.1 * k, np.array([[0.0, 2.0 * 0.1 * k]]))
    # a still object appears 2 m beside the vessel's trail: its "rates" to that trail
    # disagree with one another
    vel, moving = boats.update(1.5, np.array([[2.0, 1.5]]))
    assert not moving[0] and np.isnan(vel[0]).all()


def test_hull_centre_half_the_depth_seen_along_the_line_of_sight():
    cam = np.array([0.0, 0.0])
    contact = np.array([[10.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    # heading across the line of sight (broadside): half the beam; along it: half the length
    vel = np.array([[0.0, 2.0], [-2.0, 0.0], [np.sqrt(2), np.sqrt(2)]])
    centre, depth = hull_centre(contact, cam, vel, length=6.0, beam=2.0)
    a = np.radians(45.0)
    np.testing.assert_allclose(depth, [1.0, 3.0, 0.5 * (6 * np.cos(a) + 2 * np.sin(a))])
    np.testing.assert_allclose(centre[:2], [[11.0, 0.0], [13.0, 0.0]])
    np.testing.assert_allclose(centre[2], [0.0, 10.0 + depth[2]])


def test_hull_covariance_along_and_across_the_line_of_sight():
    contact = np.array([[3.0, 4.0]])
    cov = hull_covariance(contact, np.zeros(2), along_std=1.5, across_std=0.5)[0]
    w, v = np.linalg.eigh(cov)
    np.testing.assert_allclose(w, [0.25, 2.25])
    np.testing.assert_allclose(np.abs(v[:, 1]), [0.6, 0.8])


def test_separate_keeps_the_best_within_the_separation():
    p = np.array([[0.0, 0.0], [5.0, 0.0], [20.0, 0.0]])
    assert separate(p, np.array([0.3, 0.8, 0.5]), 9.0).tolist() == [False, True, True]
    assert separate(p, np.array([0.3, 0.8, 0.5]), 4.0).tolist() == [True, True, True]


def test_join_snapshots_shifts_the_vessel_ids():
    a = Snapshot(np.array([0, 3]), np.ones((2, 4)), np.tile(np.eye(4), (2, 1, 1)), [(3, 0, 1.5)])
    b = Snapshot(np.array([0]), 2 * np.ones((1, 4)), np.eye(4)[None], [(0, 1, 2.5)])
    j = join_snapshots(a, b, 100000)
    assert j.ids.tolist() == [0, 3, 100000]
    assert j.states[2].tolist() == [2.0] * 4
    assert j.innovations == [(3, 0, 1.5), (100000, 1, 2.5)]
    empty = Snapshot(np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros((0, 4, 4)), [])
    assert join_snapshots(a, empty, 100000).ids.tolist() == [0, 3]


def test_camera_chain_passes_the_moving_boat_only():
    from usvfast.camera.detect import Detections
    from usvfast.pipeline import load_config
    from usvfast.pipeline.camera_chain import CameraChain
    from usvfast.pipeline.pose import VesselPose
    from usvfast.pipeline.timing import StageTimer

    cfg = load_config(
        Path(usvfast.__file__).parent / "data" / "harbour" / "recording.toml",
        {"camera.moving_classes": [4, 5]},
    )
    frame = {"t": 0.0}

    def detector(images):
        # a boat crossing the view at a constant row (its range) and one that stays put,
        # both 65 px tall (about 2 m at 10 m), called "moored boat" (class 5)
        u = 150.0 + 60.0 * frame["t"]
        boxes = np.array([[u - 40, 130, u + 40, 195], [480, 130, 560, 195]], float)
        return [Detections(boxes, np.array([0.8, 0.7]), np.array([5, 5]))]

    chain = CameraChain(cfg.camera, detector, cfg.streams_of("camera")[0].mount, StageTimer())
    moving, still = [], []
    for k in range(30):
        frame["t"] = 0.1 * k
        pose = VesselPose(1000.0 + frame["t"], 0.0, 0.0, 0.0)
        res = chain.finish(chain.detect(np.zeros((360, 640, 3), np.uint8)), pose)
        assert res.vessel is not None and res.vessel.all()
        moving.append(len(res.positions))
        still.append(res.rejected.get("not_moving", 0))
    assert sum(moving[:15]) == 0  # 1.5 s of history needed first
    assert all(n == 1 for n in moving[16:]) and all(n == 1 for n in still[16:])


def test_vessel_tracker_settings_and_routing():
    from usvfast.pipeline import load_config
    from usvfast.pipeline.tracker import make_vessel_tracker

    path = Path(usvfast.__file__).parent / "data" / "harbour" / "recording.toml"
    cfg = load_config(path)
    assert cfg.tracker["vessels"] is True
    vt = make_vessel_tracker(cfg.tracker)
    assert vt is not None
    assert vt.s["q"] == cfg.tracker["vessel_q"] != cfg.tracker["q"]
    assert vt.s["prior_velocity_var"] == 6.25 and vt.s["covariance_trace"] is None
    assert vt.s["delete_after_s"] == 2.0
    assert make_vessel_tracker(load_config(path, {"tracker.vessels": False}).tracker) is None
    # a vessel at 2 m/s: its own tracker follows it within a few scans
    z0 = np.array([10.0, 0.0])
    for k in range(40):
        t = 0.4 * k
        snap = vt.step(
            t, (z0 + np.array([0.0, 2.0 * t]))[None], np.zeros(1, np.int64), np.eye(2)[None] * 0.05
        )
    assert len(snap.ids) == 1
    np.testing.assert_allclose(snap.states[0, [1, 3]], [0.0, 2.0], atol=0.1)
    with pytest.raises(ValueError, match="vessels"):
        load_config(path, {"tracker.vessels": "yes"})


def test_vessel_tracker_stonesoup_backend_gives_the_same_track():
    from usvfast.pipeline import load_config
    from usvfast.pipeline.tracker import make_vessel_tracker

    path = Path(usvfast.__file__).parent / "data" / "harbour" / "recording.toml"
    native = make_vessel_tracker(load_config(path).tracker)
    soup = make_vessel_tracker(load_config(path, {"tracker.backend": "stonesoup"}).tracker)
    assert native is not None and soup is not None
    rng = np.random.default_rng(5)
    for k in range(25):
        t = 0.4 * k
        z = (np.array([10.0, 0.0]) + np.array([0.0, 2.0 * t]) + rng.normal(0, 0.2, 2))[None]
        cov = np.eye(2)[None] * 0.05
        a = native.step(t, z, np.zeros(1, np.int64), cov)
        b = soup.step(t, z, np.zeros(1, np.int64), cov)
        np.testing.assert_allclose(a.states, b.states, atol=1e-6)
    assert len(a.ids) == 1


def test_low_boat_class_boxes_go_to_the_float_path():
    from usvfast.camera.detect import Detections
    from usvfast.pipeline import load_config
    from usvfast.pipeline.camera_chain import CameraChain
    from usvfast.pipeline.pose import VesselPose
    from usvfast.pipeline.timing import StageTimer

    path = Path(usvfast.__file__).parent / "data" / "harbour" / "recording.toml"
    # a float-sized box (10 px, about 0.3 m at 10 m) and a hull-sized one (65 px), both
    # called class 4 by the network
    boxes = np.array([[300, 185, 330, 195], [480, 130, 560, 195]], float)

    def detector(images):
        return [Detections(boxes, np.array([0.8, 0.7]), np.array([4, 4]))]

    pose = VesselPose(1000.0, 0.0, 0.0, 0.0)
    results = {}
    for low in ([3], [4]):  # [3]: no box of that class, as without the key
        cfg = load_config(path, {"camera.moving_classes": [4, 5], "camera.low_boat_classes": low})
        chain = CameraChain(cfg.camera, detector, cfg.streams_of("camera")[0].mount, StageTimer())
        results[str(low)] = chain.finish(chain.detect(np.zeros((360, 640, 3), np.uint8)), pose)
    off, on = results["[3]"], results["[4]"]
    # with no low class both are boat boxes (the hull has no history yet: nothing passes)
    assert len(off.positions) == 0 and off.rejected.get("not_moving", 0) == 1
    # with it the low box is a float detection in front of the camera, the hull stays a boat
    assert len(on.positions) == 1 and on.vessel is not None and not on.vessel.any()
    assert on.boxes[0].tolist() == boxes[0].tolist() and on.positions[0, 0] > 3.0
    assert on.rejected.get("not_moving", 0) == 1
