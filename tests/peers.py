"""Reference runs of the peers (filterpy, Stone Soup) on the same inputs as usvfast."""

from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np

EPOCH = datetime(2024, 1, 1)


def filterpy_kf_rts(model, times, z, h, noises, idx, x0, p0):
    """filterpy KalmanFilter + rts_smoother; returns (xf, pf, xs, ps, nis, loglik)."""
    from filterpy.kalman import KalmanFilter, rts_smoother

    from usvfast.kalman import transition_matrices

    nx, nz = h.shape[1], h.shape[0]
    kf = KalmanFilter(dim_x=nx, dim_z=nz)
    kf.x = x0.reshape(nx, 1).copy()
    kf.P = p0.copy()
    kf.H = h.copy()
    xs, ps, fs, qs, nis, ll = [], [], [], [], [], []
    t_prev = times[0]
    for i, t in enumerate(times):
        f, q = transition_matrices(model, t - t_prev)
        t_prev = t
        kf.F, kf.Q = f, q
        kf.predict()
        kf.R = noises[idx[i]]
        kf.update(z[i].reshape(nz, 1))
        xs.append(kf.x.ravel().copy())
        ps.append(kf.P.copy())
        fs.append(f)
        qs.append(q)
        y = kf.y.ravel()
        nis.append(float(y @ np.linalg.solve(kf.S, y)))
        ll.append(kf.log_likelihood)
    # filterpy 2's rts_smoother takes Fs[k], Qs[k] as the step from k to k + 1.
    fs_next = np.array([*fs[1:], np.eye(nx)])
    qs_next = np.array([*qs[1:], np.zeros((nx, nx))])
    xs_s, ps_s, _, _ = rts_smoother(np.array(xs), np.array(ps), fs_next, qs_next)
    return np.array(xs), np.array(ps), xs_s, ps_s, np.array(nis), np.array(ll)


def stonesoup_model(model):
    """The Stone Soup transition model equal to a usvfast component list."""
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantAcceleration,
        ConstantVelocity,
        RandomWalk,
    )

    classes = {
        "random_walk": RandomWalk,
        "constant_velocity": ConstantVelocity,
        "constant_acceleration": ConstantAcceleration,
    }
    return CombinedLinearGaussianTransitionModel(
        [classes[c.kind](c.noise_diff_coeff) for c in model]
    )


def to_datetime(t: float) -> datetime:
    return EPOCH + timedelta(seconds=float(t))


def stonesoup_kf_rts(model, times, z, h, noises, idx, x0, p0):
    """Stone Soup KalmanPredictor/KalmanUpdater + KalmanSmoother; returns (xf, pf, xs, ps)."""
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.smoother.kalman import KalmanSmoother
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track
    from stonesoup.updater.kalman import KalmanUpdater

    nx = h.shape[1]
    mapping = [int(np.flatnonzero(row)[0]) for row in h]
    transition = stonesoup_model(model)
    predictor = KalmanPredictor(transition)
    updater = KalmanUpdater(use_joseph_cov=True)
    sensors = [LinearGaussian(nx, mapping, r) for r in noises]
    state = GaussianState(x0.reshape(nx, 1), p0, timestamp=to_datetime(times[0]))
    track = Track()
    for i, t in enumerate(times):
        ts = to_datetime(t)
        pred = predictor.predict(state, timestamp=ts)
        det = Detection(z[i].reshape(-1, 1), timestamp=ts, measurement_model=sensors[idx[i]])
        state = updater.update(SingleHypothesis(pred, det))
        track.append(state)
    smoothed = KalmanSmoother(transition).smooth(track)
    xf = np.array([s.state_vector.ravel() for s in track]).astype(float)
    pf = np.array([s.covar for s in track]).astype(float)
    xs = np.array([s.state_vector.ravel() for s in smoothed]).astype(float)
    ps = np.array([s.covar for s in smoothed]).astype(float)
    return xf, pf, xs, ps
