"""Kalman filter + RTS smoother: parity with filterpy and Stone Soup, invariants, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import usvfast
from usvfast.kalman import (
    ConstantAcceleration,
    ConstantVelocity,
    RandomWalk,
    kalman_filter,
    transition_matrices,
)

from peers import filterpy_kf_rts, stonesoup_kf_rts

# (motion model, measurement matrix): fast 2/4/6-state paths and a dynamic-size one.
CASES = {
    "wiener_2state": ([ConstantVelocity(0.05)], [[1.0, 0.0]]),
    "cv_2d": ([ConstantVelocity(0.5), ConstantVelocity(0.3)], [[1, 0, 0, 0], [0, 0, 1, 0]]),
    "cv_3d": (
        [ConstantVelocity(0.2)] * 3,
        [[1, 0, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 0, 1, 0]],
    ),
    "mixed_dynamic": (
        [ConstantAcceleration(0.01), RandomWalk(0.4)],
        [[1, 0, 0, 0], [0, 0, 0, 1]],
    ),
}


def scenario(case: str, seed: int, n: int = 60):
    """Random irregular sequence with two sensors of different noise (µs-rounded times)."""
    rng = np.random.default_rng(seed)
    model, h = CASES[case]
    h = np.asarray(h, dtype=float)
    nx, nz = h.shape[1], h.shape[0]
    times = np.round(1000.0 + np.cumsum(rng.uniform(0.0, 2.0, n)), 6)
    times[5] = times[4]  # simultaneous measurements from both sensors
    a = rng.normal(size=(nz, nz))
    noises = np.stack([np.eye(nz) * 0.3, a @ a.T + np.eye(nz)])
    idx = rng.integers(0, 2, n)
    z = np.cumsum(rng.normal(size=(n, nz)), axis=0)
    x0 = rng.normal(size=nx)
    p0 = np.diag(rng.uniform(1.0, 10.0, nx))
    return model, times, z, h, noises, idx, x0, p0


def run_ours(model, times, z, h, noises, idx, x0, p0):
    return kalman_filter(
        times,
        z,
        motion_model=model,
        measurement_matrix=h,
        measurement_noise=noises,
        sensor_index=idx,
        prior_state=x0,
        prior_covariance=p0,
    )


def assert_close(a, b):
    scale = np.max(np.abs(b))
    np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12 * scale)


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_equals_filterpy(case, seed):
    args = scenario(case, seed)
    ours = run_ours(*args)
    xf, pf, xs, ps, nis, ll = filterpy_kf_rts(*args)
    assert_close(ours.filtered_states, xf)
    assert_close(ours.filtered_covariances, pf)
    assert_close(ours.smoothed_states, xs)
    assert_close(ours.smoothed_covariances, ps)
    assert_close(ours.nis, nis)
    assert_close(ours.log_likelihood, ll)


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("seed", [3, 4])
def test_equals_stonesoup(case, seed):
    args = scenario(case, seed, n=40)
    ours = run_ours(*args)
    xf, pf, xs, ps = stonesoup_kf_rts(*args)
    assert_close(ours.filtered_states, xf)
    assert_close(ours.filtered_covariances, pf)
    assert_close(ours.smoothed_states, xs)
    assert_close(ours.smoothed_covariances, ps)


@pytest.mark.parametrize("case", sorted(CASES))
def test_transition_matrices_equal_stonesoup(case):
    from peers import stonesoup_model

    model, _ = CASES[case]
    ss = stonesoup_model(model)
    for dt in (0.0, 0.37, 5.0):
        from datetime import timedelta

        f, q = transition_matrices(model, dt)
        np.testing.assert_allclose(f, ss.matrix(time_interval=timedelta(seconds=dt)), rtol=1e-12)
        np.testing.assert_allclose(
            q, ss.covar(time_interval=timedelta(seconds=dt)), rtol=1e-12, atol=1e-300
        )


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), case=st.sampled_from(sorted(CASES)))
def test_covariances_stay_spd_and_smoothing_never_inflates(seed, case):
    ours = run_ours(*scenario(case, seed, n=30))
    for name in ("filtered_covariances", "smoothed_covariances", "predicted_covariances"):
        p = getattr(ours, name)
        np.testing.assert_array_equal(p, np.transpose(p, (0, 2, 1)))
        assert np.all(np.linalg.eigvalsh(p) > 0), name
    tr_f = np.trace(ours.filtered_covariances, axis1=1, axis2=2)
    tr_s = np.trace(ours.smoothed_covariances, axis1=1, axis2=2)
    assert np.all(tr_s <= tr_f * (1 + 1e-12))
    np.testing.assert_allclose(tr_s[-1], tr_f[-1])


def test_single_noise_matrix_and_1d_measurements_are_accepted():
    t = np.array([0.0, 1.0, 2.0])
    run = kalman_filter(
        t,
        np.array([0.0, 1.0, 2.0]),
        motion_model=ConstantVelocity(0.1),
        measurement_matrix=[[1.0, 0.0]],
        measurement_noise=[[0.5]],
        prior_state=[0.0, 1.0],
        prior_covariance=np.eye(2),
        smooth=False,
    )
    assert run.filtered_states.shape == (3, 2)
    assert run.smoothed_states is None


# --- bad input: each names its argument -------------------------------------------------


def good_kwargs():
    return dict(
        motion_model=ConstantVelocity(0.1),
        measurement_matrix=[[1.0, 0.0]],
        measurement_noise=[[[0.5]], [[1.0]]],
        sensor_index=[0, 1, 0],
        prior_state=[0.0, 1.0],
        prior_covariance=np.eye(2),
    )


@pytest.mark.parametrize(
    ("change", "error", "name"),
    [
        ({"times": [0.0, np.nan, 2.0]}, usvfast.NonFiniteError, "times"),
        ({"measurements": [[0.0], [np.inf], [1.0]]}, usvfast.NonFiniteError, "measurements"),
        ({"times": [0.0, 2.0, 1.0]}, usvfast.TimeOrderError, "times"),
        (
            {"measurements": [[0.0, 1.0]] * 3, "measurement_noise": np.eye(2)},
            usvfast.DimensionError,
            "measurement_matrix",
        ),
        ({"measurements": [[0.0, 1.0]] * 3}, usvfast.DimensionError, "measurement_noise"),
        ({"measurements": [[0.0], [1.0]]}, usvfast.DimensionError, "measurements"),
        ({"measurement_noise": [[[-1.0]]]}, usvfast.NotPositiveDefiniteError, "measurement_noise"),
        (
            {"prior_covariance": [[1.0, 0.5], [0.0, 1.0]]},
            usvfast.NotPositiveDefiniteError,
            "prior_covariance",
        ),
        (
            {"prior_covariance": [[1.0, 2.0], [2.0, 1.0]]},
            usvfast.NotPositiveDefiniteError,
            "prior_covariance",
        ),
        ({"sensor_index": [0, 2, 0]}, ValueError, "sensor_index"),
        ({"sensor_index": [0, -1, 0]}, ValueError, "sensor_index"),
        ({"sensor_index": [0.0, 1.0, 0.0]}, TypeError, "sensor_index"),
        ({"sensor_index": [0, 1]}, usvfast.DimensionError, "sensor_index"),
        ({"prior_state": [0.0, 1.0, 2.0]}, usvfast.DimensionError, "prior_state"),
        ({"prior_time": 5.0}, usvfast.TimeOrderError, "prior_time"),
        ({"measurements": "abc"}, TypeError, "measurements"),
        ({"motion_model": [ConstantVelocity(-1.0)]}, ValueError, "motion_model"),
        ({"motion_model": ["cv"]}, TypeError, "motion_model"),
    ],
)
def test_bad_input_names_the_argument(change, error, name):
    kwargs = good_kwargs()
    times = change.pop("times", [0.0, 1.0, 2.0])
    z = change.pop("measurements", [[0.0], [1.0], [2.0]])
    kwargs.update(change)
    with pytest.raises(error, match=name):
        kalman_filter(times, z, **kwargs)


def test_errors_are_value_errors():
    assert issubclass(usvfast.DimensionError, ValueError)
    assert issubclass(usvfast.NotPositiveDefiniteError, ValueError)
