"""Bad input at the public boundary: a clear ValueError/TypeError naming the argument, never a
silent NaN, a leaked AttributeError/IndexError/ZeroDivisionError/cv2.error or a complex value
cut to its real part; and the empty cases (a frame with no detections) work."""

from __future__ import annotations

import math

import numpy as np
import pytest

from usvfast import frames, geodesy, lidar
from usvfast.bearing import pixel_to_bearing, reference_bearing_deg, unwrap_deg, wrap_deg
from usvfast.camera import CameraModel, georeference, horizon_line, sensitivity
from usvfast.camera.calibration import undistort_points
from usvfast.lidar.evaluation import straight_run
from usvfast.lidar.pipeline import cluster_detections, prefilter, sensor_to_world, world_to_sensor
from usvfast.tracking import GNN, MultiMeasurementInitiator, Sensor, StepsSinceUpdate, Tracker

NAN, INF = math.nan, math.inf
SEG = np.array([[0.0, 0.0, 1.0, 0.0], [0.0, 1.0, 2.0, 1.0]])
PTS = lidar.make_points(np.zeros(3), np.ones(3), np.zeros(3))

CASES = [
    ("roll", lambda: frames.rotation_matrix(NAN, 0.0, 0.0)),
    ("yaw", lambda: frames.se3(0.0, 0.0, INF, (0.0, 0.0, 0.0))),
    ("pose", lambda: sensor_to_world(np.zeros((1, 2)), (0.0, NAN, 0.0))),
    ("mount_yaw", lambda: sensor_to_world(np.zeros((1, 2)), (0, 0, 0), mount_yaw=NAN)),
    ("xy", lambda: sensor_to_world(np.full((1, 2), INF), (0.0, 0.0, 0.0))),
    ("ne", lambda: world_to_sensor(np.full((1, 2), NAN), (0.0, 0.0, 0.0))),
    ("lever_arm", lambda: world_to_sensor(np.zeros((1, 2)), (0, 0, 0), lever_arm=(NAN, 0))),
    ("distance", lambda: lidar.extend_segments(SEG, INF)),
    ("motion", lambda: lidar.move_segments(SEG, (NAN, 0.0, 0.0))),
    ("segments", lambda: lidar.point_segment_distance(np.zeros((1, 2)), SEG * NAN)),
    ("points", lambda: lidar.point_segment_distance(np.full((1, 2), INF), SEG)),
    ("tolerance", lambda: lidar.covered_mask(SEG, NAN)),
    ("tolerance", lambda: lidar.drop_covered(SEG, NAN)),
    ("x", lambda: lidar.make_points(np.array([NAN]), np.zeros(1), np.zeros(1))),
    ("x", lambda: lidar.make_points(1.0, 2.0, 3.0)),  # used to be an IndexError
    ("speed", lambda: straight_run(5, speed=NAN)),
    ("rate", lambda: straight_run(5, rate=0)),  # used to be a ZeroDivisionError
    ("time", lambda: cluster_detections(np.zeros((20, 2)), time=NAN)),
    ("angle_deg", lambda: wrap_deg(NAN)),
    ("angle_deg", lambda: unwrap_deg([0.0, NAN])),
    ("radius", lambda: prefilter(PTS, radius=NAN)),  # used to keep nothing, silently
    ("inputs", lambda: geodesy.ecef2geodetic(1e155, 1e155, 1e155)),  # lat 45°, NaN height
    ("x", lambda: geodesy.ecef2geodetic(np.array([6.4e6 + 1e3j]), 0.0, 0.0)),  # complex
    ("lat", lambda: geodesy.geodetic2ecef(np.array([1 + 1j]), 0.0, 0.0)),
    ("camera", lambda: pixel_to_bearing(1.0, 2.0, camera=None)),
    ("camera", lambda: georeference(np.zeros((1, 2)), None, height=1.0)),
    ("camera", lambda: horizon_line(None)),
    ("own", lambda: reference_bearing_deg([0.0], None, None)),
    ("image", lambda: lidar.blur(None)),  # used to be a cv2.error
    ("camera", lambda: undistort_points(np.zeros((1, 2)), None)),
    ("noise_std", lambda: Sensor.position(noise_std=NAN)),  # used to give R = NaN, silently
    ("noise_std", lambda: Sensor.position(noise_std=-1.0)),
    ("noise_std", lambda: Sensor.position(noise_std=(1.0, 2.0, 3.0))),
    ("ndim_state", lambda: Sensor.position(1.0, ndim_state=10**12)),  # used to allocate 16 TB
    ("min_points", lambda: _tracker(min_points=10**20)),  # used to be an OverflowError
    ("max_new_tentative", lambda: _tracker(max_new_tentative=2**64)),
]


def _tracker(**initiator):
    from usvfast.kalman import constant_velocity_2d

    init = MultiMeasurementInitiator(np.zeros(4), np.eye(4), **initiator)
    return Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[Sensor.position(1.0)],
        association=GNN(),
        deleter=StepsSinceUpdate(3),
        initiator=init,
    )


@pytest.mark.parametrize(("name", "call"), CASES)
def test_bad_input_is_a_named_value_or_type_error(name, call):
    with pytest.raises((ValueError, TypeError)) as info:
        call()
    assert name in str(info.value)


@pytest.fixture()
def camera():
    k = np.array([[800.0, 0.0, 320.0], [0.0, 800.0, 240.0], [0.0, 0.0, 1.0]])
    return CameraModel(k, np.array([-0.2, 0.05, 0.0, 0.0, 0.0]), (640, 480))


def test_calibrated_camera_with_no_detections(camera):
    none = np.zeros((0, 2))
    g = georeference(none, camera, height=2.0)
    assert g.positions.shape == (0, 2) and g.covariances.shape == (0, 2, 2)
    assert undistort_points(none, camera).shape == (0, 2)
    s = sensitivity(none, camera, height=2.0)
    assert s.pixel_plus.shape == (0, 2) and s.pitch_minus.shape == (0, 2)
    # and one detection still gives the same as before (the empty path is separate)
    one = georeference(np.array([[320.0, 400.0]]), camera, height=2.0)
    assert np.isfinite(one.positions).all()
