"""Water geometry of a multi-beam LiDAR: thesis Table 3.1 and the dead zone, cross-checked
against the ray-casting simulator."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from usvfast.lidar import (
    Cylinder,
    Scene,
    VLP16Simulator,
    dead_zone_radius,
    downward_angles_deg,
    water_geometry,
)

# Thesis Table 3.1 (VLP-16 at 1 m): ground intersection distance and worst-case height.
TABLE_GID = [3.73, 4.33, 5.14, 6.31, 8.14, 11.43, 19.08, 57.28]
TABLE_H = [0.14, 0.16, 0.19, 0.22, 0.29, 0.40]  # rays 1..6; ray 7 is checked below


def test_table_3_1_distances():
    dist, _ = water_geometry(1.0)
    assert dist.shape == (8,)
    # The table truncates to 2 decimals (57.2899 is printed 57.28): within 0.01 m.
    np.testing.assert_allclose(dist, TABLE_GID, atol=0.01)
    assert np.all(dist >= np.array(TABLE_GID) - 1e-9)


def test_table_3_1_heights():
    _, h = water_geometry(1.0)
    assert np.isnan(h[0])
    np.testing.assert_allclose(h[1:7], TABLE_H, atol=0.005)
    # Eq. 3.19 gives 0.667 m for ray 7 where the table prints 0.8 m: we follow the equation.
    assert h[7] == pytest.approx((57.28996 - 19.08114) / 57.28996, abs=1e-4)
    assert h[7] == pytest.approx(0.667, abs=1e-3)


def test_dead_zone_for_a_10_cm_object():
    # Thesis: 3.73 m - 0.1 * tan(75 deg) = 3.35 m (printed truncated; exactly 3.3588 m).
    r = dead_zone_radius(1.0, 0.1)
    assert r == pytest.approx(3.35, abs=0.01)
    assert r == pytest.approx(0.9 * np.tan(np.deg2rad(75.0)), rel=1e-12)
    assert dead_zone_radius(1.0, 0.0) == pytest.approx(water_geometry(1.0)[0][0])
    assert dead_zone_radius(1.0, 1.5) == 0.0
    # no beam below the horizon, or a radius beyond float64: errors naming the inputs
    with pytest.raises(ValueError, match="vfov_deg: expected 2e-9 < vfov_deg < 180"):
        dead_zone_radius(1.0, 0.0, vfov_deg=5e-324)
    with pytest.raises(ValueError, match="height, vfov_deg: out of the representable range"):
        dead_zone_radius(1e300, 0.0, vfov_deg=1e-8)


def test_downward_angles():
    np.testing.assert_allclose(downward_angles_deg(16, 30.0), 75.0 + 2.0 * np.arange(8))
    # odd channel count: the horizontal beam never meets the water
    assert downward_angles_deg(3, 30.0).tolist() == [75.0]


@given(
    height=st.floats(0.2, 20.0),
    channels=st.integers(2, 128),
    vfov=st.floats(5.0, 120.0),
)
def test_geometry_invariants(height, channels, vfov):
    dist, h = water_geometry(height, channels=channels, vfov_deg=vfov)
    assert dist.size == len(downward_angles_deg(channels, vfov))
    assert np.all(np.diff(dist) > 0)  # nearest ray first
    assert np.all(h[1:] > 0) and np.all(h[1:] < height)
    # distances scale linearly with the height, heights too
    d2, h2 = water_geometry(2 * height, channels=channels, vfov_deg=vfov)
    np.testing.assert_allclose(d2, 2 * dist, rtol=1e-12)
    np.testing.assert_allclose(h2[1:], 2 * h[1:], rtol=1e-12)
    # an object of height h_i just beyond ray i-1's water point touches ray i (eq. 3.19)
    theta = np.deg2rad(downward_angles_deg(channels, vfov))
    ray_height = height - dist[:-1] / np.tan(theta[1:])
    np.testing.assert_allclose(ray_height, h[1:], rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((0.0,), "height"),
        ((-1.0,), "height"),
        ((float("nan"),), "height"),
    ],
)
def test_bad_arguments(args, match):
    with pytest.raises(ValueError, match=match):
        water_geometry(*args)
    with pytest.raises(ValueError, match="channels"):
        water_geometry(1.0, channels=1)
    with pytest.raises(ValueError, match="vfov_deg"):
        water_geometry(1.0, vfov_deg=200.0)
    with pytest.raises(ValueError, match="object_height"):
        dead_zone_radius(1.0, -0.1)


@pytest.mark.parametrize("top", [0.1, 0.25])
def test_simulator_agrees_with_the_dead_zone(top):
    """A thin post of height `top` is hit by the lowest beam only beyond the dead-zone
    radius: ray casting and eq. 3.18/3.19 are two independent computations."""
    r0 = dead_zone_radius(1.0, top)
    for dist, expect in [(r0 - 0.08, False), (r0 + 0.08, True)]:
        post = Cylinder((dist, 0.0), 0.05, 0.0, top)
        sim = VLP16Simulator(Scene([post]), range_noise=0.0, azimuth_step_deg=0.1, seed=0)
        frame = sim.scan((0.0, 0.0, 0.0), 0.0)
        assert bool(frame.hits) is expect, (dist, frame.hits)
        if expect:
            assert set(frame.frame.points["ring"][frame.labels == 0].tolist()) == {0}
