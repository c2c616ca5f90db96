"""The native tracker API: whole runs against Stone Soup, batch == step, invariants, M-of-N,
the duplicate-free initiation option, and bad input."""

from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from usvfast import (
    DimensionError,
    NonFiniteError,
    NotPositiveDefiniteError,
    TimeOrderError,
    _core,
)
from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d

from ssharness import Code57, build_stonesoup

NOISE = (0.25, 0.5)


def scenario(seed, n_targets=4, n_scans=25, clutter=2.0, spread=20.0):
    """Targets with constant velocity, two sensors, missed detections, uniform clutter.
    Times are rounded to microseconds (Stone Soup's datetime resolution)."""
    rng = np.random.default_rng(seed)
    x = np.column_stack(
        [
            rng.uniform(0, spread, n_targets),
            rng.normal(0, 0.3, n_targets),
            rng.uniform(0, spread, n_targets),
            rng.normal(0, 0.3, n_targets),
        ]
    )
    scans, t = [], 0.0
    for _ in range(n_scans):
        dt = rng.uniform(0.3, 1.2)
        t = round(t + dt, 6)
        x[:, 0] += x[:, 1] * dt
        x[:, 2] += x[:, 3] * dt
        z, s = [], []
        for i in range(n_targets):
            if rng.random() < 0.9:
                k = int(rng.random() < 0.4)
                z.append(x[i, [0, 2]] + rng.normal(0, NOISE[k], 2))
                s.append(k)
        for _ in range(rng.poisson(clutter)):
            z.append(rng.uniform(-5, spread + 5, 2))
            s.append(int(rng.random() < 0.5))
        scans.append((t, np.array(z).reshape(-1, 2), np.array(s, dtype=np.int64)))
    return scans


def code57(association, **kw):
    """The thesis's Code 5.7 configuration (two sensors instead of one)."""
    return T.code_5_7([T.Sensor.position(s) for s in NOISE], association, **kw)


def stonesoup_run(scans, gnn):
    """The same configuration through Stone Soup (tests/ssharness.py builds Code 5.7)."""
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.types.detection import Detection

    epoch = datetime(2024, 1, 1)
    models = [LinearGaussian(4, [0, 2], np.eye(2) * s**2) for s in NOISE]

    def detector():
        for t, z, s in scans:
            ts = epoch + timedelta(seconds=t)
            yield (
                ts,
                {
                    Detection(zz.reshape(2, 1), timestamp=ts, measurement_model=models[k])
                    for zz, k in zip(z, s, strict=True)
                },
            )

    tracker, _ = build_stonesoup(Code57(associator="gnn" if gnn else "jpda"), detector())
    return [
        sorted(np.asarray(tr.state_vector, float).ravel().tolist() for tr in tracks)
        for _, tracks in tracker
    ]


@pytest.mark.parametrize("gnn", [False, True])
@pytest.mark.parametrize("seed", [1, 2])
def test_whole_run_equals_stonesoup(seed, gnn):
    scans = scenario(seed)
    want = stonesoup_run(scans, gnn)
    tracker = code57(T.GNN(missed_distance=3) if gnn else T.JPDA(0.85, 0.95, 0.125))
    for (t, z, s), w in zip(scans, want, strict=True):
        got = tracker.step(t, z, s)
        assert len(got) == len(w)
        np.testing.assert_allclose(
            np.array(sorted(got.states.tolist())).reshape(-1, 4),
            np.array(w).reshape(-1, 4),
            atol=1e-9,
        )
    assert len(want[-1]) >= 3


def test_batch_run_equals_steps_and_histories_are_consistent():
    scans = scenario(5, n_targets=6, n_scans=40)
    a = code57(T.JPDA(0.85, 0.95, 0.125))
    rows = []
    for i, (t, z, s) in enumerate(scans):
        k = a.step(t, z, s)
        rows += [(i, tid, *x) for tid, x in zip(k.ids, k.states, strict=True)]
    b = code57(T.JPDA(0.85, 0.95, 0.125))
    times = np.array([t for t, _, _ in scans])
    z = np.concatenate([z for _, z, _ in scans])
    s = np.concatenate([s for _, _, s in scans])
    idx = np.concatenate([np.full(len(z), i) for i, (_, z, _) in enumerate(scans)])
    # Shuffle rows: the batch call groups them by scan itself.
    perm = np.random.default_rng(0).permutation(len(z))
    # Within a scan the order of detections matters only for tie-breaking; keep it stable.
    perm = perm[np.argsort(idx[perm], kind="stable")]
    res = b.run(times, z, s, idx)
    got = np.column_stack([res.scan, res.track_id, res.state])
    np.testing.assert_allclose(got, np.array(rows))
    assert res.covariance.shape == (len(res.scan), 4, 4)
    for tid in np.unique(res.track_id):
        h = b.history(tid)
        assert np.all(np.diff(h.times) >= 0)
        assert h.is_update[0]  # tentative phase starts with a detection
        np.testing.assert_allclose(h.states[-1], res.state[res.track_id == tid][-1])
        assert np.all(h.nis[h.is_update & (h.detection >= 0)][1:] >= 0)
        df = h.to_dataframe()
        assert len(df) == len(h.times)
        np.testing.assert_array_equal(df["x2"].to_numpy(), h.states[:, 2])


@settings(max_examples=15)
@given(seed=st.integers(0, 10_000), gnn=st.booleans())
def test_covariances_stay_spd_and_probabilities_sum_to_one(seed, gnn):
    scans = scenario(seed, n_targets=5, n_scans=30, clutter=4.0, spread=8.0)
    tracker = code57(T.GNN(missed_distance=3) if gnn else T.JPDA(0.85, 0.95, 0.125))
    for t, z, s in scans:
        tracker.step(t, z, s)
    ids = list(tracker.tracks.ids) + list(tracker.deleted_track_ids)
    for tid in ids:
        h = tracker.history(tid)
        for p in h.covariances:
            np.testing.assert_allclose(p, p.T, rtol=1e-9, atol=1e-12)
            assert np.linalg.eigvalsh(p).min() > 0
        for i in range(len(h.times)):
            if np.isfinite(h.missed_probability[i]):
                total = h.missed_probability[i] + sum(h.association_probabilities(i).values())
                assert total == pytest.approx(1.0, abs=1e-12)


def test_empty_scans_only_predict_and_tracks_die_by_the_deleter():
    tracker = code57(T.JPDA(0.85, 0.95, 0.125))
    for k in range(3):
        tracker.step(float(k), np.array([[k * 0.1, 0.0]]), [0])
    assert len(tracker.tracks) == 1
    x0 = tracker.tracks.states[0].copy()
    k = tracker.step(3.0)
    assert len(k) == 1 and not k.is_update[0]
    np.testing.assert_allclose(k.states[0][[0, 2]], x0[[0, 2]] + x0[[1, 3]], rtol=1e-12)
    t = 3.0
    while len(tracker.tracks):
        t += 1.0
        tracker.step(t, np.empty((0, 2)), np.empty(0, dtype=int))
    assert len(tracker.deleted_track_ids) == 1
    h = tracker.history(tracker.deleted_track_ids[0])
    assert h.deleted_time == t
    # Covariance trace deleter: it dies once the trace exceeds 1.5 (before 35 steps).
    assert np.trace(h.covariances[-1]) > 1.5
    assert np.trace(h.covariances[-2]) <= 1.5


def test_m_of_n_confirmation():
    def make(m_of_n):
        return T.Tracker(
            motion_model=constant_velocity_2d(0.01),
            sensors=[T.Sensor.position(0.25)],
            association=T.GNN(missed_distance=3),
            deleter=T.StepsSinceUpdate(5),
            initiator=T.MultiMeasurementInitiator(
                np.zeros(4), np.diag([0, 1.0, 0, 1.0]), missed_distance=3, m_of_n=m_of_n
            ),
        )

    # Detected at scans 0, 2, 3: 3 of 4 confirms at scan 3; 4 of 4 never does.
    pattern = [True, False, True, True, False, False]
    for m_of_n, confirm_at in (((3, 4), 3), ((4, 4), None)):
        tr = make(m_of_n)
        confirmed = None
        for k, seen in enumerate(pattern):
            z = np.array([[10.0, 5.0]]) if seen else np.empty((0, 2))
            tr.step(float(k), z, np.zeros(len(z), dtype=int))
            if confirmed is None and len(tr.tracks):
                confirmed = k
        assert confirmed == confirm_at
        if confirm_at is None:
            assert len(tr.tentative_tracks) == 0


def test_initiate_outside_gates_avoids_duplicate_tracks():
    # Two sensors see each of 20 targets at once: Stone Soup's rule (detections whose marginal
    # does not beat the missed one go to the initiator) starts duplicate tracks; withholding
    # gated detections and checking new tracks against confirmed ones does not.
    rng = np.random.default_rng(3)
    n = 20
    targets = np.column_stack([np.arange(n) % 5 * 30.0, np.arange(n) // 5 * 30.0])
    scans = []
    for k in range(40):
        z = np.concatenate(
            [targets + rng.normal(0, 0.25, (n, 2)), targets + rng.normal(0, 0.5, (n, 2))]
        )
        scans.append((float(k), z, np.r_[np.zeros(n, int), np.ones(n, int)]))
    counts = {}
    for flag in (True, False):
        tracker = code57(T.JPDA(0.85, 0.95, 0.125), initiate_in_gates=flag)
        for t, z, s in scans:
            tracker.step(t, z, s)
        counts[flag] = len(tracker.tracks)
        if not flag:
            # One track per target, each near its target.
            d = np.linalg.norm(tracker.tracks.states[:, None, [0, 2]] - targets[None], axis=2).min(
                axis=0
            )
            assert np.all(d < 1.0)
    assert counts[False] == n
    assert counts[True] > n


def test_time_order_and_dropping():
    tracker = code57(T.JPDA(0.85, 0.95, 0.125))
    tracker.step(10.0, [[0.0, 0.0]], [0])
    tracker.step(10.0)  # equal times are fine
    with pytest.raises(TimeOrderError):
        tracker.step(9.0)
    dropping = code57(T.JPDA(0.85, 0.95, 0.125), out_of_order="drop")
    dropping.step(10.0)
    dropping.step(9.0, [[1.0, 1.0]], [0])
    assert dropping.dropped_scans == 1
    assert dropping.last_time == 10.0
    res = code57(T.JPDA(0.85, 0.95, 0.125), out_of_order="drop").run(
        [1.0, 0.5, 2.0], np.zeros((0, 2)), [], np.zeros(0, dtype=int)
    )
    assert res.dropped_scans.tolist() == [1]


def test_bad_input_is_rejected_with_named_errors():
    tracker = code57(T.JPDA(0.85, 0.95, 0.125))
    with pytest.raises(NonFiniteError, match="measurements"):
        tracker.step(0.0, [[np.nan, 0.0]], [0])
    with pytest.raises(DimensionError, match="measurements"):
        tracker.step(0.0, [[0.0, 0.0, 0.0]], [0])
    with pytest.raises(DimensionError, match="sensor_ids"):
        tracker.step(0.0, [[0.0, 0.0]], [0, 1])
    with pytest.raises(ValueError, match="sensor_ids"):
        tracker.step(0.0, [[0.0, 0.0]], [5])
    with pytest.raises(ValueError, match="sensor_ids"):
        tracker.step(0.0, [[0.0, 0.0]], [-1])
    with pytest.raises(NonFiniteError):
        tracker.step(np.inf)
    for bad in (0.0, -0.1, 1.5):
        with pytest.raises(ValueError, match="prob_detect"):
            code57(T.JPDA(bad, 0.95, 0.125))
        with pytest.raises(ValueError, match="prob_gate"):
            code57(T.JPDA(0.85, bad, 0.125))
    with pytest.raises(ValueError, match="clutter_density"):
        code57(T.JPDA(0.85, 0.95, 0.0))
    with pytest.raises(ValueError, match="clutter_density"):
        code57(T.JPDA(0.85, 0.95, None, include_all=True))
    with pytest.raises(NotPositiveDefiniteError, match="measurement_noise"):
        T.Tracker(
            motion_model=constant_velocity_2d(0.1),
            sensors=[T.Sensor(np.eye(2, 4), np.array([[1.0, 2.0], [2.0, 1.0]]))],
            association=T.GNN(),
            deleter=T.StepsSinceUpdate(3),
            initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
        )
    with pytest.raises(DimensionError, match="measurement_matrix"):
        T.Tracker(
            motion_model=constant_velocity_2d(0.1),
            sensors=[T.Sensor(np.eye(2, 3), np.eye(2))],
            association=T.GNN(),
            deleter=T.StepsSinceUpdate(3),
            initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
        )
    with pytest.raises(NonFiniteError, match="noise_std"):
        T.Sensor.position(np.nan)
    with pytest.raises(NonFiniteError, match="measurement_noise"):
        code57_with(T.Sensor(np.eye(2, 4), np.full((2, 2), np.nan)))
    with pytest.raises(DimensionError, match="prior_state"):
        T.Tracker(
            motion_model=constant_velocity_2d(0.1),
            sensors=[T.Sensor.position(1.0)],
            association=T.GNN(),
            deleter=T.StepsSinceUpdate(3),
            initiator=T.MultiMeasurementInitiator(np.zeros(3), np.eye(4)),
        )
    with pytest.raises(ValueError, match="min_points"):
        T.Tracker(
            motion_model=constant_velocity_2d(0.1),
            sensors=[T.Sensor.position(1.0)],
            association=T.GNN(),
            deleter=T.StepsSinceUpdate(3),
            initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4), min_points=0),
        )
    with pytest.raises(TypeError, match="deleter"):
        code57_with(T.Sensor.position(1.0), deleter="never")
    with pytest.raises(ValueError, match="GNN assignment is not feasible"):
        t = code57_with(T.Sensor.position(1.0), association=T.GNN())
        t.add_track([0, 0, 0, 0], np.eye(4), 0.0)
        t.add_track([1, 0, 0, 0], np.eye(4), 0.0)
        t.step(1.0, [[0.0, 0.0]], [0])


def code57_with(sensor, deleter=None, association=None):
    return T.Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[sensor],
        association=association or T.JPDA(0.85, 0.95, 0.125),
        deleter=deleter or T.StepsSinceUpdate(3),
        initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
    )


def test_initiation_model_and_prior_follow_stonesoup_simple_initiator():
    # A detection without its own model starts a track with the initiator's model (Stone
    # Soup's initiator measurement_model): x = H⁺ z on mapped axes, P = H⁺ R H⁺ᵀ + prior
    # with mapped rows/columns zeroed, + diag_load.
    sensor = T.Sensor(
        np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]]),
        np.eye(2) * 0.25,
        initiation_noise=np.diag([0.01, 0.04]),
    )
    a = np.random.default_rng(0).normal(size=(4, 4))
    prior = a @ a.T + 0.1 * np.eye(4)
    tracker = T.Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[sensor],
        association=T.JPDA(0.9, 0.95, 0.01),
        deleter=T.StepsSinceUpdate(3),
        initiator=T.MultiMeasurementInitiator(
            np.array([7.0, 0.5, 7.0, -0.5]), prior, diag_load=0.001
        ),
    )
    tracker.step(0.0, [[3.0, 4.0]], [0])
    tent = tracker.tentative_tracks
    assert len(tent) == 1
    np.testing.assert_allclose(tent.states[0], [3.0, 0.5, 4.0, -0.5], atol=1e-15)
    want = np.zeros((4, 4))
    want[np.ix_([1, 3], [1, 3])] = prior[np.ix_([1, 3], [1, 3])]
    want[0, 0], want[2, 2] = 0.01, 0.04
    np.testing.assert_allclose(tent.covariances[0], want + 0.001 * np.eye(4), atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_brute_force_and_ehm_trackers_agree(seed):
    scans = scenario(seed, n_targets=6, n_scans=20, clutter=5.0, spread=4.0)
    runs = []
    for method in ("ehm", "brute_force"):
        tracker = code57(T.JPDA(0.85, 0.95, 0.125, method=method))
        runs.append([tracker.step(t, z, s) for t, z, s in scans])
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a.ids, b.ids)
        np.testing.assert_allclose(a.states, b.states, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("seed", [0, 3])
def test_add_sensor_between_steps_equals_configured_sensors(seed):
    """A sensor registered mid-run (before its first detection) gives exactly the tracks of a
    tracker built with it; the snapshot's association data is the newest history entry's."""
    # Sensor 1 first reports at scan 8, when tracks of sensor 0 exist.
    scans = [
        (t, z[s == 0], s[s == 0]) if i < 8 else (t, z, s)
        for i, (t, z, s) in enumerate(scenario(seed))
    ]
    first = next(i for i, (_, _, s) in enumerate(scans) if (s == 1).any())
    assert first >= 8
    ref = code57(T.JPDA(0.85, 0.95, 0.125))
    late = T.Tracker(
        motion_model=constant_velocity_2d(0.001),
        sensors=[T.Sensor.position(NOISE[0])],
        association=T.JPDA(0.85, 0.95, 0.125),
        deleter=T.AnyOf(T.CovarianceTrace(1.5), T.StepsSinceUpdate(35)),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4),
            np.diag([0, 0.3, 0, 0.3]),
            min_points=2,
            deleter=T.StepsSinceUpdate(3),
            missed_distance=0.3,
        ),
    )
    for i, (t, z, s) in enumerate(scans):
        if i == first:
            assert late.add_sensor(T.Sensor.position(NOISE[1])) == 1
        a, b = ref.step(t, z, s), late.step(t, z, s)
        np.testing.assert_array_equal(a.ids, b.ids)
        np.testing.assert_array_equal(a.states, b.states)
        np.testing.assert_array_equal(a.covariances, b.covariances)
        for k, tid in enumerate(b.ids):
            h = ref.history(tid)
            lo, hi = b.assoc_offsets[k], b.assoc_offsets[k + 1]
            np.testing.assert_array_equal(
                b.assoc_detection[lo:hi],
                h.assoc_detection[h.assoc_offsets[-2] : h.assoc_offsets[-1]],
            )
            np.testing.assert_array_equal(
                b.assoc_probability[lo:hi],
                h.assoc_probability[h.assoc_offsets[-2] : h.assoc_offsets[-1]],
            )
            assert b.detection[k] == h.detection[-1] and b.scan[k] == h.scan[-1]
            np.testing.assert_array_equal(b.missed_probability[k], h.missed_probability[-1])
    # The late sensor did update tracks.
    assert any((late.history(tid).sensor == 1).any() for tid in late.tracks.ids)


def test_add_sensor_rejects_other_dimensions():
    tr = code57(T.JPDA(0.85, 0.95, 0.125))
    with pytest.raises(DimensionError, match="measurement_matrix"):
        tr.add_sensor(T.Sensor(np.eye(3, 4), np.eye(3)))
    with pytest.raises(DimensionError, match="measurement_matrix"):
        tr.add_sensor(T.Sensor(np.eye(2, 6), np.eye(2)))
    with pytest.raises(NotPositiveDefiniteError):
        tr.add_sensor(T.Sensor(np.eye(2, 4), -np.eye(2)))
    with pytest.raises(TypeError, match="sensor"):
        tr.add_sensor((np.eye(2, 4), np.eye(2)))
    assert len(tr.sensors) == 2


def test_jpda_without_a_chance_of_an_empty_scan_is_rejected():
    # P_D * P_G = 1 would give ln(0) for the missed hypothesis: NaN states on an empty scan.
    with pytest.raises(ValueError, match=r"prob_detect.*prob_gate"):
        code57(T.JPDA(prob_detect=1.0, prob_gate=1.0, clutter_density=0.1))
    # Either one below 1 is fine, and an empty scan keeps the states finite.
    tr = code57(T.JPDA(prob_detect=1.0, prob_gate=0.99, clutter_density=0.1))
    tr.add_track([0.0, 1.0, 0.0, 1.0], 0.1 * np.eye(4), 0.0)
    tr.step(1.0)
    s = tr.tracks
    assert len(s.ids) == 1 and np.all(np.isfinite(s.states)) and np.all(np.isfinite(s.covariances))


def test_jpda_estimated_clutter_needs_a_finite_gate():
    with pytest.raises(ValueError, match="prob_gate"):
        code57(T.JPDA(prob_detect=0.9, prob_gate=1.0, clutter_density=None))
    # With a given clutter density an infinite gate is allowed.
    tr = code57(T.JPDA(prob_detect=0.9, prob_gate=1.0, clutter_density=0.1))
    tr.add_track([0.0, 1.0, 0.0, 1.0], 0.1 * np.eye(4), 0.0)
    tr.step(1.0, [[1.0, 1.0]], [0])
    s = tr.tracks
    assert len(s.ids) == 1 and np.all(np.isfinite(s.states)) and np.all(np.isfinite(s.covariances))


def test_integer_arguments_are_named():
    # Counts are integers: a float (even 2.0) is a TypeError, a negative one a ValueError.
    with pytest.raises(TypeError, match="steps"):
        code57_with(T.Sensor.position(1.0), deleter=T.StepsSinceUpdate(2.7))
    with pytest.raises(TypeError, match="steps"):
        code57_with(T.Sensor.position(1.0), deleter=T.StepsSinceUpdate(2.0))
    with pytest.raises(ValueError, match="steps"):
        code57_with(T.Sensor.position(1.0), deleter=T.AnyOf(T.StepsSinceUpdate(-1)))
    with pytest.raises(ValueError, match="mapping"):
        T.Sensor.position(1, mapping=(0, 9))
    with pytest.raises(ValueError, match="mapping"):
        T.Sensor.position(1, mapping=(0, -1))
    with pytest.raises(ValueError, match="mapping"):
        code57_with(T.Sensor.position(1.0), deleter=T.CovarianceTrace(1, [-1]))
    tr = code57(T.JPDA(0.85, 0.95, 0.125))
    with pytest.raises(ValueError, match="track_id"):
        tr.history(-1)
    with pytest.raises(ValueError, match="dof"):
        _core.chi2_gate(0.5, -1)
    with pytest.raises(ValueError, match="dof"):
        _core.chi2_gate(0.5, 0)
