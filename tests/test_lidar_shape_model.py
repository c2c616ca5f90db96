"""The LiDAR measurement model by cluster shape (`LidarChain._measurement_model`): the centre
offset grows with the cluster's seen half-width, the variance along the line of sight grows
with the seen width of a low float, the covariance is symmetric positive definite and turns
with the line of sight; the cluster's top height comes from the points' heights; bad settings
are errors naming the key."""

from __future__ import annotations

import math
from importlib import resources

import numpy as np
import pytest

from usvfast.frames import Mount
from usvfast.lidar.pipeline import LidarDetection, cluster_detections
from usvfast.pipeline import ConfigError, load_config
from usvfast.pipeline.config import SCHEMA
from usvfast.pipeline.lidar_chain import LidarChain
from usvfast.pipeline.pose import VesselPose
from usvfast.pipeline.timing import StageTimer

# The simulated recordings' values (bundled recording.toml).
MODEL = dict(
    covariance="model",
    surface_offset=0.03,
    surface_offset_share=0.32,
    range_std=0.03,
    cross_range_std=0.02,
    reference_points=12,
    low_profile_std=0.29,
    low_profile_height=0.145,
)


def _chain(**changes) -> LidarChain:
    settings = {k: v for k, (_, v) in SCHEMA["lidar"].items()}
    settings.update(waterline_height=0.3, **MODEL)
    settings.update(changes)
    return LidarChain(settings, Mount(), StageTimer())


def _rot(a: float) -> np.ndarray:
    return np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])


def _detection(bearing: float, width: float, depth: float, top: float | None, n: int = 40):
    """A cluster 6 m from the sensor (at the origin) at `bearing` rad from north, seen
    `width` m across and `depth` m along the line of sight (uniform: std = size / sqrt(12))."""
    r = _rot(bearing)
    spread = r @ np.diag([depth**2 / 12, width**2 / 12]) @ r.T
    position = 6.0 * np.array([math.cos(bearing), math.sin(bearing)])
    return LidarDetection(0.0, position, np.eye(2), n, spread=spread, top=top)


POSE = VesselPose(0.0, 0.0, 0.0, 0.0)


def test_offset_and_covariance_follow_the_seen_width():
    chain = _chain()
    dets = [_detection(0.0, w, 0.1, top=0.04) for w in (0.05, 0.2, 0.4)]
    dets.append(_detection(0.0, 0.4, 0.1, top=0.2))  # as wide, but tall
    chain._measurement_model(dets, POSE)
    along = [d.covariance[0, 0] for d in dets]  # bearing 0: along = north
    assert along[0] < along[1] < along[2]
    for d, w in zip(dets[:3], (0.05, 0.2, 0.4), strict=True):
        # offset: 0.03 + 0.32 * half-width (sqrt(3) std across = w / 2)
        np.testing.assert_allclose(d.position, [6.0 + 0.03 + 0.32 * w / 2, 0.0], atol=1e-12)
        low = 1.0 - 0.04 / 0.145
        np.testing.assert_allclose(
            d.covariance, np.diag([0.03**2 + (0.29 * w * low) ** 2, 0.02**2]), atol=1e-15
        )
    # a tall object's hits stay on its face: no low-profile term
    np.testing.assert_allclose(dets[3].covariance, np.diag([0.03**2, 0.02**2]), atol=1e-15)
    for d in dets:
        np.testing.assert_array_equal(d.covariance, d.covariance.T)
        assert np.linalg.eigvalsh(d.covariance).min() > 0
    # no spread or top known (a hand-made detection): the constant model of old
    d = LidarDetection(0.0, np.array([6.0, 0.0]), np.eye(2), 6)
    chain._measurement_model([d], POSE)
    np.testing.assert_allclose(d.position, [6.03, 0.0], atol=1e-12)
    np.testing.assert_allclose(d.covariance, np.diag([0.03**2, 0.02**2]) * 2, atol=1e-15)


def test_covariance_turns_with_the_line_of_sight():
    chain = _chain()
    base = _detection(0.0, 0.35, 0.12, top=0.03, n=9)
    chain._measurement_model([base], POSE)
    assert base.covariance[0, 0] > 4 * base.covariance[1, 1]  # long along the line of sight
    for bearing in (0.4, 2.0, -2.7):
        d = _detection(bearing, 0.35, 0.12, top=0.03, n=9)
        chain._measurement_model([d], POSE)
        r = _rot(bearing)
        np.testing.assert_allclose(d.covariance, r @ base.covariance @ r.T, atol=1e-15)
        np.testing.assert_allclose(d.position, r @ base.position, atol=1e-12)


def test_model_settings_are_validated_naming_the_key():
    for key, value in (
        ("low_profile_std", -0.1),
        ("surface_offset_share", math.nan),
        ("low_profile_height", 0.0),
        ("low_profile_height", math.inf),
    ):
        with pytest.raises(ValueError, match=rf"lidar\.{key}"):
            _chain(**{key: value})
    path = resources.files("usvfast") / "data" / "harbour" / "recording.toml"
    cfg = load_config(path)
    assert cfg.lidar["low_profile_std"] == MODEL["low_profile_std"]
    with pytest.raises(ConfigError, match=r"key 'lidar\.low_profile_height'"):
        load_config(path, {"lidar.low_profile_height": "low"})


def test_cluster_top_is_the_members_highest_point():
    rng = np.random.default_rng(3)
    a = rng.normal([5.0, 0.0], 0.05, (20, 2))
    b = rng.normal([5.0, 6.0], 0.05, (30, 2))
    pts = np.vstack([a, b])
    heights = np.concatenate([rng.uniform(0.0, 0.05, 20), rng.uniform(0.0, 0.2, 30)])
    dets, _, _ = cluster_detections(pts, time=0.0, min_cluster_points=6, heights=heights)
    tops = sorted((float(d.position[1]), d.top) for d in dets)
    assert [t for _, t in tops] == [heights[:20].max(), heights[20:].max()]
    for d in dets:
        assert d.spread is not None and np.linalg.eigvalsh(d.spread).min() < 0.05**2 * 2
    with pytest.raises(ValueError, match="heights"):
        cluster_detections(pts, time=0.0, heights=heights[:-1])
    assert all(d.top is None for d in cluster_detections(pts, time=0.0)[0])
