"""The coordinated turn with the turn rate in the state ([n, v_n, e, v_e, ω], `ConstantTurn`):
single predictions equal to Stone Soup's `ConstantTurn` with its `UnscentedKalmanPredictor`
(1e-9) and `ExtendedKalmanPredictor` (to the accuracy of its finite-difference Jacobian), the
analytic Jacobian equal to a complex-step one, a whole IMM cycle (CV5 + CT) equal to an oracle
built from Stone Soup's predictors and updater with filterpy's `IMMEstimator` mixing, and
hypothesis properties (mode probabilities, positive definite covariances, ω → 0 continuity,
a constant-rate turn tracked with ω converging to the true rate); a JPDA run with CT modes;
bad input."""

from __future__ import annotations

import pickle
from datetime import datetime, timedelta

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d

T0 = datetime(2024, 1, 1)
H5 = np.array([[1.0, 0, 0, 0, 0], [0, 0, 1.0, 0, 0]])


def ss_ct(q, q_turn):
    from stonesoup.models.transition.nonlinear import ConstantTurn

    return ConstantTurn(linear_noise_coeffs=np.array([q, q], float), turn_noise_coeff=q_turn)


def single_mode_tracker(mode, sym=False):
    """A tracker holding one confirmed track whose IMM bank is `mode` alone: a step without
    detections is that mode's prediction."""
    return T.Tracker(
        motion_model=T.constant_velocity_turn_rate(0.1, 1e-3),
        sensors=[T.Sensor.position(1.0, ndim_state=5)],
        association=T.GNN(missed_distance=10.0),
        deleter=T.NeverDelete(),
        initiator=T.MultiMeasurementInitiator(np.zeros(5), np.eye(5), missed_distance=3.0),
        imm=T.IMM([mode], [[1.0]]),
        symmetric_covariance=sym,
    )


def predict_native(mode, x, p, dt):
    tr = single_mode_tracker(mode)
    tr.add_track(x, p, 0.0)
    got = tr.step(dt)
    return got.states[0], got.covariances[0]


def random_gaussian(rng, omega):
    x = np.array([rng.uniform(-500, 500), rng.normal(0, 8), rng.uniform(-500, 500)])
    x = np.append(x, [rng.normal(0, 8), omega])
    a = rng.normal(size=(5, 5)) * np.array([5.0, 1.0, 5.0, 1.0, 0.02])
    p = a @ a.T + np.diag([1.0, 0.1, 1.0, 0.1, 1e-4])
    return x, p


gaussians = st.tuples(
    st.integers(0, 2**31),
    st.floats(-0.4, 0.4).filter(lambda w: abs(w) > 1e-3),
    st.sampled_from([0.2, 1.0, 2.5, 4.0]),
    st.sampled_from([0.0, 0.05, 2.0]),
    st.sampled_from([0.0, 1e-4, 0.01]),
)


@settings(max_examples=40, deadline=None)
@given(g=gaussians)
def test_ukf_prediction_equals_stonesoup(g):
    from stonesoup.predictor.kalman import UnscentedKalmanPredictor
    from stonesoup.types.state import GaussianState

    seed, omega, dt, q, qt = g
    x, p = random_gaussian(np.random.default_rng(seed), omega)
    want = UnscentedKalmanPredictor(ss_ct(q, qt)).predict(
        GaussianState(x.reshape(5, 1).copy(), p.copy(), timestamp=T0),
        timestamp=T0 + timedelta(seconds=dt),
    )
    gx, gp = predict_native(T.ConstantTurn(q, qt, "ukf"), x, p, dt)
    scale = np.abs(p).max()
    np.testing.assert_allclose(gx, np.ravel(want.state_vector), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(gp, np.asarray(want.covar), rtol=1e-9, atol=1e-12 * scale)


@settings(max_examples=40, deadline=None)
@given(g=gaussians)
def test_ekf_prediction_equals_stonesoup(g):
    from stonesoup.predictor.kalman import ExtendedKalmanPredictor
    from stonesoup.types.state import GaussianState

    seed, omega, dt, q, qt = g
    x, p = random_gaussian(np.random.default_rng(seed), omega)
    want = ExtendedKalmanPredictor(ss_ct(q, qt)).predict(
        GaussianState(x.reshape(5, 1).copy(), p.copy(), timestamp=T0),
        timestamp=T0 + timedelta(seconds=dt),
    )
    gx, gp = predict_native(T.ConstantTurn(q, qt, "ekf"), x, p, dt)
    # The mean is f(x) in both: equal to rounding.
    np.testing.assert_allclose(gx, np.ravel(want.state_vector), rtol=1e-12, atol=1e-9)
    # The covariance is J P Jᵀ + Q with the exact (complex-step) Jacobian ...
    j = complex_step_jacobian(x, dt)
    q5 = np.asarray(ss_ct(q, qt).covar(time_interval=timedelta(seconds=dt)))
    exact = j @ p @ j.T + q5
    np.testing.assert_allclose(gp, exact, rtol=1e-12, atol=1e-12 * np.abs(exact).max())
    # ... and Stone Soup's differs by what its forward-difference Jacobian (steps of 1e8 ulp,
    # >= 1e-8; rounding error ~ ulp(f)/step) allows: |ΔP| <= (2|J| + |ΔJ|) |ΔJ| |P|.
    from stonesoup.types.state import State

    dj = np.linalg.norm(
        ss_ct(q, qt).jacobian(State(x.reshape(5, 1).copy()), time_interval=timedelta(seconds=dt))
        - j,
        2,
    )
    # Its Jacobian is the exact one to forward-difference precision (at most 3.4e-5 of |J| over
    # 6,000 draws of this domain, |ω| down to 1e-3), so the bound below is a tight one.
    assert dj < 1e-4 * np.linalg.norm(j, 2)
    bound = (2 * np.linalg.norm(j, 2) + dj) * dj * np.linalg.norm(p, 2)
    wp = np.asarray(want.covar)
    np.testing.assert_allclose(gp, wp, rtol=0, atol=1.01 * bound + 1e-12 * np.abs(wp).max())


def complex_step_jacobian(x, dt, h=1e-30):
    """∂f/∂x of `ct_function` by complex steps (exact to rounding: no subtraction)."""
    cs = np.empty((5, 5))
    for i in range(5):
        xc = x.astype(complex)
        xc[i] += 1j * h
        cs[:, i] = ct_function(xc, dt).imag / h
    return cs


def ct_function(x, dt):
    """The constant turn in numpy (complex-step safe, ω != 0; Stone Soup's `ConstantTurn`
    function), with 1 − cos ωT written 2 sin²(ωT/2) (no cancellation near ω = 0)."""
    w = x[4]
    s, c = np.sin(w * dt), np.cos(w * dt)
    a, b = s / w, 2 * np.sin(w * dt / 2) ** 2 / w
    return np.array(
        [x[0] + a * x[1] - b * x[3], c * x[1] - s * x[3], x[2] + b * x[1] + a * x[3],
         s * x[1] + c * x[3], w]
    )  # fmt: skip


def native_jacobian(x, dt, predictor="ekf"):
    """The native EKF's Jacobian read back from predictions with rank-one covariances and no
    process noise: P = e_i e_iᵀ gives J_i J_iᵀ, P = (e_0 + e_i)(e_0 + e_i)ᵀ adds
    e_0 J_iᵀ + J_i e_0ᵀ + e_0 e_0ᵀ (column 0 of J is e_0), whose row 0 is J_i."""
    mode = T.ConstantTurn(0.0, 0.0, predictor)
    j = np.zeros((5, 5))
    j[0, 0] = 1.0
    e = np.eye(5)
    for i in range(1, 5):
        _, m1 = predict_native(mode, x, np.outer(e[i], e[i]), dt)
        u = e[0] + e[i]
        _, m2 = predict_native(mode, x, np.outer(u, u), dt)
        d = m2 - m1 - np.outer(e[0], e[0])
        j[:, i] = d[0]
        j[0, i] = d[0, 0] / 2
    return j


@pytest.mark.parametrize(
    "omega,dt", [(0.1, 1.0), (-0.25, 3.0), (0.02, 2.5), (3e-3, 2.0), (-1e-3, 4.0)]
)
def test_analytic_jacobian_equals_complex_step(omega, dt):
    from stonesoup.types.state import State

    x = np.array([120.0, 6.0, -80.0, -4.0, omega])
    # The numpy function is Stone Soup's ConstantTurn.function.
    ss = ss_ct(0.0, 0.0).function(
        State(x.reshape(5, 1).copy()), time_interval=timedelta(seconds=dt)
    )
    np.testing.assert_allclose(ct_function(x, dt), np.ravel(ss), rtol=1e-13, atol=1e-12)
    cs = complex_step_jacobian(x, dt)
    got = native_jacobian(x, dt)
    np.testing.assert_allclose(got, cs, rtol=1e-10, atol=1e-10 * np.abs(cs).max())


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    dt=st.sampled_from([0.5, 1.0, 3.0]),
    predictor=st.sampled_from(["ekf", "ukf"]),
)
def test_turn_rate_to_zero_is_continuous(seed, dt, predictor):
    rng = np.random.default_rng(seed)
    x, p = random_gaussian(rng, 0.0)
    p[4, 4] += 0.01  # UKF sigma points then straddle ω = 0 at every ω below
    mode = T.ConstantTurn(0.05, 1e-3, predictor)
    x0, p0 = predict_native(mode, x, p, dt)
    assert np.isfinite(x0).all() and np.isfinite(p0).all()
    for eps in (1e-12, 1e-8, 1e-5, -1e-5, -1e-8):
        xe, pe = predict_native(mode, x + np.eye(5)[4] * eps, p, dt)
        # f is smooth in ω (|∂f/∂ω| <= dt (dt |v| + |v|) + 1 at every sigma point, whose
        # speeds stay within 3 σ here; the UKF's weights sum to 1 in absolute value 12.3):
        # the change is of the order of eps, down to rounding.
        v = np.abs(x[[1, 3]]).sum() + 3 * np.sqrt(p[1, 1] + p[3, 3])
        bound = 15 * abs(eps) * (dt * (dt + 1) * v + 1) + 1e-12 * np.abs(x).max()
        assert np.abs(xe - x0).max() <= bound
        assert np.abs(pe - p0).max() <= 1e3 * bound * np.abs(p).max() + 1e-9 * np.abs(p0).max()
    # At ω = 0 the mean is the constant-velocity one.
    cv = np.array([x[0] + dt * x[1], x[1], x[2] + dt * x[3], x[3], 0.0])
    if predictor == "ekf":
        np.testing.assert_allclose(x0, cv, rtol=1e-14, atol=1e-12)


def turning_plots(seed, omega, speed=6.0, n=60, dt=1.0, sigma=3.0, turn_from=10):
    """A boat going straight for `turn_from` scans, then turning at the constant rate omega;
    the truth (n, 5) and noisy position plots (n, 2)."""
    rng = np.random.default_rng(seed)
    x = np.array([0.0, speed, 0.0, 0.0, 0.0])
    truth, zs = [], []
    for k in range(n):
        w = omega if k >= turn_from else 0.0
        x[4] = w
        x = ct_function(x, dt) if w else np.array([x[0] + dt * x[1], x[1], x[2] + dt * x[3],
                                                   x[3], 0.0])  # fmt: skip
        truth.append(x.copy())
        zs.append(x[[0, 2]] + rng.normal(0, sigma, 2))
    return np.array(truth), np.array(zs)


def ExactCT(q, q_turn):
    """Stone Soup's `ConstantTurn` with the complex-step Jacobian in place of its forward
    differences, whose ω column is off near ω = 0: 1 − cos ωT at ω = 1e-8 keeps one or two
    bits, so (1 − cos ωT)/ω and the derivative taken from it are ~10 % wrong there."""
    from stonesoup.models.transition.nonlinear import ConstantTurn

    class _Exact(ConstantTurn):
        def jacobian(self, state, **kwargs):
            dt = kwargs["time_interval"].total_seconds()
            return complex_step_jacobian(np.ravel(state.state_vector).astype(float), dt)

    return _Exact(linear_noise_coeffs=np.array([q, q], float), turn_noise_coeff=q_turn)


# ---- a whole IMM cycle against Stone Soup's predictors + filterpy's IMM formulas ----

M2 = np.array([[0.95, 0.05], [0.1, 0.9]])


def oracle_imm(x0, p0, zs, dt, mu0, q, qw, qc, qt, r, predictor):
    """filterpy's `IMMEstimator` cycle (mixing, mode predictions, updates, μ ∝ c̄ Λ,
    moment-matched output) with Stone Soup's `KalmanPredictor` on [CV, CV, RandomWalk], its
    `ExtendedKalmanPredictor` / `UnscentedKalmanPredictor` on `ConstantTurn`, and its
    `KalmanUpdater` (P − K S Kᵀ); the EKF's Jacobian is exact (see `ExactCT`)."""
    from scipy.stats import multivariate_normal
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
        RandomWalk,
    )
    from stonesoup.predictor.kalman import (
        ExtendedKalmanPredictor,
        KalmanPredictor,
        UnscentedKalmanPredictor,
    )
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.state import GaussianState
    from stonesoup.updater.kalman import KalmanUpdater

    cv = CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(q), ConstantVelocity(q), RandomWalk(qw)]
    )
    ukf = predictor == "ukf"
    preds = [
        KalmanPredictor(cv),
        UnscentedKalmanPredictor(ss_ct(qc, qt))
        if ukf
        else ExtendedKalmanPredictor(ExactCT(qc, qt)),
    ]
    mm = LinearGaussian(ndim_state=5, mapping=(0, 2), noise_covar=r)
    upd = KalmanUpdater(mm)
    xs, ps, mu = [x0.copy(), x0.copy()], [p0.copy(), p0.copy()], np.asarray(mu0, float)
    out = []
    for k, z in enumerate(zs):
        t, t1 = T0 + timedelta(seconds=k * dt), T0 + timedelta(seconds=(k + 1) * dt)
        cbar = mu @ M2
        omega = M2 * mu[:, None] / cbar[None, :]
        new_x, new_p, lik = [], [], np.zeros(2)
        for j in range(2):
            xm = sum(omega[i, j] * xs[i] for i in range(2))
            pm = sum(omega[i, j] * (np.outer(xs[i] - xm, xs[i] - xm) + ps[i]) for i in range(2))
            pr = preds[j].predict(GaussianState(xm.reshape(5, 1), pm, timestamp=t), timestamp=t1)
            det = Detection(z.reshape(2, 1), timestamp=t1, measurement_model=mm)
            mp = upd.predict_measurement(pr, measurement_model=mm)
            lik[j] = multivariate_normal.pdf(
                z, mean=np.ravel(mp.state_vector), cov=np.asarray(mp.covar)
            )
            post = upd.update(SingleHypothesis(pr, det, measurement_prediction=mp))
            new_x.append(np.ravel(post.state_vector).astype(float))
            new_p.append(np.asarray(post.covar, float))
        xs, ps = new_x, new_p
        mu = cbar * lik
        mu /= mu.sum()
        x = sum(m * xi for m, xi in zip(mu, xs, strict=True))
        p = sum(m * (np.outer(xi - x, xi - x) + pi) for m, xi, pi in zip(mu, xs, ps, strict=True))
        out.append((x, p, mu.copy()))
    return out


@settings(max_examples=6, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    omega=st.sampled_from([0.06, -0.1]),
    predictor=st.sampled_from(["ekf", "ukf"]),
)
def test_imm_cycle_equals_stonesoup_filterpy_oracle(seed, omega, predictor):
    dt, q, qw, qc, qt = 1.0, 0.05, 1e-5, 0.3, 1e-3
    r = np.diag([9.0, 6.0])
    _, zs = turning_plots(seed, omega, n=30, dt=dt)
    x0, p0 = np.array([0.0, 6.0, 0.0, 0.0, 0.0]), np.diag([9.0, 1.0, 9.0, 1.0, 0.01])
    mu0 = [0.7, 0.3]
    want = oracle_imm(x0, p0, zs, dt, mu0, q, qw, qc, qt, r, predictor)
    tr = T.Tracker(
        motion_model=T.constant_velocity_turn_rate(q, qw),
        sensors=[T.Sensor(H5, r)],
        association=T.GNN(missed_distance=1e6),
        deleter=T.NeverDelete(),
        initiator=T.MultiMeasurementInitiator(np.zeros(5), np.eye(5)),
        imm=T.IMM(
            [T.constant_velocity_turn_rate(q, qw), T.ConstantTurn(qc, qt, predictor)], M2, mu0
        ),
        symmetric_covariance=False,  # Stone Soup's KalmanUpdater: P − K S Kᵀ as it comes
    )
    tr.add_track(x0, p0, 0.0)
    for k, (z, (wx, wp, wmu)) in enumerate(zip(zs, want, strict=True)):
        got = tr.step((k + 1) * dt, z.reshape(1, 2))
        np.testing.assert_allclose(got.states[0], wx, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(got.covariances[0], wp, rtol=1e-9, atol=1e-11)
        np.testing.assert_allclose(got.mode_probabilities[0], wmu, rtol=1e-9, atol=1e-12)
    # The turn (from scan 10) is seen: the CT mode gains weight and ω takes the turn's sign.
    ct = [w[2][1] for w in want]
    assert np.mean(ct[20:]) > np.mean(ct[2:10]) and np.sign(want[-1][0][4]) == np.sign(omega)


def test_stonesoup_ekf_turn_rate_column_is_off_near_zero():
    """Why the oracle above differentiates exactly: at ω = 0 the analytic ∂x'/∂ω is −T²/2 ẏ
    (ours, read back from the native EKF), Stone Soup's forward difference is ~10 % off."""
    from stonesoup.types.state import State

    x, dt = np.array([0.0, 6.0, 0.0, 2.0, 0.0]), 2.0
    ss = ss_ct(0.0, 0.0).jacobian(
        State(x.reshape(5, 1).copy()), time_interval=timedelta(seconds=dt)
    )
    assert abs(ss[0, 4] + 4.0) > 0.4
    np.testing.assert_allclose(native_jacobian(x, dt)[:, 4], [-4.0, -4.0, 12.0, 12.0, 1.0])


# ---- properties of whole runs ----


def ct_tracker(association, predictor="ukf", existence=None, sensors=None, cv=True):
    """A 5-D tracker whose IMM is CV5 + CT (or CT alone with `cv=False`)."""
    cv5 = T.constant_velocity_turn_rate(0.05, 1e-6)
    ct = T.ConstantTurn(0.2, 1e-4, predictor)
    return T.Tracker(
        motion_model=cv5,
        sensors=sensors or [T.Sensor.position(3.0, ndim_state=5)],
        association=association,
        deleter=T.StepsSinceUpdate(5),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(5), np.diag([0, 50.0, 0, 50.0, 0.02]), min_points=3, missed_distance=3.0
        ),
        imm=T.IMM([cv5, ct], M2) if cv else T.IMM([ct], [[1.0]]),
        existence=existence,
    )


@settings(max_examples=12, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    omega=st.floats(0.04, 0.15).map(lambda w: round(w, 3)),
    sign=st.sampled_from([1.0, -1.0]),
    speed=st.floats(4.0, 10.0),
    predictor=st.sampled_from(["ekf", "ukf"]),
)
def test_constant_rate_turn_is_tracked_and_omega_converges(seed, omega, sign, speed, predictor):
    w = sign * omega
    truth, zs = turning_plots(seed, w, speed=speed, n=70, turn_from=5)
    for cv in (False, True):
        tr = ct_tracker(T.GNN(missed_distance=5.0), predictor, cv=cv)
        est = []
        for k, z in enumerate(zs):
            got = tr.step(float(k), z.reshape(1, 2))
            if len(got):
                np.testing.assert_allclose(got.mode_probabilities.sum(axis=1), 1.0, atol=1e-12)
                for c in got.covariances:
                    np.testing.assert_allclose(c, c.T, rtol=0, atol=1e-9 * np.abs(c).max())
                    assert np.linalg.eigvalsh(c).min() > 0
                est.append((k, got.states[0]))
        assert len(tr.tracks) == 1 and len(tr.deleted_track_ids) == 0
        late = np.array([x for k, x in est if k >= 45])
        assert np.hypot(*(late[-1][[0, 2]] - truth[-1][[0, 2]])) < 10.0
        wh = np.median(late[:, 4])
        if not cv:
            # The CT filter's turn rate converges to the true rate (plots σ 3 m, speeds
            # 4-10 m/s, radii 27-250 m).
            assert abs(wh - w) < 0.1 * abs(w) + 0.005, wh
        else:
            # In the IMM the CV mode's ω (a random walk there, correlated with the positions
            # through mixing) absorbs part of the CV prediction's lag in the turn, and the
            # combined ω is biased outwards, most at slow, tight turns (0.04 rad/s at 4 m/s:
            # 0.108): the sign is right and the size within a factor of 3.
            assert 0.5 * abs(w) < wh * np.sign(w) < 3 * abs(w), wh


@pytest.mark.parametrize("predictor", ["ekf", "ukf"])
def test_jpda_with_constant_turn_modes_in_clutter(predictor):
    rng = np.random.default_rng(5)
    t1, z1 = turning_plots(1, 0.08, speed=6.0, n=50, turn_from=5)
    t2, z2 = turning_plots(2, -0.06, speed=5.0, n=50, turn_from=5)
    z2 = z2 + np.array([0.0, 150.0])
    t2[:, 2] += 150.0
    ex = T.Existence(survival=0.999, initial=0.9, delete=0.01)
    tr = ct_tracker(T.JPDA(0.9, 0.99, 1e-5), predictor, existence=ex)
    for k in range(50):
        z = [p for p in (z1[k], z2[k]) if rng.random() < 0.9]
        z += list(rng.uniform(-150, 250, (rng.poisson(4), 2)))
        got = tr.step(float(k), np.array(z).reshape(-1, 2))
        assert got.states.shape[1:] == (5,) and got.covariances.shape[1:] == (5, 5)
        if len(got):
            np.testing.assert_allclose(got.mode_probabilities.sum(axis=1), 1.0, atol=1e-12)
            assert ((got.existence > 0) & (got.existence <= 1)).all()
            for c in got.covariances:
                assert np.linalg.eigvalsh((c + c.T) / 2).min() > 0
    # Each target has a track ending near it, its turn rate of the right sign and size (the
    # IMM's outward bias: see test_constant_rate_turn_is_tracked_and_omega_converges).
    for truth, w in ((t1, 0.08), (t2, -0.06)):
        d = np.hypot(*(got.states[:, [0, 2]] - truth[-1][[0, 2]]).T)
        i = int(np.argmin(d))
        assert d[i] < 10.0
        assert 0.5 * abs(w) < got.states[i, 4] * np.sign(w) < 3 * abs(w)
    # A pickled copy continues bit-exactly (IMM state of the CT modes included).
    copy = pickle.loads(pickle.dumps(tr))
    z = np.array([z1[-1] + [3.0, 3.0], z2[-1] + [3.0, 3.0]])
    a, b = tr.step(50.0, z), copy.step(50.0, z)
    assert (a.states == b.states).all() and (a.mode_probabilities == b.mode_probabilities).all()


def test_radar_bearing_range_on_the_five_state():
    """A range–bearing sensor maps [0, 2] of the 5-D state; the CT IMM follows a turn seen by
    a radar on a moving own ship."""
    radar = T.Sensor.bearing_range(noise_std=(np.deg2rad(0.5), 3.0), ndim_state=5)
    tr = ct_tracker(T.JPDA(0.9, 0.99, 1e-6), "ukf", sensors=[radar])
    truth, _ = turning_plots(3, 0.07, speed=6.0, n=60, sigma=0.0, turn_from=5)
    rng = np.random.default_rng(0)
    for k, x in enumerate(truth):
        own = np.array([-300.0 + 2.0 * k, -200.0])
        d = x[[0, 2]] - own
        z = [[np.arctan2(d[1], d[0]) + rng.normal(0, 0.008), np.hypot(*d) + rng.normal(0, 3)]]
        got = tr.step(float(k), z, [0], origins=own.reshape(1, 2))
    assert len(got) == 1
    assert np.hypot(*(got.states[0, [0, 2]] - truth[-1][[0, 2]])) < 10.0
    assert 0.035 < got.states[0, 4] < 0.21


# ---- configuration, the command and bad input ----


def test_toml_preset_with_constant_turn_writes_the_turn_rate(tmp_path):
    import csv

    from typer.testing import CliRunner

    from usvfast.cli import app
    from usvfast.trackcmd import tracker_from_config

    truth, zs = turning_plots(4, 0.08, n=40)
    plots = tmp_path / "plots.csv"
    plots.write_text(
        "time,north,east\n"
        + "".join(f"{k}.0,{float(z[0])!r},{float(z[1])!r}\n" for k, z in enumerate(zs))
    )
    cfg = tmp_path / "ct.toml"
    cfg.write_text(
        "[tracker]\nq = 0.05\nsigma = 3.0\nprob_detect = 0.9\nclutter_density = 1e-5\n"
        "[tracker.initiator]\nmissed_distance = 3.0\nprior_velocity_var = 50.0\n"
        "prior_turn_rate_var = 0.02\n"
        "[tracker.imm]\nct_q = [0.2]\nct_q_turn = [1e-4]\ncv_q_turn = 1e-6\n"
        'ct_predictor = "ekf"\nstay = 0.95\n'
    )
    out = tmp_path / "out"
    r = CliRunner().invoke(app, ["track", str(plots), "--config", str(cfg), "--out", str(out)])
    assert r.exit_code == 0, r.output
    with (out / "tracks.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert rows and list(rows[0])[-2:] == ["turn_rate", "var_turn_rate"]
    assert 0.04 < float(rows[-1]["turn_rate"]) < 0.24
    last = rows[-1]
    assert np.hypot(float(last["north"]) - truth[-1][0], float(last["east"]) - truth[-1][2]) < 10
    # The same table builds a 5-D tracker.
    import tomllib

    tr = tracker_from_config(tomllib.loads(cfg.read_text())["tracker"])
    assert tr.step(0.0, [[1.0, 2.0]]).states.shape == (0, 5)


@pytest.mark.parametrize(
    "imm,match",
    [
        ({"ct_q": [1.0], "turn_rates": [0.1]}, "cannot share"),
        ({"ct_q": [1.0, 2.0], "ct_q_turn": [1e-3, 1e-3, 1e-3]}, "ct_q_turn"),
        ({"ct_q": "x"}, "ct_q"),
        ({"turn_rates": [0.1], "ct_q_turn": [1e-3]}, "needs ct_q"),
        ({"ct_q": [1.0], "turn_q": 2.0}, r"turn_q.*needs turn_rates"),
        ({"ct_q": [1.0], "ct_predictor": "pf"}, "predictor"),
        ({"ct_q": [-1.0]}, "q"),
    ],
)
def test_bad_toml_imm_table(imm, match):
    from usvfast.trackcmd import tracker_from_config

    with pytest.raises(ValueError, match=match):
        tracker_from_config({"imm": imm})


def test_bad_constant_turn_is_named():
    with pytest.raises(ValueError, match=r"^q:"):
        T.ConstantTurn(-1.0, 1e-3)
    with pytest.raises(ValueError, match=r"^q:"):
        T.ConstantTurn((1.0, 2.0, 3.0), 1e-3)
    with pytest.raises(TypeError, match=r"^q:"):
        T.ConstantTurn("a", 1e-3)
    with pytest.raises(ValueError, match=r"^q_turn:"):
        T.ConstantTurn(1.0, float("nan"))
    with pytest.raises(TypeError, match=r"^q_turn:"):
        T.ConstantTurn(1.0, True)
    with pytest.raises(ValueError, match=r"^predictor:"):
        T.ConstantTurn(1.0, 1e-3, "pf")
    with pytest.raises(ValueError, match=r"^alpha:"):
        T.ConstantTurn(1.0, 1e-3, "ukf", alpha=0.0)
    with pytest.raises(ValueError, match=r"^kappa:"):
        T.ConstantTurn(1.0, 1e-3, "ukf", kappa=-5.0)
    with pytest.raises(ValueError, match=r"^q_turn:"):
        T.constant_velocity_turn_rate(1.0, -1.0)
    # A turn-rate mode in a 4-D tracker, a 4-D mode beside it, and an object that only looks
    # like a ConstantTurn reach the core's checks, which name the mode.
    four = dict(
        motion_model=constant_velocity_2d(0.1),
        sensors=[T.Sensor.position(1.0)],
        association=T.GNN(),
        deleter=T.NeverDelete(),
        initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
    )
    with pytest.raises(ValueError, match=r"imm\.modes\[1\]"):
        T.Tracker(**four, imm=T.IMM([constant_velocity_2d(0.1), T.ConstantTurn(1, 0)], np.eye(2)))
    with pytest.raises(ValueError, match=r"imm\.modes\[0\]"):
        single_mode_tracker(T.KnownTurnRate(0.1, 0.1))

    class Fake:
        q, q_turn, predictor, alpha, beta, kappa = 1.0, 1e-3, "particles", 0.5, 2.0, None

    with pytest.raises(ValueError, match=r"imm\.modes\[0\]\.predictor"):
        single_mode_tracker(Fake())
    Fake.predictor, Fake.q_turn = "ekf", -1.0
    with pytest.raises(ValueError, match=r"imm\.modes\[0\]"):
        single_mode_tracker(Fake())
