"""Range–bearing (radar) sensors against Stone Soup's `CartesianToBearingRange` with the
`ExtendedKalmanUpdater` and the `UnscentedKalmanUpdater`: single updates on random cases (with
bearings across ±π), and whole JPDA / GNN runs from a moving own ship.

Stone Soup's `CartesianToBearingRange.jacobian` is a forward finite difference (relative step
1e-8), ours is analytic: the 1e-9 comparisons give Stone Soup's model the analytic Jacobian
(`AnalyticBearingRange`, everything else Stone Soup's own); against the stock model states and
covariances agree to ~1e-5 (the finite-difference error), which is checked too.
"""

from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d

EPOCH = datetime(2024, 1, 1)


def _analytic_model_class():
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange

    class AnalyticBearingRange(CartesianToBearingRange):
        """Stone Soup's model with the exact Jacobian of atan2 and the range."""

        def jacobian(self, state, **kwargs):
            x = np.asarray(state.state_vector, dtype=float).ravel()
            off = np.asarray(self.translation_offset, dtype=float).ravel()
            dx = x[self.mapping[0]] - off[0]
            dy = x[self.mapping[1]] - off[1]
            r2 = dx * dx + dy * dy
            r = np.sqrt(r2)
            j = np.zeros((2, self.ndim_state))
            j[0, self.mapping[0]], j[0, self.mapping[1]] = -dy / r2, dx / r2
            j[1, self.mapping[0]], j[1, self.mapping[1]] = dx / r, dy / r
            return j

    return AnalyticBearingRange


def ss_model(r, origin, analytic=True):
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange

    cls = _analytic_model_class() if analytic else CartesianToBearingRange
    return cls(
        ndim_state=4,
        mapping=(0, 2),
        noise_covar=np.asarray(r, float),
        translation_offset=np.asarray(origin, float).reshape(2, 1),
    )


def ss_updater(update):
    from stonesoup.updater.kalman import ExtendedKalmanUpdater, UnscentedKalmanUpdater

    return ExtendedKalmanUpdater(None) if update == "ekf" else UnscentedKalmanUpdater(None)


def single_tracker(update, r):
    return T.Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[T.Sensor.bearing_range(noise=r, update=update)],
        association=T.GNN(),
        deleter=T.NeverDelete(),
        initiator=T.MultiMeasurementInitiator(np.zeros(4), np.diag([0, 1.0, 0, 1.0])),
        symmetric_covariance=False,
    )


def random_case(seed):
    """A prediction (x, P), a sensor position, its radar plot of the target, and R. Every
    fourth case puts the target due south of the sensor (bearing near ±π) with the plot on
    the other side of the cut."""
    rng = np.random.default_rng(seed)
    origin = rng.uniform(-50, 50, 2)
    rng_m, brg = rng.uniform(20, 500), rng.uniform(-np.pi, np.pi)
    if seed % 4 == 0:
        brg = np.pi - rng.uniform(0, 0.01)
    x = np.array(
        [
            origin[0] + rng_m * np.cos(brg),
            rng.normal(0, 3),
            origin[1] + rng_m * np.sin(brg),
            rng.normal(0, 3),
        ]
    )
    a = rng.normal(size=(4, 4))
    p = a @ a.T * rng.uniform(0.5, 5) + np.eye(4)
    sb, sr = np.deg2rad(rng.uniform(0.2, 2.0)), rng.uniform(1.0, 10.0)
    r = np.diag([sb**2, sr**2])
    z = np.array([brg + rng.normal(0, sb), rng_m + rng.normal(0, sr)])
    if seed % 4 == 0:
        z[0] = -np.pi + rng.uniform(0, 0.01)  # the plot just across the ±π cut
    return x, p, origin, z, r


def ss_update(x, p, origin, z, r, update, analytic=True):
    from stonesoup.types.angle import Bearing
    from stonesoup.types.array import StateVector
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.prediction import GaussianStatePrediction

    pred = GaussianStatePrediction(x.reshape(4, 1), p, timestamp=EPOCH)
    det = Detection(
        StateVector([[Bearing(z[0])], [z[1]]]),
        timestamp=EPOCH,
        measurement_model=ss_model(r, origin, analytic),
    )
    upd = ss_updater(update).update(SingleHypothesis(pred, det))
    return np.asarray(upd.state_vector, float).ravel(), np.asarray(upd.covar, float)


@pytest.mark.parametrize("update", ["ekf", "ukf"])
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31))
def test_single_update_equals_stonesoup(update, seed):
    x, p, origin, z, r = random_case(seed)
    want_x, want_p = ss_update(x, p, origin, z, r, update)
    tr = single_tracker(update, r)
    tr.add_track(x, p, 0.0)
    got = tr.step(0.0, z.reshape(1, 2), origins=origin)  # dt = 0: the prediction is (x, P)
    assert got.is_update.tolist() == [True] and got.nis_dof.tolist() == [2]
    np.testing.assert_allclose(got.states[0], want_x, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(got.covariances[0], want_p, rtol=1e-9, atol=1e-9)


def test_bearing_cut_is_handled_and_stock_jacobian_is_close():
    # Target due south: prediction at bearing ~ +π, plot at ~ −π. Without wrapping the
    # innovation would be ~2π and the update would throw the track across the sensor.
    for seed in (0, 4, 8, 12):
        x, p, origin, z, r = random_case(seed)
        assert abs(z[0] - np.arctan2(x[2] - origin[1], x[0] - origin[0])) > np.pi
        tr = single_tracker("ekf", r)
        tr.add_track(x, p, 0.0)
        got = tr.step(0.0, z.reshape(1, 2), origins=origin)
        assert np.hypot(got.states[0, 0] - x[0], got.states[0, 2] - x[2]) < 50
        stock_x, stock_p = ss_update(x, p, origin, z, r, "ekf", analytic=False)
        np.testing.assert_allclose(got.states[0], stock_x, rtol=1e-3, atol=1e-4)
        np.testing.assert_allclose(got.covariances[0], stock_p, rtol=1e-3, atol=1e-4)


# ---- whole runs ------------------------------------------------------------------------------

R_RADAR = np.diag([np.deg2rad(1.0) ** 2, 4.0**2])
Q, PRIOR_VV = 0.05, 4.0
PD, PG, CLUTTER = 0.9, 0.99, 2e-4


def radar_scenario(seed, n_scans=30):
    """Own ship sailing north-east at 3 m/s; two targets, one passing south of it (bearings
    across ±π); 1 s scans, P_D 0.9, uniform clutter in range/bearing around the ship."""
    rng = np.random.default_rng(seed)
    targets = np.array([[-120.0, 1.0, -30.0, 4.1], [150.0, -3.0, -100.0, 2.0]])
    scans = []
    for k in range(n_scans):
        t = float(k)
        own = np.array([3.0 * t * 0.7, 3.0 * t * 0.7])
        z, o = [], []
        for tg in targets:
            n, e = tg[0] + tg[1] * t, tg[2] + tg[3] * t
            if rng.random() < PD:
                dn, de = n - own[0], e - own[1]
                z.append(
                    [
                        np.arctan2(de, dn) + rng.normal(0, np.sqrt(R_RADAR[0, 0])),
                        np.hypot(dn, de) + rng.normal(0, np.sqrt(R_RADAR[1, 1])),
                    ]
                )
        for _ in range(rng.poisson(1.0)):
            z.append([rng.uniform(-np.pi, np.pi), rng.uniform(50, 300)])
        z = np.array(z).reshape(-1, 2)
        o = np.tile(own, (len(z), 1))
        scans.append((t, z[rng.permutation(len(z))], o))
    return scans


def stonesoup_radar(scans, update, gnn):
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
    from stonesoup.predictor.kalman import ExtendedKalmanPredictor
    from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
    from stonesoup.types.detection import Detection
    from stonesoup.types.state import GaussianState

    predictor = ExtendedKalmanPredictor(
        CombinedLinearGaussianTransitionModel([ConstantVelocity(Q), ConstantVelocity(Q)])
    )
    updater = ss_updater(update)
    initiator = MultiMeasurementInitiator(
        prior_state=GaussianState(np.zeros((4, 1)), np.diag([0, PRIOR_VV, 0, PRIOR_VV])),
        deleter=UpdateTimeStepsDeleter(2),
        data_associator=GNNWith2DAssignment(
            DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=3.0)
        ),
        updater=updater,
        min_points=3,
    )
    deleter = CompositeDeleter(
        [UpdateTimeStepsDeleter(3), CovarianceBasedDeleter(covar_trace_thresh=5e3)],
        intersect=False,
    )
    if gnn:
        assoc = GNNWith2DAssignment(
            DistanceHypothesiser(predictor, updater, Mahalanobis(), missed_distance=4.0)
        )
        cls = MultiTargetTracker
    else:
        assoc = JPDA(
            PDAHypothesiser(
                predictor, updater, clutter_spatial_density=CLUTTER, prob_detect=PD, prob_gate=PG
            )
        )
        cls = MultiTargetMixtureTracker

    def detector():
        for t, z, o in scans:
            ts = EPOCH + timedelta(seconds=t)
            yield (
                ts,
                {
                    Detection(
                        zz.reshape(2, 1), timestamp=ts, measurement_model=ss_model(R_RADAR, oo)
                    )
                    for zz, oo in zip(z, o, strict=True)
                },
            )

    tracker = cls(
        initiator=initiator,
        deleter=deleter,
        detector=detector(),
        data_associator=assoc,
        updater=updater,
    )
    return [
        sorted(np.asarray(tr.state_vector, float).ravel().tolist() for tr in tracks)
        for _, tracks in tracker
    ]


def native_radar(update, gnn):
    return T.Tracker(
        motion_model=constant_velocity_2d(Q),
        sensors=[T.Sensor.bearing_range(noise=R_RADAR, update=update)],
        association=T.GNN(missed_distance=4.0) if gnn else T.JPDA(PD, PG, CLUTTER),
        deleter=T.AnyOf(T.StepsSinceUpdate(3), T.CovarianceTrace(5e3)),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4),
            np.diag([0, PRIOR_VV, 0, PRIOR_VV]),
            min_points=3,
            deleter=T.StepsSinceUpdate(2),
            missed_distance=3.0,
        ),
        symmetric_covariance=False,
    )


@pytest.mark.parametrize("gnn", [False, True], ids=["jpda", "gnn"])
@pytest.mark.parametrize("update", ["ekf", "ukf"])
def test_whole_radar_run_equals_stonesoup(update, gnn):
    scans = radar_scenario(5)
    want = stonesoup_radar(scans, update, gnn)
    tr = native_radar(update, gnn)
    for (t, z, o), w in zip(scans, want, strict=True):
        got = tr.step(t, z, origins=o)
        assert len(got) == len(w)
        order = np.lexsort(got.states.T[::-1])
        np.testing.assert_allclose(
            got.states[order], np.array(w).reshape(-1, 4), rtol=1e-9, atol=1e-8
        )
    assert len(want[-1]) >= 2, "the targets were not tracked: the comparison proves little"
    # One of them passes due south of the own ship: bearings on both sides of ±π.
    brg = np.concatenate([z[:, 0] for _, z, _ in scans])
    assert (brg > 3.0).any() and (brg < -3.0).any()


def test_radar_and_linear_sensors_mix_and_run_equals_steps():
    scans = radar_scenario(2)
    make = lambda: T.Tracker(  # noqa: E731
        motion_model=constant_velocity_2d(Q),
        sensors=[T.Sensor.bearing_range(noise=R_RADAR), T.Sensor.position(5.0)],
        association=T.JPDA(PD, PG, CLUTTER),
        deleter=T.StepsSinceUpdate(3),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0, 4.0, 0, 4.0]), missed_distance=3.0
        ),
    )
    a, b = make(), make()
    rows = []
    zs, os_, ss, si = [], [], [], []
    for k, (t, z, o) in enumerate(scans):
        # The same targets also as position plots from sensor 1 ("AIS").
        pos = np.column_stack(
            [o[:, 0] + z[:, 1] * np.cos(z[:, 0]), o[:, 1] + z[:, 1] * np.sin(z[:, 0])]
        )
        zz = np.vstack([z, pos])
        oo = np.vstack([o, np.zeros_like(o)])
        sid = np.r_[np.zeros(len(z), int), np.ones(len(z), int)]
        got = a.step(t, zz, sid, origins=oo)
        rows.append(got.states.copy())
        zs.append(zz), os_.append(oo), ss.append(sid), si.append(np.full(len(zz), k))
    res = b.run(
        [t for t, _, _ in scans],
        np.vstack(zs),
        np.concatenate(ss),
        np.concatenate(si),
        origins=np.vstack(os_),
    )
    np.testing.assert_array_equal(res.state, np.vstack(rows))
    assert len(rows[-1]) >= 2


def test_bad_polar_input_is_named():
    with pytest.raises(ValueError, match="mapping"):
        T.Sensor.bearing_range((0.01, 1.0), mapping=(0, 0))
    with pytest.raises(ValueError, match="update"):
        T.Sensor.bearing_range((0.01, 1.0), update="pf")
    with pytest.raises(TypeError, match="noise"):
        T.Sensor.bearing_range()
    tr = single_tracker("ekf", R_RADAR)
    with pytest.raises(ValueError, match="origins"):
        tr.step(0.0, [[0.1, 100.0]], origins=np.zeros((2, 2)))
    with pytest.raises(ValueError, match="origins"):
        tr.step(0.0, [[0.1, 100.0]], origins=[np.nan, 0.0])
    with pytest.raises(ValueError, match="use_joseph_cov"):
        T.Tracker(
            motion_model=constant_velocity_2d(0.1),
            sensors=[T.Sensor.bearing_range((0.01, 1.0), update="ukf")],
            association=T.GNN(),
            deleter=T.NeverDelete(),
            initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
            use_joseph_cov=True,
        )
    with pytest.raises(ValueError, match="initiate_in_gates"):
        T.Tracker(
            motion_model=constant_velocity_2d(0.1),
            sensors=[T.Sensor.bearing_range((0.01, 1.0))],
            association=T.GNN(),
            deleter=T.NeverDelete(),
            initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
            initiate_in_gates=False,
        )
