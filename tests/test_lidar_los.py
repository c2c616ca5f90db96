"""Line-of-sight filter: the Rust sweep equals the naive Rust loop and the numpy broadcast
peer on random and degenerate scenes, and does what the thesis figure 3.12 shows on hand-made
ones."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from usvfast import DimensionError, NonFiniteError
from usvfast.lidar import (
    line_of_sight_filter,
    line_of_sight_filter_naive,
    line_of_sight_filter_numpy,
)


def all_three(points, segments, **kw):
    fast = line_of_sight_filter(points, segments, **kw)
    naive = line_of_sight_filter_naive(points, segments, **kw)
    peer = line_of_sight_filter_numpy(points, segments, **kw)
    np.testing.assert_array_equal(fast, naive)
    np.testing.assert_array_equal(fast, peer)
    return fast


# --- hand-made scenes ------------------------------------------------------------------


def test_wall_in_front_hides_points_behind_it():
    wall = [[5.0, -2.0, 5.0, 2.0]]
    points = [[3.0, 0.0], [8.0, 0.0], [8.0, 3.1], [8.0, 8.0], [-6.0, 0.0], [7.0, -2.5]]
    keep = all_three(points, wall)
    # In front, hidden, just hidden by the end (x=8 ray through (5,2) reaches y=3.2), beside
    # the shadow, behind the sensor, hidden near the lower end.
    np.testing.assert_array_equal(keep, [True, False, False, True, True, False])


def test_points_on_the_wall_are_removed_by_tolerance():
    wall = [[5.0, -2.0, 5.0, 2.0]]
    points = [[4.95, 0.0], [4.85, 0.0], [5.0, 2.09], [5.0, 2.2], [5.0, -2.0]]
    keep = all_three(points, wall, tolerance=0.1)
    np.testing.assert_array_equal(keep, [False, True, False, True, False])
    # A larger tolerance drops the nearby points too.
    keep = all_three(points, wall, tolerance=0.3)
    np.testing.assert_array_equal(keep, [False, False, False, False, False])


def test_harbour_scene_with_sensor_offset():
    # Quay along y = 6 and a pier x = -4; sensor at (1, 1); floating objects in the open.
    segments = [[-10.0, 6.0, 10.0, 6.0], [-4.0, -10.0, -4.0, 6.0]]
    objects = [[2.0, 3.0], [-2.0, -5.0], [5.0, -1.0]]
    behind = [[0.0, 9.0], [-7.0, 0.0], [8.0, 12.0]]
    on_walls = [[3.0, 6.02], [-4.05, -3.0]]
    keep = all_three(objects + behind + on_walls, segments, sensor=(1.0, 1.0))
    np.testing.assert_array_equal(keep, [True] * 3 + [False] * 3 + [False] * 2)


def test_degenerate_cases_follow_the_documented_rules():
    sensor = (1.0, 1.0)
    # Zero-length segment: a point obstacle hiding exactly the points behind it.
    keep = all_three([[5.0, 1.0], [5.0, 1.5], [2.0, 1.0]], [[3.0, 1.0, 3.0, 1.0]], sensor=sensor)
    np.testing.assert_array_equal(keep, [False, True, True])
    # Segment through the sensor: hides only the points along it.
    seg = [[0.0, 0.0, 2.0, 2.0]]
    keep = all_three([[4.0, 4.0], [4.0, 3.0], [-3.0, -3.0], [1.0, 3.0]], seg, sensor=sensor)
    np.testing.assert_array_equal(keep, [False, True, False, True])
    # Collinear segment beyond the point hides nothing; before it, it hides.
    keep = all_three([[4.0, 1.0], [10.0, 1.0]], [[6.0, 1.0, 9.0, 1.0]], sensor=sensor)
    np.testing.assert_array_equal(keep, [True, False])
    # A point exactly at the sensor is never hidden, only dropped by tolerance.
    keep = all_three([[1.0, 1.0]], [[-5.0, -5.0, 5.0, -5.0]], sensor=sensor)
    np.testing.assert_array_equal(keep, [True])
    keep = all_three([[1.0, 1.0]], [[1.0, 1.0, 1.0, 4.0]], sensor=sensor)
    np.testing.assert_array_equal(keep, [False])
    # Endpoint exactly on the sight line: hidden (closed segments).
    keep = all_three([[5.0, 5.0]], [[3.0, 3.0, 3.0, 0.0]], sensor=sensor)
    np.testing.assert_array_equal(keep, [False])


def test_segment_across_the_bearing_cut():
    # Wall behind the sensor crossing the ±π bearing (negative x axis).
    keep = all_three([[-8.0, 0.0], [-8.0, 0.5], [-8.0, -0.5], [-8.0, 5.0]], [[-5, -1, -5, 1]])
    np.testing.assert_array_equal(keep, [False, False, False, True])


def test_sensor_inside_a_closed_box_sees_only_the_inside():
    box = [[-3, -3, 3, -3], [3, -3, 3, 3], [3, 3, -3, 3], [-3, 3, -3, -3]]
    rng = np.random.default_rng(0)
    inside = rng.uniform(-2.8, 2.8, (200, 2))
    outside = rng.uniform(3.2, 9, (200, 2)) * rng.choice([-1, 1], (200, 2))
    keep = all_three(np.vstack([inside, outside]), box, sensor=(0.5, -1.0))
    assert keep[:200].all() and not keep[200:].any()


def test_empty_inputs():
    assert all_three(np.zeros((0, 2)), [[0, 0, 1, 1]]).shape == (0,)
    np.testing.assert_array_equal(all_three([[1.0, 2.0]], np.zeros((0, 4))), [True])
    np.testing.assert_array_equal(all_three([[1.0, 2.0]], []), [True])


# --- random scenes (hypothesis) ---------------------------------------------------------

GRID = st.integers(-4, 4).map(lambda v: v * 0.5)
REAL = st.floats(-20, 20, allow_nan=False, allow_infinity=False)


@st.composite
def scenes(draw):
    coord = draw(st.sampled_from([GRID, REAL]))
    sensor = draw(st.sampled_from([(0.0, 0.0), (0.5, -1.0), (draw(REAL), draw(REAL))]))
    pt = st.tuples(coord, coord)

    def rel(v, k):  # sensor + k · (v - sensor)
        return (sensor[0] + k * (v[0] - sensor[0]), sensor[1] + k * (v[1] - sensor[1]))

    segs = []
    for kind in draw(st.lists(st.sampled_from(["any", "zero", "through", "cut"]), max_size=12)):
        a = draw(pt)
        if kind == "any":
            b = draw(pt)
        elif kind == "zero":
            b = a
        elif kind == "through":  # line through the sensor, or ending at it
            b = rel(a, draw(st.sampled_from([-1.0, -0.5, 0.0, 2.0])))
        else:  # crossing the negative-x axis seen from the sensor
            y = draw(st.floats(0.1, 5))
            a = (sensor[0] - draw(st.floats(0.5, 10)), sensor[1] - y)
            b = (a[0] + draw(st.floats(-2, 2)), sensor[1] + draw(st.floats(0.1, 5)))
        segs.append((*a, *b))
    points = draw(st.lists(pt, max_size=40))
    # Points on the sight lines through segment endpoints, and at the sensor.
    for s in segs[:6]:
        k = draw(st.sampled_from([0.5, 1.0, 1.5, 2.0, 3.0]))
        points.append(rel((s[0], s[1]), k))
        points.append(rel((s[2], s[3]), k))
    points.append(sensor)
    tol = draw(st.sampled_from([0.05, 0.1, 0.25, 1.0]))
    return np.array(points, float).reshape(-1, 2), np.array(segs).reshape(-1, 4), sensor, tol


@given(scenes())
def test_sweep_equals_naive_equals_numpy(scene):
    points, segments, sensor, tol = scene
    all_three(points, segments, sensor=sensor, tolerance=tol)


@given(st.integers(0, 2**32 - 1), st.integers(0, 400), st.integers(0, 60))
def test_sweep_equals_naive_on_dense_random_scenes(seed, n, m):
    rng = np.random.default_rng(seed)
    points = rng.uniform(-15, 15, (n, 2))
    centres = rng.uniform(-15, 15, (m, 2))
    segments = np.hstack([centres, centres + rng.normal(0, 3, (m, 2))])
    all_three(points, segments, sensor=tuple(rng.uniform(-3, 3, 2)), tolerance=0.1)


# --- bad input --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "fn", [line_of_sight_filter, line_of_sight_filter_naive, line_of_sight_filter_numpy]
)
def test_bad_input_names_the_argument(fn):
    seg = [[0.0, 1.0, 1.0, 1.0]]
    with pytest.raises(DimensionError, match="points"):
        fn([[1.0, 2.0, 3.0]], seg)
    with pytest.raises(DimensionError, match="segments"):
        fn([[1.0, 2.0]], [[0.0, 1.0, 1.0]])
    with pytest.raises(NonFiniteError, match="points"):
        fn([[np.nan, 2.0]], seg)
    with pytest.raises(NonFiniteError, match="segments"):
        fn([[1.0, 2.0]], [[0.0, np.inf, 1.0, 1.0]])
    with pytest.raises(NonFiniteError, match="sensor"):
        fn([[1.0, 2.0]], seg, sensor=(np.nan, 0.0))
    with pytest.raises(DimensionError, match="sensor"):
        fn([[1.0, 2.0]], seg, sensor=(0.0, 0.0, 0.0))
    for bad in (0.0, -0.1, np.nan, np.inf):
        with pytest.raises(ValueError, match="tolerance"):
            fn([[1.0, 2.0]], seg, tolerance=bad)
    with pytest.raises(TypeError, match="points"):
        fn("abc", seg)


def test_native_functions_check_shapes_and_tolerance_too():
    from usvfast import _core

    with pytest.raises(DimensionError, match="segments"):
        _core.line_of_sight_filter(np.zeros((1, 2)), np.zeros((1, 3)))
    with pytest.raises(ValueError, match="tolerance"):
        _core.line_of_sight_filter_naive(np.zeros((1, 2)), np.zeros((1, 4)), tolerance=-1.0)
    with pytest.raises(NonFiniteError, match="points"):
        _core.line_of_sight_filter(np.full((1, 2), np.nan), np.zeros((1, 4)))
