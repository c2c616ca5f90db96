"""Radar ↔ AIS association primitives: covariance intersection against Stone Soup's, the
optimal ω against a dense search, the χ² track-to-track statistic against scipy, the §1.2
identity test, and the sliding window's hysteresis (accept after N, keep through a close
pass of a decoy, keep through stale AIS, let go when the vessels separate)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from usvfast.fusion import Chi2Test, JCost, WindowAssociator, covariance_intersection, same_object


def _spd(rng, n=4):
    a = rng.standard_normal((n, n))
    return a @ a.T + n * np.eye(n)


@pytest.mark.parametrize("seed", range(5))
def test_covariance_intersection_equals_stonesoup(seed):
    from stonesoup.mixturereducer.gaussianmixture import CovarianceIntersection
    from stonesoup.types.state import GaussianState

    rng = np.random.default_rng(seed)
    x1, x2 = rng.standard_normal(4), rng.standard_normal(4)
    p1, p2 = _spd(rng), 5 * _spd(rng)
    w = float(rng.uniform(0.05, 0.95))
    x, p, w_out = covariance_intersection(x1, p1, x2, p2, omega=w)
    ref = CovarianceIntersection.merge_components(
        GaussianState(x1.reshape(-1, 1), p1),
        GaussianState(x2.reshape(-1, 1), p2),
        weights=[w, 1 - w],
    )
    assert w_out == w
    np.testing.assert_allclose(x, np.asarray(ref.state_vector, float).ravel(), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(p, np.asarray(ref.covar, float), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("seed", range(5))
def test_covariance_intersection_omega_minimises_the_determinant(seed):
    rng = np.random.default_rng(seed)
    p1, p2 = _spd(rng), _spd(rng) * rng.uniform(0.1, 10)
    _, p, w = covariance_intersection(np.zeros(4), p1, np.ones(4), p2)
    grid = np.linspace(0, 1, 2001)
    dets = [
        np.linalg.det(np.linalg.inv(g * np.linalg.inv(p1) + (1 - g) * np.linalg.inv(p2)))
        for g in grid
    ]
    assert np.linalg.det(p) <= min(dets) * (1 + 1e-6)
    assert abs(w - grid[int(np.argmin(dets))]) < 2e-3
    # Consistent whatever the correlation: P >= each input's "share" (P^-1 <= P1^-1 + P2^-1).
    info = np.linalg.inv(p1) + np.linalg.inv(p2) - np.linalg.inv(p)
    assert np.linalg.eigvalsh(info).min() > -1e-9


def test_covariance_intersection_bad_input():
    with pytest.raises(ValueError, match="omega"):
        covariance_intersection(np.zeros(2), np.eye(2), np.zeros(2), np.eye(2), omega=1.5)
    with pytest.raises(ValueError, match="shapes"):
        covariance_intersection(np.zeros(2), np.eye(2), np.zeros(3), np.eye(3))


def test_chi2_sample_is_the_mahalanobis_distance_and_gate_is_scipys():
    rng = np.random.default_rng(3)
    xr, xa, pr, pa = rng.standard_normal(4), rng.standard_normal(4), _spd(rng), _spd(rng)
    d = xr - xa
    assert Chi2Test().sample(xr, pr, xa, pa) == pytest.approx(d @ np.linalg.inv(pr + pa) @ d)
    t = Chi2Test(p_gate=0.95)
    assert t.cost([2.0, 3.0]) == pytest.approx(5.0 / chi2.ppf(0.95, 8))
    # Under H0 (same target) the window statistic is accepted ~95 % of the time.
    s = [t.cost(rng.chisquare(4, size=8)) < 1.0 for _ in range(4000)]
    assert 0.93 < np.mean(s) < 0.97
    with pytest.raises(ValueError, match="p_gate"):
        Chi2Test(p_gate=0.999, p_release=0.9)


def test_jcost_uses_absolute_differences():
    j = JCost(k1=1.0, k2=1.0, k3=1.0, j_set=1.0)
    a = np.array([0.0, 5.0, 0.0, 0.0])
    # Signed sums would cancel: +10 m then -10 m, +1 m/s then -1 m/s.
    s1 = j.sample(np.array([10.0, 6.0, 0.0, 0.0]), None, a, None)
    s2 = j.sample(np.array([-10.0, 4.0, 0.0, 0.0]), None, a, None)
    assert j.cost([s1, s2]) == pytest.approx(11.0)
    assert j.sample(np.array([0, 0, 0, 5.0]), None, a, None)[2] == pytest.approx(90.0)
    with pytest.raises(ValueError, match="release"):
        JCost(release=0.5)


def test_same_object():
    assert same_object((0, 0), (5, 0), 0.0, (51, 2), 10.0, t_d=30.0, radius=5.0)
    assert not same_object((0, 0), (5, 0), 0.0, (60, 0), 10.0, t_d=30.0, radius=5.0)
    assert not same_object((0, 0), (5, 0), 0.0, (50, 0), 40.0, t_d=30.0, radius=5.0)
    with pytest.raises(ValueError, match="radius"):
        same_object((0, 0), (5, 0), 0.0, (50, 0), 10.0, t_d=30.0, radius=-1.0)


def _state(n, e, vn, ve):
    return np.array([n, vn, e, ve], float)


def test_window_hysteresis_decoy_and_separation():
    cov = np.tile(np.diag([100.0, 1.0, 100.0, 1.0]), (1, 1, 1))
    acov = np.tile(np.diag([25.0, 0.1, 25.0, 0.1]), (2, 1, 1))
    for method in (JCost(), Chi2Test()):
        w = WindowAssociator(method, window=4)
        hist = []
        for k in range(40):
            t = 10.0 * k
            track = _state(5 * t, 0.0, 5.0, 0.0)
            ais = _state(5 * t + 3, 2.0, 5.0, 0.0)
            # A decoy crossing at right angles passes within 10 m at k = 20.
            decoy = _state(5 * 200.0 + 10, 5.0 * (t - 200.0), 0.0, 5.0)
            if k >= 30:  # the AIS vessel turns away: separation
                ais = _state(5 * t + 3 + 40 * (k - 29), 2.0 + 40 * (k - 29), 5.0, 4.0)
            fresh = [k % 7 != 3, True]  # some stale AIS scans
            pairs = w.update([1], track[None], cov, [111, 222], np.stack([ais, decoy]), acov, fresh)
            hist.append(pairs.get(1))
        name = type(method).__name__
        assert hist[:3] == [None] * 3, name  # a full window is needed
        assert all(h == 111 for h in hist[4:30]), (name, hist)  # kept through the decoy's pass
        assert hist[-1] is None, name  # released after separating
        assert 222 not in hist, name


def test_window_one_to_one_and_bad_input():
    w = WindowAssociator(JCost(), window=1)
    cov = np.tile(np.eye(4), (2, 1, 1))
    tr = np.stack([_state(0, 0, 5, 0), _state(5, 0, 5, 0)])
    pairs = w.update([1, 2], tr, cov, [7], tr[:1], cov[:1])
    assert pairs == {1: 7}
    with pytest.raises(TypeError, match="method"):
        WindowAssociator("j")
    with pytest.raises(ValueError, match="window"):
        WindowAssociator(JCost(), window=0)
    with pytest.raises(ValueError, match="fresh"):
        w.update([1], tr[:1], cov[:1], [7], tr[:1], cov[:1], fresh=[True, False])
