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

from usvfast.tracking.components import (
    GNN,
    JPDA,
    AllOf,
    AnyOf,
    BearingRange,
    CovarianceTrace,
    MultiMeasurementInitiator,
    NeverDelete,
    Sensor,
    StepsSinceUpdate,
    TimeSinceUpdate,
)
from usvfast.tracking.models import (
    IMM,
    ConstantTurn,
    Existence,
    KnownTurnRate,
    constant_velocity_turn_rate,
)
from usvfast.tracking.tracker import RunResult, StepStats, Tracker, TrackHistory, Tracks, code_5_7

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
