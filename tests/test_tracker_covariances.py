"""Per-detection measurement noise (`Tracker.step(..., covariances=...)`) against Stone Soup
detections that each carry their own `LinearGaussian` model, the per-track NIS of the last
update, and bad covariances named by row."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast import DimensionError, NonFiniteError, NotPositiveDefiniteError
from usvfast import stonesoup as us
from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d

import ssharness as H


def random_noise(rng, n):
    """n random SPD 2x2 covariances: std 0.1-0.6 m per axis, correlation in (-0.6, 0.6)."""
    sd = rng.uniform(0.1, 0.6, (n, 2))
    rho = rng.uniform(-0.6, 0.6, n)
    c = np.empty((n, 2, 2))
    c[:, 0, 0] = sd[:, 0] ** 2
    c[:, 1, 1] = sd[:, 1] ** 2
    c[:, 0, 1] = c[:, 1, 0] = rho * sd[:, 0] * sd[:, 1]
    return c


def with_noise(scenario, seed):
    """Per-plot covariances (one (m_k, 2, 2) array per scan)."""
    rng = np.random.default_rng(seed)
    return [random_noise(rng, len(z)) for z in scenario.measurements]


def stonesoup_scans(scenario, covs):
    """Detections each with its own LinearGaussian (noise_covar = its covariance)."""
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.types.detection import Detection

    out = []
    for (t, z, _), c in zip(scenario.scans(), covs, strict=True):
        ts = H.to_datetime(t)
        dets = {
            Detection(
                zi.reshape(2, 1),
                timestamp=ts,
                measurement_model=LinearGaussian(ndim_state=4, mapping=[0, 2], noise_covar=ci),
            )
            for zi, ci in zip(z, c, strict=True)
        }
        out.append((ts, dets))
    return out


def native(cfg: H.Code57):
    """The native tracker of Code 5.7 (one sensor whose R every detection overrides)."""
    if cfg.associator == "gnn":
        assoc = T.GNN(missed_distance=cfg.gnn_missed_distance)
    else:
        assoc = T.JPDA(cfg.prob_detect, cfg.prob_gate, cfg.clutter_density)
    return T.Tracker(
        motion_model=constant_velocity_2d(cfg.q),
        sensors=[T.Sensor.position(np.sqrt(cfg.init_noise))],
        association=assoc,
        deleter=T.AnyOf(T.StepsSinceUpdate(cfg.delete_steps), T.CovarianceTrace(cfg.covar_trace)),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4),
            np.diag([0, cfg.prior_velocity_var, 0, cfg.prior_velocity_var]),
            min_points=cfg.min_points,
            deleter=T.StepsSinceUpdate(cfg.init_steps),
            missed_distance=cfg.missed_distance,
        ),
        symmetric_covariance=False,
    )


CASES = [H.crossing(0), H.two_sensors(1), H.separated(3, seed=2)]
SHORT = dict(delete_steps=4, covar_trace=1.0)


@pytest.mark.parametrize("scenario", CASES, ids=[s.name for s in CASES])
@pytest.mark.parametrize("associator", ["jpda", "gnn"])
def test_native_per_detection_noise_equals_stonesoup(scenario, associator):
    cfg = H.Code57(associator=associator, **SHORT)
    covs = with_noise(scenario, 7)
    ref, _ = H.build_stonesoup(cfg, detector=stonesoup_scans(scenario, covs))
    ours = native(cfg)
    n_tracks = 0
    for (t, z, _), c, (_, want) in zip(scenario.scans(), covs, ref, strict=True):
        got = ours.step(t, z, covariances=c)
        w = sorted(np.asarray(tr.state_vector, float).ravel().tolist() for tr in want)
        wc = sorted(
            (np.asarray(tr.state_vector, float).ravel().tolist(), np.asarray(tr.covar).tolist())
            for tr in want
        )
        order = np.lexsort(got.states.T[::-1])
        assert len(got) == len(w)
        np.testing.assert_allclose(got.states[order], np.array(w).reshape(-1, 4), atol=1e-9)
        np.testing.assert_allclose(
            got.covariances[order], np.array([p for _, p in wc]).reshape(-1, 4, 4), atol=1e-9
        )
        n_tracks = max(n_tracks, len(got))
    assert n_tracks >= 2, "no tracks: the comparison proves nothing"


@pytest.mark.parametrize("associator", ["jpda", "gnn"])
def test_dropin_honours_each_detections_model(associator):
    scenario = H.two_sensors(3)
    cfg = H.Code57(associator=associator, **SHORT)
    scans = stonesoup_scans(scenario, with_noise(scenario, 11))
    ref_tracker, _ = H.build_stonesoup(cfg, detector=scans)
    ref = H.run_tracker(ref_tracker)
    base, _ = H.build_stonesoup(cfg)
    cls = us.MultiTargetMixtureTracker if associator == "jpda" else us.MultiTargetTracker
    drop = cls(
        initiator=base.initiator,
        deleter=base.deleter,
        detector=scans,
        data_associator=base.data_associator,
        updater=base.updater,
    )
    ours = H.run_tracker(drop)
    assert H.compare_runs(ours, ref, atol=1e-9) == []
    assert len(ref) >= 2
    # One core sensor for all those models (they share H).
    assert len(drop._sensor_specs) == 1


def test_sensor_noise_as_covariances_changes_nothing():
    sc = H.two_sensors(0)
    cfg = H.Code57(**SHORT)
    a, b = native(cfg), native(cfg)
    r = cfg.init_noise * np.eye(2)
    for t, z, _ in sc.scans():
        ta = a.step(t, z)
        tb = b.step(t, z, covariances=np.broadcast_to(r, (len(z), 2, 2)))
        np.testing.assert_array_equal(ta.states, tb.states)
        np.testing.assert_array_equal(ta.covariances, tb.covariances)


def test_run_with_covariances_equals_steps():
    sc = H.crossing(1)
    cfg = H.Code57(**SHORT)
    covs = with_noise(sc, 3)
    stepper, batch = native(cfg), native(cfg)
    rows = []
    for k, ((t, z, _), c) in enumerate(zip(sc.scans(), covs, strict=True)):
        got = stepper.step(t, z, covariances=c)
        rows += [(k, i, *s) for i, s in zip(got.ids, got.states, strict=True)]
    res = batch.run(
        sc.times,
        np.concatenate(sc.measurements),
        scan_index=np.concatenate([np.full(len(z), k) for k, z in enumerate(sc.measurements)]),
        covariances=np.concatenate(covs),
    )
    np.testing.assert_array_equal(res.scan, [r[0] for r in rows])
    np.testing.assert_array_equal(res.track_id, [r[1] for r in rows])
    np.testing.assert_array_equal(res.state, np.array([r[2:] for r in rows]).reshape(-1, 4))


def test_nis_of_the_last_update():
    # One track, GNN: NIS = yᵀ S⁻¹ y of the assigned detection with its own R.
    tr = T.Tracker(
        motion_model=constant_velocity_2d(0.01),
        sensors=[T.Sensor.position(0.5)],
        association=T.GNN(missed_distance=5.0),
        deleter=T.StepsSinceUpdate(5),
        initiator=T.MultiMeasurementInitiator(np.zeros(4), np.diag([0, 1, 0, 1])),
    )
    x, p = np.array([0.0, 1.0, 0.0, 0.5]), np.diag([1.0, 0.5, 1.0, 0.5])
    tr.add_track(x, p, 0.0)
    before = tr.tracks
    assert before.nis_dof.tolist() == [0] and before.nis.tolist() == [0.0]
    z, r = np.array([[1.3, 0.2]]), np.array([[[0.3, 0.05], [0.05, 0.2]]])
    got = tr.step(1.0, z, covariances=r)
    from usvfast.kalman import transition_matrices

    f, q = transition_matrices(constant_velocity_2d(0.01), 1.0)
    xp, pp = f @ x, f @ p @ f.T + q
    h = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0]])
    y = z[0] - h @ xp
    s = h @ pp @ h.T + r[0]
    assert got.nis_dof.tolist() == [2]
    np.testing.assert_allclose(got.nis, [y @ np.linalg.solve(s, y)], rtol=1e-12)
    # A missed scan: no NIS (dof 0), never NaN.
    got = tr.step(2.0)
    assert got.nis_dof.tolist() == [0] and np.isfinite(got.nis).all()


def test_jpda_nis_is_the_most_probable_detections():
    sc = H.parallel(4, seed=1)
    tr = native(H.Code57())
    checked = 0
    for t, z, _ in sc.scans():
        got = tr.step(t, z)
        for i, tid in enumerate(got.ids):
            if got.nis_dof[i] > 0:
                hist = tr.history(tid)
                assert got.nis[i] == hist.nis[-1]
                a, b = got.assoc_offsets[i], got.assoc_offsets[i + 1]
                best = got.assoc_detection[a:b][np.argmax(got.assoc_probability[a:b])]
                assert got.detection[i] == best
                checked += 1
            else:
                assert got.nis[i] == 0.0 and not got.is_update[i]
    assert checked > 20


def test_bad_covariances_are_named():
    tr = native(H.Code57())
    z = np.array([[0.0, 0.0], [1.0, 1.0]])
    good = np.stack([np.eye(2)] * 2)
    with pytest.raises(DimensionError, match="covariances"):
        tr.step(0.0, z, covariances=np.eye(2))
    bad = good.copy()
    bad[1] = [[1.0, 2.0], [2.0, 1.0]]  # symmetric, indefinite
    with pytest.raises(NotPositiveDefiniteError, match=r"covariances\[1\]"):
        tr.step(0.0, z, covariances=bad)
    bad[1] = [[1.0, 0.5], [0.0, 1.0]]  # not symmetric
    with pytest.raises(NotPositiveDefiniteError, match=r"covariances\[1\]"):
        tr.step(0.0, z, covariances=bad)
    bad[1, 0, 0] = np.nan
    with pytest.raises(NonFiniteError, match="covariances"):
        tr.step(0.0, z, covariances=bad)
    # In a batch run the row of the whole run is named.
    bad = np.stack([np.eye(2)] * 4)
    bad[3] = -np.eye(2)
    with pytest.raises(NotPositiveDefiniteError, match=r"covariances\[3\]"):
        native(H.Code57()).run(
            [0.0, 1.0], np.zeros((4, 2)), scan_index=[0, 0, 1, 1], covariances=bad
        )
    # Nothing happened to the tracker on the refused scans.
    assert tr.last_time is None
