"""Stages of the LiDAR chain, each against an independent reference."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from sklearn.cluster import MeanShift

from usvfast.lidar import (
    LidarConfig,
    LidarDetector,
    LineMemory,
    VLP16Simulator,
    blur,
    cluster_detections,
    covered_mask,
    detect_segments,
    drop_covered,
    extend_segments,
    harbour_scene,
    make_points,
    move_segments,
    point_segment_distance,
    prefilter,
    rasterize,
    sensor_motion,
    sensor_to_world,
    world_to_sensor,
)

finite = st.floats(-50, 50, allow_nan=False)
angle = st.floats(-np.pi, np.pi)
pose_st = st.tuples(finite, finite, angle)
mount_st = st.tuples(st.floats(-3, 3), st.floats(-3, 3), angle)


# ------------------------------------------------------------------------- prefilter
def test_prefilter_against_the_thesis_loop():
    rng = np.random.default_rng(0)
    n = 3000
    x, y = rng.uniform(-14, 14, n), rng.uniform(-14, 14, n)
    z = rng.uniform(-2.0, 1.0, n)
    pts = make_points(x, y, z, rng.uniform(0, 100, n), 0, 0.0)
    pts[100:150] = pts[0:50]  # duplicates
    xy, index = prefilter(pts, radius=10.0, mount_height=1.2, slice_min=-0.3, slice_max=0.4)
    # reference: thesis Code 5.4 (np.unique, then a loop with the thresholds)
    expect = []
    seen = set()
    for i, p in enumerate(pts):
        key = (float(p["x"]), float(p["y"]), float(p["z"]))
        h = float(p["z"]) + 1.2
        if key in seen:
            continue
        if np.hypot(float(p["x"]), float(p["y"])) <= 10.0 and -0.3 <= h <= 0.4:
            seen.add(key)
            expect.append(i)
    np.testing.assert_array_equal(index, expect)
    np.testing.assert_array_equal(xy, np.column_stack([x, y])[index].astype(np.float32))
    # intensity threshold
    _, idx2 = prefilter(
        pts, radius=10.0, mount_height=1.2, slice_min=-0.3, slice_max=0.4, min_intensity=50.0
    )
    np.testing.assert_array_equal(idx2, [i for i in expect if pts["intensity"][i] >= 50.0])


def test_prefilter_empty():
    xy, index = prefilter(make_points(np.zeros(0), np.zeros(0), np.zeros(0)))
    assert xy.shape == (0, 2) and index.shape == (0,)


# ------------------------------------------------------------------------- raster + LSD
def test_rasterize_pixels():
    img = rasterize(np.array([[-10.0, -10.0], [9.99, 9.99], [0.0, 0.0], [0.1, 0.3], [10, 0]]))
    assert img.shape == (100, 100) and img.dtype == np.uint8
    assert img[0, 0] == img[99, 99] == img[50, 50] == img[51, 50] == 255
    assert img.sum() == 4 * 255  # x = 10 is outside [-10, 10)


@pytest.mark.parametrize("angle_deg", [0.0, 17.0, 45.0, 90.0, 133.0])
def test_lsd_finds_a_wall_in_metres(angle_deg):
    a = np.deg2rad(angle_deg)
    t = np.linspace(-4.0, 4.0, 400)
    centre = np.array([1.0, -2.0])
    wall = centre + np.column_stack([t * np.cos(a), t * np.sin(a)])
    seg = detect_segments(blur(rasterize(wall)))
    assert 1 <= len(seg) <= 4
    # every endpoint lies within 0.4 m (2 px) of the true line, and the segments cover it
    d = point_segment_distance(np.vstack([seg[:, :2], seg[:, 2:]]), wall[[0, -1]].ravel())
    assert d.max() < 0.4
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    assert length.max() > 7.0


def test_lsd_ignores_a_small_object():
    rng = np.random.default_rng(1)
    blob = np.array([3.0, 4.0]) + rng.uniform(-0.25, 0.25, (60, 2))
    assert detect_segments(blur(rasterize(blob)), min_length=1.0).shape == (0, 4)


def test_point_segment_distance_and_extension():
    seg = np.array([[0.0, 0.0, 2.0, 0.0], [1.0, 1.0, 1.0, 1.0]])
    d = point_segment_distance(np.array([[1.0, 0.5], [3.0, 0.0], [-1.0, -1.0]]), seg)
    np.testing.assert_allclose(d, [[0.5, 0.5], [1.0, np.hypot(2, 1)], [np.sqrt(2), np.sqrt(8)]])
    # beyond 1e154 m the squares overflow: computed in units of the largest coordinate
    big = point_segment_distance(np.array([[1.0, 0.5], [3.0, 0.0]]) * 1e300, seg * 1e300)
    np.testing.assert_allclose(big, d[:2] * 1e300, rtol=1e-12)
    # the simulator's point-to-polyline distance is the nearest of its segments'
    from usvfast.sim.motion import point_segment_distance as to_polyline

    line = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 5.0]])
    assert to_polyline(np.array([3.0, 1.0]), line) == pytest.approx(1.0)
    assert to_polyline(np.array([1.0, -2.0]), line) == pytest.approx(2.0)
    assert to_polyline(np.array([3.0, 1.0]) * 1e300, line * 1e300) == pytest.approx(1e300)
    ext = extend_segments(seg, 0.5)
    np.testing.assert_allclose(ext, [[-0.5, 0.0, 2.5, 0.0], [1.0, 1.0, 1.0, 1.0]])


def test_drop_covered():
    long = [0.0, 0.0, 10.0, 0.0]
    inside = [2.0, 0.1, 5.0, -0.1]  # within 0.2 m of `long`
    sticking_out = [8.0, 0.0, 12.0, 0.0]
    parallel = [0.0, 1.0, 10.0, 1.0]
    seg = np.array([inside, long, sticking_out, parallel, long])
    np.testing.assert_array_equal(drop_covered(seg, 0.2), np.array([long, sticking_out, parallel]))


# ------------------------------------------------------------------------- frames / motion
@given(pose=pose_st, mount=mount_st, pts=st.lists(st.tuples(finite, finite), min_size=1))
def test_world_sensor_round_trip(pose, mount, pts):
    xy = np.array(pts)
    kw = {"lever_arm": mount[:2], "mount_yaw": mount[2]}
    back = world_to_sensor(sensor_to_world(xy, pose, **kw), pose, **kw)
    np.testing.assert_allclose(back, xy, atol=1e-9)


def test_sensor_to_world_convention():
    # heading east: forward is east, left (y > 0) is north
    ne = sensor_to_world(np.array([[1.0, 0.0], [0.0, 1.0]]), (10.0, 20.0, np.pi / 2))
    np.testing.assert_allclose(ne, [[10.0, 21.0], [11.0, 20.0]], atol=1e-12)
    # lever arm 2 m forward, 1 m starboard, heading north
    ne = sensor_to_world(np.zeros((1, 2)), (0.0, 0.0, 0.0), lever_arm=(2.0, 1.0))
    np.testing.assert_allclose(ne, [[2.0, 1.0]])


@given(p0=pose_st, p1=pose_st, mount=mount_st, seg=st.lists(finite, min_size=4, max_size=4))
def test_move_segments_follows_the_vessel(p0, p1, mount, seg):
    kw = {"lever_arm": mount[:2], "mount_yaw": mount[2]}
    world = np.array(seg).reshape(2, 2)
    s0 = world_to_sensor(world, p0, **kw).reshape(1, 4)
    moved = move_segments(s0, sensor_motion(p0, p1, **kw))
    np.testing.assert_allclose(moved, world_to_sensor(world, p1, **kw).reshape(1, 4), atol=1e-7)


def test_line_memory_lifetime_and_motion():
    mem = LineMemory(frames=3)
    seg = np.array([[5.0, -2.0, 5.0, 2.0]])
    out = mem.update(seg)
    np.testing.assert_array_equal(out, seg)
    # vessel moves 1 m forward each frame: the remembered wall comes 1 m closer
    out = mem.update(np.zeros((0, 4)), (1.0, 0.0, 0.0))
    np.testing.assert_allclose(out, [[4.0, -2.0, 4.0, 2.0]])
    out = mem.update(np.zeros((0, 4)), (1.0, 0.0, 0.0))
    np.testing.assert_allclose(out, [[3.0, -2.0, 3.0, 2.0]])
    assert mem.update(np.zeros((0, 4)), (1.0, 0.0, 0.0)).shape == (0, 4)  # 3 frames: gone
    # a new detection of the same wall replaces the older copy (covered)
    mem.reset()
    mem.update(seg)
    out = mem.update(np.array([[5.0, -3.0, 5.0, 3.0]]))
    np.testing.assert_allclose(out, [[5.0, -3.0, 5.0, 3.0]])
    with pytest.raises(ValueError, match="frames"):
        LineMemory(frames=0)


# ------------------------------------------------------------------------- clustering
def test_cluster_detections_match_scikit_learn():
    rng = np.random.default_rng(5)
    objects = np.array([[0.0, 0.0], [6.0, 1.0], [2.0, 9.0]])
    sizes = [40, 25, 8]
    pts = np.vstack([c + rng.normal(0, 0.15, (k, 2)) for c, k in zip(objects, sizes, strict=True)])
    pts = np.vstack([pts, rng.uniform(-20, 20, (5, 2))])  # sparse noise
    dets, labels, centres = cluster_detections(
        pts, time=12.5, min_cluster_points=15, min_position_std=0.1, backend="sklearn"
    )
    ref = MeanShift(bandwidth=2.0, cluster_all=False).fit(pts)
    np.testing.assert_allclose(centres, ref.cluster_centers_)
    assert len(dets) == 2
    for d in dets:
        k = int(np.argmin(np.linalg.norm(centres - d.position, axis=1)))
        members = pts[ref.labels_ == k]
        assert d.n_points == len(members) >= 15
        np.testing.assert_allclose(d.position, members.mean(axis=0))
        w = np.linalg.eigvalsh(d.covariance)
        assert np.all(w >= 0.1**2 - 1e-12)
        np.testing.assert_allclose(d.covariance, d.covariance.T)
        assert d.time == 12.5 and d.sensor_id == "lidar"
    small = ref.labels_ == int(np.argmin(np.linalg.norm(centres - objects[2], axis=1)))
    assert (labels[small] == -1).all()


def test_covariance_floor_on_a_line_cluster():
    pts = np.column_stack([np.linspace(0, 0.5, 30), np.zeros(30)])
    (det,), _, _ = cluster_detections(pts, time=0.0, min_position_std=0.2, backend="sklearn")
    w = np.linalg.eigvalsh(det.covariance)
    assert w[0] == pytest.approx(0.04)  # floored across the line
    assert w[1] == pytest.approx(max(np.var(pts[:, 0], ddof=1), 0.04))


def test_core_radius_keeps_a_small_object_and_drops_sparse_clutter():
    rng = np.random.default_rng(11)
    bottle = np.array([4.0, 1.0]) + rng.normal(0, 0.04, (10, 2))
    # sparse surface clutter 0.7-1.6 m around it: the wide mean shift gathers it too
    ang = rng.uniform(0, 2 * np.pi, 5)
    rad = rng.uniform(0.7, 1.6, 5)
    near = np.array([4.0, 1.0]) + np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])
    clutter = np.array([-8.0, 3.0]) + rng.uniform(-1.4, 1.4, (12, 2))  # a clutter-only patch
    pts = np.vstack([bottle, near, clutter])
    wide, _, _ = cluster_detections(pts, time=0.0, min_cluster_points=8, backend="sklearn")
    assert len(wide) == 2  # the thesis's clusters: the clutter patch is a detection
    d_wide = min(wide, key=lambda d: np.linalg.norm(d.position - [4.0, 1.0]))
    assert d_wide.n_points == 15
    dets, labels, _ = cluster_detections(
        pts, time=0.0, min_cluster_points=8, core_radius=0.5, backend="sklearn"
    )
    assert len(dets) == 1
    (d,) = dets
    # the core: scikit-learn's flat-kernel mean shift of radius 0.5 from the members' median
    members = pts[:15]
    ref = MeanShift(bandwidth=0.5, seeds=np.median(members, axis=0)[None]).fit(members)
    np.testing.assert_allclose(d.position, bottle.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(ref.cluster_centers_[0], d.position, atol=1e-3)
    assert d.n_points == 10
    assert (labels[10:] == -1).all() and (labels[:10] >= 0).all()
    assert np.linalg.norm(d_wide.position - [4.0, 1.0]) > np.linalg.norm(d.position - [4.0, 1.0])
    # two floats 1.2 m apart, the second with more points: one mean-shift cluster (its mean
    # between them); the median lies in neither, the core is the float nearest it
    shift = np.array([1.2, 0.0])
    dense = np.array([4.0, 1.0]) + shift + rng.normal(0, 0.02, (12, 2))
    pair = np.vstack([bottle, dense])
    (merged,), _, _ = cluster_detections(pair, time=0.0, min_cluster_points=8, backend="sklearn")
    assert merged.n_points == 22
    (core,), _, _ = cluster_detections(
        pair, time=0.0, min_cluster_points=8, core_radius=0.5, backend="sklearn"
    )
    np.testing.assert_allclose(core.position, dense.mean(axis=0), atol=1e-12)
    assert core.n_points == 12
    with pytest.raises(ValueError, match="core_radius"):
        cluster_detections(pts, time=0.0, core_radius=0.0)
    with pytest.raises(ValueError, match="core_radius"):
        LidarConfig(core_radius=-1.0)


# ------------------------------------------------------------------------- the detector
def test_detector_cycles_and_intermediates():
    scene = harbour_scene(seed=2, floats=6)
    sim = VLP16Simulator(scene, seed=2)
    cfg = LidarConfig(buffer_frames=3, backend="sklearn", bin_seeding=True)
    det = LidarDetector(cfg)
    cycles = []
    for i in range(7):
        pose = (0.1 * i, 0.0, 0.0)
        res = det.process(sim.scan(pose, 100.0 + 0.1 * i).frame, pose)
        assert res.xy.shape == (res.index.size, 2) and res.keep.shape == (res.index.size,)
        assert res.image.shape == (120, 120)  # (radius + line_margin) * 2 / pixel
        assert res.world.shape == (int(res.keep.sum()), 2)
        assert np.all(np.hypot(*res.xy.T) <= cfg.radius)
        if res.cycle is not None:
            cycles.append((i, res.cycle))
    assert [i for i, _ in cycles] == [2, 5]
    for _, c in cycles:
        assert c.points.shape[0] == c.labels.shape[0] == c.frame_index.shape[0]
        assert len(c.detections) >= 3
        for d in c.detections:
            assert d.n_points == int(
                np.sum(c.labels == np.argmin(np.linalg.norm(c.centres - d.position, axis=1)))
            )


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"radius": 0.0}, "radius"),
        ({"buffer_frames": 0}, "buffer_frames"),
        ({"slice_min": 1.0, "slice_max": 0.5}, "slice_min"),
        ({"los_tolerance": -1.0}, "los_tolerance"),
        ({"min_cluster_points": float("inf")}, "min_cluster_points"),  # not an OverflowError
        ({"line_memory_frames": float("nan")}, "line_memory_frames"),
    ],
)
def test_config_validation(kw, match):
    with pytest.raises(ValueError, match=match):
        LidarConfig(**kw)


@given(
    seg=st.lists(
        st.lists(st.floats(-5, 5).map(lambda v: round(v, 1)), min_size=4, max_size=4),
        min_size=0,
        max_size=25,
    ),
    tol=st.sampled_from([0.0, 0.1, 0.3]),
)
def test_covered_mask_equals_the_dense_definition(seg, tol):
    seg = np.array(seg, dtype=float).reshape(-1, 4)
    seg = np.vstack([seg, seg[::2]])  # exact duplicates too
    m = seg.shape[0]
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    idx = np.arange(m)
    near = (point_segment_distance(seg[:, :2], seg) <= tol) & (
        point_segment_distance(seg[:, 2:], seg) <= tol
    )
    np.fill_diagonal(near, False)
    longer = (length[None, :] > length[:, None]) | (
        (length[None, :] == length[:, None]) & (idx[None, :] < idx[:, None])
    )
    np.testing.assert_array_equal(covered_mask(seg, tol), (near & longer).any(axis=1))
