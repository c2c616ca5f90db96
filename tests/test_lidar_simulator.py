"""The VLP-16 simulator: sensor layout, geometry of its returns, noise, determinism."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast.lidar import (
    POINT_DTYPE,
    Box,
    Cylinder,
    Scene,
    VLP16Simulator,
    Wall,
    harbour_scene,
    sensor_to_world,
    water_geometry,
)
from usvfast.lidar.simulator import BOAT


def wall_scene():
    # a long 5 m high wall 6 m east of the origin, running north
    return Scene([Wall(np.array([[-100.0, 6.0], [100.0, 6.0]]), height=5.0)])


def test_layout_of_a_full_frame():
    # a closed basin 50 m square: every beam meets a wall unless it meets the water first
    square = np.array([[-25.0, -25.0], [25.0, -25.0], [25.0, 25.0], [-25.0, 25.0], [-25, -25]])
    sim = VLP16Simulator(Scene([Wall(square, 30.0)]), seed=0)
    f = sim.scan((0.0, 0.0, 0.3), 50.0)
    p = f.frame.points
    assert p.dtype == POINT_DTYPE
    # 1800 azimuths x 16 rings; the walls are 25..35 m away: rings meeting the water
    # closer than that (eq. 3.18) return nothing
    dist, _ = water_geometry(1.0)
    water_rings = int(np.sum(dist < 25.0))
    assert water_rings == 7
    assert len(p) == 1800 * (16 - water_rings)
    assert set(np.unique(p["ring"]).tolist()) == set(range(water_rings, 16))
    el = np.degrees(np.arctan2(p["z"], np.hypot(p["x"], p["y"])))
    np.testing.assert_allclose(el, -15.0 + 2.0 * p["ring"], atol=0.05)  # ~3 cm noise
    # one rotation at 600 rpm: times span 0.1 s before the stamp
    assert p["time"].min() == pytest.approx(-0.1 + 0.1 / 1800, abs=1e-6)
    assert p["time"].max() == pytest.approx(0.0, abs=1e-6)
    az = np.degrees(np.arctan2(-p["y"], p["x"])) % 360.0
    steps = np.unique(np.round(az[p["ring"] == 15] / 0.2).astype(int))
    assert steps.size == 1800


def test_wall_returns_lie_on_the_wall_with_range_noise():
    sim = VLP16Simulator(wall_scene(), range_noise=0.03, seed=4)
    f = sim.scan((0.0, 0.0, 0.0), 0.0)
    p = f.frame.points
    assert (f.labels == 0).all() and f.hits == {0: len(p)}
    world = sensor_to_world(np.column_stack([p["x"], p["y"]]), (0.0, 0.0, 0.0))
    # heading north: the wall (east = 6) is on the right, y = -6 in the sensor frame
    assert np.all(p["y"] < 0)
    # horizontal offset from the wall ~ range noise x cos(elevation) x 1/cos(incidence)
    err = world[:, 1] - 6.0
    near = np.abs(p["x"]) < 3.0  # near-normal incidence
    assert abs(err[near].mean()) < 0.005
    assert err[near].std() == pytest.approx(0.03, rel=0.15)
    height = p["z"] + 1.0
    assert height.min() >= -0.15 and height.max() <= 5.0 + 0.15


def test_water_returns_nothing_but_clutter():
    sim = VLP16Simulator(Scene([]), seed=1)
    assert len(sim.scan((0, 0, 0), 0).frame) == 0
    sim = VLP16Simulator(Scene([], clutter_probability=0.05, clutter_range=12.0), seed=1)
    f = sim.scan((0, 0, 0), 0)
    p = f.frame.points
    assert (f.labels == -1).all() and len(p) > 0
    assert np.abs(p["z"] + 1.0).max() < 0.05  # on the water surface
    assert np.hypot(p["x"], p["y"]).max() <= 12.1
    # about 5 % of the beams meeting the water within 12 m (rings 0..5: 6 x 1800)
    assert len(p) == pytest.approx(0.05 * 6 * 1800, rel=0.2)


def test_pose_and_objects():
    # a floating cylinder 5 m ahead-left of a vessel heading east (pi/2)
    scene = Scene([Cylinder((5.0, 5.0), 0.3, 0.0, 0.3)])
    sim = VLP16Simulator(scene, range_noise=0.0, seed=0)
    f = sim.scan((5.0, 0.0, np.pi / 2), 0.0)  # at north 5, east 0, facing east
    p = f.frame.points
    assert f.hits and len(p) == f.hits[0]
    # in the sensor frame the object is straight ahead (x ~ 4.7..5.3, y ~ 0)
    assert np.all((p["x"] > 4.6) & (p["x"] < 5.31)) and np.abs(p["y"]).max() < 0.31
    assert np.all(p["z"] + 1.0 <= 0.3 + 1e-6)


def test_occlusion_by_a_boat():
    boat = Box((0.0, 4.0), 6.0, 2.0, 0.0, 0.0, 1.5)
    hidden = Cylinder((0.0, 7.0), 0.3, 0.0, 0.3)
    f = VLP16Simulator(Scene([boat, hidden]), seed=0).scan((0, 0, 0), 0)
    assert 0 in f.hits and 1 not in f.hits


def test_deterministic_given_seed():
    scene = harbour_scene(seed=3, clutter_probability=0.001)
    a = VLP16Simulator(scene, seed=7).scan((1.0, 0.5, 0.1), 10.0)
    b = VLP16Simulator(scene, seed=7).scan((1.0, 0.5, 0.1), 10.0)
    c = VLP16Simulator(scene, seed=8).scan((1.0, 0.5, 0.1), 10.0)
    np.testing.assert_array_equal(a.frame.points, b.frame.points)
    np.testing.assert_array_equal(a.labels, b.labels)
    assert not np.array_equal(a.frame.points["x"], c.frame.points["x"])


def test_harbour_scene_rules():
    scene = harbour_scene(seed=5, walls=2, boats=3, floats=9)
    kinds = scene.kinds()
    assert (kinds == "wall").sum() == 2 and (kinds == "boat").sum() == 3
    floats = [o for o in scene.objects if o.kind == "float"]
    assert len(floats) == 9
    c = np.array([o.center for o in floats])
    r = np.hypot(c[:, 0], c[:, 1])
    assert np.all((r >= 3.5) & (r <= 10.0))
    d = np.hypot(*(c[:, None, :] - c[None, :, :]).transpose(2, 0, 1))
    assert d[np.triu_indices(9, 1)].min() >= 4.0
    assert all(0.05 <= o.top <= 0.30 for o in floats)
    with pytest.raises(ValueError, match="floats"):
        harbour_scene(seed=0, floats=40)
    # boats must fit along the wall (north of -10 m, up to `length`): a huge count fails fast
    with pytest.raises(ValueError, match=r"boats: only \d+ of 1000000000 fit"):
        harbour_scene(seed=0, boats=10**9)
    with pytest.raises(ValueError, match="boats: expected >= 0"):
        harbour_scene(seed=0, boats=-1)
    boats = [o for o in harbour_scene(seed=0, boats=4, length=60.0).objects if o.kind == BOAT]
    assert len(boats) == 4 and max(b.center[0] + b.length / 2 for b in boats) <= 60.0
