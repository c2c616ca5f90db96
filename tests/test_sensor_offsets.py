"""The per-track sensor offsets in the pipeline's native tracker (`tracker.camera_offset_std`,
`lidar_offset_std`): state [n, v_n, e, v_e, then (b_n, b_e) per sensor with an offset], each
such sensor measuring position + its b, the others position."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast.pipeline.config import ConfigError, load_config
from usvfast.pipeline.tracker import make_tracker

BUNDLED = "python/usvfast/data/harbour/recording.toml"


def _settings(**over):
    s = dict(load_config(BUNDLED).tracker)
    s.update(over)
    return s


def _run(tracker, offset, seconds=30.0, seed=0, lidar_offset=0.0):
    """A float drifting north-east at 5 cm/s, 10 m ahead; LiDAR every 0.5 s (σ 5 cm) and the
    camera every 0.1 s (σ 5 cm) off by `offset` m. Returns the last snapshot, the NIS of the
    LiDAR updates after 5 s (each follows camera updates) and the truth's last position."""
    rng = np.random.default_rng(seed)
    r = np.diag([0.05**2, 0.05**2])
    lidar_nis, snap = [], None
    for k in range(1, int(seconds * 10) + 1):
        t = 0.1 * k
        truth = np.array([10.0 + 0.05 * t, 0.05 * t])
        sensor = 0 if k % 5 == 0 else 1
        z = truth + rng.normal(0, 0.05, 2) + (offset if sensor == 1 else lidar_offset)
        snap = tracker.step(t, z[None], np.array([sensor]), r[None])
        if sensor == 0 and t > 5:
            lidar_nis += [v for _, s, v in snap.innovations if s == 0]
    return snap, np.array(lidar_nis), truth


def test_offset_is_estimated_and_the_track_follows_the_lidar():
    offset = np.array([0.5, -0.3])
    tr = make_tracker(_settings(camera_offset_std=0.5, camera_offset_q=1e-4))
    snap, nis, truth = _run(tr, offset)
    assert snap.ids.size == 1 and snap.states.shape == (1, 4)
    assert snap.covariances.shape == (1, 4, 4)
    np.testing.assert_allclose(snap.states[0, [0, 2]], truth, atol=0.06)
    np.testing.assert_allclose(tr.tracker.tracks.states[0, 4:6], offset, atol=0.06)
    assert nis.size >= 49 and 0.5 < nis.mean() < 4.0  # every LiDAR detection updates
    # without the offset state the camera drags the track 0.58 m off, and the LiDAR's
    # detections fall far off it (most outside its gate)
    plain = make_tracker(_settings(camera_offset_std=0.0))
    snap0, nis0, _ = _run(plain, offset)
    assert np.hypot(*(snap0.states[0, [0, 2]] - truth)) > 0.3
    assert nis0.size < 25 or nis0.mean() > 10 * nis.mean()


def test_both_offsets_take_the_sensors_difference_and_widen_the_position():
    cam, lid = np.array([0.5, -0.3]), np.array([0.1, 0.05])
    tr = make_tracker(
        _settings(
            camera_offset_std=0.5, camera_offset_q=1e-4, lidar_offset_std=0.1, lidar_offset_q=1e-4
        )
    )
    lidar, camera = tr.tracker.sensors[0], tr.tracker.sensors[1]
    # [n, v_n, e, v_e, b_lidar (n, e), b_camera (n, e)]
    np.testing.assert_array_equal(lidar.measurement_matrix[:, 4:], [[1, 0, 0, 0], [0, 1, 0, 0]])
    np.testing.assert_array_equal(camera.measurement_matrix[:, 4:], [[0, 0, 1, 0], [0, 0, 0, 1]])
    snap, nis, truth = _run(tr, cam, lidar_offset=lid)
    x = tr.tracker.tracks.states[0]
    # only the sensors' difference is observed; the position lies between, near the LiDAR
    np.testing.assert_allclose(x[6:8] - x[4:6], cam - lid, atol=0.06)
    assert np.hypot(*(snap.states[0, [0, 2]] - truth)) < np.hypot(*lid) + 0.06
    assert nis.size >= 49 and 0.5 < nis.mean() < 4.0
    # the position's covariance keeps the offsets' prior: the LiDAR's 0.1 m (the plain
    # tracker's shrinks to the averaged white noise)
    plain = make_tracker(_settings(camera_offset_std=0.5, camera_offset_q=1e-4))
    snap0, _, _ = _run(plain, cam, lidar_offset=lid)
    assert snap.covariances[0, 0, 0] > 0.5 * 0.1**2 > 4 * snap0.covariances[0, 0, 0]


def test_vessel_tracker_offset_state_is_its_own():
    from usvfast.pipeline.tracker import make_vessel_tracker

    vt = make_vessel_tracker(_settings(camera_offset_std=0.5, lidar_offset_std=0.1, vessels=True))
    assert vt is not None and vt.tracker.sensors[1].measurement_matrix.shape == (2, 4)
    vt = make_vessel_tracker(_settings(vessel_camera_offset_std=1.0, vessels=True))
    assert vt is not None and vt.tracker.sensors[1].measurement_matrix.shape == (2, 6)


@pytest.mark.parametrize(
    "over, match",
    [
        ({"camera_offset_std": -0.1}, "camera_offset_std"),
        ({"camera_offset_q": -1.0}, "camera_offset_q"),
        ({"lidar_offset_std": -0.1}, "lidar_offset_std"),
        ({"lidar_offset_q": -1.0}, "lidar_offset_q"),
        ({"lidar_offset_std": 0.1, "backend": "stonesoup"}, "lidar_offset_std"),
        ({"camera_offset_std": 0.2, "backend": "stonesoup"}, "native"),
        ({"vessel_camera_offset_std": -1.0}, "vessel_camera_offset_std"),
        ({"vessel_camera_offset_std": 1.0, "backend": "stonesoup"}, "vessel_camera_offset_std"),
    ],
)
def test_bad_offset_settings_are_named(over, match):
    with pytest.raises(ConfigError, match=match):
        load_config(BUNDLED).with_options(tracker=over)
