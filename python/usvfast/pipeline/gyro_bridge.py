"""The GNSS heading carried across its gaps by the IMU's gyro (`[recording]
gyro_heading_bridge`).

A GNSS compass goes silent for a second or two under a crane or a bridge; interpolating its
heading linearly across the gap misses every turn begun or ended inside it. The IMU's rates
do not stop: the heading's rate in NED is ψ̇ = (q sin φ + r cos φ) / cos θ from the body's FRD
rates (p, q, r) and its roll φ and pitch θ (the Euler-angle kinematics, Fossen 2011, eq. 2.29).
Inside each gap the heading follows the integrated rate from the sample before the gap, and the
gyro's drift over the gap is spread linearly so that the bridge meets the sample after it:

    ψ(t) = ψ₀ + I(t) + (t − t₀) / (t₁ − t₀) · wrap(ψ₁ − ψ₀ − I(t₁)),   I(t) = ∫ from t₀ to t of ψ̇

(I by the trapezoid rule over the IMU samples).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from usvfast._core import DimensionError
from usvfast._validate import as_float_array

__all__ = ["bridge_heading_gaps", "heading_rates"]


def heading_rates(angular_velocity_flu: ArrayLike, roll: ArrayLike, pitch: ArrayLike) -> np.ndarray:
    """Heading rates (n,) rad/s, clockwise from north, of IMU samples: `angular_velocity_flu`
    (n, 3) body rates rad/s in REP-103 FLU, `roll` and `pitch` (n,) rad (FRD/NED)."""
    w = as_float_array("angular_velocity_flu", angular_velocity_flu, ndim=2)
    phi = as_float_array("roll", roll, ndim=1)
    theta = as_float_array("pitch", pitch, ndim=1)
    if w.shape[1] != 3 or len(w) != len(phi) or len(phi) != len(theta):
        raise DimensionError(
            f"angular_velocity_flu, roll, pitch: expected shapes (n, 3), (n,), (n,), got "
            f"{w.shape}, {phi.shape}, {theta.shape}"
        )
    q, r = -w[:, 1], -w[:, 2]  # FLU -> FRD
    return (q * np.sin(phi) + r * np.cos(phi)) / np.cos(theta)


def bridge_heading_gaps(
    times: ArrayLike,
    headings: ArrayLike,
    rate_times: ArrayLike,
    rates: ArrayLike,
    min_gap: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Headings with every gap longer than `min_gap` s filled at the IMU's sample times.

    times, headings (n,): the GNSS headings (UNIX s, rad), sorted by time; rate_times, rates
    (m,): heading rates (rad/s, `heading_rates`), sorted by time. A gap is bridged only when
    the rates cover it (a rate sample at or before its start and at or after its end). Returns
    the times and headings (rad in [0, 2π)) with the bridge samples merged in order.
    """
    t = as_float_array("times", times, ndim=1)
    h = as_float_array("headings", headings, ndim=1)
    rt = as_float_array("rate_times", rate_times, ndim=1)
    rr = as_float_array("rates", rates, ndim=1)
    if len(t) != len(h) or len(rt) != len(rr):
        raise DimensionError(
            f"times, headings / rate_times, rates: expected equal lengths, got {len(t)}, "
            f"{len(h)} / {len(rt)}, {len(rr)}"
        )
    if np.any(np.diff(t) < 0) or np.any(np.diff(rt) < 0):
        raise ValueError("times, rate_times: must be sorted ascending")
    if not min_gap > 0:
        raise ValueError(f"min_gap: must be > 0 s, got {min_gap}")
    if len(rt) < 2:
        return t, h
    # I(t): the integrated rate from the first rate sample (trapezoid rule)
    integral = np.concatenate([[0.0], np.cumsum(0.5 * (rr[1:] + rr[:-1]) * np.diff(rt))])
    out_t, out_h = [t], [h]
    for i in np.flatnonzero(np.diff(t) > min_gap):
        t0, t1 = t[i], t[i + 1]
        if rt[0] > t0 or rt[-1] < t1:
            continue
        inside = (rt > t0) & (rt < t1)
        if not inside.any():
            continue
        i0, i1 = (float(np.interp(x, rt, integral)) for x in (t0, t1))
        drift = (h[i + 1] - h[i] - (i1 - i0) + np.pi) % (2 * np.pi) - np.pi
        ts = rt[inside]
        out_t.append(ts)
        out_h.append(h[i] + (integral[inside] - i0) + (ts - t0) / (t1 - t0) * drift)
    all_t, all_h = np.concatenate(out_t), np.concatenate(out_h)
    order = np.argsort(all_t, kind="stable")
    return all_t[order], np.mod(all_h[order], 2 * np.pi)
