"""usvfast.radar.calibration: tracker parameters from a calibration run. Each estimator recovers
the parameters of synthetic data drawn from its own model within stated tolerances; the
mixture's expectation-maximisation reaches the maximum that SciPy's optimiser finds on the same
likelihood (written independently with scipy.stats); invariances under turning the scene and
scaling speeds; bad input raises errors naming the argument."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import optimize, stats

from usvfast.radar import cv_noise_mixture, plot_statistics, turn_noise


def radar_scene(sigma, pd, lam, n=3000, seed=0, half_width=600.0):
    """n scans of a target on a circle: its plot N(truth, sigma² I) with probability pd, and
    Poisson clutter of density lam (per m² per scan) uniform over a square of side
    2 half_width about it. Returns (plots, scan_index, reference)."""
    rng = np.random.default_rng(seed)
    k = np.arange(n)
    ref = np.stack([800 * np.cos(k / 50), 800 * np.sin(k / 50)], axis=1)
    plots, si = [], []
    for i in k:
        m = rng.poisson(lam * (2 * half_width) ** 2)
        rows = list(ref[i] + rng.uniform(-half_width, half_width, (m, 2)))
        if rng.random() < pd:
            rows.insert(int(rng.integers(0, m + 1)), ref[i] + rng.normal(0, sigma, 2))
        plots += rows
        si += [i] * len(rows)
    return np.array(plots).reshape(-1, 2), np.array(si, dtype=np.int64), ref


@pytest.mark.parametrize(
    ("sigma", "pd", "lam"), [(12.0, 0.8, 1e-5), (8.0, 0.95, 3e-5), (15.0, 0.6, 2e-6)]
)
def test_plot_statistics_recover_the_scene(sigma, pd, lam):
    p, si, ref = radar_scene(sigma, pd, lam)
    s = plot_statistics(p, si, ref)
    # Tolerances: a few standard errors for 3,000 scans (the Rayleigh median's relative
    # error ~1.2 / sqrt(n P_D); the clutter count's ~1 / sqrt(n λ π R²)).
    assert s.sigma_m == pytest.approx(sigma, rel=0.05)
    assert s.prob_detect == pytest.approx(pd, abs=0.025)
    assert s.clutter_density == pytest.approx(lam, rel=0.15 if lam > 5e-6 else 0.35)
    assert s.scans == 3000
    assert s.pairs >= round(3000 * pd * 0.95)


def test_plot_statistics_correct_for_clutter_in_the_gate():
    # With dense clutter the fraction of scans with a plot in the gate overstates P_D by
    # (1 − P_D) P_c; the joint moment fit removes it.
    p, si, ref = radar_scene(10.0, 0.7, 6e-5, seed=4)
    s = plot_statistics(p, si, ref)
    raw = s.pairs / s.scans
    p_c = 1 - np.exp(-6e-5 * np.pi * 60**2)
    assert raw == pytest.approx(0.7 + 0.3 * p_c, abs=0.02)  # ~0.89: far from 0.7
    assert s.prob_detect == pytest.approx(0.7, abs=0.025)


def test_plot_statistics_scans_and_missing_reference():
    p, si, ref = radar_scene(10.0, 0.9, 1e-5, n=400, seed=2)
    part = plot_statistics(p, si, ref, scans=np.arange(100, 300))
    assert part.scans == 200
    sel = (si >= 100) & (si < 300)
    alone = plot_statistics(p[sel], si[sel] - 100, ref[100:300])
    assert part == alone
    ref2 = ref.copy()
    ref2[:200] = np.nan  # scans without a reference are not used
    assert plot_statistics(p, si, ref2) == plot_statistics(p, si, ref, scans=np.arange(200, 400))


@settings(max_examples=25, deadline=None)
@given(st.floats(-np.pi, np.pi), st.floats(-1e3, 1e3), st.floats(-1e3, 1e3))
def test_plot_statistics_do_not_depend_on_the_frame(angle, dn, de):
    p, si, ref = radar_scene(10.0, 0.8, 2e-5, n=150, seed=5)
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]])
    a = plot_statistics(p, si, ref)
    b = plot_statistics(p @ R.T + [dn, de], si, ref @ R.T + [dn, de])
    assert (a.pairs, a.scans) == (b.pairs, b.scans)
    assert b.sigma_m == pytest.approx(a.sigma_m, rel=1e-9)
    assert b.prob_detect == pytest.approx(a.prob_detect, rel=1e-9, abs=1e-12)
    assert b.clutter_density == pytest.approx(a.clutter_density, rel=1e-9, abs=1e-18)


def cv_mixture_track(q, weight, n=4000, seed=0):
    """Times and velocities whose increments are N(0, q_m dt I₂), mode m drawn independently
    per interval (quiet with probability weight), dt uniform in [2, 3] s."""
    rng = np.random.default_rng(seed)
    dt = rng.uniform(2.0, 3.0, n)
    qm = np.where(rng.random(n) < weight, q[0], q[1])
    dv = rng.normal(size=(n, 2)) * np.sqrt(qm * dt)[:, None]
    t = np.concatenate([[0.0], np.cumsum(dt)])
    v = np.array([5.0, 3.0]) + np.concatenate([np.zeros((1, 2)), np.cumsum(dv, axis=0)])
    return t, v


@pytest.mark.parametrize(("q", "w"), [((0.05, 5.0), 0.7), ((0.2, 8.0), 0.9)])
def test_cv_mixture_recovers_the_modes(q, w):
    t, v = cv_mixture_track(q, w)
    m = cv_noise_mixture(t, v)
    assert m.q_quiet == pytest.approx(q[0], rel=0.08)
    assert m.q_high == pytest.approx(q[1], rel=0.12)
    assert m.weight_quiet == pytest.approx(w, abs=0.03)
    assert m.intervals == 4000


def test_cv_mixture_is_the_maximum_scipy_finds():
    # The same likelihood written with scipy.stats and maximised by Nelder-Mead from another
    # start: EM reaches the same parameters and log-likelihood.
    t, v = cv_mixture_track((0.1, 3.0), 0.6, n=600, seed=3)
    dt, dv = np.diff(t), np.diff(v, axis=0)

    def nll(z):
        q1, q2, w = np.exp(z[0]), np.exp(z[1]), 1 / (1 + np.exp(-z[2]))
        a = stats.norm.logpdf(dv, scale=np.sqrt(q1 * dt)[:, None]).sum(1)
        b = stats.norm.logpdf(dv, scale=np.sqrt(q2 * dt)[:, None]).sum(1)
        return -np.logaddexp(np.log(w) + a, np.log1p(-w) + b).sum()

    res = optimize.minimize(
        nll, [np.log(0.5), np.log(1.0), 0.0], method="Nelder-Mead",
        options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 20000, "maxfev": 40000},
    )  # fmt: skip
    m = cv_noise_mixture(t, v)
    assert m.log_likelihood == pytest.approx(-res.fun, abs=1e-6)
    assert m.q_quiet == pytest.approx(np.exp(res.x[0]), rel=1e-4)
    assert m.q_high == pytest.approx(np.exp(res.x[1]), rel=1e-4)
    assert m.weight_quiet == pytest.approx(1 / (1 + np.exp(-res.x[2])), rel=1e-4)


def test_cv_mixture_of_one_mode_gives_its_intensity():
    # One mode: both components near the single-mode maximum-likelihood q = mean(|Δv|²/dt)/2.
    t, v = cv_mixture_track((0.5, 0.5), 1.0, n=3000, seed=1)
    m = cv_noise_mixture(t, v)
    q_ml = np.mean(np.sum(np.diff(v, axis=0) ** 2, 1) / np.diff(t)) / 2
    assert q_ml == pytest.approx(0.5, rel=0.05)
    assert m.q_quiet == pytest.approx(q_ml, rel=0.15)
    assert m.q_high == pytest.approx(q_ml, rel=0.15)


def turning_tracks(q, q_turn, tracks=250, scans=12, dt=2.5, speed=10.0, h=0.01, seed=0):
    """Velocities of the coordinated turn with a turn-rate random walk, simulated in steps of
    h seconds (v ← R(ω h) v + N(0, q h I₂), ω ← ω + N(0, q_turn h)) and sampled every dt
    seconds; `tracks` independent tracks joined with a NaN row between them."""
    rng = np.random.default_rng(seed)
    sub = round(dt / h)
    hd = rng.uniform(0, 2 * np.pi, tracks)
    v = speed * np.stack([np.cos(hd), np.sin(hd)], 1)
    w = rng.normal(0, 0.05, tracks)
    out = [v.copy()]
    for _ in range(scans):
        for _ in range(sub):
            c, s = np.cos(w * h), np.sin(w * h)
            v = np.stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1]], 1)
            v += rng.normal(0, np.sqrt(q * h), v.shape)
            w += rng.normal(0, np.sqrt(q_turn * h), tracks)
        out.append(v.copy())
    vel = np.stack(out, 1)  # (tracks, scans + 1, 2)
    vel = np.concatenate([vel, np.full((tracks, 1, 2), np.nan)], 1).reshape(-1, 2)
    return np.arange(len(vel)) * dt, vel


def test_turn_noise_recovers_both_intensities():
    # The Joyride preset's sizes: q 0.17 m²/s³, q_turn 6.4e-4 rad²/s³, 10 m/s, 2.5 s scans
    # (3,000 intervals; over 8 seeds the estimates have a spread of 3 % and 8 %).
    t, v = turning_tracks(0.17, 6.4e-4)
    n = turn_noise(t, v)
    assert n.intervals == 250 * 12
    assert n.rate_increments == 250 * 11
    assert n.q == pytest.approx(0.17, rel=0.08)
    assert n.q_turn == pytest.approx(6.4e-4, rel=0.2)
    # Without the cross-track term the rate increments would give more than twice q_turn.
    dt = np.diff(t)
    s = np.hypot(*v.T)
    w = np.arctan2(v[:-1, 0] * v[1:, 1] - v[:-1, 1] * v[1:, 0], np.sum(v[:-1] * v[1:], 1)) / dt
    dw = np.diff(w)
    ok = np.isfinite(dw)
    naive = np.sum(dw[ok] ** 2) / np.sum((dt[:-1] + dt[1:])[ok] / 3)
    assert naive > 2 * 6.4e-4
    assert s[np.isfinite(s)].min() > 1.0


def test_turn_noise_of_straight_runs_is_zero_turn_noise():
    t, v = turning_tracks(0.3, 0.0, seed=2)
    n = turn_noise(t, v)
    assert n.q == pytest.approx(0.3, rel=0.08)
    # True value 0: the moment equation gives 0-1.3e-4 over 8 seeds (0 when floored), against
    # the ~7e-3 that the rate increments would give without their cross-track term.
    assert n.q_turn < 1.5e-4


@settings(max_examples=20, deadline=None)
@given(st.floats(0.2, 5.0), st.floats(-np.pi, np.pi))
def test_turn_noise_scales_with_speed(c, angle):
    # Speeds times c: velocity noise times c², turn-rate noise unchanged; a turned frame: none.
    t, v = turning_tracks(0.2, 3e-4, tracks=20, scans=8, seed=6)
    a = turn_noise(t, v, min_speed_mps=0.01)
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    b = turn_noise(t, c * v @ R.T, min_speed_mps=0.01 * c)
    assert b.q == pytest.approx(c**2 * a.q, rel=1e-9)
    assert b.q_turn == pytest.approx(a.q_turn, rel=1e-7, abs=1e-15)
    m1, m2 = cv_noise_mixture(t, v), cv_noise_mixture(t, c * v @ R.T)
    # (EM stops at a relative log-likelihood gain of 1e-12: equal to its convergence)
    assert m2.q_quiet == pytest.approx(c**2 * m1.q_quiet, rel=1e-4)
    assert m2.q_high == pytest.approx(c**2 * m1.q_high, rel=1e-4)


def test_bad_input_names_the_argument():
    p, si, ref = radar_scene(10.0, 0.9, 1e-5, n=50)
    with pytest.raises(ValueError, match="plots"):
        plot_statistics(p[:, :1], si, ref)
    with pytest.raises(ValueError, match="scan_index"):
        plot_statistics(p, si[:-1], ref)
    with pytest.raises(TypeError, match="scan_index"):
        plot_statistics(p, si.astype(float), ref)
    with pytest.raises(ValueError, match="scan_index"):
        plot_statistics(p, si + 1, ref)
    with pytest.raises(ValueError, match="gate_m"):
        plot_statistics(p, si, ref, gate_m=0.0)
    with pytest.raises(ValueError, match="clutter_radius_m"):
        plot_statistics(p, si, ref, clutter_radius_m=50.0)
    with pytest.raises(TypeError, match="scans"):
        plot_statistics(p, si, ref, scans=[0.5, 1.5])
    with pytest.raises(ValueError, match="scans"):
        plot_statistics(p, si, ref, scans=[0, 50])
    with pytest.raises(ValueError, match="reference"):
        plot_statistics(p, si, ref + 1e4)  # no plot within the gate
    bad = p.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match="plots"):
        plot_statistics(bad, si, ref)
    t, v = cv_mixture_track((0.1, 1.0), 0.5, n=20)
    with pytest.raises(ValueError, match="times"):
        cv_noise_mixture(t[::-1], v)
    with pytest.raises(ValueError, match="times"):
        turn_noise(np.where(np.arange(len(t)) == 3, np.nan, t), v)
    with pytest.raises(ValueError, match="velocities"):
        cv_noise_mixture(t, v[:, :1])
    with pytest.raises(ValueError, match="velocities"):
        turn_noise(t, np.where(np.arange(len(t))[:, None] == 2, np.inf, v))
    with pytest.raises(ValueError, match="velocities"):
        cv_noise_mixture(t[:4], v[:4])  # 3 intervals
    with pytest.raises(ValueError, match="velocities"):
        cv_noise_mixture(t, np.ones_like(v))  # no velocity change
    with pytest.raises(ValueError, match="velocities"):
        cv_noise_mixture(t, v * 1e200)  # overflow
    with pytest.raises(ValueError, match="velocities"):
        turn_noise(t, v * 1e-3)  # every speed below min_speed_mps
    with pytest.raises(ValueError, match="min_speed_mps"):
        turn_noise(t, v, min_speed_mps=-1.0)
    with pytest.raises(ValueError, match="tol"):
        cv_noise_mixture(t, v, tol=0.0)
    with pytest.raises(ValueError, match="max_iter"):
        cv_noise_mixture(t, v, max_iter=0)
    with pytest.raises(TypeError, match="times"):
        cv_noise_mixture("abc", v)
