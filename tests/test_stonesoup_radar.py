"""Radar plots through the Stone Soup drop-in: detections with Stone Soup's
`CartesianToBearingRange` (a moving own ship as `translation_offset`) and the
`ExtendedKalmanUpdater` / `UnscentedKalmanUpdater` give Stone Soup's tracks — the same births,
deaths and update/prediction kinds, states within the error of Stone Soup's finite-difference
Jacobian (usvfast's is analytic; tests/test_tracker_polar.py shows 1e-9 agreement once Stone
Soup is given the exact Jacobian) — also mixed with LiDAR position plots in one tracker."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast import stonesoup as us

import ssharness as H

R_RADAR = np.diag([np.radians(1.0) ** 2, 4.0**2])  # (rad², m²)
R_LIDAR = np.diag([2.0**2, 2.0**2])
Q = 0.05
PD, PG, CLUTTER = 0.9, 0.99, 1e-3
TOL = 1e-4  # Stone Soup's forward-difference Jacobian (step 1e-8 relative) against exact


def scenario(seed: int, n_scans: int = 40, lidar: bool = False):
    """Own ship sailing north-east at 3 m/s; two targets, one passing south of it (bearings
    across ±π); 1 s scans, P_D 0.9, clutter in range and bearing. Per scan (t, [(z, origin
    or None), ...]); with `lidar`, every third scan also holds LiDAR position plots."""
    rng = np.random.default_rng(seed)
    targets = np.array([[-120.0, 1.0, -30.0, 4.1], [150.0, -3.0, -100.0, 2.0]])
    out = []
    for k in range(n_scans):
        t = float(k)
        own = np.array([2.1 * t, 2.1 * t])
        plots = []
        for tg in targets:
            n, e = tg[0] + tg[1] * t, tg[2] + tg[3] * t
            if rng.random() < PD:
                dn, de = n - own[0], e - own[1]
                phi = np.arctan2(de, dn) + rng.normal(0, np.sqrt(R_RADAR[0, 0]))
                rho = np.hypot(dn, de) + rng.normal(0, np.sqrt(R_RADAR[1, 1]))
                plots.append((np.array([np.angle(np.exp(1j * phi)), rho]), own))
            if lidar and k % 3 == 0 and rng.random() < PD:
                plots.append((np.array([n, e]) + rng.normal(0, 2.0, 2), None))
        for _ in range(rng.poisson(1.0)):
            plots.append((np.array([rng.uniform(-np.pi, np.pi), rng.uniform(50, 300)]), own))
        out.append((t, [plots[i] for i in rng.permutation(len(plots))]))
    return out


def detections(scans):
    """Stone Soup detector output: radar plots with their own CartesianToBearingRange, LiDAR
    plots with one shared LinearGaussian."""
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
    from stonesoup.types.detection import Detection

    lidar = LinearGaussian(ndim_state=4, mapping=[0, 2], noise_covar=R_LIDAR)
    out = []
    for t, plots in scans:
        ts = H.to_datetime(t)
        dets = set()
        for z, origin in plots:
            if origin is None:
                model = lidar
            else:
                model = CartesianToBearingRange(
                    ndim_state=4,
                    mapping=(0, 2),
                    noise_covar=R_RADAR,
                    translation_offset=origin.reshape(2, 1),
                )
            dets.add(Detection(z.reshape(2, 1), timestamp=ts, measurement_model=model))
        out.append((ts, dets))
    return out


def components(update: str, gnn: bool, predictor: str = "kalman"):
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.dataassociator.probability import JPDA
    from stonesoup.deleter.error import CovarianceBasedDeleter
    from stonesoup.deleter.multi import CompositeDeleter
    from stonesoup.deleter.time import UpdateTimeStepsDeleter
    from stonesoup.hypothesiser.distance import DistanceHypothesiser
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.initiator.simple import MultiMeasurementInitiator
    from stonesoup.measures import Mahalanobis
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )
    from stonesoup.predictor.kalman import KalmanPredictor, UnscentedKalmanPredictor
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import ExtendedKalmanUpdater, UnscentedKalmanUpdater

    cv = CombinedLinearGaussianTransitionModel([ConstantVelocity(Q), ConstantVelocity(Q)])
    pred = (UnscentedKalmanPredictor if predictor == "unscented" else KalmanPredictor)(cv)
    upd = ExtendedKalmanUpdater(None) if update == "ekf" else UnscentedKalmanUpdater(None)
    initiator = MultiMeasurementInitiator(
        prior_state=GaussianState(np.zeros((4, 1)), np.diag([0, 25.0, 0, 25.0])),
        deleter=UpdateTimeStepsDeleter(2),
        data_associator=GNNWith2DAssignment(
            DistanceHypothesiser(pred, upd, Mahalanobis(), missed_distance=3.0)
        ),
        updater=upd,
        min_points=3,
    )
    deleter = CompositeDeleter(
        [UpdateTimeStepsDeleter(3), CovarianceBasedDeleter(covar_trace_thresh=5e3)],
        intersect=False,
    )
    if gnn:
        assoc = GNNWith2DAssignment(DistanceHypothesiser(pred, upd, Mahalanobis(), 4.0))
    else:
        assoc = JPDA(PDAHypothesiser(pred, upd, CLUTTER, prob_detect=PD, prob_gate=PG))
    return dict(initiator=initiator, deleter=deleter, data_associator=assoc, updater=upd)


def run_both(scans, update, gnn, predictor="kalman"):
    from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker

    dets = detections(scans)
    ss_cls = MultiTargetTracker if gnn else MultiTargetMixtureTracker
    ref = H.run_tracker(ss_cls(detector=dets, **components(update, gnn, predictor)))
    ours_cls = us.MultiTargetTracker if gnn else us.MultiTargetMixtureTracker
    dropin = ours_cls(detector=dets, **components(update, gnn, predictor))
    return H.run_tracker(dropin), ref, dropin


@pytest.mark.parametrize("gnn", [False, True], ids=["jpda", "gnn"])
@pytest.mark.parametrize("update", ["ekf", "ukf"])
def test_radar_detections_give_stonesoups_tracks(update, gnn):
    ours, ref, dropin = run_both(scenario(5), update, gnn)
    assert H.compare_runs(ours, ref, atol=TOL) == []
    assert len(ref) >= 2 and sum(len(r.times) for r in ref) > 40
    # One polar core sensor for all the per-detection models (a moving own ship).
    assert len(dropin._sensor_specs) == 1 and dropin._sensor_specs[0][0] == "polar"


@pytest.mark.parametrize("seed", [5, 8])  # 8: a gated bearing across ±π
@pytest.mark.parametrize("gnn", [False, True], ids=["jpda", "gnn"])
def test_radar_hypotheses_are_stonesoups(gnn, seed):
    # Every attribute of every state and hypothesis (measurement predictions by the updater's
    # own predict_measurement for bearing-range detections, Mahalanobis distances, JPDA
    # probabilities, priors) as Stone Soup's, within its finite-difference Jacobian's error.
    from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
    from test_stonesoup_lazy import same_tracks_deeply

    dets = detections(scenario(seed, lidar=True))
    ss_cls = MultiTargetTracker if gnn else MultiTargetMixtureTracker
    ours_cls = us.MultiTargetTracker if gnn else us.MultiTargetMixtureTracker
    ref, ours = set(), set()
    for _, tracks in ss_cls(detector=dets, **components("ekf", gnn)):
        ref |= tracks
    for _, tracks in ours_cls(detector=dets, **components("ekf", gnn)):
        ours |= tracks
    assert len(ours) == len(ref) >= 2
    assert same_tracks_deeply(list(ours), list(ref), TOL) > 40


def test_radar_and_lidar_detections_in_one_tracker():
    ours, ref, dropin = run_both(scenario(3, lidar=True), "ukf", False, predictor="unscented")
    assert H.compare_runs(ours, ref, atol=TOL) == []
    assert sorted(s[0] for s in dropin._sensor_specs) == ["linear", "polar"]
    assert len(ref) >= 2


def test_radar_needs_one_nonlinear_updater():
    from stonesoup.updater.kalman import KalmanUpdater

    dets = detections(scenario(1, n_scans=3))
    kw = components("ekf", False)
    kw["updater"] = KalmanUpdater(None)  # the tracker's own updater differs
    dropin = us.MultiTargetMixtureTracker(detector=dets, **kw)
    with pytest.raises(us.UnsupportedComponentError, match="ExtendedKalmanUpdater or Unscented"):
        next(iter(dropin))


def test_rotated_radar_model_is_refused():
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
    from stonesoup.types.detection import Detection

    model = CartesianToBearingRange(
        ndim_state=4, mapping=(0, 2), noise_covar=R_RADAR, rotation_offset=np.c_[[0.0, 0.0, 0.1]]
    )
    ts = H.to_datetime(0.0)
    dropin = us.MultiTargetMixtureTracker(**components("ekf", False))
    det = Detection(np.c_[[0.1, 100.0]], timestamp=ts, measurement_model=model)
    with pytest.raises(us.UnsupportedComponentError, match="rotation_offset"):
        dropin.update_tracker(ts, {det})
