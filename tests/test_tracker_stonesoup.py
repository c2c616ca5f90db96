"""Component parity with Stone Soup on random single scans: PDA weights, JPDA posteriors
(marginals + moment-matched mixture), GNN assignments, and the initiator's first tracks."""

from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
from stonesoup.dataassociator.probability import JPDA as SSJPDA
from stonesoup.functions import gm_reduce_single
from stonesoup.hypothesiser.distance import DistanceHypothesiser
from stonesoup.hypothesiser.probability import PDAHypothesiser
from stonesoup.measures import Mahalanobis
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import (
    CombinedLinearGaussianTransitionModel,
    ConstantVelocity,
)
from stonesoup.predictor.kalman import KalmanPredictor
from stonesoup.types.array import StateVectors
from stonesoup.types.detection import Detection
from stonesoup.types.state import GaussianState
from stonesoup.types.track import Track
from stonesoup.updater.kalman import KalmanUpdater

from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d

EPOCH = datetime(2024, 1, 1)
Q = 0.05
NOISE = (0.3, 0.8)  # standard deviations of the two sensors, metres


def scene(seed: int, n_tracks: int, n_dets: int):
    """Tracks close together and detections around them, two sensors."""
    rng = np.random.default_rng(seed)
    xs = np.column_stack(
        [
            rng.uniform(0, 4, n_tracks),
            rng.normal(0, 0.5, n_tracks),
            rng.uniform(0, 4, n_tracks),
            rng.normal(0, 0.5, n_tracks),
        ]
    )
    covs = []
    for _ in range(n_tracks):
        a = rng.normal(0, 0.4, (4, 4))
        covs.append(a @ a.T + np.diag([0.2, 0.05, 0.2, 0.05]))
    z = rng.uniform(-1, 5, (n_dets, 2))
    sensors = rng.integers(0, 2, n_dets)
    dt = round(float(rng.uniform(0.1, 2.0)), 6)
    return xs, covs, z, sensors, dt


def stonesoup_parts():
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(Q), ConstantVelocity(Q)])
    models = [LinearGaussian(4, [0, 2], np.eye(2) * s**2) for s in NOISE]
    predictor = KalmanPredictor(transition)
    updater = KalmanUpdater(models[0])
    return predictor, updater, models


def ours(association, xs, covs, z, sensors, dt):
    tracker = T.Tracker(
        motion_model=constant_velocity_2d(Q),
        sensors=[T.Sensor.position(s) for s in NOISE],
        association=association,
        deleter=T.NeverDelete(),
        initiator=T.MultiMeasurementInitiator(np.zeros(4), np.diag([0, 1.0, 0, 1.0])),
    )
    ids = [tracker.add_track(x, p, 0.0) for x, p in zip(xs, covs, strict=True)]
    tracker.step(dt, z.reshape(-1, 2), sensors)
    return tracker, ids


def ss_tracks(xs, covs):
    return [
        Track([GaussianState(x.reshape(4, 1), p, timestamp=EPOCH)])
        for x, p in zip(xs, covs, strict=True)
    ]


def ss_detections(z, sensors, models, dt):
    ts = EPOCH + timedelta(seconds=dt)
    return [
        Detection(zz.reshape(2, 1), timestamp=ts, measurement_model=models[s])
        for zz, s in zip(z, sensors, strict=True)
    ], ts


@pytest.mark.parametrize("clutter", [0.05, None])
@given(seed=st.integers(0, 2**31), n_dets=st.integers(0, 6))
def test_pda_weights_of_a_single_track(clutter, seed, n_dets):
    xs, covs, z, sensors, dt = scene(seed, 1, n_dets)
    predictor, updater, models = stonesoup_parts()
    hyp = PDAHypothesiser(
        predictor, updater, clutter_spatial_density=clutter, prob_detect=0.8, prob_gate=0.99
    )
    dets, ts = ss_detections(z, sensors, models, dt)
    mh = hyp.hypothesise(ss_tracks(xs, covs)[0], set(dets), ts)
    total = float(sum(h.probability for h in mh))
    want = {dets.index(h.measurement): float(h.probability) / total for h in mh if h}
    want_missed = float(next(h.probability for h in mh if not h)) / total

    tracker, ids = ours(T.JPDA(0.8, 0.99, clutter), xs, covs, z, sensors, dt)
    h = tracker.history(ids[0])
    got = h.association_probabilities(1)
    assert set(got) == set(want)
    for d, p in want.items():
        assert got[d] == pytest.approx(p, rel=1e-9, abs=1e-15)
    assert h.missed_probability[1] == pytest.approx(want_missed, rel=1e-9, abs=1e-15)


def mixture_posterior(mh, updater):
    states, weights = [], []
    for hyp in mh:
        states.append(hyp.prediction if not hyp else updater.update(hyp))
        weights.append(hyp.probability)
    means = StateVectors([s.state_vector for s in states])
    covars = np.stack([s.covar for s in states], axis=2)
    mean, cov = gm_reduce_single(means, covars, np.asarray(weights))
    missed = next(h.weight for h in mh if not h)
    is_update = any(h.weight > missed for h in mh)
    return np.asarray(mean, float).ravel(), np.asarray(cov, float), is_update


@given(seed=st.integers(0, 2**31), n_tracks=st.integers(1, 4), n_dets=st.integers(0, 6))
def test_single_scan_jpda_posterior_equals_stonesoup(seed, n_tracks, n_dets):
    xs, covs, z, sensors, dt = scene(seed, n_tracks, n_dets)
    predictor, updater, models = stonesoup_parts()
    hyp = PDAHypothesiser(
        predictor, updater, clutter_spatial_density=0.02, prob_detect=0.9, prob_gate=0.95
    )
    tracks = ss_tracks(xs, covs)
    dets, ts = ss_detections(z, sensors, models, dt)
    assoc = SSJPDA(hyp).associate(set(tracks), set(dets), ts)

    tracker, ids = ours(T.JPDA(0.9, 0.95, 0.02), xs, covs, z, sensors, dt)
    for track, tid in zip(tracks, ids, strict=True):
        mh = assoc[track]
        mean, cov, is_update = mixture_posterior(mh, updater)
        h = tracker.history(tid)
        np.testing.assert_allclose(h.states[1], mean, rtol=1e-9, atol=1e-10)
        np.testing.assert_allclose(h.covariances[1], cov, rtol=1e-9, atol=1e-10)
        assert bool(h.is_update[1]) == is_update
        got = h.association_probabilities(1)
        for sh in mh:
            if sh:
                assert got[dets.index(sh.measurement)] == pytest.approx(
                    float(sh.probability), rel=1e-9, abs=1e-13
                )
        np.testing.assert_allclose(h.missed_probability[1] + sum(got.values()), 1.0, rtol=1e-12)


@given(seed=st.integers(0, 2**31), n_tracks=st.integers(1, 5), n_dets=st.integers(0, 7))
def test_single_scan_gnn_equals_stonesoup(seed, n_tracks, n_dets):
    xs, covs, z, sensors, dt = scene(seed, n_tracks, n_dets)
    predictor, updater, models = stonesoup_parts()
    hyp = DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=2.5)
    tracks = ss_tracks(xs, covs)
    dets, ts = ss_detections(z, sensors, models, dt)
    assoc = GNNWith2DAssignment(hyp).associate(set(tracks), set(dets), ts)

    tracker, ids = ours(T.GNN(missed_distance=2.5), xs, covs, z, sensors, dt)
    for track, tid in zip(tracks, ids, strict=True):
        h = tracker.history(tid)
        sh = assoc[track]
        state = updater.update(sh) if sh else sh.prediction
        want_det = dets.index(sh.measurement) if sh else -1
        assert h.detection[1] == want_det
        np.testing.assert_allclose(h.states[1], np.asarray(state.state_vector, float).ravel())
        np.testing.assert_allclose(h.covariances[1], np.asarray(state.covar, float), atol=1e-12)
