"""Multi-target tracking (JPDA or GNN) with a multi-measurement initiator, in one Rust core.

The tracker reproduces Stone Soup's ``MultiTargetMixtureTracker`` + ``JPDA`` (or
``JPDAwithEHM``) + ``PDAHypothesiser`` and ``MultiTargetTracker`` + ``GNNWith2DAssignment`` +
``DistanceHypothesiser``, with ``MultiMeasurementInitiator`` and the Stone Soup deleters, step
for step (same births, deaths and states), only much faster. Each step at scan time ``t``:

1. predict every confirmed track to ``t``;
2. JPDA: gate each (track, detection) pair with the detection's own sensor model,
   ``yᵀ S⁻¹ y <= chi2.ppf(prob_gate, m)``; PDA weights ``1 − P_D P_G`` (missed) and
   ``N(z; H x⁻, S) P_D / λ`` (detections); exact joint marginals per cluster of tracks sharing
   detections (EHM, or brute force); moment-matched mixture of the prediction and the Kalman
   updates. The new state counts as an update when some detection's marginal beats the missed
   one, and those detections are not offered to the initiator.
   GNN: Mahalanobis distances, detections beyond ``missed_distance`` dropped, an optimal
   assignment in which a miss costs ``missed_distance``;
3. delete confirmed tracks (``deleter``);
4. the initiator GNN-associates its tentative tracks with the detections left, confirms those
   with ``min_points`` updates (or M of N), drops those its own deleter deletes, and starts a
   tentative track on every detection still left.

Native API (stable; the Stone Soup drop-in builds on it)::

    import numpy as np
    from usvfast.kalman import constant_velocity_2d
    from usvfast.tracking import (JPDA, MultiMeasurementInitiator, Sensor, StepsSinceUpdate,
                                  CovarianceTrace, AnyOf, Tracker)

    lidar = Sensor.position(noise_std=0.25)          # H maps [n, v_n, e, v_e] -> [n, e]
    camera = Sensor.position(noise_std=0.5)
    tracker = Tracker(
        motion_model=constant_velocity_2d(0.001),
        sensors=[lidar, camera],
        association=JPDA(prob_detect=0.85, prob_gate=0.95, clutter_density=0.125),
        deleter=AnyOf(CovarianceTrace(1.5), StepsSinceUpdate(35)),
        initiator=MultiMeasurementInitiator(
            prior_state=np.zeros(4), prior_covariance=np.diag([0, 0.3, 0, 0.3]),
            min_points=2, deleter=StepsSinceUpdate(3), missed_distance=0.3),
    )
    tracker = code_5_7([lidar, camera])                 # the same tracker in one call
    tracks = tracker.step(t, measurements, sensor_ids)   # (k, 2) metres, (k,) ints
    tracks = tracker.step(t, measurements, sensor_ids, covariances=r_k)  # (k, 2, 2) m² each
    tracks.ids, tracks.states, tracks.covariances
    tracker.history(tracks.ids[0]).states               # every state, incl. tentative phase
    result = tracker.run(times, measurements, sensor_ids, scan_index)   # whole recording

Per-detection noise: ``covariances`` (k, m, m) in ``step`` (and (d, m, m) in ``run``) gives each
detection its own measurement noise covariance in place of its sensor's R — used for gating,
the PDA/distance hypotheses, the Kalman updates of confirmed and tentative tracks and the
start of a tentative track (unless the sensor has its own ``initiation_noise``), as Stone Soup
does for a ``Detection`` that carries its own ``LinearGaussian`` measurement model.

Range–bearing (radar) sensors: ``Sensor.bearing_range(noise_std=(σ_φ rad, σ_ρ m),
update="ekf" | "ukf")`` measures z = (bearing, range) of the state positions from the sensor
position given per detection as ``origins`` (k, 2) to ``step``/``run`` (the own-ship north,
east); bearings are compass bearings (atan2(east, north)), residuals wrapped to [−π, π). Updates
are extended (analytic Jacobian) or unscented Kalman — Stone Soup's ``CartesianToBearingRange``
with ``ExtendedKalmanUpdater`` / ``UnscentedKalmanUpdater`` — and the linearised (or
sigma-point) S is used by the gate, the PDA weights and GNN distances; tentative tracks start
at the inverse of the plot with J⁺ R J⁺ᵀ (``SimpleMeasurementInitiator``). Radar and linear
sensors mix in one tracker (all have m = 2). A polar sensor's plots are gated against every
track (no spatial grid: cost tracks × plots); ``initiate_in_gates=False`` and, with "ukf",
``use_joseph_cov`` are refused.

Also: ``tracker.add_track(state, covariance, time, existence=None)`` seeds a confirmed track
(first state a prior, not an update; with its existence and visibility if given);
``tracker.add_sensor(Sensor(...))`` registers a sensor between steps (returns its id);
``tracker.tracks`` also carries each track's newest association data;
``tracker.tentative_tracks``, ``tracker.deleted_track_ids``,
``tracker.history(id).to_dataframe()``, ``tracker.dropped_scans``. Track ids are stable
integers counted in order of confirmation. Kernels: ``usvfast._core.linear_sum_assignment``,
``jpda_marginals`` (EHM, brute force, or "lbp" belief propagation) and ``chi2_gate``.
Trackers pickle (the whole state, bit-exact) and copy; ``tracker.last_step`` reports the JPDA
clusters of the last step and how many were approximated (see `JPDA.max_hypotheses`).

Units SI, state ``[n, v_n, e, v_e]`` (NED metres, m/s) for the 2-D model; times float seconds
(use times relative to a recent epoch for sub-microsecond ``dt``). All detections of a scan
share the scan time and are associated jointly. Scans must come in time order: an older scan
raises ``TimeOrderError`` (or is dropped and counted with ``out_of_order="drop"``); equal times
are allowed; an empty scan only predicts.

Differences from Stone Soup to know: all sensors share one measurement dimension; detections
of a scan have the scan's time; GNN is distance-based only (Mahalanobis or squared). The
native option ``initiate_in_gates=False`` avoids Stone Soup's duplicate tracks on one target:
it withholds from the initiator every detection inside a confirmed track's gate, and drops a
tentative track about to be confirmed when its position lies inside the gate of a confirmed
track (or of one confirmed before it in the same scan). Updated covariances are symmetrised
by default (``symmetric_covariance=True``; Stone Soup's ``force_symmetric_covariance`` is off):
otherwise rounding asymmetry of ``P − K S Kᵀ`` grows through long predictions and makes
constant-acceleration tracks indefinite (NotPositiveDefiniteError naming the option).
"""

from __future__ import annotations

import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from usvfast import _core
from usvfast._validate import as_float_array
from usvfast.kalman import MotionModel

__all__ = [
    "GNN",
    "IMM",
    "JPDA",
    "AllOf",
    "AnyOf",
    "BearingRange",
    "ConstantTurn",
    "CovarianceTrace",
    "Existence",
    "KnownTurnRate",
    "MultiMeasurementInitiator",
    "NeverDelete",
    "RunResult",
    "Sensor",
    "StepStats",
    "StepsSinceUpdate",
    "TimeSinceUpdate",
    "TrackHistory",
    "Tracker",
    "Tracks",
    "code_5_7",
    "constant_velocity_turn_rate",
]


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
    """

    measurement_matrix: Any
    measurement_noise: Any
    initiation_matrix: Any = None
    initiation_noise: Any = None
    polar: BearingRange | None = None

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


@dataclass(frozen=True)
class KnownTurnRate:
    """Coordinated turn at a known rate `omega` (rad/s) on [n, v_n, e, v_e] — Stone Soup's
    `KnownTurnRate(turn_noise_diff_coeffs=(q, q), turn_rate=omega)`: exact transition of a
    constant turn (positive omega turns from north towards east, i.e. to starboard), Wiener
    velocity noise q (m² s⁻³) per axis (`q` a float or (q_n, q_e)). An IMM mode."""

    q: float | tuple[float, float]
    omega: float


def _noise_coeff(name: str, v: Any) -> float:
    """`v` as a finite float >= 0, else TypeError/ValueError naming `name`."""
    if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
        raise TypeError(f"{name}: expected a float, got {type(v).__name__}")
    if not (np.isfinite(v) and v >= 0):
        raise ValueError(f"{name}: must be finite and >= 0, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class ConstantTurn:
    """Coordinated turn with the turn rate in the state [n, v_n, e, v_e, ω] (ω rad/s, positive
    from north towards east, i.e. to starboard) — Stone Soup's
    `ConstantTurn(linear_noise_coeffs=(q, q), turn_noise_coeff=q_turn)`: exact transition of a
    constant turn (ω → 0 is the constant-velocity limit, no division by zero), process noise
    block_diag(q_n Q, q_e Q, q_turn dt), Q = [[dt³/3, dt²/2], [dt²/2, dt]]. An IMM mode of a
    5-D tracker, whose other modes are 5-D too (e.g. `constant_velocity_turn_rate(q, q_w)`).

    q: velocity noise (m² s⁻³), a float or (q_n, q_e); q_turn: turn-rate noise (rad² s⁻³);
    predictor: "ekf" (Stone Soup's `ExtendedKalmanPredictor`, here with the analytic Jacobian)
    or "ukf" (`UnscentedKalmanPredictor` with alpha, beta, kappa; kappa None: 3 − 5).
    Bad values raise ValueError (TypeError for a wrong type) naming the argument."""

    q: float | tuple[float, float]
    q_turn: float
    predictor: Literal["ekf", "ukf"] = "ekf"
    alpha: float = 0.5
    beta: float = 2.0
    kappa: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.q, tuple | list | np.ndarray):
            if len(self.q) != 2:
                raise ValueError(f"q: expected a float or (q_n, q_e), got {self.q!r}")
            q: Any = (_noise_coeff("q", self.q[0]), _noise_coeff("q", self.q[1]))
        else:
            q = _noise_coeff("q", self.q)
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "q_turn", _noise_coeff("q_turn", self.q_turn))
        if self.predictor not in ("ekf", "ukf"):
            raise ValueError(f"predictor: expected 'ekf' or 'ukf', got {self.predictor!r}")
        for name in ("alpha", "beta") + (("kappa",) if self.kappa is not None else ()):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float | np.integer | np.floating):
                raise TypeError(f"{name}: expected a float, got {type(v).__name__}")
            if not np.isfinite(v):
                raise ValueError(f"{name}: must be finite, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.alpha <= 0:
            raise ValueError(f"alpha: must be > 0, got {self.alpha!r}")
        if self.kappa is not None and 5 + self.kappa <= 0:
            raise ValueError(f"kappa: 5 + kappa must be > 0, got {self.kappa!r}")


def constant_velocity_turn_rate(q: float, q_turn: float) -> MotionModel:
    """The constant-velocity model of a 5-D turn-rate state [n, v_n, e, v_e, ω]:
    [ConstantVelocity(q), ConstantVelocity(q), RandomWalk(q_turn)] (q m² s⁻³, q_turn
    rad² s⁻³): the tracker's model (tentative tracks) and the CV mode beside `ConstantTurn`
    in an IMM; ω is carried (as a random walk) so that every mode shares one state."""
    from usvfast.kalman import ConstantVelocity, RandomWalk

    q = _noise_coeff("q", q)
    return (ConstantVelocity(q), ConstantVelocity(q), RandomWalk(_noise_coeff("q_turn", q_turn)))


@dataclass(frozen=True)
class IMM:
    """Interacting multiple models for the confirmed tracks (Blom and Bar-Shalom 1988).

    modes: motion models over the tracker's state (usvfast.kalman models such as
    constant_velocity_2d(q), or `KnownTurnRate(q, omega)`; on the 5-D state [n, v_n, e, v_e,
    ω] `ConstantTurn(q, q_turn)` beside e.g. `constant_velocity_turn_rate(q, q_w)`);
    transition (r, r): Markov switching matrix, transition[i, j] = P(mode j at the next scan |
    mode i now), rows summing to 1;
    initial (r,): mode probabilities of a newly confirmed track (default uniform). Each scan:
    mixing, mode predictions, a mode-conditioned update (Kalman update under GNN, PDA mixture
    with the track's JPDA association weights under JPDA), mode probabilities from the mode
    likelihoods, and the moment-matched output state (which gating and association use in its
    predicted form Σ c̄_j N(x_j⁻, P_j⁻)). filterpy's `IMMEstimator` on a single target.
    Tentative tracks use the initiator's model unless `MultiMeasurementInitiator(imm=True)`
    runs the bank on them too; `Tracks.mode_probabilities` holds μ.
    """

    modes: Sequence[Any]
    transition: Any
    initial: Any = None


@dataclass(frozen=True)
class Existence:
    """Track existence with visibility for confirmed JPDA tracks (IPDA, Mušicki, Evans and
    Stanković 1994; the visibility chain of Brekke et al.'s VIMMJIPDA).

    Per track: r = P(target exists), v = P(visible | exists). Each scan r⁻ = survival·r,
    v⁻ = v·vis_stay + (1 − v)(1 − invis_stay); with the likelihood ratio of the scan
    L = 1 − P_D P_G + Σ_i P_D N(z_i; ẑ, S)/λ over the track's gated detections (the JPDA
    hypothesis weights), r⁺ = r⁻(v⁻L + 1 − v⁻) / (r⁻(v⁻L + 1 − v⁻) + 1 − r⁻) and
    v⁺ = v⁻L / (v⁻L + 1 − v⁻). A confirmed track starts at r = initial, v = 1 and is deleted
    once r < delete (besides `deleter`). The defaults vis_stay = 1, invis_stay = 0 keep v = 1
    (plain IPDA); vis_stay < 1 lets a target exist unseen (behind another ship) without losing
    its existence.

    joint: JIPDA (Mušicki and Evans, IEEE Trans. AES 40(3), 2004, with the VIMMJIPDA's
    visibility) for the confirmed tracks instead of the per-track IPDA: in each JPDA cluster a
    track's hypotheses are weighted by its predicted r⁻v⁻ — missed 1 − P_D P_G r⁻v⁻, detection
    r⁻v⁻ P_D N(z; ẑ, S)/λ — so a track that probably does not exist yields its detections to one
    that does; from the joint marginals β (β_0 missed) r⁺ = β_0 r⁻(1 − P_D P_G v⁻)/(1 − P_D P_G
    r⁻v⁻) + Σ_{j≥1} β_j, v⁺ = (β_0 r⁻v⁻(1 − P_D P_G)/(1 − P_D P_G r⁻v⁻) + Σ_{j≥1} β_j)/r⁺, and
    the state is the mixture with the association probabilities given existence
    (β_0 r⁻(1 − P_D P_G v⁻)/((1 − P_D P_G r⁻v⁻) r⁺) missed, β_j/r⁺), which also decide
    whether the state is an update and which detections are kept from the initiator, and
    which `Tracks`/`TrackHistory` report as missed_probability and assoc_probability. A track
    alone in its cluster gets the IPDA's r⁺ and v⁺; its state is the IPDA's PDA update when
    v⁻ = 1, and
    weights the missed hypothesis by 1 − P_D P_G v⁻ (against v⁻ P_D N/λ) when v⁻ < 1 (a target
    may exist unseen). Under an IMM the mode likelihoods are those given existence
    (1 − P_D P_G v⁻ + v⁻ Σ P_D N_mode(z)/λ). Default False (per-track IPDA, as before).

    confirm: confirmation by existence. Tentative tracks then start at r = birth, are updated
    each scan with the likelihood ratio of their GNN-assigned detection
    (L = 1 − P_D P_G + P_D N(z; ẑ, S)/λ, or 1 − P_D P_G when missed), are confirmed once the
    initiator would confirm them (min_points / M-of-N) and r >= confirm, dropped once
    r < delete, and keep their r when confirmed. None: the initiator alone confirms and
    confirmed tracks start at r = initial.
    """

    survival: float = 0.99
    initial: float = 0.9
    delete: float = 0.05
    vis_stay: float = 1.0
    invis_stay: float = 0.0
    confirm: float | None = None
    birth: float = 0.5
    joint: bool = False


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
class Tracks:
    """Confirmed tracks after a step: ids (k,), times (k,) of the current states, states
    (k, ndim), covariances (k, ndim, ndim), is_update (k,) whether the last state was an
    update, n_updates (k,), first_scan (k,) the scan of the first state. The newest history
    entry's association data (as in TrackHistory): scan (k,), detection (k,),
    missed_probability (k,), and the hypothesised detections of track i,
    assoc_detection/assoc_probability[assoc_offsets[i]:assoc_offsets[i+1]].

    nis (k,) and nis_dof (k,): the normalised innovation squared yᵀ S⁻¹ y of the last update and
    its degrees of freedom (the measurement dimension) where the last state is an update with a
    detection's innovation (GNN: the assigned detection; JPDA: the most probable detection, the
    one `detection` names — the mixture itself has no single innovation); elsewhere (a
    prediction, or a tentative track's first state) nis is 0 with nis_dof 0, so `nis_dof > 0` is
    the mask of valid entries (no NaN). mode_probabilities (k, r): IMM mode probabilities
    ((k, 0) without an IMM). existence (k,), visibility (k,): the `Existence` probabilities
    (1 without an existence model; the initial value before a track's first scan)."""

    ids: np.ndarray
    times: np.ndarray
    states: np.ndarray
    covariances: np.ndarray
    is_update: np.ndarray
    n_updates: np.ndarray
    first_scan: np.ndarray
    scan: np.ndarray
    detection: np.ndarray
    missed_probability: np.ndarray
    assoc_offsets: np.ndarray
    assoc_detection: np.ndarray
    assoc_probability: np.ndarray
    nis: np.ndarray
    nis_dof: np.ndarray
    mode_probabilities: np.ndarray
    existence: np.ndarray
    visibility: np.ndarray

    def __len__(self) -> int:
        return len(self.ids)


@dataclass(frozen=True)
class TrackHistory:
    """Every state of one track (k entries, the tentative phase included).

    times (k,); states (k, ndim); covariances (k, ndim, ndim); is_update (k,); scan (k,) the
    0-based count of processed steps; sensor (k,) and detection (k,) of the most probable
    detection of an update (row in its scan's measurements), −1 otherwise; nis (k,) of that
    detection, NaN otherwise; missed_probability (k,); association probabilities of the
    hypothesised detections of entry i: assoc_detection/assoc_probability[
    assoc_offsets[i]:assoc_offsets[i+1]]. confirmed_time / deleted_time (NaN if alive).
    """

    id: int
    times: np.ndarray
    states: np.ndarray
    covariances: np.ndarray
    is_update: np.ndarray
    scan: np.ndarray
    sensor: np.ndarray
    detection: np.ndarray
    nis: np.ndarray
    missed_probability: np.ndarray
    assoc_offsets: np.ndarray
    assoc_detection: np.ndarray
    assoc_probability: np.ndarray
    confirmed_time: float
    deleted_time: float

    def to_dataframe(self) -> Any:
        """The history as a pandas DataFrame, one row per entry: time, scan, is_update, sensor,
        detection, nis, missed_probability, state columns x0..x{n-1} and the covariance
        diagonal var0..var{n-1}. Needs pandas."""
        try:
            import pandas as pd
        except ImportError as exc:  # pragma: no cover - depends on the environment
            raise ImportError(
                "TrackHistory.to_dataframe needs pandas (pip install pandas)"
            ) from exc
        cols: dict[str, Any] = {
            "track_id": np.full(len(self.times), self.id),
            "time": self.times,
            "scan": self.scan,
            "is_update": self.is_update,
            "sensor": self.sensor,
            "detection": self.detection,
            "nis": self.nis,
            "missed_probability": self.missed_probability,
        }
        diag = np.diagonal(self.covariances, axis1=1, axis2=2)
        for i in range(self.states.shape[1]):
            cols[f"x{i}"] = self.states[:, i]
        for i in range(self.states.shape[1]):
            cols[f"var{i}"] = diag[:, i]
        return pd.DataFrame(cols)

    def association_probabilities(self, i: int) -> dict[int, float]:
        """{detection row: probability} hypothesised at entry i."""
        a, b = self.assoc_offsets[i], self.assoc_offsets[i + 1]
        return dict(
            zip(
                self.assoc_detection[a:b].tolist(),
                self.assoc_probability[a:b].tolist(),
                strict=True,
            )
        )


@dataclass(frozen=True)
class StepStats:
    """What the last `Tracker.step` did: processed (False when dropped as out of order),
    clusters of confirmed tracks sharing gated detections (JPDA; 0 under GNN),
    approximated_clusters among them (belief propagation past `JPDA.max_hypotheses`, or
    method "lbp"), largest_cluster (tracks)."""

    processed: bool
    clusters: int
    approximated_clusters: int
    largest_cluster: int


@dataclass(frozen=True)
class RunResult:
    """Confirmed tracks after every scan of a batch run, one row per (scan, track):
    scan (r,), track_id (r,), time (r,), state (r, ndim), covariance (r, ndim, ndim),
    is_update (r,); dropped_scans: indices of scans dropped as out of order;
    approximated_clusters (s,): JPDA clusters approximated in each scan (see `JPDA`)."""

    scan: np.ndarray
    track_id: np.ndarray
    time: np.ndarray
    state: np.ndarray
    covariance: np.ndarray
    is_update: np.ndarray
    dropped_scans: np.ndarray
    approximated_clusters: np.ndarray


def _restore_tracker(
    cls: type[Tracker], sensors: tuple, m: int, last_step: StepStats | None, state: bytes
) -> Tracker:
    """Rebuilds a pickled `Tracker` (see `Tracker.__reduce__`)."""
    new = object.__new__(cls)
    new.sensors = tuple(sensors)
    new.last_step = last_step
    new._m = m
    new._busy = threading.Lock()
    new._core = _core.TrackerCore.from_bytes(state)
    return new


class Tracker:
    """Multi-target tracker (see the module docstring for the step and the parameters).

    motion_model: usvfast.kalman components (e.g. constant_velocity_2d(q)); sensors: list of
    `Sensor` (all with the same measurement dimension); association: `JPDA(...)` or `GNN(...)`;
    deleter of confirmed tracks; initiator: `MultiMeasurementInitiator`; use_joseph_cov:
    Joseph-form covariance update (Stone Soup's default is P − K S Kᵀ); symmetric_covariance:
    replace updated covariances by (P + Pᵀ)/2 (Stone Soup's force_symmetric_covariance, off
    there; on here: without it rounding asymmetry grows through long predictions and makes P
    indefinite, e.g. constant-acceleration models on Joyride); delete_last_prediction:
    Stone Soup's `delete_last_pred`; out_of_order: "raise" (TimeOrderError) or "drop";
    initiate_in_gates: see the module docstring; imm: an `IMM` bank for the confirmed tracks
    (its modes replace motion_model for them; for the tentative ones too with
    `MultiMeasurementInitiator(imm=True)`); existence: an `Existence` model for the
    confirmed tracks (JPDA only); max_deleted: keep at most this many deleted tracks (oldest
    dropped first; `drain_deleted` hands them out), None: all.

    Raises ValueError subclasses naming the argument on bad shapes (DimensionError), NaN/inf
    (NonFiniteError), non-positive-definite noise (NotPositiveDefiniteError) or probabilities
    outside (0, 1] (ValueError).
    """

    def __init__(
        self,
        *,
        motion_model: MotionModel,
        sensors: Sequence[Sensor],
        association: JPDA | GNN,
        deleter: Any,
        initiator: MultiMeasurementInitiator,
        use_joseph_cov: bool = False,
        symmetric_covariance: bool = True,
        delete_last_prediction: bool = False,
        out_of_order: Literal["raise", "drop"] = "raise",
        initiate_in_gates: bool = True,
        imm: IMM | None = None,
        existence: Existence | None = None,
        max_deleted: int | None = None,
    ) -> None:
        if not isinstance(association, JPDA | GNN):
            raise TypeError(f"association: expected JPDA or GNN, got {association!r}")
        if existence is not None and not isinstance(existence, Existence):
            raise TypeError(f"existence: expected Existence, got {existence!r}")
        if imm is not None and not isinstance(imm, IMM):
            raise TypeError(f"imm: expected IMM, got {imm!r}")
        if not isinstance(initiator, MultiMeasurementInitiator):
            raise TypeError(f"initiator: expected MultiMeasurementInitiator, got {initiator!r}")
        if isinstance(sensors, Sensor):
            sensors = [sensors]
        for i, s in enumerate(sensors):
            if not isinstance(s, Sensor):
                raise TypeError(f"sensors[{i}]: expected Sensor, got {s!r}")
        self.sensors = tuple(sensors)
        self.last_step: StepStats | None = None
        self._busy = threading.Lock()
        # The configuration objects cross into Rust as they are, read there by attribute.
        self._core = _core.TrackerCore(
            motion_model,
            list(sensors),
            association,
            deleter,
            initiator,
            use_joseph_cov=bool(use_joseph_cov),
            symmetric_covariance=bool(symmetric_covariance),
            delete_last_prediction=bool(delete_last_prediction),
            out_of_order=out_of_order,
            initiate_in_gates=bool(initiate_in_gates),
            imm=imm,
            existence=existence,
            max_deleted=None
            if max_deleted is None
            else _non_negative_int("max_deleted", max_deleted),
        )
        self._m = self._core.measurement_dim

    @contextmanager
    def _exclusive(self) -> Iterator[None]:
        """One call into the core at a time: a second thread gets a clear error instead of
        pyo3's "Already borrowed"."""
        if not self._busy.acquire(blocking=False):
            raise RuntimeError(
                "Tracker: used from two threads at once; a Tracker is not thread-safe (give each "
                "thread its own, e.g. copy.deepcopy(tracker))"
            )
        try:
            yield
        finally:
            self._busy.release()

    def __copy__(self) -> Tracker:
        """A real copy (copy.copy and copy.deepcopy alike): the copy and the original then
        advance independently."""
        new = object.__new__(type(self))
        new.sensors = self.sensors
        new.last_step = self.last_step
        new._m = self._m
        new._busy = threading.Lock()
        with self._exclusive():
            new._core = self._core.copy()
        return new

    def __deepcopy__(self, memo: dict[int, Any]) -> Tracker:
        return self.__copy__()

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickling: the whole state (configuration, tracks and histories, counters, IMM and
        existence states) goes out as bytes and comes back bit-exact, so a restored tracker
        (e.g. in a process pool) continues exactly like the original."""
        with self._exclusive():
            state = self._core.to_bytes()
        return (_restore_tracker, (type(self), self.sensors, self._m, self.last_step, state))

    def _detections(self, measurements: Any, sensor_ids: Any) -> tuple[np.ndarray, np.ndarray]:
        z = as_float_array("measurements", measurements)
        if z.size == 0:
            z = z.reshape(0, self._m)
        if z.ndim == 1 and self._m == 1:
            z = z.reshape(-1, 1)
        if z.ndim != 2 or z.shape[1] != self._m:
            raise _core.DimensionError(
                f"measurements: expected shape (k, {self._m}), got {z.shape}"
            )
        if sensor_ids is None:
            ids = np.zeros(len(z), dtype=np.int64)
        else:
            ids = np.asarray(sensor_ids)
            if ids.ndim == 0:
                ids = np.full(len(z), int(ids), dtype=np.int64)
            if ids.size == 0:
                ids = ids.astype(np.int64)
            if ids.dtype.kind not in "iu":
                raise TypeError(f"sensor_ids: expected integers, got dtype {ids.dtype}")
            ids = np.ascontiguousarray(ids, dtype=np.int64)
            if ids.shape != (len(z),):
                raise _core.DimensionError(
                    f"sensor_ids: expected shape ({len(z)},), got {ids.shape}"
                )
        return z, ids

    def _covariances(self, covariances: Any, k: int) -> np.ndarray | None:
        if covariances is None:
            return None
        c = as_float_array("covariances", covariances)
        if c.size == 0 and k == 0:
            c = c.reshape(0, self._m, self._m)
        if c.shape != (k, self._m, self._m):
            raise _core.DimensionError(
                f"covariances: expected shape ({k}, {self._m}, {self._m}), got {c.shape}"
            )
        return c

    def _origins(self, origins: Any, k: int) -> np.ndarray | None:
        if origins is None:
            return None
        o = as_float_array("origins", origins)
        if o.shape == (2,):
            o = np.ascontiguousarray(np.broadcast_to(o, (k, 2)))
        if o.size == 0 and k == 0:
            o = o.reshape(0, 2)
        if o.shape != (k, 2):
            raise _core.DimensionError(f"origins: expected shape ({k}, 2) or (2,), got {o.shape}")
        return o

    def step(
        self,
        t: float,
        measurements: Any = (),
        sensor_ids: Any = None,
        covariances: Any = None,
        origins: Any = None,
    ) -> Tracks:
        """Process the scan at time `t` (seconds): measurements (k, m), sensor_ids (k,) ints
        (default: all sensor 0; a scalar applies to all), covariances (k, m, m) each detection's
        own measurement noise (measurement units squared, symmetric positive definite; default:
        its sensor's R), origins (k, 2) or (2,) for all: the position of the sensor that made
        each detection in the state's mapped position coordinates (e.g. own-ship north, east
        in m; used by range–bearing sensors, ignored by linear ones; default (0, 0)). Returns
        the confirmed tracks. A bad covariance raises NotPositiveDefiniteError naming
        `covariances[i]`."""
        z, ids = self._detections(measurements, sensor_ids)
        c = self._covariances(covariances, len(z))
        o = self._origins(origins, len(z))
        with self._exclusive():
            self.last_step = StepStats(*self._core.step(float(t), z, ids, c, o))
        return self.tracks

    def run(
        self,
        times: ArrayLike,
        measurements: Any,
        sensor_ids: Any = None,
        scan_index: ArrayLike | None = None,
        covariances: Any = None,
        origins: Any = None,
    ) -> RunResult:
        """Run a whole recording in one Rust call: scan i at times[i] (s,) holds the rows of
        measurements (d, m) whose scan_index (d,) is i; sensor_ids (d,); covariances (d, m, m)
        per row as in `step` (NotPositiveDefiniteError names the row of the whole run);
        origins (d, 2) per row as in `step`.
        Returns the confirmed tracks after every scan."""
        t = as_float_array("times", times, ndim=1)
        z, ids = self._detections(measurements, sensor_ids)
        c = self._covariances(covariances, len(z))
        o = self._origins(origins, len(z))
        if scan_index is None:
            raise TypeError("scan_index: required, one scan number per measurement row")
        si = np.asarray(scan_index)
        if si.size == 0:
            si = si.astype(np.int64)
        if si.dtype.kind not in "iu":
            raise TypeError(f"scan_index: expected integers, got dtype {si.dtype}")
        si = np.ascontiguousarray(si, dtype=np.int64)
        if si.shape != (len(z),):
            raise _core.DimensionError(f"scan_index: expected shape ({len(z)},), got {si.shape}")
        with self._exclusive():
            out = self._core.run(t, z, ids, si, c, o)
        return RunResult(**out)

    def add_sensor(self, sensor: Sensor) -> int:
        """Register one more sensor between steps (tracks are kept); returns its index for
        `sensor_ids`. Same checks as the constructor's `sensors` (DimensionError when H does
        not fit the state or the shared measurement dimension)."""
        if not isinstance(sensor, Sensor):
            raise TypeError(f"sensor: expected Sensor, got {sensor!r}")
        with self._exclusive():
            idx = self._core.add_sensor(sensor)
        self.sensors = (*self.sensors, sensor)
        return idx

    def add_track(
        self,
        state: ArrayLike,
        covariance: ArrayLike,
        time: float,
        *,
        existence: float | None = None,
        visibility: float = 1.0,
    ) -> int:
        """Add a confirmed track (state (ndim,), covariance (ndim, ndim) at `time`); its first
        state is a prior, not an update. existence: its probability r in (0, 1] of existing,
        with visibility v in [0, 1] (needs the tracker's `Existence` model); None: the
        model's `initial`, visible. Returns its id."""
        rv = None
        if existence is not None:
            rv = (_probability("existence", existence), _probability("visibility", visibility))
        elif visibility != 1.0:
            raise ValueError("visibility: needs existence (the track's r) as well")
        with self._exclusive():
            return self._core.add_track(
                as_float_array("state", state, ndim=1),
                as_float_array("covariance", covariance, ndim=2),
                float(time),
                rv,
            )

    @property
    def tracks(self) -> Tracks:
        """The confirmed, alive tracks."""
        with self._exclusive():
            return Tracks(**self._core.snapshot())

    @property
    def tentative_tracks(self) -> Tracks:
        """The initiator's tentative tracks (their ids are a separate counter)."""
        with self._exclusive():
            return Tracks(**self._core.snapshot(tentative=True))

    @property
    def deleted_track_ids(self) -> np.ndarray:
        """Ids of deleted confirmed tracks, in order of deletion."""
        return self._core.track_ids()[1]

    def history(self, track_id: int) -> TrackHistory:
        """Every state of a confirmed track, alive or deleted."""
        return TrackHistory(**self._core.history(_non_negative_int("track_id", track_id)))

    def drain_deleted(self) -> list[TrackHistory]:
        """Remove the deleted tracks kept so far and return their histories (in order of
        deletion); memory then stays bounded over long runs."""
        with self._exclusive():
            return [TrackHistory(**h) for h in self._core.drain_deleted()]

    @property
    def capped_detections(self) -> int:
        """Detections that started no tentative track because of `max_new_tentative`."""
        return self._core.capped_detections

    @property
    def dropped_scans(self) -> int:
        """Number of scans dropped as out of order (out_of_order="drop")."""
        return self._core.dropped_scans

    @property
    def last_time(self) -> float | None:
        """Time of the last processed scan."""
        return self._core.last_time


def code_5_7(sensors: Sequence[Sensor], association: Any = None, **kw: Any) -> Tracker:
    """The thesis's Code 5.7 tracker: constant velocity (q = 0.001 m²/s³), JPDA (P_D 0.85,
    P_G 0.95, clutter 0.125 per m²) unless `association` is given, deletion at covariance
    trace 1.5 or 35 steps without update, and a 2-point initiator (prior velocity variance
    0.3 m²/s², tentative deletion after 3 steps, GNN distance 0.3). `kw` goes to `Tracker`."""
    from usvfast.kalman import constant_velocity_2d

    return Tracker(
        motion_model=constant_velocity_2d(0.001),
        sensors=list(sensors),
        association=JPDA(0.85, 0.95, 0.125) if association is None else association,
        deleter=AnyOf(CovarianceTrace(1.5), StepsSinceUpdate(35)),
        initiator=MultiMeasurementInitiator(
            np.zeros(4),
            np.diag([0, 0.3, 0, 0.3]),
            min_points=2,
            deleter=StepsSinceUpdate(3),
            missed_distance=0.3,
        ),
        **kw,
    )
