"""Filter consistency: NEES and NIS (thesis eqs. 4.5–4.6) and their χ² confidence bands.

For a consistent filter, NEES ε_k = (x̂_k − x_k)ᵀ P_k⁻¹ (x̂_k − x_k) and NIS ε_k^ν = ν_kᵀ S_k⁻¹ ν_k
are χ²(d) distributed; the sum of N independent samples is χ²(Σd), so the average (ANEES,
ANIS) lies with probability `confidence` inside

    [χ²⁻¹((1 − c)/2, Σd) / N,  χ²⁻¹((1 + c)/2, Σd) / N]

(Bar-Shalom, Li & Kirubarajan 2001, §5.4; the thesis's 90 % band of one 2-dof NIS sample is
[0.103, 5.991]). Example::

    eps = nees(errors, covariances)            # (N,)
    c = average_consistency(eps, dof=2)        # c.mean, c.lower, c.upper, c.inside
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import chi2

from usvfast._core import DimensionError, NotPositiveDefiniteError
from usvfast._validate import as_float_array


def chi2_band(dof: ArrayLike, n: int = 1, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided `confidence` band of the average of `n` χ² samples whose degrees of freedom
    sum to `dof` × n (dof: an int, or an array of each sample's dof with n = its length)."""
    if not 0 < confidence < 1:
        raise ValueError(f"confidence: must lie in (0, 1), got {confidence}")
    d = np.asarray(dof)
    if d.ndim:
        n, total = len(d), float(d.sum())
    else:
        total = float(d) * n
    if n < 1 or not total > 0:
        raise ValueError(f"dof, n: need at least one sample with dof > 0, got {dof}, {n}")
    lo, hi = chi2.ppf([(1 - confidence) / 2, (1 + confidence) / 2], total) / n
    if not (np.isfinite(lo) and np.isfinite(hi)):
        raise ValueError(f"dof: χ² quantiles are not finite for {total} degrees of freedom")
    return float(lo), float(hi)


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
    when they differ)."""

    mean: float
    n: int
    dof: int
    lower: float
    upper: float
    inside: bool
    confidence: float

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready dict."""
        return asdict(self)


def average_consistency(
    values: ArrayLike, dof: ArrayLike, confidence: float = 0.95
) -> Consistency | None:
    """Mean of the NEES or NIS `values` (N,) and its χ² band; dof: an int or (N,) per sample.
    None when there are no values."""
    v = as_float_array("values", values, ndim=1)
    if len(v) == 0:
        return None
    d = np.broadcast_to(np.asarray(dof), v.shape)
    lo, hi = chi2_band(d, confidence=confidence)
    vals, counts = np.unique(d, return_counts=True)
    m = float(v.mean())
    return Consistency(
        mean=m,
        n=len(v),
        dof=int(vals[np.argmax(counts)]),
        lower=lo,
        upper=hi,
        inside=bool(lo <= m <= hi),
        confidence=confidence,
    )
