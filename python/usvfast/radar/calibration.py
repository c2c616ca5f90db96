"""Tracker parameters from a calibration run against a reference track: a radar watching one
target whose true positions and velocities are logged (its GNSS, or AIS), from which the plot
noise, the probability of detection and the clutter density are measured on the plots
(`plot_statistics`), and the process noises of the tracker's motion models on the target's
own logged motion (`cv_noise_mixture`, `turn_noise`). Each is a stated estimator, not a
search over tracker scores: the tracker is never run.

Remove the radar's bearing bias first (`usvfast.radar.bearing_bias_deg` and the tracker's
`bearing_correction_deg`) if the tracker will run on corrected plots: the plot noise is the
spread about the reference of the plots the tracker sees.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from usvfast._validate import as_float_array
from usvfast.radar.alignment import (
    _points,
    chosen_scans,
    in_reference,
    nearest_pairs,
    scan_numbers,
    scan_slices,
)

__all__ = [
    "CvNoiseMixture",
    "PlotStatistics",
    "TurnNoise",
    "cv_noise_mixture",
    "plot_statistics",
    "turn_noise",
]

# Median of a Rayleigh variable of unit scale: sqrt(2 ln 2).
_RAYLEIGH_MEDIAN = float(np.sqrt(2.0 * np.log(2.0)))


def _positive(name: str, v: object) -> float:
    if isinstance(v, bool) or not (isinstance(v, int | float) and 0 < v < np.inf):
        raise ValueError(f"{name}: a positive finite number, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class PlotStatistics:
    """What `plot_statistics` measured: `sigma_m` the plot noise per axis (m), `prob_detect`
    the probability that the target gives a plot, `clutter_density` non-target plots per m² per
    scan near the target; `scans` the scans with a reference position used, `pairs` those with
    a plot within the pairing gate, `clutter_plots` the clutter plots within the clutter radius
    that the fit implies (rounded)."""

    sigma_m: float
    prob_detect: float
    clutter_density: float
    scans: int
    pairs: int
    clutter_plots: int


def plot_statistics(
    plots: ArrayLike,
    scan_index: ArrayLike,
    reference: ArrayLike,
    *,
    scans: ArrayLike | None = None,
    gate_m: float = 60.0,
    clutter_radius_m: float = 100.0,
) -> PlotStatistics:
    """Plot noise, probability of detection and clutter density of a radar against a reference.

    plots (d, 2): north/east (m) of every plot (bias-corrected if the tracker's will be);
    scan_index (d,): the scan (0-based) of each plot; reference (s, 2): the target's true
    north/east (m) at each scan, NaN where not known; scans: the scans to use (indices into
    reference; default all). Scans whose reference is not finite are not used.

    Pairing: in each scan the plot nearest the reference, if within `gate_m` metres, is the
    target's plot (`usvfast.radar.bearing_bias_deg` pairs the same way); r_k is its offset.

    - sigma_m = median_k |r_k| / sqrt(2 ln 2): for isotropic Gaussian plots of standard
      deviation σ per axis about the truth |r| is Rayleigh(σ), whose median is σ sqrt(2 ln 2);
      the median keeps the odd wild or clutter plot in the gate from inflating it.
    - prob_detect P_D and clutter_density λ (plots per m² per scan), by the method of moments
      with Poisson clutter, uniform near the target, solved together: with n̄ the mean number
      of plots a scan within R = `clutter_radius_m` of the reference (the clutter the gates
      about the target see, not the radar's whole picture) and f the fraction of scans with a
      plot within the gate,
      n̄ = P_D + λ π R²  and  f = P_D + (1 − P_D) (1 − exp(−λ π gate_m²))
      (a scan without the target's plot still pairs when clutter falls in the gate). The second
      is increasing in P_D once the first gives λ, for gate_m < R, and is solved by bisection on
      [0, min(1, n̄)]; λ = (n̄ − P_D) / (π R²), floored at 0.

    Raises ValueError naming the argument for shapes that do not match, non-finite plots,
    scans or scan indices outside reference, a gate or radius that is not positive and finite,
    a radius not larger than the gate, and fewer than 2 pairs; TypeError for scan numbers
    that are not integers.
    """
    p = _points("plots", plots)
    ref = _points("reference", reference)
    si = scan_numbers(scan_index, len(p))
    if not np.all(np.isfinite(p)):
        raise ValueError("plots: every value must be finite")
    in_reference(si, len(ref))
    gate = _positive("gate_m", gate_m)
    radius = _positive("clutter_radius_m", clutter_radius_m)
    if radius <= gate:
        raise ValueError(
            f"clutter_radius_m: larger than gate_m={gate_m} m, got {clutter_radius_m!r}"
        )
    use = chosen_scans(scans, len(ref))
    use = use[np.all(np.isfinite(ref[use]), axis=1)]
    k, rows = nearest_pairs(p, si, ref, use, gate)
    if len(k) < 2:
        raise ValueError(
            f"reference: {len(k)} scans with a plot within gate_m={gate_m} m of it, need 2"
        )
    r = np.hypot(*(p[rows] - ref[k]).T)
    sigma = float(np.median(r) / _RAYLEIGH_MEDIAN)
    order, starts = scan_slices(si, len(ref))
    near = 0
    for j in use:
        o = order[starts[j] : starts[j + 1]]
        near += int(np.count_nonzero(np.hypot(*(p[o] - ref[j]).T) <= radius))
    nbar, f, a = near / len(use), len(k) / len(use), (gate / radius) ** 2

    def excess(pd: float) -> float:
        # f = P_D + (1 − P_D)(1 − exp(−λπG²)) with λπG² = (n̄ − P_D) G²/R²
        return pd + (1.0 - pd) * (1.0 - np.exp(-max(nbar - pd, 0.0) * a)) - f

    lo, hi = 0.0, min(1.0, nbar)
    if excess(lo) >= 0.0:
        hi = lo
    elif excess(hi) <= 0.0:
        lo = hi
    for _ in range(200):
        if hi - lo <= 1e-15:
            break
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if excess(mid) < 0.0 else (lo, mid)
    pd = 0.5 * (lo + hi)
    lam = max(nbar - pd, 0.0) / (np.pi * radius**2)
    clutter = round(float(lam * np.pi * radius**2 * len(use)))
    return PlotStatistics(sigma, float(pd), float(lam), len(use), len(k), clutter)


def _motion(times: ArrayLike, velocities: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    t = as_float_array("times", times, 1)
    v = as_float_array("velocities", velocities, 2, finite=False)
    if np.any(np.diff(t) <= 0):
        raise ValueError("times: must be strictly increasing")
    if v.shape != (len(t), 2):
        raise ValueError(f"velocities: shape ({len(t)}, 2) (north/east m/s), got {v.shape}")
    if np.any(np.isinf(v)):
        raise ValueError("velocities: infinite value (NaN marks an unknown one)")
    return t, v


def _finite(name: str, v: float) -> float:
    if not np.isfinite(v):
        raise ValueError(f"{name}: values so large or steps so short that the sums overflow")
    return v


@dataclass(frozen=True)
class CvNoiseMixture:
    """What `cv_noise_mixture` fitted: `q_quiet` and `q_high` (m² s⁻³) the white-noise
    acceleration intensities of a quiet and a manoeuvre constant-velocity mode
    (q_quiet <= q_high), `weight_quiet` the fraction of intervals of the quiet mode,
    `intervals` the velocity increments used, `log_likelihood` their log-likelihood."""

    q_quiet: float
    q_high: float
    weight_quiet: float
    intervals: int
    log_likelihood: float


def cv_noise_mixture(
    times: ArrayLike, velocities: ArrayLike, *, tol: float = 1e-12, max_iter: int = 10_000
) -> CvNoiseMixture:
    """Maximum-likelihood intensities of a quiet and a manoeuvre constant-velocity mode from a
    reference track's velocity increments.

    times (s,): seconds, strictly increasing; velocities (s, 2): the target's north/east
    velocity (m/s) at those times, NaN where unknown (an interval with a NaN end is skipped).

    Under constant velocity with white-noise acceleration of intensity q (the tracker's
    Wiener-velocity model, Bar-Shalom, Li & Kirubarajan, "Estimation with Applications to
    Tracking and Navigation", 2001, sec. 6.2.2), the increment Δv_k = v_{k+1} − v_k over dt_k is
    N(0, q dt_k I₂). The two modes are fitted as a two-component scale mixture,
    Δv_k ~ w N(0, q₁ dt_k I₂) + (1 − w) N(0, q₂ dt_k I₂), by expectation-maximisation (Dempster,
    Laird & Rubin, JRSS B 39(1), 1977): with x_k = |Δv_k|² / dt_k, responsibilities
    γ_km ∝ w_m q_m⁻¹ exp(−x_k / (2 q_m)), then q_m = Σ γ_km x_k / (2 Σ γ_km),
    w_m = mean_k γ_km, until the log-likelihood gains less than `tol` (relative). The mode
    sequence is treated as independent draws (an IMM's Markov switching is not fitted). The
    intervals the fit gives to the high mode are the manoeuvring ones. Started from the means of
    x/2 below and above its median.

    Raises ValueError naming the argument for times that are not finite and strictly
    increasing, velocities of the wrong shape or infinite, fewer than 4 usable intervals or
    fewer than 2 non-zero increments (a mixture needs spread), a non-positive `tol` or
    `max_iter`.
    """
    t, v = _motion(times, velocities)
    tol = _positive("tol", tol)
    if isinstance(max_iter, bool) or not isinstance(max_iter, int) or max_iter < 1:
        raise ValueError(f"max_iter: an integer >= 1, got {max_iter!r}")
    dv = np.diff(v, axis=0)
    dt = np.diff(t)
    ok = np.all(np.isfinite(dv), axis=1)
    with np.errstate(over="ignore"):
        x = np.sum(dv[ok] ** 2, axis=1) / dt[ok]
    _finite("velocities", float(np.sum(x)))
    if len(x) < 4 or np.count_nonzero(x) < 2:
        raise ValueError(
            f"velocities: {len(x)} usable intervals ({np.count_nonzero(x)} with a velocity "
            "change), need 4 and 2"
        )
    log_dt = np.sum(np.log(dt[ok]))
    med = np.median(x)
    lo, hi = x[x <= med], x[x > med]
    q = np.array([lo.mean() / 2, (hi.mean() if len(hi) else lo.mean()) / 2])
    q = np.maximum(q, np.max(x) * 1e-12)
    w = np.array([0.5, 0.5])

    def loglik(q: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray]:
        # log(w_m N(Δv; 0, q_m dt I₂)) = log w_m − log(2π q_m dt) − x / (2 q_m)
        lp = np.log(w) - np.log(2 * np.pi * q) - x[:, None] / (2 * q)
        top = lp.max(axis=1, keepdims=True)
        s = top[:, 0] + np.log(np.exp(lp - top).sum(axis=1))
        return float(s.sum() - log_dt), np.exp(lp - s[:, None])

    ll, g = loglik(q, w)
    for _ in range(max_iter):
        n = g.sum(axis=0)
        if np.any(n <= 0):  # a mode lost every interval: one mode fits
            q, w = np.full(2, x.mean() / 2), np.array([0.5, 0.5])
            ll, g = loglik(q, w)
            break
        q = np.maximum((g * x[:, None]).sum(axis=0) / (2 * n), np.max(x) * 1e-12)
        w = n / len(x)
        new, g = loglik(q, w)
        done = abs(new - ll) <= tol * max(1.0, abs(new))
        ll = new
        if done:
            break
    i = np.argsort(q)
    return CvNoiseMixture(float(q[i[0]]), float(q[i[1]]), float(w[i[0]]), len(x), ll)


@dataclass(frozen=True)
class TurnNoise:
    """What `turn_noise` measured: `q` the coordinated turn's velocity noise (m² s⁻³ per axis),
    `q_turn` its turn-rate noise (rad² s⁻³), `intervals` the speed increments and
    `rate_increments` the turn-rate increments used."""

    q: float
    q_turn: float
    intervals: int
    rate_increments: int


def turn_noise(times: ArrayLike, velocities: ArrayLike, *, min_speed_mps: float = 1.0) -> TurnNoise:
    """The process noises of a coordinated turn with the turn rate in the state (the tracker's
    `ConstantTurn` on [n, v_n, e, v_e, ω]: Wiener-velocity noise q per axis and a turn-rate
    random walk q_turn; Li & Jilkov, IEEE Trans. AES 39(4), 2003, sec. V) from a reference
    track's velocities.

    times (s,): seconds, strictly increasing; velocities (s, 2): north/east velocity (m/s),
    NaN where unknown. Intervals with an unknown end or a speed below `min_speed_mps` at either
    end are not used (the heading is not defined at rest).

    With the rate known, the model's isotropic velocity noise moves the speed by its
    along-track part and the heading by its cross-track part. Per interval k (length dt_k,
    speeds s_k, s_{k+1}, heading change Δθ_k in (−π, π]):
    - q = Σ_k (s_{k+1} − s_k)² / Σ_k dt_k: the maximum-likelihood intensity of the speed's
      random walk, (s_{k+1} − s_k) ~ N(0, q dt_k);
    - the interval's mean rate ω_k = Δθ_k / dt_k; for consecutive usable intervals, under the
      random walk of intensity q_turn, E[(ω_k − ω_{k−1})²] = q_turn (dt_{k−1} + dt_k) / 3
      + q (1 / (s̄²dt)_{k−1} + 1 / (s̄²dt)_k), the second term the cross-track velocity noise
      seen as heading (s̄ the interval's mean speed). q_turn is that moment equation solved
      over all such pairs (sums of both sides), floored at 0. The heading term is first order
      in q dt / s², valid while the velocity noise of an interval is small against the speed
      (q dt / s² = 0.004 at 0.17 m²/s³, 2.5 s, 10 m/s); slow tracks with a large q get too
      large a q_turn.

    Raises ValueError naming the argument for times that are not finite and strictly
    increasing, velocities of the wrong shape or infinite, a `min_speed_mps` that is not
    positive and finite, fewer than 2 usable intervals or no consecutive pair of them.
    """
    t, v = _motion(times, velocities)
    vmin = _positive("min_speed_mps", min_speed_mps)
    s = np.hypot(v[:, 0], v[:, 1])
    dt = np.diff(t)
    with np.errstate(invalid="ignore"):
        ok = np.isfinite(s[:-1]) & np.isfinite(s[1:]) & (s[:-1] >= vmin) & (s[1:] >= vmin)
    n_ok = int(np.count_nonzero(ok))
    pair = ok[1:] & ok[:-1]
    if n_ok < 2 or not np.any(pair):
        raise ValueError(
            f"velocities: {n_ok} intervals with known speeds >= min_speed_mps={min_speed_mps} "
            "m/s at both ends, need 2 consecutive ones"
        )
    ds = np.diff(s)
    with np.errstate(over="ignore"):
        q = _finite("velocities", float(np.sum(ds[ok] ** 2) / np.sum(dt[ok])))
    a, b = v[:-1], v[1:]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    dot = np.sum(a * b, axis=1)
    with np.errstate(invalid="ignore"):
        w = np.arctan2(cross, dot) / dt
    sbar = 0.5 * (s[:-1] + s[1:])
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / (sbar**2 * dt)
    dw = np.diff(w)[pair]
    lhs = np.sum(dw**2) - q * np.sum(inv[:-1][pair] + inv[1:][pair])
    with np.errstate(over="ignore", invalid="ignore"):
        q_turn = max(
            0.0, _finite("velocities", float(lhs / np.sum((dt[:-1][pair] + dt[1:][pair]) / 3.0)))
        )
    return TurnNoise(q, q_turn, n_ok, int(np.count_nonzero(pair)))
