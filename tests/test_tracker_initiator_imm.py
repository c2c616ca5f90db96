"""IMM in the initiator (`MultiMeasurementInitiator(imm=True)`): a one-mode bank equals the
plain initiator (1e-12); a tentative track that is then confirmed equals filterpy's
`IMMEstimator` started from the initiation Gaussian (linear modes) and the Stone Soup +
filterpy oracle of tests/test_tracker_constant_turn.py (`ConstantTurn` modes) to 1e-9 over its
whole life, i.e. the confirmed track keeps its tentative modes and probabilities; a turning
target is confirmed sooner and closer; pickling, the TOML key and bad settings."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import test_tracker_constant_turn as CT
import test_tracker_imm as TI
from hypothesis import given, settings
from hypothesis import strategies as st

from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d

R = np.array([[4.0, 0.5], [0.5, 2.5]])


def scene(seed, n=30, clutter=3.0):
    """Three boats (two crossing) with P_D 0.9 and Poisson clutter: scans of plots."""
    rng = np.random.default_rng(seed)
    starts = [([0.0, 3.0, 0.0, 1.0]), ([0.0, 3.0, 60.0, -1.5]), ([200.0, -2.0, 20.0, 0.5])]
    xs = [np.array(s) for s in starts]
    scans = []
    for _ in range(n):
        z = [x[[0, 2]] + rng.normal(0, 1.5, 2) for x in xs if rng.random() < 0.9]
        z += list(rng.uniform([-50, -50], [250, 120], (rng.poisson(clutter), 2)))
        scans.append(np.array(z).reshape(-1, 2))
        xs = [x + np.array([x[1], 0, x[3], 0]) for x in xs]
    return scans


def one_mode_tracker(imm_init, association, existence=None, q=0.05):
    return T.Tracker(
        motion_model=constant_velocity_2d(q),
        sensors=[T.Sensor.position(1.5)],
        association=association,
        deleter=T.StepsSinceUpdate(4),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4),
            np.diag([0.0, 16.0, 0.0, 16.0]),
            min_points=3,
            missed_distance=3.0,
            imm=imm_init,
        ),
        imm=T.IMM([constant_velocity_2d(q)], [[1.0]]),
        existence=existence,
        initiate_in_gates=False,
    )


@pytest.mark.parametrize(
    "association,existence",
    [
        (T.GNN(missed_distance=4.0), None),
        (T.JPDA(0.9, 0.99, 1e-4), None),
        (T.JPDA(0.9, 0.99, 1e-4), T.Existence(0.99, confirm=0.6, birth=0.4, delete=0.01)),
    ],
)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_one_mode_bank_equals_the_plain_initiator(association, existence, seed):
    plain = one_mode_tracker(False, association, existence)
    imm = one_mode_tracker(True, association, existence)
    tentative_seen = 0
    for k, z in enumerate(scene(seed)):
        a, b = plain.step(float(k), z), imm.step(float(k), z)
        ta, tb = plain.tentative_tracks, imm.tentative_tracks
        for x, y in ((a, b), (ta, tb)):
            np.testing.assert_array_equal(x.ids, y.ids)
            np.testing.assert_array_equal(x.is_update, y.is_update)
            np.testing.assert_allclose(x.states, y.states, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(x.covariances, y.covariances, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(x.existence, y.existence, rtol=1e-12, atol=1e-12)
        tentative_seen += len(ta)
        # A one-mode bank's probability is 1 on every track, tentative ones included.
        assert (tb.mode_probabilities == 1.0).all() and tb.mode_probabilities.shape[1] == 1
    assert tentative_seen > 20 and len(plain.tracks) >= 2


def linear_tracker(imm_init, mu0, min_points):
    """The filterpy set-up of tests/test_tracker_imm.py, its one track started by the
    initiator (prior velocity variance 1, R with a correlation) and confirmed after
    `min_points` updates; Joseph-form updates (filterpy's) everywhere."""
    return T.Tracker(
        motion_model=constant_velocity_2d(0.05),
        sensors=[T.Sensor(TI.H, R)],
        association=T.GNN(),
        deleter=T.NeverDelete(),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4),
            np.diag([0.0, 1.0, 0.0, 1.0]),
            min_points=min_points,
            deleter=T.NeverDelete(),
            use_joseph_cov=True,
            symmetric_covariance=False,
            imm=imm_init,
        ),
        imm=T.IMM(TI.modes(0.05), TI.TRANSITION, mu0),
        use_joseph_cov=True,
        symmetric_covariance=False,
    )


def initiation_gaussian(z, prior_var):
    """The initiator's start from plot z: H⁺ z on the positions, H⁺ R H⁺ᵀ there, the prior
    (zero mean, variance prior_var) on the rest."""
    x0 = np.zeros(len(prior_var))
    x0[[0, 2]] = z
    p0 = np.diag(np.asarray(prior_var, float))
    p0[np.ix_([0, 2], [0, 2])] = R
    return x0, p0


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31), dt=st.sampled_from([1.0, 2.0]))
def test_tentative_then_confirmed_track_equals_filterpy_imm(seed, dt):
    zs = TI.turning_target(seed, n=30, dt=dt)
    mu0 = [0.6, 0.2, 0.2]
    x0, p0 = initiation_gaussian(zs[0], [0.0, 1.0, 0.0, 1.0])
    want = TI.filterpy_imm(x0, p0, zs[1:], dt, 0.05, R, mu0)
    tr = linear_tracker(True, mu0, min_points=12)
    tr.step(0.0, zs[:1])
    phases = set()
    for k, (z, (wx, wp, wmu)) in enumerate(zip(zs[1:], want, strict=True), start=1):
        got = tr.step(k * dt, z.reshape(1, 2))
        tent = tr.tentative_tracks
        # Tentative for 11 updates (scans 1-10), confirmed at scan 11, then one GNN track.
        now = tent if len(tent) else got
        assert len(now) == 1 and len(tent) + len(got) == 1
        phases.add("tentative" if len(tent) else "confirmed")
        np.testing.assert_allclose(now.states[0], wx, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(now.covariances[0], wp, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(now.mode_probabilities[0], wmu, rtol=1e-9, atol=1e-12)
    assert phases == {"tentative", "confirmed"}
    # Without the option the tentative phase is a CV filter and the confirmed track restarts
    # every mode at its state with the initial probabilities: another estimate.
    plain = linear_tracker(False, mu0, min_points=12)
    for k, z in enumerate(zs[:13]):
        got = plain.step(k * dt, z.reshape(1, 2))
        if k == 11:
            assert not np.allclose(got.states[0], want[k - 1][0], rtol=1e-6, atol=1e-6)
    # One scan after confirmation: μ is one step from the initial probabilities.
    assert np.abs(got.mode_probabilities[0] - want[11][2]).max() > 1e-4


@settings(max_examples=4, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    omega=st.sampled_from([0.06, -0.1]),
    predictor=st.sampled_from(["ekf", "ukf"]),
)
def test_tentative_constant_turn_bank_equals_the_stonesoup_filterpy_oracle(seed, omega, predictor):
    dt, q, qw, qc, qt = 1.0, 0.05, 1e-5, 0.3, 1e-3
    _, zs = CT.turning_plots(seed, omega, n=25, dt=dt)
    prior = [0.0, 20.0, 0.0, 20.0, 0.01]
    x0, p0 = initiation_gaussian(zs[0], prior)
    mu0 = [0.7, 0.3]
    want = CT.oracle_imm(x0, p0, zs[1:], dt, mu0, q, qw, qc, qt, R, predictor)
    tr = T.Tracker(
        motion_model=T.constant_velocity_turn_rate(q, qw),
        sensors=[T.Sensor(CT.H5, R)],
        association=T.GNN(missed_distance=1e6),
        deleter=T.NeverDelete(),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(5),
            np.diag(prior),
            min_points=8,
            missed_distance=1e6,
            deleter=T.NeverDelete(),
            symmetric_covariance=False,
            imm=True,
        ),
        imm=T.IMM(
            [T.constant_velocity_turn_rate(q, qw), T.ConstantTurn(qc, qt, predictor)], CT.M2, mu0
        ),
        symmetric_covariance=False,
    )
    tr.step(0.0, zs[:1])
    for k, (z, (wx, wp, wmu)) in enumerate(zip(zs[1:], want, strict=True), start=1):
        got = tr.step(k * dt, z.reshape(1, 2))
        tent = tr.tentative_tracks
        now = tent if len(tent) else got
        assert len(now) == 1 and (len(tent) == 1) == (k < 7)
        np.testing.assert_allclose(now.states[0], wx, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(now.covariances[0], wp, rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(now.mode_probabilities[0], wmu, rtol=1e-9, atol=1e-12)


def hard_turn(seed, w=0.25, speed=10.0, n=25, sigma=1.0):
    """A boat turning at w rad/s from its first plot, heading random: truth (n, 4), plots."""
    rng = np.random.default_rng(seed)
    th = rng.uniform(0, 2 * np.pi)
    x = np.array([0.0, speed * np.cos(th), 0.0, speed * np.sin(th)])
    f, _ = TI.turn_matrices(0.0, w, 1.0)
    truth, zs = [], []
    for _ in range(n):
        truth.append(x.copy())
        zs.append(x[[0, 2]] + rng.normal(0, sigma, 2))
        x = np.asarray(f, float) @ x
    return np.array(truth), np.array(zs)


def test_a_turning_target_is_confirmed_sooner_and_closer():
    """A tight turn (0.25 rad/s at 10 m/s, plots σ 1 m) from the first plot: the CV initiator's
    prediction leaves its 3σ gate and its tentative tracks die before 5 updates, while the
    bank (CV, turns at ±0.25 rad/s) holds them."""
    w = 0.25
    bank = T.IMM(
        [constant_velocity_2d(0.05), T.KnownTurnRate(0.05, w), T.KnownTurnRate(0.05, -w)],
        np.full((3, 3), 0.05) + np.eye(3) * 0.85,
    )
    first, err = {False: [], True: []}, {False: [], True: []}
    for seed in range(20):
        truth, zs = hard_turn(seed, w)
        for flag in (False, True):
            tr = T.Tracker(
                motion_model=constant_velocity_2d(0.05),
                sensors=[T.Sensor.position(1.0)],
                association=T.GNN(missed_distance=4.0),
                deleter=T.StepsSinceUpdate(3),
                initiator=T.MultiMeasurementInitiator(
                    np.zeros(4),
                    np.diag([0.0, 100.0, 0.0, 100.0]),
                    min_points=5,
                    missed_distance=3.0,
                    deleter=T.StepsSinceUpdate(1),
                    imm=flag,
                ),
                imm=bank,
            )
            k_conf = None
            for k, z in enumerate(zs):
                got = tr.step(float(k), z.reshape(1, 2))
                if len(got) and k_conf is None:
                    k_conf = k
                    err[flag].append(np.hypot(*(got.states[0, [0, 2]] - truth[k, [0, 2]])))
            first[flag].append(len(zs) if k_conf is None else k_conf)
    imm, cv = np.array(first[True]), np.array(first[False])
    # Measured: with the bank all 20 at scan 4 (the 5th plot, the earliest possible); the CV
    # initiator 3 at scan 4, 5 later (scans 17-23) and 12 never within the 25 scans.
    assert (imm == 4).all()
    assert np.sum(cv > 4) >= 15 and np.sum(cv == 25) >= 10  # 25: never
    # ... and at confirmation the track is closer to the boat (median 0.91 m against 2.31 m).
    assert np.median(err[True]) < 0.5 * np.median(err[False])


def test_tentative_imm_state_pickles_and_continues():
    scans = scene(5, n=12)
    bank = T.IMM(
        [constant_velocity_2d(0.05), T.KnownTurnRate(0.05, 0.1), T.KnownTurnRate(0.05, -0.1)],
        TI.TRANSITION,
    )
    tr = T.Tracker(
        motion_model=constant_velocity_2d(0.05),
        sensors=[T.Sensor.position(1.5)],
        association=T.JPDA(0.9, 0.99, 1e-4),
        deleter=T.StepsSinceUpdate(4),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0.0, 16.0, 0.0, 16.0]), min_points=4, missed_distance=3.0,
            imm=True,
        ),
        imm=bank,
    )  # fmt: skip
    for k, z in enumerate(scans[:-1]):
        tr.step(float(k), z)
    tent = tr.tentative_tracks
    # Tentative tracks with one update or more have left the initial probabilities.
    moved = ~np.isclose(tent.mode_probabilities, [1 / 3] * 3).all(axis=1)
    assert moved.any()
    np.testing.assert_allclose(tent.mode_probabilities.sum(axis=1), 1.0, atol=1e-12)
    copy = pickle.loads(pickle.dumps(tr))
    a, b = tr.step(11.0, scans[-1]), copy.step(11.0, scans[-1])
    np.testing.assert_array_equal(a.states, b.states)
    np.testing.assert_array_equal(a.mode_probabilities, b.mode_probabilities)
    np.testing.assert_array_equal(
        tr.tentative_tracks.mode_probabilities, copy.tentative_tracks.mode_probabilities
    )


def test_bad_settings_are_named():
    base = dict(
        motion_model=constant_velocity_2d(0.05),
        sensors=[T.Sensor.position(1.0)],
        association=T.GNN(missed_distance=4.0),
        deleter=T.StepsSinceUpdate(3),
    )
    bank = T.IMM([constant_velocity_2d(0.05)], [[1.0]])
    with pytest.raises(ValueError, match=r"initiator\.imm.*IMM bank"):
        T.Tracker(**base, initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4), imm=True))
    with pytest.raises(ValueError, match=r"initiator\.imm.*motion_model"):
        T.Tracker(
            **base,
            imm=bank,
            initiator=T.MultiMeasurementInitiator(
                np.zeros(4), np.eye(4), motion_model=constant_velocity_2d(1.0), imm=True
            ),
        )
    with pytest.raises(TypeError, match=r"initiator\.imm"):
        T.Tracker(
            **base, imm=bank, initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4), imm=1)
        )


def test_the_toml_key():
    from usvfast.trackcmd import load_config, tracker_from_config

    cfg = load_config("joyride")
    rng = np.random.default_rng(3)
    zs = [np.array([[10.0 * k, 5.0 * k]]) + rng.normal(0, 8.0, 2) for k in range(6)]

    def tentative_mu(init):
        tr = tracker_from_config({**cfg, "initiator": init})
        tr.step(0.0, zs[0])
        # Confirmed at its second plot (min_points = 2), with its tentative μ or the initial.
        return tr.step(1.0, zs[1]).mode_probabilities

    plain = tentative_mu(dict(cfg["initiator"]))
    off = tentative_mu({**cfg["initiator"], "imm": False})
    on = tentative_mu({**cfg["initiator"], "imm": True})
    np.testing.assert_array_equal(plain, off)
    assert len(on) == 1 and not np.allclose(on, off)
    with pytest.raises(ValueError, match=r"tracker\.initiator\.imm"):
        tracker_from_config({**cfg, "initiator": {**cfg["initiator"], "imm": "yes"}})
    no_bank = {k: v for k, v in cfg.items() if k != "imm"}
    no_bank["initiator"] = {"imm": True}
    with pytest.raises(ValueError, match=r"tracker\.initiator\.imm.*\[tracker\.imm\]"):
        tracker_from_config(no_bank)
