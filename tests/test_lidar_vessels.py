"""Moving vessels among the LiDAR's line structures (usvfast.lidar.vessels): a moving hull gets
one detection near its centre; a moored hull alongside a quay, a quay alone and a static hull
get none; bad parameters are errors naming them."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from usvfast.lidar import Box, LidarConfig, LidarDetector, Scene, VLP16Simulator, Wall
from usvfast.lidar.vessels import VesselFinder, single_linkage

HULL = Box((0.0, 0.0), 6.0, 2.2, 0.0, 0.0, 1.0)


def _outline(centre, yaw, length=6.0, beam=2.2, step=0.05):
    """Points (n, 2) NED on a hull's outline (all four sides)."""
    u = np.array([np.cos(yaw), np.sin(yaw)])
    n = np.array([-u[1], u[0]])
    a = np.arange(-length / 2, length / 2, step)
    c = np.arange(-beam / 2, beam / 2, step)
    pts = [
        *(np.outer(a, u) + s * beam / 2 * n for s in (-1, 1)),
        *(np.outer(c, n) + s * length / 2 * u for s in (-1, 1)),
    ]
    return np.asarray(centre) + np.vstack(pts)


def _seen(points, sensor):
    """The points of an outline facing `sensor`: nearer than the outline's centroid along the
    line of sight (a rough self-occlusion)."""
    c = points.mean(axis=0)
    los = c - sensor
    return points[(points - c) @ los <= 0.3]


def _faces_seen(centre, yaw, length, sensor, beam=2.2, step=0.05):
    """Points (n, 2) NED on the sides of a hull (yaw 0: along north) that face `sensor`: a
    side is seen when the sensor lies on its outer side (a convex outline)."""
    u = np.array([np.cos(yaw), np.sin(yaw)])
    n = np.array([-u[1], u[0]])
    centre = np.asarray(centre, dtype=float)
    pts = []
    for normal, half, side_dir, side_half in (
        (u, length / 2, n, beam / 2),
        (-u, length / 2, n, beam / 2),
        (n, beam / 2, u, length / 2),
        (-n, beam / 2, u, length / 2),
    ):
        mid = centre + half * normal
        if float((sensor - mid) @ normal) > 0:
            s = np.arange(-side_half, side_half, step)
            pts.append(mid + np.outer(s, side_dir))
    return np.vstack(pts)


def test_moving_hull_found_near_its_centre_static_one_not():
    sensor = np.array([0.0, 0.0])
    finder = VesselFinder(radius=12.0)
    found = []
    for k in range(12):
        t = 100.0 + 0.4 * k
        moving_c = np.array([-4.0 + 1.6 * 0.4 * k, 6.0])
        static_c = np.array([2.0, -6.0])
        pts = np.vstack(
            [_seen(_outline(moving_c, 0.0), sensor), _seen(_outline(static_c, 0.0), sensor)]
        )
        for cand in finder.update(pts, t, sensor):
            centre, cov = finder.detection(cand, sensor)
            found.append((k, centre, cov, moving_c, cand.speed))
    # the trail needs min_baseline = 0.7 s (2 cycles back), then min_moving = 2 judgements
    assert [f[0] for f in found] == list(range(3, 12))
    for _, centre, cov, truth, speed in found:
        assert np.hypot(*(centre - truth)) < finder.end_std
        assert 0.9 < speed < 2.2  # the ends move with the hull (and with what is seen of it)
        assert np.all(np.linalg.eigvalsh(cov) > 0)
        # along the hull (north) the end error, across it the beam's
        assert np.sqrt(cov[0, 0]) == pytest.approx(finder.end_std)
        assert np.sqrt(cov[1, 1]) == pytest.approx(finder.beam_std)


def test_clipped_end_uses_the_trail_learned_hull_length():
    """A 7.2 m hull passes north 5 m east of the sensor at 1.6 m/s; its bow leaves the 10 m
    range on the later cycles. The trail learned the hull's length while both ends were in
    view, so the centre stays within 0.3 m with the bow clipped; the configured 6 m (the same
    candidates without a learned length) puts it 0.6 m off."""
    sensor = np.zeros(2)
    finder = VesselFinder()
    true_length = 7.2
    clipped_found = short = 0
    for k in range(17):
        t = 50.0 + 0.4 * k
        truth = np.array([-2.0 + 1.6 * 0.4 * k, 5.0])
        pts = _faces_seen(truth, 0.0, true_length, sensor)
        pts = pts[np.hypot(*(pts - sensor).T) < finder.radius]  # beyond the range: no return
        for cand in finder.update(pts, t, sensor):
            assert cand.learned_length == pytest.approx(true_length, abs=0.35)
            if not cand.clipped.any():
                continue
            clipped_found += 1
            centre, cov = finder.detection(cand, sensor)
            assert np.hypot(*(centre - truth)) < 0.3
            # a learned length: the seen end's error along the hull, as with both ends seen
            assert np.sqrt(cov[0, 0]) == pytest.approx(finder.end_std)
            # without a learned length: the configured one, or the extent seen if longer
            unlearned = dataclasses.replace(cand, extents=[])
            assert np.sqrt(finder.detection(unlearned, sensor)[1][0, 0]) == pytest.approx(
                finder.length_std
            )
            assert np.isnan(unlearned.learned_length)
            a = (cand.cells - cand.centroid) @ cand.axis
            seen = float(a.max() - a.min()) + finder.cell
            assert finder.hull_length(unlearned) == pytest.approx(max(finder.length, seen))
            if seen < finder.length:
                short += 1
                fixed, _ = finder.detection(unlearned, sensor)
                assert abs(float(fixed[0] - truth[0])) > 0.45
    assert clipped_found >= 4 and short >= 3


def test_seen_side_unbiased_over_the_cell_grid():
    """A broadside hull's seen side shifted across the 0.2 m cell grid in 2 cm steps: the
    centre placed from the nearest cell centre is unbiased across the hull (the cells' near
    edge put it 0.1 m too near on average)."""
    sensor = np.zeros(2)
    finder = VesselFinder()
    errors = []
    for shift in np.arange(0.0, 0.2, 0.02):
        truth = np.array([0.3, 5.0 + shift])
        (cand,) = finder.candidates(_faces_seen(truth, 0.0, 6.5, sensor), 0.0, sensor)
        centre, _ = finder.detection(cand, sensor)
        errors.append(float(centre[1] - truth[1]))
        assert abs(float(centre[0] - truth[0])) < 0.15
    assert abs(np.mean(errors)) < 0.03, errors
    assert max(np.abs(errors)) <= finder.cell / 2 + 1e-9


def test_single_linkage_equals_dbscan_with_one_sample():
    from sklearn.cluster import DBSCAN

    rng = np.random.default_rng(4)
    pts = np.vstack([rng.normal(c, 0.6, (80, 2)) for c in ((0, 0), (3, 1), (8, -2), (8, 4))])
    pts = np.round(pts / 0.2) * 0.2  # grid cells, as the finder groups them (ties at link)
    ours = single_linkage(pts, 0.8)
    ref = DBSCAN(eps=0.8, min_samples=1).fit_predict(pts)
    # the same partition (labels may be numbered differently)
    pairs = {(a, b) for a, b in zip(ours.tolist(), ref.tolist(), strict=True)}
    assert len(pairs) == len(set(ours.tolist())) == len(set(ref.tolist()))
    assert single_linkage(np.zeros((0, 2)), 0.8).shape == (0,)


def test_long_quay_is_no_candidate():
    finder = VesselFinder()
    quay = np.column_stack([np.linspace(-9, 9, 400), np.full(400, 5.0)])
    assert finder.candidates(quay, 0.0, np.zeros(2)) == []
    small = np.column_stack([np.linspace(-0.3, 0.3, 60), np.zeros(60)])
    assert finder.candidates(small, 0.0, np.array([0.0, -5.0])) == []


def test_detector_moving_vessel_detected_moored_boat_and_quay_not():
    """VLP-16 frames of a quay with a hull moored alongside and a hull passing at 1.6 m/s;
    the sensor moves north at 0.5 m/s."""
    quay = Wall(np.array([[-30.0, -8.4], [30.0, -8.4]]), 2.0)
    moored = dataclasses.replace(HULL, center=(2.0, -7.1), width=2.5)
    cfg = LidarConfig(vessels=True, backend="sklearn", bin_seeding=True)
    det = LidarDetector(cfg)
    sim = VLP16Simulator(Scene([quay, moored]), seed=3)
    vessel_dets, other = [], []
    for k in range(48):
        t = 200.0 + 0.1 * k
        pose = (0.05 * k, 0.0, 0.0)
        truth = np.array([-5.0 + 0.16 * k, 5.5])
        sim.scene = Scene([quay, moored, dataclasses.replace(HULL, center=tuple(truth))])
        res = det.process(sim.scan(pose, t).frame, pose)
        if res.cycle is None:
            continue
        for d in res.cycle.detections:
            (vessel_dets if d.extended else other).append((k, d, truth))
    assert len(vessel_dets) >= 7  # from the 4th of 12 cycles on
    errors = [np.hypot(*(d.position - truth)) for _, d, truth in vessel_dets]
    assert max(errors) < 0.6, errors
    assert np.median(errors) < 0.35, errors
    # nothing else: no mean-shift detection on either hull, none on the quay
    assert other == []


def test_bad_parameters_named():
    with pytest.raises(ValueError, match="beam"):
        VesselFinder(beam=0.0)
    with pytest.raises(ValueError, match="min_moving"):
        VesselFinder(min_moving=0)
    with pytest.raises(ValueError, match="min_baseline"):
        VesselFinder(min_baseline=2.0, max_baseline=1.0)
    with pytest.raises(ValueError, match="sensor"):
        VesselFinder().candidates(np.zeros((50, 2)), 0.0, np.zeros(3))
    with pytest.raises(ValueError, match="points"):
        VesselFinder().update(np.full((50, 2), np.nan), 0.0, np.zeros(2))


def test_bundled_recording_vessel_gets_one_lidar_track():
    """The bundled harbour recording (seed 7), LiDAR only: the moving vessel, which passes
    6-10 m from the USV for ≈ 5 s, gets one track within 1.5 m of its hull's centre; without
    the finder none comes within 2 m of it."""
    import csv

    from usvfast.pipeline import Pipeline, load_config
    from usvfast.pipeline.command import bundled_recording

    path = bundled_recording()
    assert path is not None
    truth: dict[float, np.ndarray] = {}
    with open(path.parent / "truth.csv", newline="") as fh:
        for r in csv.DictReader(fh):
            if r["kind"] == "vessel" and r["object_id"] == "12":
                truth[round(float(r["time"]), 1)] = np.array([float(r["north"]), float(r["east"])])

    def nearest(vessels: bool) -> dict[int, list[float]]:
        cfg = load_config(path, {"camera.enabled": False, "lidar.vessels": vessels})
        out: dict[int, list[float]] = {}
        for up in Pipeline(cfg).run():
            p = truth.get(round(up.time, 1))
            if p is None:
                continue
            for i, s in zip(up.tracks.ids.tolist(), up.tracks.states, strict=True):
                d = float(np.hypot(s[0] - p[0], s[2] - p[1]))
                if d < 5.0:
                    out.setdefault(i, []).append(d)
        return out

    with_finder = nearest(True)
    on_vessel = {i: d for i, d in with_finder.items() if np.median(d) < 1.5}
    assert len(on_vessel) == 1, with_finder
    (errors,) = on_vessel.values()
    assert len(errors) >= 5 and np.median(errors) < 1.0
    without = nearest(False)
    assert all(min(d) > 2.0 for d in without.values()), without


def test_a_trail_keeps_a_bounded_number_of_hull_extents():
    """A hull escorted for 120 cycles (48 s, the sensor running beside it) stays in full view;
    its trail keeps the newest MAX_EXTENTS extents."""
    from usvfast.lidar.vessels import MAX_EXTENTS

    finder = VesselFinder()
    longest = 0
    for k in range(120):
        truth = np.array([-2.0 + 1.6 * 0.4 * k, 5.0])
        sensor = truth - [0.0, 5.0]
        for cand in finder.update(_faces_seen(truth, 0.0, 7.2, sensor), 50.0 + 0.4 * k, sensor):
            longest = max(longest, len(cand.extents))
            assert len(cand.extents) <= MAX_EXTENTS
    assert longest == MAX_EXTENTS
