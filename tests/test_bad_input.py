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
from usvfast.fusion.ais_feed import AisTargets, fix_times
from usvfast.fusion.picture import draw_overlay
from usvfast.fusion.pipeline import radar_tracker, run_vts
from usvfast.fusion.visual import match_detections
from usvfast.lidar.evaluation import straight_run
from usvfast.lidar.pipeline import cluster_detections, prefilter, sensor_to_world, world_to_sensor
from usvfast.nav.linetime import clock_time
from usvfast.pipeline.config import apply_overrides, config_from_dict
from usvfast.report import figures
from usvfast.report.table import summary_tables
from usvfast.shore.annotate import draw_frame
from usvfast.shore.appearance import box_histogram, histogram_distance
from usvfast.shore.bayes import BayesDetector
from usvfast.shore.daynight import frame_features, gaussian_density
from usvfast.shore.horizon import HorizonConfig, detect_horizon, horizon_keep, normalise_ir
from usvfast.shore.sort import SortTracker, box_to_z, state_to_box
from usvfast.sim.gnss import simulate_gnss, simulate_imu
from usvfast.sim.motion import PathMotion, chaikin, point_segment_distance
from usvfast.sim.scene import place_body
from usvfast.sim.velodyne import decoded_azimuths
from usvfast.stonesoup import build_native
from usvfast.sweep.summary import best_rows, param_columns
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
    # found by the fuzz suite over every package (each used to leak another exception type,
    # crash in OpenCV or return inf/NaN)
    ("positions", lambda: fix_times(0.0)),  # AttributeError
    ("origin", lambda: AisTargets(_FEED, (NAN, 0.0))),
    ("feed", lambda: AisTargets(0.0, (60.0, 5.0))),
    ("image", lambda: draw_overlay(0.0, np.zeros((0, 2)), [])),
    ("labels", lambda: draw_overlay(IMG, np.zeros((1, 2)), [1.0])),  # cv2.error in putText
    ("cfg", lambda: radar_tracker(0.0)),
    ("plots", lambda: run_vts(0.0, None, None, origin=(60.0, 5.0))),
    ("projection", lambda: match_detections(False, None, np.zeros((0, 4)))),
    ("line", lambda: clock_time(0.0)),
    ("data", lambda: apply_overrides([], 7)),
    ("data", lambda: config_from_dict("")),
    ("ax", lambda: figures.draw_usv(0.0, None)),
    ("tracks", lambda: figures.draw_tracks(_AX, 0.0)),
    ("ids", lambda: figures.track_colors(np.array([INF]))),  # OverflowError
    ("mean_ne", lambda: figures.ellipse(np.zeros(4), np.eye(2))),
    ("innovations", lambda: figures.nis_figure(0.0)),
    ("metrics", lambda: summary_tables(0.0)),
    ("image", lambda: draw_frame(0.0, None, None, None, None, "")),
    ("image", lambda: box_histogram(np.zeros((4, 4)), np.zeros(4))),  # float image
    ("a", lambda: histogram_distance(np.zeros(3), np.zeros(3))),  # cv2.error
    ("config", lambda: BayesDetector(config=1e300)),
    ("image", lambda: frame_features(np.full((4, 4), NAN))),  # NaN features
    ("sigma", lambda: gaussian_density(0.0, 0.0, 0.0)),  # ZeroDivisionError
    ("image", lambda: detect_horizon(0.0)),
    ("detections", lambda: horizon_keep(np.zeros((2, 4)), None, 10, HorizonConfig())),
    ("gray", lambda: normalise_ir("x")),  # cv2.error
    ("config", lambda: SortTracker(config=np.zeros(3))),
    ("box", lambda: box_to_z(np.array([0.0, 0.0, 1e300, 1e300]))),  # inf area
    ("x", lambda: state_to_box((1.0, 2.0, 3.0))),  # IndexError
    ("world", lambda: simulate_gnss((1.0, 2.0), 0.0, 1.0)),
    ("world", lambda: simulate_imu(np.zeros((2, 3)), 0.0, 1.0)),
    ("vertices", lambda: PathMotion(-1e300, 1.0)),  # IndexError
    ("points", lambda: chaikin(0)),
    ("p, polyline", lambda: point_segment_distance((1.0, 2.0), np.zeros((0, 2)))),  # inf
    ("body", lambda: place_body(0.0, 0.0, 0.0, 0.0)),
    ("block_azimuths", lambda: decoded_azimuths(0.0)),  # IndexError
    ("cfg", lambda: build_native(0.0, [])),
    ("table", lambda: best_rows(np.zeros((0, 2)), "rmse")),  # IndexError
    ("table", lambda: param_columns(0.0)),
]


IMG = np.zeros((8, 8, 3), np.uint8)


def _feed():
    from pyais.encode import encode_dict

    from usvfast.fusion import read_ais_feed

    d = dict(type=1, msg_type=1, mmsi=257000009, lat=63.0, lon=10.0, speed=1.0, course=0.0)
    line = encode_dict(d, talker_id="AI", sentence_type="VDM")[0]
    return read_ais_feed([f"1700000000 {line}"])


def _ax():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    plt.close(fig)
    return ax


_FEED = _feed()
_AX = _ax()


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
