"""IMM in the tracker: equal to filterpy's `IMMEstimator` on a single target with linear modes
(constant velocity and known-rate coordinated turns), the turn model equal to Stone Soup's
`KnownTurnRate`, and invariants under JPDA with clutter (mode probabilities sum to 1,
covariances positive definite)."""

from __future__ import annotations

from datetime import timedelta

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d

H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
OMEGA = 0.08


def modes(q=0.05):
    return [
        constant_velocity_2d(q),
        T.KnownTurnRate(q, OMEGA),
        T.KnownTurnRate(q, -OMEGA),
    ]


TRANSITION = np.array([[0.9, 0.05, 0.05], [0.1, 0.85, 0.05], [0.1, 0.05, 0.85]])


def turn_matrices(q, omega, dt):
    from stonesoup.models.transition.linear import KnownTurnRate

    m = KnownTurnRate(turn_noise_diff_coeffs=(q, q), turn_rate=omega)
    return m.matrix(time_interval=timedelta(seconds=dt)), m.covar(
        time_interval=timedelta(seconds=dt)
    )


def test_known_turn_rate_equals_stonesoup():
    from usvfast.kalman import transition_matrices

    for omega, dt in [(0.08, 1.0), (-0.3, 2.5), (1e-4, 0.1)]:
        f, q = turn_matrices(0.05, omega, dt)
        tr = T.Tracker(
            motion_model=constant_velocity_2d(0.05),
            sensors=[T.Sensor.position(1.0)],
            association=T.GNN(missed_distance=10.0),
            deleter=T.NeverDelete(),
            initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4), missed_distance=3.0),
            imm=T.IMM([T.KnownTurnRate(0.05, omega)], [[1.0]]),
        )
        x, p = np.array([1.0, 2.0, -3.0, 0.5]), np.diag([1.0, 0.5, 2.0, 0.3])
        tr.add_track(x, p, 0.0)
        got = tr.step(dt)  # no detection: a pure prediction of the single mode
        np.testing.assert_allclose(got.states[0], f @ x, rtol=1e-13, atol=1e-13)
        np.testing.assert_allclose(got.covariances[0], f @ p @ f.T + q, rtol=1e-12, atol=1e-13)
    # Zero turn rate is the constant-velocity model.
    f0, _ = transition_matrices(constant_velocity_2d(0.05), 1.5)
    tr = T.Tracker(
        motion_model=constant_velocity_2d(0.05),
        sensors=[T.Sensor.position(1.0)],
        association=T.GNN(missed_distance=10.0),
        deleter=T.NeverDelete(),
        initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4), missed_distance=3.0),
        imm=T.IMM([T.KnownTurnRate(0.05, 0.0)], [[1.0]]),
    )
    tr.add_track(np.ones(4), np.eye(4), 0.0)
    np.testing.assert_allclose(tr.step(1.5).states[0], f0 @ np.ones(4), rtol=1e-15)


def turning_target(seed, n=40, dt=1.0, sigma=2.0):
    """A boat going straight, turning to starboard, then to port; position plots."""
    rng = np.random.default_rng(seed)
    x = np.array([0.0, 5.0, 0.0, 0.0])
    zs = []
    for k in range(n):
        w = 0.1 if 10 <= k < 20 else (-0.1 if 25 <= k < 32 else 0.0)
        if w:
            s, c = np.sin(w * dt), np.cos(w * dt)
            v = np.array([c * x[1] - s * x[3], s * x[1] + c * x[3]])
        else:
            v = x[[1, 3]]
        x = np.array([x[0] + v[0] * dt, v[0], x[2] + v[1] * dt, v[1]])
        zs.append(x[[0, 2]] + rng.normal(0, sigma, 2))
    return np.array(zs)


def filterpy_imm(x0, p0, zs, dt, q, r, mu0):
    from filterpy.kalman import IMMEstimator, KalmanFilter

    filters = []
    for m in modes(q):
        kf = KalmanFilter(dim_x=4, dim_z=2)
        if isinstance(m, T.KnownTurnRate):
            kf.F, kf.Q = turn_matrices(q, m.omega, dt)
        else:
            from usvfast.kalman import transition_matrices

            kf.F, kf.Q = transition_matrices(m, dt)
        kf.F, kf.Q = np.asarray(kf.F, float), np.asarray(kf.Q, float)
        kf.H, kf.R = H, r
        kf.x, kf.P = x0.reshape(4, 1).copy(), p0.copy()
        filters.append(kf)
    imm = IMMEstimator(filters, np.asarray(mu0, float), TRANSITION)
    out = []
    for z in zs:
        imm.predict()
        imm.update(z.reshape(2, 1))
        out.append((imm.x.ravel().copy(), imm.P.copy(), imm.mu.copy()))
    return out


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31), dt=st.sampled_from([0.5, 1.0, 2.0]))
def test_single_target_equals_filterpy_imm(seed, dt):
    zs = turning_target(seed, dt=dt)
    r = np.diag([4.0, 2.5])
    x0, p0 = np.array([0.0, 5.0, 0.0, 0.0]), np.diag([4.0, 1.0, 4.0, 1.0])
    mu0 = [0.6, 0.2, 0.2]
    want = filterpy_imm(x0, p0, zs, dt, 0.05, r, mu0)
    tr = T.Tracker(
        motion_model=constant_velocity_2d(0.05),
        sensors=[T.Sensor(H, r)],
        association=T.GNN(),
        deleter=T.NeverDelete(),
        initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
        imm=T.IMM(modes(0.05), TRANSITION, mu0),
        use_joseph_cov=True,  # filterpy's KalmanFilter.update is the Joseph form
        symmetric_covariance=False,
    )
    tr.add_track(x0, p0, 0.0)
    for k, (z, (wx, wp, wmu)) in enumerate(zip(zs, want, strict=True)):
        got = tr.step((k + 1) * dt, z.reshape(1, 2))
        np.testing.assert_allclose(got.states[0], wx, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got.covariances[0], wp, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got.mode_probabilities[0], wmu, rtol=1e-9, atol=1e-12)
    # The turns were seen (at 1-2 s scans; at 0.5 s the 5 s turn hides in the plot noise): the
    # starboard mode gains weight during the first turn.
    if dt >= 1.0:
        before = np.mean([w[2][1] for w in want[2:10]])
        assert np.mean([w[2][1] for w in want[13:20]]) > before + 0.1


@pytest.mark.parametrize("gnn", [False, True])
def test_invariants_under_clutter(gnn):
    rng = np.random.default_rng(3)
    truth = turning_target(1, n=45, sigma=0.0)
    tr = T.Tracker(
        motion_model=constant_velocity_2d(0.05),
        sensors=[T.Sensor.position(2.0)],
        association=T.GNN(missed_distance=4.0) if gnn else T.JPDA(0.9, 0.99, 1e-4),
        deleter=T.StepsSinceUpdate(4),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0, 25.0, 0, 25.0]), min_points=3, missed_distance=3.0
        ),
        imm=T.IMM(modes(0.05), TRANSITION),
    )
    seen = 0
    for k, p in enumerate(truth):
        z = [p + rng.normal(0, 2.0, 2)] if rng.random() < 0.9 else []
        z += list(rng.uniform(-50, 250, (rng.poisson(3), 2)))
        got = tr.step(float(k), np.array(z).reshape(-1, 2))
        if len(got):
            seen += 1
            np.testing.assert_allclose(got.mode_probabilities.sum(axis=1), 1.0, atol=1e-12)
            assert (got.mode_probabilities >= 0).all()
            for c in got.covariances:
                assert np.linalg.eigvalsh((c + c.T) / 2).min() > 0
    assert seen > 30
    # The target is held through both turns: a track ends near the truth.
    err = np.min(np.hypot(*(got.states[:, [0, 2]] - truth[-1]).T))
    assert err < 10.0


def test_bad_imm_is_named():
    def make(imm):
        return T.Tracker(
            motion_model=constant_velocity_2d(0.05),
            sensors=[T.Sensor.position(2.0)],
            association=T.GNN(missed_distance=4.0),
            deleter=T.StepsSinceUpdate(4),
            initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
            imm=imm,
        )

    with pytest.raises(ValueError, match=r"imm\.transition"):
        make(T.IMM(modes(), np.eye(2)))
    with pytest.raises(ValueError, match=r"imm\.transition"):
        make(T.IMM(modes(), np.full((3, 3), 0.5)))
    with pytest.raises(ValueError, match=r"imm\.initial"):
        make(T.IMM(modes(), TRANSITION, [1.0, 0.0]))
    with pytest.raises(ValueError, match=r"imm\.modes\[1\]"):
        make(T.IMM([constant_velocity_2d(0.1), T.KnownTurnRate(0.1, np.inf)], np.eye(2) * 1.0))
    with pytest.raises(TypeError, match="imm"):
        make({"modes": modes()})
