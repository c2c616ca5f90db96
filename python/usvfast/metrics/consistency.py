"""Filter consistency: NEES and NIS (thesis eqs. 4.5–4.6) and their χ² confidence bands.

For a consistent filter, NEES ε_k = (x̂_k − x_k)ᵀ P_k⁻¹ (x̂_k − x_k) and NIS ε_k^ν = ν_kᵀ S_k⁻¹ ν_k
are χ²(d) distributed; the sum of N independent samples is χ²(Σd), so the average (ANEES,
ANIS) lies with probability `confidence` inside

    [χ²⁻¹((1 − c)/2, Σd) / N,  χ²⁻¹((1 + c)/2, Σd) / N]

(Bar-Shalom, Li & Kirubarajan 2001, §5.4; the thesis's 90 % band of one 2-dof NIS sample is
[0.103, 5.991]).

A tracker only reports the NIS of a detection it associated, and it associates only detections
inside its validation gate ε^ν ≤ γ with P(χ²(d) ≤ γ) = P_G. Such a NIS is χ²(d) truncated at γ:
its mean is d F_{d+2}(γ) / P_G and its second moment d (d + 2) F_{d+4}(γ) / P_G (F_k the χ²(k)
CDF; x^r times the χ²(d) density is a multiple of the χ²(d + 2r) density), which is the
PDAF's truncation factor c_τ (Bar-Shalom, Daum & Huang 2009, eq. 30). With P_G = 0.99 and
d = 2 a consistent filter's ANIS is 1.907, not 2. With `gate=` the band is that of the mean of
N such samples: a gamma law with the sum's mean and variance, which is the exact χ²(Σd) band
when nothing is truncated (truncated: within 0.002 of the sampled quantiles at N = 400 and
P_G = 0.99, 0.01 at N = 40).

The band assumes independent samples. The NIS of one track are not when the sensors' errors
change slowly (an object's seen side, a box's fit): then the mean of N samples varies as that
of N / f independent ones. With `groups=` (each sample's track, the samples of a track in
time order) `average_consistency` also gives f, estimated as the Bartlett-weighted long-run
variance within the tracks over the variance (Newey & West 1987; lags by their 1994 rule), and
the band of N / f samples beside the plain one. Example::

    eps = nees(errors, covariances)            # (N,)
    c = average_consistency(eps, dof=2)        # c.mean, c.lower, c.upper, c.inside
    a = average_consistency(nis, dof=2, gate=0.99)   # a.expected 1.907
    a = average_consistency(nis, dof=2, gate=0.99, groups=track_ids)  # a.variance_factor
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2, gamma

from usvfast._core import DimensionError, NotPositiveDefiniteError
from usvfast._validate import as_float_array


def gated_chi2_moments(dof: ArrayLike, gate: ArrayLike = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Mean and variance of χ²(dof) truncated at its `gate` quantile (the gate probability
    P_G in (0, 1]; 1: not truncated, mean dof and variance 2 dof). Broadcasts dof and gate."""
    d, g = np.broadcast_arrays(np.asarray(dof, np.float64), np.asarray(gate, np.float64))
    if not np.all(d > 0):
        raise ValueError(f"dof: every degree of freedom must be > 0, got {dof}")
    if not np.all((g > 0) & (g <= 1)):
        raise ValueError(f"gate: a gate probability must lie in (0, 1], got {gate}")
    gamma_ = chi2.ppf(g, d)  # inf where g == 1: F(inf) = 1 below
    m1 = d * chi2.cdf(gamma_, d + 2) / g
    m2 = d * (d + 2) * chi2.cdf(gamma_, d + 4) / g
    return m1, m2 - m1 * m1


def chi2_band(
    dof: ArrayLike,
    n: int = 1,
    confidence: float = 0.95,
    gate: ArrayLike | None = None,
    variance_factor: float = 1.0,
) -> tuple[float, float]:
    """Two-sided `confidence` band of the average of `n` χ² samples whose degrees of freedom
    sum to `dof` × n (dof: an int, or an array of each sample's dof with n = its length).
    gate: the gate probability P_G each sample was truncated at (a number or one per sample;
    None: not truncated; module doc). variance_factor (>= 1): the average's variance is that
    many times the independent samples' (correlated samples; the band is then the gamma law
    of the inflated variance)."""
    if not 0 < confidence < 1:
        raise ValueError(f"confidence: must lie in (0, 1), got {confidence}")
    if not (math.isfinite(variance_factor) and variance_factor >= 1):
        raise ValueError(f"variance_factor: expected a finite number >= 1, got {variance_factor}")
    d = np.asarray(dof)
    if d.ndim:
        n, total = len(d), float(d.sum())
    else:
        total = float(d) * n
    if n < 1 or not total > 0:
        raise ValueError(f"dof, n: need at least one sample with dof > 0, got {dof}, {n}")
    q = [(1 - confidence) / 2, (1 + confidence) / 2]
    if gate is None and variance_factor == 1:
        lo, hi = chi2.ppf(q, total) / n
    else:
        per = d if d.ndim else np.full(n, float(d))
        g = np.asarray(1.0 if gate is None else gate, np.float64)
        if g.ndim and g.shape != per.shape:
            raise ValueError(f"gate: expected a number or {per.shape[0]} values, got {g.shape}")
        mean, var = (np.broadcast_to(v, per.shape).sum() for v in gated_chi2_moments(per, g))
        var = var * variance_factor
        lo, hi = gamma.ppf(q, mean * mean / var, scale=var / mean) / n
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ValueError(f"dof: χ² quantiles are not finite for {total} degrees of freedom")
    return float(lo), float(hi)


def variance_inflation(values: ArrayLike, groups: ArrayLike, max_lag: int | None = None) -> float:
    """How many times the variance of the mean of `values` (N,) exceeds that of N independent
    samples when the samples of each group (`groups` (N,) labels, e.g. track ids; a group's
    samples in time order) are correlated with each other and not across groups: 1 + 2 Σ
    (1 - l / (L + 1)) γ_l / γ_0 over the lags l = 1..L within the groups (γ_l the pooled
    autocovariance about the overall mean; Bartlett weights, Newey & West 1987), at least 1.
    max_lag L: None for floor(4 (N / 100)^(2/9)) (Newey & West 1994)."""
    v = as_float_array("values", values, ndim=1)
    g = np.asarray(groups)
    if g.shape != v.shape:
        raise DimensionError(f"groups: expected one label per value ({v.shape}), got {g.shape}")
    lags = math.floor(4 * (len(v) / 100) ** (2 / 9)) if max_lag is None else max_lag
    if isinstance(lags, bool) or not isinstance(lags, int | np.integer) or lags < 0:
        raise ValueError(f"max_lag: expected an integer >= 0, got {max_lag}")
    if len(v) < 2:
        return 1.0
    if g.dtype.kind == "f" and not np.all(np.isfinite(g)):
        raise ValueError("groups: labels must be finite (NaN is no track)")
    try:
        order = np.argsort(g, kind="stable")
    except TypeError as exc:
        raise TypeError(f"groups: labels of one type are needed ({exc})") from exc
    d, g = v[order] - v.mean(), g[order]
    g0 = float(d @ d)
    if g0 == 0:
        return 1.0
    total = g0
    for lag in range(1, min(lags, len(v) - 1) + 1):
        same = g[lag:] == g[:-lag]
        total += 2 * (1 - lag / (lags + 1)) * float(d[lag:][same] @ d[:-lag][same])
    return max(1.0, total / g0)


def nees(errors: ArrayLike, covariances: ArrayLike) -> np.ndarray:
    """ε_k = e_kᵀ P_k⁻¹ e_k for every row. errors: (N, d); covariances: (N, d, d), positive
    definite. Returns (N,). Raises DimensionError on shapes, NotPositiveDefiniteError naming
    `covariances` when one is not positive definite."""
    e = as_float_array("errors", errors, ndim=2)
    p = as_float_array("covariances", covariances, ndim=3)
    n, d = e.shape
    if p.shape != (n, d, d):
        raise DimensionError(f"covariances: expected shape ({n}, {d}, {d}), got {p.shape}")
    if n == 0:
        return np.zeros(0)
    try:
        low = np.linalg.cholesky(p)
    except np.linalg.LinAlgError as exc:
        raise NotPositiveDefiniteError("covariances: a matrix is not positive definite") from exc
    # ε = |L⁻¹ e|² with P = L Lᵀ
    w = np.linalg.solve(low, e[:, :, None])[:, :, 0]
    return np.einsum("ij,ij->i", w, w)


@dataclass(frozen=True)
class Consistency:
    """Average of n χ² samples (ANEES or ANIS): mean, its band [lower, upper] at `confidence`,
    inside: lower ≤ mean ≤ upper; dof: each sample's degrees of freedom (the most common one
    when they differ); expected: the average a consistent filter gives (dof, less when the
    samples were gated); gate: the gate probability P_G they were truncated at (the most
    common one; None: not gated). With the samples' groups (module doc): variance_factor f
    and the band [corrected_lower, corrected_upper] of N / f samples, corrected_inside (None
    without groups)."""

    mean: float
    n: int
    dof: int
    lower: float
    upper: float
    inside: bool
    confidence: float
    expected: float
    gate: float | None = None
    variance_factor: float | None = None
    corrected_lower: float | None = None
    corrected_upper: float | None = None
    corrected_inside: bool | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return asdict(self)


def average_consistency(
    values: ArrayLike,
    dof: ArrayLike,
    confidence: float = 0.95,
    gate: ArrayLike | None = None,
    groups: ArrayLike | None = None,
) -> Consistency | None:
    """Mean of the NEES or NIS `values` (N,) and its χ² band; dof: an int or (N,) per sample;
    gate: the gate probability P_G each NIS was truncated at (a number or (N,); NaN or 1
    where a sample was not gated; None: none was); groups: (N,) each sample's track (its
    samples in time order) for the band corrected for their correlation (`variance_inflation`;
    None: none). None when there are no values."""
    v = as_float_array("values", values, ndim=1)
    if len(v) == 0:
        return None
    d = np.broadcast_to(np.asarray(dof), v.shape)
    g = None
    if gate is not None:
        g = np.broadcast_to(np.asarray(gate, np.float64), v.shape)
        g = np.where(np.isnan(g), 1.0, g)
        if np.all(g == 1.0):
            g = None
    lo, hi = chi2_band(d, confidence=confidence, gate=g)
    expected = float(gated_chi2_moments(d, 1.0 if g is None else g)[0].mean())
    vals, counts = np.unique(d, return_counts=True)
    gate_mode = None
    if g is not None:
        gvals, gcounts = np.unique(g, return_counts=True)
        gate_mode = float(gvals[np.argmax(gcounts)])
    m = float(v.mean())
    corrected: dict[str, Any] = {}
    if groups is not None:
        f = variance_inflation(v, groups)
        clo, chi = chi2_band(d, confidence=confidence, gate=g, variance_factor=f)
        corrected = {
            "variance_factor": f,
            "corrected_lower": clo,
            "corrected_upper": chi,
            "corrected_inside": bool(clo <= m <= chi),
        }
    return Consistency(
        mean=m,
        n=len(v),
        dof=int(vals[np.argmax(counts)]),
        lower=lo,
        upper=hi,
        inside=bool(lo <= m <= hi),
        confidence=confidence,
        expected=expected,
        gate=gate_mode,
        **corrected,
    )
