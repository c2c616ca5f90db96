"""The tracker's parts by Stone Soup role: sensors (position, bearing-range), data association
(JPDA, GNN), deleters and the multi-measurement initiator; frozen settings that
`usvfast.tracking.Tracker` hands to the native core."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from usvfast import _core
from usvfast._validate import as_float_array
from usvfast.kalman import MotionModel

#: The largest count the native core takes (a signed 64-bit integer).
_MAX_COUNT = 2**63 - 1
#: The largest state dimension a sensor is built for (its H is allocated here).
_MAX_NDIM = 4096


def _probability(name: str, v: Any) -> float:
    """`v` as a float, else TypeError naming `name` (the core checks its range)."""
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
        raise TypeError(f"{name}: expected a float, got {v!r}")
    return float(v)


def _non_negative_int(name: str, v: Any, high: int = _MAX_COUNT) -> int:
    """`v` as an int in [0, `high`], else ValueError naming `name` (so no OverflowError or
    huge allocation comes from a number too large for the native core)."""
    try:
        ok = not isinstance(v, bool) and int(v) == v and 0 <= int(v) <= high
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        raise ValueError(f"{name}: must be an integer in [0, {high}], got {v!r}")
    return int(v)


@dataclass(frozen=True)
class BearingRange:
    """The range–bearing part of a `Sensor.bearing_range` (see there): state indices `mapping`
    of the Cartesian (x, y) it observes, `update` "ekf" (extended Kalman, analytic Jacobian) or
    "ukf" (unscented, sigma-point parameters alpha, beta, kappa as Stone Soup's
    `UnscentedKalmanUpdater`; kappa None: 3 − ndim)."""

    mapping: tuple[int, int] = (0, 2)
    update: Literal["ekf", "ukf"] = "ekf"
    alpha: float = 0.5
    beta: float = 2.0
    kappa: float | None = None


@dataclass(frozen=True)
class Sensor:
    """A linear-Gaussian sensor: z = H x + w, w ~ N(0, R) — or a range–bearing sensor
    (`Sensor.bearing_range`).

    measurement_matrix H: (m, ndim); measurement_noise R: (m, m), symmetric positive definite,
    in measurement units squared. `initiation_matrix`/`initiation_noise` (default: the same)
    are the model the initiator uses to start tracks from this sensor's detections (Stone
    Soup's initiator `measurement_model` for detections without their own model).
    `polar`: set by `Sensor.bearing_range` (then H only selects the mapped positions).
    `starts_tracks`: whether this sensor's detections left over after association start
    tentative tracks (True, as Stone Soup's initiator); False: they only update existing
    tracks, tentative ones included — e.g. a detector's low-score boxes registered as a sensor
    of their own beside its high-score ones (the two-threshold association of ByteTrack,
    Zhang et al. 2022).
    """

    measurement_matrix: Any
    measurement_noise: Any
    initiation_matrix: Any = None
    initiation_noise: Any = None
    polar: BearingRange | None = None
    starts_tracks: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.starts_tracks, bool):
            raise TypeError(f"starts_tracks: expected a bool, got {self.starts_tracks!r}")

    @classmethod
    def bearing_range(
        cls,
        noise_std: Sequence[float] | None = None,
        *,
        noise: Any = None,
        update: Literal["ekf", "ukf"] = "ekf",
        ndim_state: int = 4,
        mapping: Sequence[int] = (0, 2),
        alpha: float = 0.5,
        beta: float = 2.0,
        kappa: float | None = None,
        initiation_noise: Any = None,
    ) -> Sensor:
        """A range–bearing sensor (radar): z = (φ, ρ), φ = atan2(y − y₀, x − x₀) in radians,
        ρ the range in metres, of the state positions (x, y) = state[mapping] seen from the
        sensor position (x₀, y₀) given per detection as `origins` to `Tracker.step`/`run`.
        With the state [n, v_n, e, v_e] and mapping (0, 2), φ is the compass bearing from north
        (clockwise). Stone Soup's `CartesianToBearingRange(ndim_state, mapping, noise_covar,
        translation_offset=origin)`; bearings and residuals wrapped to [−π, π).

        noise_std (σ_φ rad, σ_ρ m) or noise R (2, 2) in (rad², m²); update "ekf" (Stone Soup's
        `ExtendedKalmanUpdater` with the analytic Jacobian) or "ukf" (`UnscentedKalmanUpdater`
        with alpha, beta, kappa). New tracks start at the inverse of the detection with
        covariance J⁺ R J⁺ᵀ on the positions (Stone Soup's `SimpleMeasurementInitiator`).
        """
        ndim_state = _non_negative_int("ndim_state", ndim_state, _MAX_NDIM)
        mp = tuple(_non_negative_int("mapping", i) for i in mapping)
        if len(mp) != 2 or mp[0] == mp[1] or max(mp) >= ndim_state:
            raise ValueError(
                f"mapping: two distinct state indices < ndim_state={ndim_state}, got {mapping}"
            )
        if (noise_std is None) == (noise is None):
            raise TypeError("bearing_range: give exactly one of noise_std and noise")
        if noise is None:
            std = as_float_array("noise_std", noise_std, ndim=1)
            if std.shape != (2,):
                raise _core.DimensionError(
                    f"noise_std: expected (bearing rad, range m), got shape {std.shape}"
                )
            noise = np.diag(std**2)
        if update not in ("ekf", "ukf"):
            raise ValueError(f"update: expected 'ekf' or 'ukf', got {update!r}")
        h = np.zeros((2, ndim_state))
        h[0, mp[0]] = h[1, mp[1]] = 1.0
        return cls(
            h,
            noise,
            None,
            initiation_noise,
            BearingRange(
                (mp[0], mp[1]),
                update,
                float(alpha),
                float(beta),
                None if kappa is None else float(kappa),
            ),
        )

    @classmethod
    def position(
        cls,
        noise_std: float | Sequence[float],
        *,
        ndim_state: int = 4,
        mapping: Sequence[int] = (0, 2),
    ) -> Sensor:
        """A position sensor measuring the `mapping` entries of the state (default [n, e] of
        [n, v_n, e, v_e]) with standard deviation `noise_std` (scalar or one per axis)."""
        ndim_state = _non_negative_int("ndim_state", ndim_state, _MAX_NDIM)
        mapping = [_non_negative_int("mapping", i) for i in mapping]
        if any(i >= ndim_state for i in mapping):
            raise ValueError(f"mapping: indices must be < ndim_state={ndim_state}, got {mapping}")
        std = as_float_array("noise_std", noise_std)
        if std.ndim > 1 or std.size not in (1, len(mapping)):
            raise _core.DimensionError(
                f"noise_std: expected a scalar or {len(mapping)} values, got shape {std.shape}"
            )
        if np.any(std <= 0):
            raise ValueError(f"noise_std: must be > 0 (R positive definite), got {noise_std!r}")
        std = np.broadcast_to(std, (len(mapping),))
        h = np.zeros((len(mapping), ndim_state))
        h[np.arange(len(mapping)), list(mapping)] = 1.0
        return cls(h, np.diag(std**2))


@dataclass(frozen=True)
class JPDA:
    """JPDA association with PDA hypotheses (Stone Soup `PDAHypothesiser` + `JPDA`).

    prob_detect P_D and prob_gate P_G in (0, 1]; clutter_density λ > 0 per unit measurement
    volume (m⁻² for 2-D positions), or None for Stone Soup's estimate from the gate volume;
    include_all keeps detections outside the gate (needs clutter_density); method "ehm"
    (exact, fast), "brute_force" (exact, exponential) or "lbp" (loopy belief propagation,
    approximate: Williams & Lau, IEEE Trans. AES 50(4), 2014).

    max_hypotheses: per-cluster budget of the exact method (EHM: edges of its hypothesis net
    times the 64-bit words of a node key, one per 64 detections in the cluster — its memory
    and work, a few tens of bytes and nanoseconds each; brute force: joint hypotheses). A cluster
    past it gets belief-propagation marginals instead and is counted in
    `Tracker.last_step.approximated_clusters` (and `RunResult.approximated_clusters`). None:
    always exact, unbounded (Stone Soup's behaviour; a dense cluster can then exhaust memory).
    """

    prob_detect: float = 0.85
    prob_gate: float = 0.95
    clutter_density: float | None = None
    include_all: bool = False
    method: Literal["ehm", "brute_force", "lbp"] = "ehm"
    max_hypotheses: int | None = 1_000_000


@dataclass(frozen=True)
class GNN:
    """Global nearest neighbour with an optimal assignment (Stone Soup `DistanceHypothesiser`
    + `GNNWith2DAssignment`): detections at distance >= missed_distance are not hypothesised
    (unless include_all) and a missed detection costs missed_distance. measure
    "mahalanobis" or "squared_mahalanobis"."""

    missed_distance: float = float("inf")
    measure: Literal["mahalanobis", "squared_mahalanobis"] = "mahalanobis"
    include_all: bool = False


@dataclass(frozen=True)
class StepsSinceUpdate:
    """Delete after more than `steps` distinct timestamps without an update
    (Stone Soup `UpdateTimeStepsDeleter(time_steps_since_update=steps)`)."""

    steps: int


@dataclass(frozen=True)
class TimeSinceUpdate:
    """Delete when no update lies within `seconds` of the newest state
    (Stone Soup `UpdateTimeDeleter`)."""

    seconds: float


@dataclass(frozen=True)
class CovarianceTrace:
    """Delete when the covariance trace (over `mapping` indices, default all) exceeds
    `threshold` (Stone Soup `CovarianceBasedDeleter`)."""

    threshold: float
    mapping: Sequence[int] | None = None


class _Composite:
    """Deleters combined like Stone Soup's CompositeDeleter."""

    deleters: tuple

    def __init__(self, *deleters: Any) -> None:
        object.__setattr__(self, "deleters", tuple(deleters))


@dataclass(frozen=True, init=False)
class AnyOf(_Composite):
    """Delete when any of the deleters would (CompositeDeleter(intersect=False))."""

    deleters: tuple


@dataclass(frozen=True, init=False)
class AllOf(_Composite):
    """Delete when all of the deleters would (CompositeDeleter(intersect=True))."""

    deleters: tuple


@dataclass(frozen=True)
class NeverDelete:
    """Never delete."""


Deleter = StepsSinceUpdate | TimeSinceUpdate | CovarianceTrace | AnyOf | AllOf | NeverDelete


@dataclass(frozen=True)
class MultiMeasurementInitiator:
    """Tentative tracks, GNN-associated with their own gate, confirmed after `min_points`
    updates (Stone Soup `MultiMeasurementInitiator`), or M of their first N states with
    `m_of_n=(M, N)`.

    prior_state (ndim,) and prior_covariance (ndim, ndim): the entries a sensor measures are
    replaced by H⁺ z and H⁺ R H⁺ᵀ. deleter drops tentative tracks (ignored with m_of_n).
    missed_distance/measure/include_all: the tentative tracks' `DistanceHypothesiser`.
    motion_model: the initiator predictor's model (default: the tracker's). use_joseph_cov /
    symmetric_covariance: the initiator updater's covariance form (as the tracker's).
    max_new_tentative: at most this many new tentative tracks per scan (the first free
    detections in scan order; `Tracker.capped_detections` counts the rest), so a clutter burst
    costs O(plots) and leaves no flood of tracks; None: no cap.
    imm: run the tracker's `IMM` bank (needed; not with motion_model) on the tentative tracks
    too: each starts every mode at its initiation Gaussian (the prior with H⁺ z, H⁺ R H⁺ᵀ)
    with the bank's initial probabilities, and each scan mixes, predicts every mode, updates
    it with the track's GNN detection (mode likelihoods N(z; ẑ_j, S_j); a missed scan keeps
    the predicted probabilities) and gates on the combined prediction; a confirmed track
    keeps its modes and probabilities. False (default): tentative tracks use the initiator's
    model and a confirmed track starts every mode at its state.
    """

    prior_state: Any
    prior_covariance: Any
    min_points: int = 2
    deleter: Any = field(default_factory=lambda: StepsSinceUpdate(3))
    missed_distance: float = float("inf")
    measure: Literal["mahalanobis", "squared_mahalanobis"] = "mahalanobis"
    include_all: bool = False
    updates_only: bool = True
    diag_load: float = 0.0
    m_of_n: tuple[int, int] | None = None
    motion_model: MotionModel | None = None
    use_joseph_cov: bool = False
    symmetric_covariance: bool = True
    max_new_tentative: int | None = None
    imm: bool = False
