"""Fusion of visible and thermal camera bearings with a Wiener-velocity Kalman filter and RTS
smoother (Sect. 2.4 of the paper), and its evaluation against AIS (Table 1).

The state is [β, β̇] in degrees and degrees/second; the motion model is
`usvfast.kalman.ConstantVelocity(q)` (F = [[1, Δt], [0, 1]], Q = q·[[Δt³/3, Δt²/2],
[Δt²/2, Δt]]), measured through H = [1, 0] with the variance of each sample's source. The
whole stream is filtered and smoothed in one Rust call (`usvfast.kalman.kalman_filter`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from usvfast._angles import wrap_deg
from usvfast._core import DimensionError, TimeOrderError
from usvfast._validate import as_float_array, instance, real
from usvfast.bearing.angles import unwrap_raw_deg as unwrap_deg
from usvfast.kalman import ConstantVelocity, KalmanResult, kalman_filter

VISIBLE = 1
"""Source id of the visible-light camera."""
THERMAL = 2
"""Source id of the thermal infrared camera."""
SOURCE_NAMES = {VISIBLE: "visible", THERMAL: "thermal"}
"""Display names of the paper's source ids."""

PAPER_MEASUREMENT_STD_DEG: Mapping[int, float] = {VISIBLE: 0.7, THERMAL: 1.0}
"""Bearing noise standard deviation per source (degrees): r ~ N(0, 0.7²) visible, N(0, 1²) IR."""
PAPER_NOISE_DIFF_COEFF_DEG2 = 0.01**2
"""Process noise spectral density q of the Wiener velocity model (deg²/s³): q = 0.01²."""


@dataclass(frozen=True)
class BearingFusion:
    """Result of `fuse_bearings` over n samples, in input order (time order).

    times (n,) UNIX seconds, source (n,) ids, measured_bearing_deg and confidence (n,) as
    given (bearing wrapped to (-180°, 180°]). bearing_deg: RTS-smoothed bearing wrapped to
    (-180°, 180°]; bearing_unwrapped_deg: the same without wrapping (continuous through
    ±180°); bearing_std_deg: its standard deviation. bearing_rate_deg_s and
    bearing_rate_std_deg_s: smoothed bearing rate (deg/s, clockwise positive) and its
    standard deviation. filtered_bearing_deg: the causal (Kalman-only) estimate, wrapped.
    kalman: the raw batch result, states in unwrapped degrees.
    """

    times: np.ndarray
    source: np.ndarray
    measured_bearing_deg: np.ndarray
    confidence: np.ndarray
    bearing_deg: np.ndarray
    bearing_unwrapped_deg: np.ndarray
    bearing_std_deg: np.ndarray
    bearing_rate_deg_s: np.ndarray
    bearing_rate_std_deg_s: np.ndarray
    filtered_bearing_deg: np.ndarray
    kalman: KalmanResult


def _source_ids(value: Any, n: int, known: Mapping[int, float]) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind == "f":
        if not np.all(np.isfinite(arr)):
            raise ValueError("source: contains a non-finite value (NaN or inf)")
        if np.any(arr != np.round(arr)):
            raise ValueError("source: expected integer source ids")
    elif arr.dtype.kind not in "iu":
        raise TypeError(f"source: expected integer source ids, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    if arr.shape != (n,):
        raise DimensionError(f"source: expected shape ({n},), got {arr.shape}")
    unknown = sorted(set(np.unique(arr).tolist()) - set(known))
    if unknown:
        raise ValueError(f"source: unknown source id(s) {unknown}; known: {sorted(known)}")
    return arr


def fuse_bearings(
    source: Any,
    times: ArrayLike,
    bearing_deg: ArrayLike,
    confidence: ArrayLike | None = None,
    *,
    measurement_std_deg: Mapping[int, float] = PAPER_MEASUREMENT_STD_DEG,
    noise_diff_coeff_deg2: float = PAPER_NOISE_DIFF_COEFF_DEG2,
    prior_rate_std_deg_s: float = 5.0,
) -> BearingFusion:
    """Fuse a time-ordered stream of bearing samples [source, t, β, confidence] from several
    cameras with the Wiener-velocity Kalman filter and RTS smoother, in one batch call.

    source: (n,) integer ids, each a key of `measurement_std_deg` (default: 1 visible with
    0.7°, 2 thermal with 1.0°). times: (n,) UNIX seconds, non-decreasing (simultaneous
    samples allowed). bearing_deg: (n,) degrees relative to own heading, any branch.
    confidence: (n,) detector confidences in [0, 1], carried through (default 1).
    noise_diff_coeff_deg2: q in deg²/s³ (default 0.01²). prior_rate_std_deg_s: standard
    deviation of the bearing rate before the first sample (the first bearing itself gets
    10x its source's standard deviation, i.e. practically diffuse).

    Wrap-around: the bearings are unwrapped along the stream (each moved by a multiple of 360°
    to lie within 180° of the previous unwrapped sample) before filtering and the outputs are
    wrapped back, so a target crossing ±180° (astern) is tracked through without a jump. This
    assumes consecutive samples differ by less than 180°.

    Raises ValueError subclasses naming the argument on NaN/inf, mismatched lengths, an empty
    stream, times going backwards, unknown source ids or confidences outside [0, 1].
    """
    t = as_float_array("times", times, ndim=1)
    n = len(t)
    if n == 0:
        raise ValueError("times: no samples")
    if np.any(np.diff(t) < 0):
        k = int(np.argmax(np.diff(t) < 0))
        raise TimeOrderError(f"times: must be non-decreasing; times[{k + 1}] < times[{k}]")
    instance("measurement_std_deg", measurement_std_deg, Mapping)
    stds = {int(k): real(f"measurement_std_deg[{k}]", v) for k, v in measurement_std_deg.items()}
    for k, v in stds.items():
        if not np.isfinite(v) or v <= 0:
            raise ValueError(f"measurement_std_deg: source {k} must have a std > 0, got {v}")
    if not np.isfinite(noise_diff_coeff_deg2) or noise_diff_coeff_deg2 < 0:
        raise ValueError(f"noise_diff_coeff_deg2: must be >= 0, got {noise_diff_coeff_deg2}")
    if not np.isfinite(prior_rate_std_deg_s) or prior_rate_std_deg_s <= 0:
        raise ValueError(f"prior_rate_std_deg_s: must be > 0, got {prior_rate_std_deg_s}")
    src = _source_ids(source, n, stds)
    b = as_float_array("bearing_deg", bearing_deg, ndim=1)
    if b.shape != (n,):
        raise DimensionError(f"bearing_deg: expected shape ({n},), got {b.shape}")
    conf = np.ones(n) if confidence is None else as_float_array("confidence", confidence, ndim=1)
    if conf.shape != (n,):
        raise DimensionError(f"confidence: expected shape ({n},), got {conf.shape}")
    if np.any((conf < 0) | (conf > 1)):
        raise ValueError("confidence: values must be in [0, 1]")

    measured = wrap_deg(b)
    z = unwrap_deg(measured)
    ids = sorted(stds)
    sensor_index = np.searchsorted(ids, src)
    noise = np.array([[[stds[k] ** 2]] for k in ids])
    first_var = noise[sensor_index[0], 0, 0]
    run = kalman_filter(
        t,
        z,
        motion_model=ConstantVelocity(noise_diff_coeff_deg2),
        measurement_matrix=[[1.0, 0.0]],
        measurement_noise=noise,
        sensor_index=sensor_index,
        prior_state=[z[0], 0.0],
        prior_covariance=np.diag([100.0 * first_var, prior_rate_std_deg_s**2]),
        smooth=True,
    )
    xs = run.smoothed_states
    ps = run.smoothed_covariances
    if xs is None or ps is None:  # pragma: no cover - smooth=True always returns them
        raise RuntimeError("kalman_filter returned no smoothed states")
    return BearingFusion(
        times=t,
        source=src,
        measured_bearing_deg=measured,
        confidence=conf,
        bearing_deg=wrap_deg(xs[:, 0]),
        bearing_unwrapped_deg=xs[:, 0].copy(),
        bearing_std_deg=np.sqrt(ps[:, 0, 0]),
        bearing_rate_deg_s=xs[:, 1].copy(),
        bearing_rate_std_deg_s=np.sqrt(ps[:, 1, 1]),
        filtered_bearing_deg=wrap_deg(run.filtered_states[:, 0]),
        kalman=run,
    )


def rmse_deg(estimate_deg: ArrayLike, reference_deg: ArrayLike) -> tuple[float, int]:
    """Root-mean-square of the wrapped differences estimate − reference (degrees) over the
    pairs where the reference is finite (NaN = no AIS coverage); returns (rmse, count), with
    rmse NaN when count is 0. Arrays must have one shape; the estimate must be finite.
    """
    est = as_float_array("estimate_deg", estimate_deg)
    ref = np.asarray(reference_deg, dtype=np.float64)
    if ref.shape != est.shape:
        raise DimensionError(f"reference_deg: expected shape {est.shape}, got {ref.shape}")
    ok = np.isfinite(ref)
    count = int(ok.sum())
    if count == 0:
        return float("nan"), 0
    err = wrap_deg(est[ok] - ref[ok])
    return float(np.sqrt(np.mean(err**2))), count


@dataclass(frozen=True)
class RmseRow:
    """One line of the RMSE table: what was compared, RMSE (degrees), number of samples."""

    label: str
    rmse_deg: float
    count: int


def bearing_rmse_table(fusion: BearingFusion, reference_deg: ArrayLike) -> list[RmseRow]:
    """RMSE against the AIS reference bearing, as in the paper's Table 1.

    reference_deg: (n,) AIS bearing at the fusion's sample times (NaN where AIS does not
    cover; see `reference_bearing_deg`). Rows: each source's raw bearings at its own sample
    times (unfused), the Kalman filter alone, and KF + RTS, at all samples. Angle differences
    are wrapped.
    """
    instance("fusion", fusion, BearingFusion)
    ref = as_float_array("reference_deg", reference_deg, finite=False).reshape(
        np.shape(reference_deg)
    )
    if ref.shape != fusion.times.shape:
        raise DimensionError(f"reference_deg: expected shape {fusion.times.shape}, got {ref.shape}")
    rows = []
    for s in np.unique(fusion.source):
        m = fusion.source == s
        name = SOURCE_NAMES.get(int(s), f"source {int(s)}")
        rows.append(RmseRow(f"{name} (unfused)", *rmse_deg(fusion.measured_bearing_deg[m], ref[m])))
    rows.append(RmseRow("fused KF", *rmse_deg(fusion.filtered_bearing_deg, ref)))
    rows.append(RmseRow("fused KF + RTS", *rmse_deg(fusion.bearing_deg, ref)))
    return rows
