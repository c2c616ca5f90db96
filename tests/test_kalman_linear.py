"""General linear model of usvfast.kalman (user F and Q, fixed or per-dt) and the stacked
predict/update used by the image trackers: parity with filterpy to 1e-9."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter, rts_smoother

from usvfast.kalman import (
    ConstantVelocity,
    LinearModel,
    kalman_filter,
    predict_states,
    transition_matrices,
    update_states,
)


def pixel_model() -> LinearModel:
    """Kim, Chung and Lee (eq. 11): state [x, y, v_x, v_y], dt = 1 frame, Q = I."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = 1.0
    return LinearModel(f, np.eye(4))


H_PIXEL = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])


def filterpy_run(f_of_step, q_of_step, z, h, r, x0, p0):
    """filterpy's KalmanFilter (predict then update per measurement) and rts_smoother."""
    kf = KalmanFilter(dim_x=len(x0), dim_z=h.shape[0])
    kf.x, kf.P, kf.H, kf.R = x0.copy(), p0.copy(), h, r
    xs, ps, fs, qs = [], [], [], []
    for i, zi in enumerate(z):
        kf.F, kf.Q = f_of_step(i), q_of_step(i)
        kf.predict()
        kf.update(zi)
        xs.append(kf.x.copy())
        ps.append(kf.P.copy())
        fs.append(kf.F)
        qs.append(kf.Q)
    xs, ps = np.array(xs), np.array(ps)
    # filterpy's smoother takes F_k, Q_k as the step from k to k+1.
    xsm, psm, _, _ = rts_smoother(xs, ps, [*fs[1:], fs[-1]], [*qs[1:], qs[-1]])
    return xs, ps, xsm, psm


def test_fixed_pixel_model_equals_filterpy():
    rng = np.random.default_rng(3)
    n = 40
    truth = np.cumsum(rng.normal(0, 2, (n, 2)), axis=0) + np.array([100.0, 80.0])
    z = truth + rng.normal(0, 1, (n, 2))
    x0, p0 = np.array([100.0, 80.0, 0.0, 0.0]), np.diag([10.0, 10.0, 100.0, 100.0])
    model = pixel_model()
    # A per-frame model predicts before every frame: the prior is one frame before frame 0.
    ours = kalman_filter(
        np.arange(n, dtype=float),
        z,
        motion_model=model,
        measurement_matrix=H_PIXEL,
        measurement_noise=np.eye(2),
        prior_state=x0,
        prior_covariance=p0,
        prior_time=-1.0,
    )
    f, q = model.matrices(1.0)
    xs, ps, xsm, psm = filterpy_run(lambda i: f, lambda i: q, z, H_PIXEL, np.eye(2), x0, p0)
    np.testing.assert_allclose(ours.filtered_states, xs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.filtered_covariances, ps, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.smoothed_states, xsm, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.smoothed_covariances, psm, rtol=0, atol=1e-9)


def test_of_dt_model_equals_filterpy_and_components():
    rng = np.random.default_rng(5)
    n = 30
    times = np.cumsum(rng.uniform(0.1, 2.0, n))
    z = np.cumsum(rng.normal(size=(n, 1)), axis=0)
    h, r = np.array([[1.0, 0.0]]), np.array([[0.4]])
    x0, p0 = np.array([0.0, 0.0]), np.diag([5.0, 1.0])

    def of_dt(dt):
        return transition_matrices(ConstantVelocity(0.3), dt)

    ours = kalman_filter(
        times,
        z,
        motion_model=LinearModel(of_dt=of_dt),
        measurement_matrix=h,
        measurement_noise=r,
        prior_state=x0,
        prior_covariance=p0,
    )
    builtin = kalman_filter(
        times,
        z,
        motion_model=ConstantVelocity(0.3),
        measurement_matrix=h,
        measurement_noise=r,
        prior_state=x0,
        prior_covariance=p0,
    )
    np.testing.assert_allclose(ours.smoothed_states, builtin.smoothed_states, atol=1e-12)
    dts = np.diff(times, prepend=times[0])
    xs, ps, xsm, psm = filterpy_run(
        lambda i: of_dt(dts[i])[0], lambda i: of_dt(dts[i])[1], z, h, r, x0, p0
    )
    np.testing.assert_allclose(ours.filtered_states, xs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.filtered_covariances, ps, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.smoothed_states, xsm, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.smoothed_covariances, psm, rtol=0, atol=1e-9)


def test_stacked_predict_update_equal_filterpy():
    rng = np.random.default_rng(9)
    k = 5
    model = pixel_model()
    f, q = model.matrices(1.0)
    x = rng.normal(100, 20, (k, 4))
    p = np.stack([np.diag(rng.uniform(1, 10, 4)) for _ in range(k)])
    z = rng.normal(100, 20, (k, 2))
    xp, pp = predict_states(x, p, transition_matrix=f, process_noise=q)
    xu, pu, nis = update_states(xp, pp, z, measurement_matrix=H_PIXEL, measurement_noise=np.eye(2))
    for i in range(k):
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x, kf.P, kf.F, kf.Q, kf.H, kf.R = x[i], p[i], f, q, H_PIXEL, np.eye(2)
        kf.predict()
        np.testing.assert_allclose(xp[i], kf.x, atol=1e-9)
        np.testing.assert_allclose(pp[i], kf.P, atol=1e-9)
        kf.update(z[i])
        np.testing.assert_allclose(xu[i], kf.x, atol=1e-9)
        np.testing.assert_allclose(pu[i], kf.P, atol=1e-9)
        y = kf.y
        np.testing.assert_allclose(nis[i], y @ np.linalg.solve(kf.S, y), rtol=1e-9)


def test_bad_input_names_the_argument():
    f = np.eye(2)
    with pytest.raises(TypeError, match="LinearModel"):
        LinearModel(f)
    with pytest.raises(TypeError, match="LinearModel"):
        LinearModel(f, f, of_dt=lambda dt: (f, f))
    with pytest.raises(ValueError, match="process_noise"):
        kalman_filter(
            [0.0, 1.0],
            [[0.0], [1.0]],
            motion_model=LinearModel(f, -f),
            measurement_matrix=[[1.0, 0.0]],
            measurement_noise=[[1.0]],
            prior_state=[0.0, 0.0],
            prior_covariance=np.eye(2),
        )
    x, p = np.zeros((2, 2)), np.stack([np.eye(2)] * 2)
    with pytest.raises(ValueError, match="covariances"):
        predict_states(x, p[:1], transition_matrix=f, process_noise=f)
    with pytest.raises(ValueError, match="measurement_noise"):
        update_states(
            x, p, [[0.0], [1.0]], measurement_matrix=[[1.0, 0.0]], measurement_noise=[[0.0]]
        )
    with pytest.raises(ValueError, match="states"):
        predict_states([[np.nan, 0.0]], p[:1], transition_matrix=f, process_noise=f)
