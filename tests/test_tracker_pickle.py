"""A Tracker pickles (configuration, sensors, models, initiator, deleters, IMM, existence,
tracks and histories): a restored tracker — here and in another process — continues exactly
like the original."""

from __future__ import annotations

import multiprocessing as mp
import pickle

import numpy as np
import pytest

from usvfast import _core
from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d


def make() -> T.Tracker:
    cv = constant_velocity_2d(0.5)
    return T.Tracker(
        motion_model=cv,
        sensors=[
            T.Sensor.position(1.0),
            T.Sensor.bearing_range(noise_std=(np.deg2rad(1.0), 2.0), update="ukf"),
        ],
        association=T.JPDA(0.9, 0.99, 1e-4, max_hypotheses=50),
        deleter=T.AnyOf(T.CovarianceTrace(400.0), T.StepsSinceUpdate(4)),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4),
            np.diag([0, 4.0, 0, 4.0]),
            min_points=2,
            missed_distance=4.0,
            max_new_tentative=50,
        ),
        imm=T.IMM(
            [cv, T.KnownTurnRate(0.5, 0.1), T.KnownTurnRate(0.5, -0.1)],
            [[0.9, 0.05, 0.05], [0.1, 0.9, 0.0], [0.1, 0.0, 0.9]],
        ),
        existence=T.Existence(vis_stay=0.9, invis_stay=0.5, confirm=0.6),
        max_deleted=5,
    )


def scans(n: int, seed: int = 0):
    """Five crossing targets seen by both sensors, clutter, one target dying halfway."""
    rng = np.random.default_rng(seed)
    for k in range(n):
        t = float(k)
        pos = np.array([[10.0 * i + 3 * t, 50.0 - 2 * i * t] for i in range(5)])
        if k > n // 2:
            pos = pos[:4]
        seen = pos[rng.random(len(pos)) < 0.9]
        lin = seen + rng.normal(0, 1.0, seen.shape)
        d = seen - np.array([-100.0, 0.0])
        polar = np.column_stack([np.arctan2(d[:, 1], d[:, 0]), np.hypot(d[:, 0], d[:, 1])])
        polar += rng.normal(0, [np.deg2rad(1.0), 2.0], polar.shape)
        clutter = rng.uniform(-50, 150, (rng.poisson(3), 2))
        z = np.vstack([lin, clutter, polar])
        ids = np.r_[np.zeros(len(lin) + len(clutter), int), np.ones(len(polar), int)]
        origins = np.tile([-100.0, 0.0], (len(z), 1))
        yield t, z, ids, origins


def advance(tr: T.Tracker, items) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    out = []
    for t, z, ids, o in items:
        s = tr.step(t, z, ids, origins=o)
        out.append((s.ids, s.states, s.mode_probabilities, s.existence))
    return out


def continue_in_worker(blob: bytes) -> list:
    tr = pickle.loads(blob)
    return advance(tr, list(scans(40))[20:])


def assert_same(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x[0], y[0])
        for u, v in zip(x[1:], y[1:], strict=True):
            np.testing.assert_allclose(u, v, rtol=0, atol=1e-12)


def test_restored_tracker_continues_exactly():
    items = list(scans(40))
    tr = make()
    advance(tr, items[:20])
    assert len(tr.tracks) >= 3
    blob = pickle.dumps(tr)
    restored = pickle.loads(blob)
    np.testing.assert_array_equal(restored.tracks.states, tr.tracks.states)
    h0 = tr.history(int(tr.tracks.ids[0]))
    h1 = restored.history(int(tr.tracks.ids[0]))
    np.testing.assert_array_equal(h0.covariances, h1.covariances)
    assert restored.last_time == tr.last_time and len(restored.sensors) == 2
    np.testing.assert_array_equal(
        restored.sensors[1].measurement_noise, tr.sensors[1].measurement_noise
    )
    a, b = advance(tr, items[20:]), advance(restored, items[20:])
    assert_same(a, b)
    np.testing.assert_array_equal(tr.deleted_track_ids, restored.deleted_track_ids)
    assert len(tr.deleted_track_ids) >= 1
    # The copy is independent: stepping the restored one leaves the original alone.
    restored.step(100.0)
    assert tr.last_time == 39.0


def test_restored_tracker_continues_exactly_in_a_process_pool():
    items = list(scans(40))
    tr = make()
    advance(tr, items[:20])
    blob = pickle.dumps(tr)
    with mp.get_context("spawn").Pool(1) as pool:
        remote = pool.apply(continue_in_worker, (blob,))
    assert_same(advance(tr, items[20:]), remote)


def test_damaged_state_is_a_clear_error():
    blob = pickle.dumps(make())
    with pytest.raises(ValueError, match="state"):
        _core.TrackerCore.from_bytes(b"not a tracker")
    with pytest.raises(ValueError, match="state"):
        _core.TrackerCore.from_bytes(_core.TrackerCore.to_bytes(make()._core)[:-7])
    assert pickle.loads(blob).last_time is None
