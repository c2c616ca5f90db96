"""The ANIS band corrected for NIS correlated within tracks (`variance_inflation`,
`average_consistency(groups=)`): equal to statsmodels' panel HAC variance of a mean, and a band
that holds its confidence on correlated samples where the plain one does not."""

from __future__ import annotations

import numpy as np
import pytest
import statsmodels.api as sm
from hypothesis import given, settings
from hypothesis import strategies as st

from usvfast._core import DimensionError
from usvfast.metrics.consistency import average_consistency, chi2_band, variance_inflation


def _statsmodels_factor(v: np.ndarray, groups: np.ndarray, lags: int) -> float:
    """Var(mean) by statsmodels' Newey-West panel HAC (Bartlett, no small-sample correction)
    over that of independent samples."""
    fit = sm.OLS(v, np.ones(len(v))).fit(
        cov_type="hac-panel",
        cov_kwds={"groups": groups, "maxlags": lags, "use_correction": False},
    )
    e = v - v.mean()
    return float(fit.bse[0] ** 2 * len(v) ** 2 / (e @ e))


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    tracks=st.integers(1, 12),
    length=st.integers(3, 60),
    lags=st.integers(0, 12),
    rho=st.floats(-0.5, 0.95),
)
def test_equals_statsmodels_panel_hac(seed, tracks, length, lags, rho):
    rng = np.random.default_rng(seed)
    lags = min(lags, length - 1)  # statsmodels takes no lag as long as a track
    v, g = [], []
    for k in range(tracks):
        x = np.empty(length)
        x[0] = rng.normal()
        for i in range(1, length):
            x[i] = rho * x[i - 1] + rng.normal()
        v.append(x + rng.normal())  # each track its own level too
        g.append(np.full(length, k))
    v, g = np.concatenate(v), np.concatenate(g)
    want = max(1.0, _statsmodels_factor(v, g, lags))
    assert variance_inflation(v, g, lags) == pytest.approx(want, rel=1e-9)
    # the rows of the tracks interleaved in time give the same factor
    order = np.argsort(np.tile(np.arange(length), tracks), kind="stable")
    assert variance_inflation(v[order], g[order], lags) == pytest.approx(want, rel=1e-9)


def test_independent_samples_need_no_correction():
    rng = np.random.default_rng(1)
    f = [variance_inflation(rng.chisquare(2, 600), np.repeat(np.arange(10), 60)) for _ in range(50)]
    assert 1.0 <= np.mean(f) < 1.1


def _correlated_nis(rng: np.random.Generator, rho: float, tracks: int, length: int) -> np.ndarray:
    """NIS |ν|² of unit 2-d Gaussian innovations that follow an AR(1) with coefficient rho in
    each track: χ²(2) each, as from a consistent filter, but correlated in time."""
    nu = np.empty((tracks, length, 2))
    nu[:, 0] = rng.normal(size=(tracks, 2))
    w = np.sqrt(1 - rho * rho)
    for i in range(1, length):
        nu[:, i] = rho * nu[:, i - 1] + w * rng.normal(size=(tracks, 2))
    return (nu**2).sum(-1).ravel()


def test_corrected_band_holds_its_confidence_on_correlated_nis():
    rng = np.random.default_rng(7)
    groups = np.repeat(np.arange(10), 60)
    plain, corrected = [], []
    for _ in range(400):
        c = average_consistency(_correlated_nis(rng, 0.6, 10, 60), 2, groups=groups)
        plain.append(c.inside)
        corrected.append(c.corrected_inside)
    # the plain band of 600 independent samples misses a consistent filter's ANIS far more
    # often than 5 %; the corrected one about as often as it should (its lags, 5 by Newey and
    # West's rule, leave a little of the correlation out)
    # (seven seeds of this set-up: plain 0.78-0.87, corrected 0.885-0.95)
    assert np.mean(plain) < 0.88
    assert np.mean(corrected) > 0.9
    assert np.mean(corrected) - np.mean(plain) > 0.05


def test_consistency_fields_and_band():
    rng = np.random.default_rng(3)
    nis, groups = _correlated_nis(rng, 0.8, 8, 50), np.repeat(np.arange(8), 50)
    c = average_consistency(nis, 2, gate=None, groups=groups)
    assert c.variance_factor == variance_inflation(nis, groups) > 1.5
    lo, hi = chi2_band(2, 400, variance_factor=c.variance_factor)
    assert (c.corrected_lower, c.corrected_upper) == (lo, hi)
    assert c.corrected_lower < c.lower < c.upper < c.corrected_upper
    d = average_consistency(nis, 2).as_dict()
    assert d["variance_factor"] is None and d["corrected_inside"] is None
    # a factor of 1 gives the gamma law of the plain band's moments: the χ² band to 1e-3
    assert chi2_band(2, 400, gate=1.0, variance_factor=1.0) == pytest.approx(
        chi2_band(2, 400), abs=2e-3
    )


def test_bad_input_is_named():
    with pytest.raises(DimensionError, match="groups"):
        variance_inflation(np.ones(4), np.zeros(3))
    with pytest.raises(ValueError, match="max_lag"):
        variance_inflation(np.ones(4), np.zeros(4), -1)
    with pytest.raises(ValueError, match="max_lag"):
        variance_inflation(np.ones(1), np.zeros(1), 2.5)
    with pytest.raises(ValueError, match="variance_factor"):
        chi2_band(2, 10, variance_factor=0.5)
    with pytest.raises(ValueError, match="variance_factor"):
        chi2_band(2, 10, variance_factor=float("nan"))
    with pytest.raises(ValueError, match="groups"):
        variance_inflation(np.ones(3), np.array([0.0, np.nan, 1.0]))
    with pytest.raises(TypeError, match="groups"):
        variance_inflation(np.ones(3), np.array([1, "a", 2.0], dtype=object))
    assert variance_inflation(np.full(5, 2.0), np.zeros(5)) == 1.0
