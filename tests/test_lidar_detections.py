"""Clusters -> detections (`usvfast.lidar.detections`): the small-cluster rule
(`small_cluster_points` K, `small_cluster_radius` r) against brute-force counts written here
with the standard library (`statistics.median`, `math.hypot`), and scikit-learn's mean shift
for the clusters."""

from __future__ import annotations

import math
import statistics

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from usvfast import DimensionError
from usvfast.lidar import LidarConfig, cluster_detections, near_median


def _brute_near(points, radius: float) -> list[bool]:
    """Which points lie within `radius` of the coordinate-wise median: one by one."""
    mx = statistics.median(float(p[0]) for p in points)
    my = statistics.median(float(p[1]) for p in points)
    return [math.hypot(float(x) - mx, float(y) - my) <= radius for x, y in points]


def _margin(points, radius: float) -> float:
    """How far the nearest point's distance to the median is from `radius` (m): the two
    definitions may round a distance that equals the radius either way."""
    mx = statistics.median(float(p[0]) for p in points)
    my = statistics.median(float(p[1]) for p in points)
    return min(abs(math.hypot(float(x) - mx, float(y) - my) - radius) for x, y in points)


coordinate = st.floats(-5.0, 5.0, allow_nan=False)


@given(
    points=st.lists(st.tuples(coordinate, coordinate), min_size=1, max_size=12),
    radius=st.floats(0.01, 5.0),
)
def test_near_median_equals_the_brute_force_count(points, radius):
    assume(_margin(points, radius) > 1e-9)
    mask = near_median(np.array(points), radius)
    assert mask.dtype == bool and mask.shape == (len(points),)
    assert mask.tolist() == _brute_near(points, radius)


def _arc(centre, n, length, rng, across=0.005):
    """n returns of one ring across a small float: along a line `length` m long through
    `centre`, a few mm of range noise across it."""
    t = np.linspace(-length / 2, length / 2, n)
    return np.asarray(centre) + np.column_stack([t, rng.normal(0, across, n)])


def test_a_grazed_bottle_with_a_stray_return_is_kept_without_it():
    rng = np.random.default_rng(3)
    # one rotation's 4 hits on a 0.24 m bottle, and a crest return 0.45 m off in its core
    bottle = _arc([6.0, 2.0], 4, 0.2, rng)
    stray = np.array([[6.3, 2.34]])
    box = _arc([-5.0, 4.0], 5, 0.36, rng, across=0.02)  # 5 hits over 0.36 m
    # 4 sparse crest returns, all within the 0.5 m core, 0.25-0.32 m from their median
    corners = np.array([[-0.25, -0.2], [0.25, -0.15], [0.2, 0.25], [-0.2, 0.2]])
    water = np.array([2.0, -7.0]) + corners
    pair = _arc([-3.0, -6.0], 3, 0.1, rng)  # 3 points: below small_cluster_points
    big = np.array([8.0, -4.0]) + rng.normal(0, 0.1, (9, 2))  # >= min_cluster_points
    pts = np.vstack([bottle, stray, box, water, pair, big])
    heights = np.concatenate([np.full(4, 0.05), [0.3], np.full(len(pts) - 5, 0.1)])
    kw = dict(time=1.0, min_cluster_points=6, core_radius=0.5, backend="sklearn")
    kw["heights"] = heights
    thesis, _, _ = cluster_detections(pts, **kw)
    assert [d.n_points for d in thesis] == [9] and not thesis[0].small
    dets, labels, _ = cluster_detections(
        pts, small_cluster_points=4, small_cluster_radius=0.15, **kw
    )
    assert sorted(d.n_points for d in dets) == [4, 9]
    (small,) = [d for d in dets if d.small]
    # the detection is the 4 hits alone: their mean, spread and top; the stray is unlabelled
    np.testing.assert_allclose(small.position, bottle.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(small.spread, np.cov(bottle, rowvar=False), atol=1e-12)
    assert small.top == 0.05
    assert (labels[:4] >= 0).all() and (labels[4:17] == -1).all()
    (big_det,) = [d for d in dets if not d.small]
    np.testing.assert_allclose(big_det.position, thesis[0].position, atol=0)
    # the box's 5 hits: 3 within 0.15 m of their median, all 5 within 0.2 m
    assert sum(_brute_near(box, 0.15)) == 3 and all(_brute_near(box, 0.2))
    wide, _, _ = cluster_detections(pts, small_cluster_points=4, small_cluster_radius=0.2, **kw)
    assert sorted(d.n_points for d in wide) == [4, 5, 9]
    three, _, _ = cluster_detections(pts, small_cluster_points=3, small_cluster_radius=0.15, **kw)
    assert sorted(d.n_points for d in three) == [3, 3, 4, 9]  # the pair, and the box's 3
    # the water patch was dropped for its scatter, not its count
    loose, _, _ = cluster_detections(pts, small_cluster_points=4, small_cluster_radius=0.4, **kw)
    assert sorted(d.n_points for d in loose) == [4, 4, 5, 9]


@st.composite
def _groups(draw):
    """Groups of 1-9 points 6 m apart, each inside a 0.7 m square (so that a 1 m mean shift
    makes one cluster of each), some tight and some scattered."""
    groups = []
    for _ in range(draw(st.integers(1, 6))):
        scale = draw(st.sampled_from([0.01, 0.05, 0.1, 0.2, 0.35]))
        unit = st.floats(-1.0, 1.0, allow_nan=False)
        raw = draw(st.lists(st.tuples(unit, unit), min_size=1, max_size=9))
        groups.append(np.array(raw) * scale)
    return groups


@given(
    groups=_groups(),
    small=st.one_of(st.none(), st.integers(2, 6)),
    radius=st.floats(0.02, 0.4),
)
def test_small_cluster_rule_property(groups, small, radius):
    """Each group is kept iff it has min_cluster_points (7) members, or (with the rule) at
    least K members within r of its median by the brute-force count; a kept small group's
    detection is those members (count and mean); the rule only ever adds detections."""
    min_points = 7
    parts, expected = [], {}
    for k, g in enumerate(groups):
        assume(_margin(g, radius) > 1e-9)
        parts.append(g + np.array([6.0 * k, 0.0]))
        near = np.array(_brute_near(g, radius))
        if len(g) >= min_points:
            expected[k] = g
        elif small is not None and len(g) >= small and near.sum() >= small:
            expected[k] = g[near]
    pts = np.vstack(parts)
    kw = dict(time=0.0, min_cluster_points=min_points, bandwidth=1.0, backend="sklearn")
    dets, labels, _ = cluster_detections(
        pts, small_cluster_points=small, small_cluster_radius=radius, **kw
    )
    got = {round(float(d.position[0]) / 6.0): d for d in dets}
    assert sorted(got) == sorted(expected)
    for k, members in expected.items():
        d = got[k]
        assert d.n_points == len(members) and d.small == (len(groups[k]) < min_points)
        shift = np.array([6.0 * k, 0.0])
        np.testing.assert_allclose(d.position, members.mean(axis=0) + shift, atol=1e-9)
    assert (labels >= 0).sum() == sum(len(m) for m in expected.values())
    thesis, _, _ = cluster_detections(pts, **kw)
    assert {round(d.position[0] / 6.0) for d in thesis} <= set(got)


@pytest.mark.parametrize(
    ("kw", "error"),
    [
        ({"small_cluster_points": 1}, ValueError),
        ({"small_cluster_points": 3.5}, TypeError),
        ({"small_cluster_points": True}, TypeError),
        ({"small_cluster_points": 4, "small_cluster_radius": 0.0}, ValueError),
        ({"small_cluster_radius": -0.1}, ValueError),
        ({"small_cluster_radius": float("nan")}, ValueError),
        ({"small_cluster_radius": "0.1"}, TypeError),
    ],
)
def test_small_cluster_validation(kw, error):
    pts = np.zeros((3, 2))
    with pytest.raises(error, match="small_cluster"):
        cluster_detections(pts, time=0.0, backend="sklearn", **kw)
    with pytest.raises(error, match="small_cluster"):
        LidarConfig(**kw)


@pytest.mark.parametrize(
    ("points", "radius", "error", "match"),
    [
        (np.zeros((3, 2)), 0.0, ValueError, "radius"),
        (np.zeros((3, 2)), float("inf"), ValueError, "radius"),
        (np.zeros((3, 3)), 0.1, DimensionError, "points"),
        (np.zeros((0, 2)), 0.1, DimensionError, "points"),
        (np.zeros(4), 0.1, DimensionError, "points"),
        (np.array([[0.0, np.nan]]), 0.1, ValueError, "points"),
        ("abc", 0.1, TypeError, "points"),
    ],
)
def test_near_median_bad_input(points, radius, error, match):
    with pytest.raises(error, match=match):
        near_median(points, radius)
