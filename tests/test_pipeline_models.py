"""The pipeline's measurement models: the LiDAR centroid moved to the object's centre with a
line-of-sight covariance, camera boxes read in pixel-centre coordinates and moved to the
object's centre (cv2.projectPoints is the peer for where a water point images), the camera's
coverage (cv2.calibrationMatrixValues for the field of view) and coverage-based targets in the
report."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

import usvfast
from usvfast.camera.calibration import CameraModel
from usvfast.camera.chain import CameraPipeline
from usvfast.frames import Mount
from usvfast.lidar.pipeline import LidarDetection
from usvfast.metrics.tables import Nav, Truth
from usvfast.pipeline.camera_chain import CameraChain, _depth_table
from usvfast.pipeline.config import SCHEMA, ConfigError, load_config
from usvfast.pipeline.lidar_chain import LidarChain
from usvfast.pipeline.pose import VesselPose
from usvfast.pipeline.timing import StageTimer
from usvfast.report.evaluate import _visible


def _defaults(table: str) -> dict:
    return {k: v for k, (_, v) in SCHEMA[table].items()}


def test_lidar_measurement_model_moves_along_the_line_of_sight():
    settings = {**_defaults("lidar"), "waterline_height": 0.3, "covariance": "model"}
    settings.update(surface_offset=0.1, range_std=0.1, cross_range_std=0.04)
    mount = Mount(lever_arm=(0.5, 0.2, -0.6))
    chain = LidarChain(settings, mount, StageTimer())
    pose = VesselPose(0.0, 10.0, -3.0, math.radians(60.0))
    # the sensor in NED: the lever arm (forward 0.5, starboard 0.2) turned by the heading
    h = pose.heading
    c, s_ = math.cos(h), math.sin(h)
    sensor = np.array([10.0 + 0.5 * c - 0.2 * s_, -3.0 + 0.5 * s_ + 0.2 * c])
    target = sensor + np.array([3.0, 4.0])  # 5 m away
    det = LidarDetection(0.0, target.copy(), np.eye(2), 30)
    chain._measurement_model([det], pose)
    u = np.array([0.6, 0.8])
    np.testing.assert_allclose(det.position, target + 0.1 * u, atol=1e-12)
    w, v = np.linalg.eigh(det.covariance)
    np.testing.assert_allclose(w, [0.04**2, 0.1**2], atol=1e-15)
    assert abs(abs(v[:, 1] @ u) - 1.0) < 1e-12  # the range axis is the line of sight
    for key, value in (("range_std", -1.0), ("surface_offset", math.nan)):
        with pytest.raises(ValueError, match=f"lidar.{key}"):
            LidarChain({**settings, key: value}, mount, StageTimer())
    with pytest.raises(ValueError, match="range_std"):
        LidarChain({**settings, "range_std": 0.0}, mount, StageTimer())


def test_lidar_model_covariance_grows_for_clusters_of_few_points():
    settings = {**_defaults("lidar"), "waterline_height": 0.3, "covariance": "model"}
    settings.update(range_std=0.05, cross_range_std=0.03, reference_points=30)
    chain = LidarChain(settings, Mount(), StageTimer())
    pose = VesselPose(0.0, 0.0, 0.0, 0.0)  # heading north: along = north, across = east
    dets = [LidarDetection(0.0, np.array([6.0, 0.0]), np.eye(2), n) for n in (6, 15, 30, 90)]
    chain._measurement_model(dets, pose)
    for d, scale in zip(dets, (5.0, 2.0, 1.0, 1.0), strict=True):
        np.testing.assert_allclose(
            d.covariance, np.diag([0.05**2, 0.03**2]) * scale, rtol=1e-12, atol=1e-15
        )
    with pytest.raises(ValueError, match=r"lidar\.reference_points"):
        LidarChain({**settings, "reference_points": -1}, Mount(), StageTimer())


def _camera_chain(depth: float) -> tuple[CameraChain, CameraModel]:
    k = np.array([[300.0, 0.0, 319.5], [0.0, 300.0, 179.5], [0.0, 0.0, 1.0]])
    model = CameraModel(k, np.array([-0.1, 0.02, 0.0, 0.0, 0.0]), (640, 360))
    chain = CameraChain.__new__(CameraChain)
    chain.settings = {
        **_defaults("camera"),
        "waterline_height": 0.3,
        "object_depth_factor": depth,
        "pixel_sigma_uv": (0.8, 0.3),
    }
    chain.camera = model
    from usvfast.camera.georef import mount_rotation

    chain.rotation = mount_rotation([0.0, 0.0, 0.0])
    chain.position = np.array([0.0, 0.0, -0.9])
    chain.height = 1.2
    chain.timer = StageTimer()
    chain.moving_classes = None
    return chain, model


def _image(model: CameraModel, forward: float, starboard: float) -> np.ndarray:
    """Pixel (centre convention) of a water point (forward, starboard) m of the camera (level,
    1.2 m above the water): cv2.projectPoints through the distorted model."""
    return model.project(np.array([[starboard, 1.2, forward]]))[0]


def test_camera_boxes_in_pixel_centre_coordinates_and_the_object_centre():
    pose = VesselPose(0.0, 0.0, 0.0, 0.0)
    chain, model = _camera_chain(0.0)
    for fwd, stb in ((6.0, 0.5), (12.0, -1.5), (18.0, 2.0)):
        u, v = _image(model, fwd, stb)
        # a detector box counts pixel edges: the contact pixel centre (u, v) is its bottom
        # edge at v + 0.5 and its horizontal centre at u + 0.5
        box = np.array([[u - 5.0 + 0.5, v - 8.0, u + 5.0 + 0.5, v + 0.5]])
        g = chain._georeference(box, pose)
        np.testing.assert_allclose(g.positions[0], [fwd, stb], atol=2e-3 * fwd)
    # the object's centre lies half its seen width beyond the near waterline point
    chain, model = _camera_chain(0.5)
    fwd, stb, width = 10.0, 1.0, 0.6
    ul, vl = _image(model, fwd, stb - width / 2)
    ur, vr = _image(model, fwd, stb + width / 2)
    box = np.array([[ul + 0.5, min(vl, vr) - 6.0, ur + 0.5, (vl + vr) / 2 + 0.5]])
    contact = chain._georeference(box, pose).positions
    moved = chain._to_centre(box, contact, pose, 0.5)
    los = contact[0] - chain.position[:2]
    expected = contact[0] + 0.5 * width * los / np.linalg.norm(los)
    np.testing.assert_allclose(moved[0], expected, atol=0.02)
    assert np.linalg.norm(moved[0] - contact[0]) == pytest.approx(0.3, abs=0.02)


def test_camera_class_with_a_known_depth():
    # A 6 m hull seen side-on 12 m ahead: its box spans 6 m across the line of sight, so
    # object_depth_factor x width would put it 3 m beyond the waterline; class 4 (vessel)
    # has its centre half a beam (1.1 m) beyond it, with 1 m of extra standard deviation.
    pose = VesselPose(0.0, 0.0, 0.0, 0.0)
    chain, model = _camera_chain(0.5)
    chain.settings.update(depth_classes=(4.0,), class_depth_m=(1.1,), class_depth_std_m=(1.0,))
    chain.depth_table = _depth_table(chain.settings)
    chain.filters = CameraPipeline(detector=lambda ims: [], camera=model, height=1.2)
    ul, vl = _image(model, 12.0, -3.0)
    ur, vr = _image(model, 12.0, 3.0)
    box = [[ul + 0.5, min(vl, vr) - 20.0, ur + 0.5, (vl + vr) / 2 + 0.5]]
    contact = chain._georeference(np.array(box), pose).positions[0]
    vessel = chain.finish((box, [0.9], [4]), pose)
    floating = chain.finish((box, [0.9], [0]), pose)
    assert np.linalg.norm(vessel.positions[0] - contact) == pytest.approx(1.1, abs=1e-6)
    assert np.linalg.norm(floating.positions[0] - contact) == pytest.approx(3.0, abs=0.05)
    np.testing.assert_allclose(
        vessel.covariances[0] - floating.covariances[0], np.eye(2), atol=1e-12
    )
    for bad in ({"class_depth_m": (1.0, 2.0)}, {"class_depth_std_m": (-1.0,)}):
        with pytest.raises(ValueError, match="class_depth"):
            _depth_table({**chain.settings, **bad})


def test_camera_centre_error_along_and_across_the_line_of_sight():
    # A float 10 m ahead and 5 m to starboard: camera.centre_along_std / centre_across_std
    # add (0.1 m)^2 along the line of sight from the camera and (0.05 m)^2 across it.
    pose = VesselPose(0.0, 0.0, 0.0, 0.0)
    chain, model = _camera_chain(0.0)
    chain.depth_table = _depth_table(chain.settings)
    chain.filters = CameraPipeline(detector=lambda ims: [], camera=model, height=1.2)
    u, v = _image(model, 10.0, 5.0)
    box = [[u - 5.0 + 0.5, v - 8.0, u + 5.0 + 0.5, v + 0.5]]
    plain = chain.finish((box, [0.9], [0]), pose)
    chain.settings.update(centre_along_std=0.1, centre_across_std=0.05)
    wider = chain.finish((box, [0.9], [0]), pose)
    np.testing.assert_array_equal(wider.positions, plain.positions)
    los = plain.positions[0] - chain.position[:2]
    along = los / np.linalg.norm(los)
    across = np.array([-along[1], along[0]])
    added = wider.covariances[0] - plain.covariances[0]
    assert along @ added @ along == pytest.approx(0.01, abs=1e-12)
    assert across @ added @ across == pytest.approx(0.0025, abs=1e-12)
    assert along @ added @ across == pytest.approx(0.0, abs=1e-12)


def test_camera_centre_error_must_not_be_negative():
    bundled = Path(usvfast.__file__).parent / "data" / "harbour" / "recording.toml"
    with pytest.raises(ConfigError, match=r"key 'camera\.centre_across_std': must be >= 0"):
        load_config(bundled, {"camera.centre_across_std": -0.1})


def test_camera_coverage_is_the_calibrated_field_of_view():
    chain, model = _camera_chain(0.0)
    chain.camera = CameraModel(model.camera_matrix, np.zeros(5), (640, 360))
    rng, fov, yaw = chain.coverage()
    fovx, *_ = cv2.calibrationMatrixValues(model.camera_matrix, (640, 360), 1.0, 1.0)
    assert rng == 40.0 and yaw == pytest.approx(0.0, abs=1e-9)
    assert fov == pytest.approx(fovx, abs=0.2)
    chain.settings["max_range"] = 15.0
    from usvfast.camera.georef import mount_rotation

    chain.rotation = mount_rotation([30.0, -5.0, 0.0])  # turned 30 deg to starboard
    rng, _, yaw = chain.coverage()
    assert rng == 15.0 and yaw == pytest.approx(30.0, abs=1e-9)


def test_targets_are_what_some_sensor_covers():
    # the USV at the origin heading north; objects ahead at 20 m, astern at 20 m, abeam at 8 m
    t = np.arange(0.0, 10.0, 0.1)
    nav = Nav(t, np.zeros((len(t), 2)), np.zeros(len(t)))
    pos = {0: (20.0, 0.0), 1: (-20.0, 0.0), 2: (0.0, 8.0)}
    rows = [(ti, k, *p) for ti in t for k, p in pos.items()]
    a = np.array(rows)
    truth = Truth(a[:, 0], a[:, 1].astype(np.int64), np.full(len(a), "box"), a[:, 2:4])
    cov = {"lidar": (10.0, 360.0, 0.0), "camera": (40.0, 90.0, 0.0)}
    seen = _visible(truth, nav, 40.0, cov)
    by = {k: seen[truth.object_id == k].all() for k in pos}
    assert by == {0: True, 1: False, 2: True}
    assert _visible(truth, nav, 40.0, None).all()  # all round, without coverage
    with pytest.raises(ValueError, match="coverage"):
        _visible(truth, nav, 40.0, {"camera": (40.0, 90.0)})
