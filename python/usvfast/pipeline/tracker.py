"""The tracker stage: two position sensors (0 = LiDAR, 1 = camera) into a JPDA (or GNN)
tracker built from the [tracker] table (defaults: the thesis's Code 5.7), run by the native
`usvfast.tracking.Tracker` or, with `backend = "stonesoup"`, by Stone Soup's own
`MultiTargetMixtureTracker` / `MultiTargetTracker` with the same components (each detection
then carries a `LinearGaussian` with its own covariance, as Code 5.8 packages them).

Both backends take scans `(t, z (k, 2), sensor (k,), R (k, 2, 2)[, starts (k,)])` and return
a `Snapshot` of the confirmed tracks plus, for every track updated by a detection, its
normalised innovation squared (NIS) against the prediction from the track's previous state.
A detection with `starts` False (e.g. a camera box scored under camera.start_confidence) may
update tracks, tentative ones included, but never starts one: the native tracker gives it to a
copy of its sensor with `Sensor.starts_tracks = False`; Stone Soup's initiator drops the
tentative tracks it would start (`usvfast.pipeline.stonesoup_gates.StartingInitiator`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from datetime import datetime, timedelta
from typing import Any

import numpy as np

__all__ = [
    "SENSORS",
    "VESSEL_IDS",
    "Snapshot",
    "join_snapshots",
    "make_tracker",
    "make_vessel_tracker",
]

#: First track id of the vessel tracker (tracker.vessels).
VESSEL_IDS = 100000

SENSORS = ("lidar", "camera")
_H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
_EPOCH = datetime(2000, 1, 1)


@dataclass(frozen=True)
class Snapshot:
    """Confirmed tracks after a scan: ids (k,), states (k, 4) [n, v_n, e, v_e], covariances
    (k, 4, 4); innovations: (track id, sensor index, NIS) of the tracks a detection updated."""

    ids: np.ndarray
    states: np.ndarray
    covariances: np.ndarray
    innovations: list[tuple[int, int, float]]


def _cv(q: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    f1 = np.array([[1.0, dt], [0.0, 1.0]])
    q1 = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    f, qq = np.zeros((4, 4)), np.zeros((4, 4))
    f[:2, :2] = f[2:, 2:] = f1
    qq[:2, :2] = qq[2:, 2:] = q1
    return f, qq


class _Base:
    def __init__(self, settings: dict[str, Any]) -> None:
        self.s = settings
        self.per_detection = bool(settings["per_detection_covariance"])
        self.r = [
            np.eye(2) * settings["lidar_noise_std"] ** 2,
            np.eye(2) * settings["camera_noise_std"] ** 2,
        ]

    @property
    def nis_gate(self) -> float:
        """The gate probability P_G of the reported NIS: a detection updates a track only
        inside its gate (JPDA: prob_gate; GNN: the χ²(2) probability of gnn_missed_distance²)."""
        if self.s["association"] == "gnn":
            from scipy.stats import chi2

            return float(chi2.cdf(float(self.s["gnn_missed_distance"]) ** 2, 2))
        return float(self.s["prob_gate"])


class NativeTracker(_Base):
    """`usvfast.tracking.Tracker` with the [tracker] settings; per-detection covariances go
    through `Tracker.step(..., covariances=)` (per_detection_covariance; otherwise each
    sensor's R is used), and the NIS is the tracker's own."""

    def __init__(self, settings: dict[str, Any]) -> None:
        super().__init__(settings)
        from usvfast import tracking as tk
        from usvfast.kalman import RandomWalk, constant_velocity_2d

        s = settings
        prior = np.diag([0.0, s["prior_velocity_var"], 0.0, s["prior_velocity_var"]])
        motion: Any = constant_velocity_2d(s["q"])
        lidar = tk.Sensor.position(s["lidar_noise_std"])
        camera = tk.Sensor.position(s["camera_noise_std"])
        offsets = [
            (name, float(s[f"{name}_offset_std"]), float(s[f"{name}_offset_q"]))
            for name in ("lidar", "camera")
            if float(s[f"{name}_offset_std"]) > 0
        ]
        if offsets:
            # State [n, v_n, e, v_e, (b_n, b_e) per sensor with an offset]: b that sensor's
            # offset for this track (a slow random walk), seen by that sensor only; a
            # detection starts a track at its position with b = 0 and prior std
            # <sensor>_offset_std, from its position rows with the sensor's R (the position is
            # the detection less an unknown offset: with the detection's own R the track is
            # sure of a biased start and the other sensor's detections fall outside its gate).
            ndim = 4 + 2 * len(offsets)
            motion = (*motion, *(rw for _, _, q in offsets for rw in (RandomWalk(q),) * 2))
            var = [sd * sd for _, sd, _ in offsets for _ in (0, 1)]
            prior = np.diag([0.0, s["prior_velocity_var"], 0.0, s["prior_velocity_var"], *var])
            cols = {name: 4 + 2 * i for i, (name, _, _) in enumerate(offsets)}

            def sensor(name: str) -> Any:
                base = tk.Sensor.position(s[f"{name}_noise_std"], ndim_state=ndim)
                if name not in cols:
                    return base
                h = base.measurement_matrix.copy()
                h[0, cols[name]] = h[1, cols[name] + 1] = 1.0
                return tk.Sensor(
                    h, base.measurement_noise, base.measurement_matrix, base.measurement_noise
                )

            lidar, camera = sensor("lidar"), sensor("camera")
        deleter: Any = (
            tk.StepsSinceUpdate(s["delete_steps"])
            if s["deletion"] == "steps"
            else tk.TimeSinceUpdate(s["delete_after_s"])
        )
        init_deleter = (
            tk.StepsSinceUpdate(s["init_delete_steps"])
            if s["deletion"] == "steps"
            else tk.TimeSinceUpdate(s["init_delete_after_s"])
        )
        if s["covariance_trace"] is not None:
            deleter = tk.AnyOf(tk.CovarianceTrace(s["covariance_trace"]), deleter)
        if s["association"] == "gnn":
            assoc: Any = tk.GNN(missed_distance=s["gnn_missed_distance"])
        else:
            assoc = tk.JPDA(
                prob_detect=s["prob_detect"],
                prob_gate=s["prob_gate"],
                clutter_density=s["clutter_density"],
                method=s["method"],
            )
        # Sensors 2 and 3: the LiDAR and the camera for detections that start no track.
        no_start = [replace(sensor, starts_tracks=False) for sensor in (lidar, camera)]
        self.tracker = tk.Tracker(
            motion_model=motion,
            sensors=[lidar, camera, *no_start],
            association=assoc,
            deleter=deleter,
            initiator=tk.MultiMeasurementInitiator(
                prior_state=np.zeros(len(prior)),
                prior_covariance=prior,
                min_points=s["min_points"],
                deleter=init_deleter,
                missed_distance=s["missed_distance"],
            ),
            initiate_in_gates=s["initiate_in_gates"],
        )
        self.uses_detection_covariance = self.per_detection

    def step(
        self,
        t: float,
        z: np.ndarray,
        sensors: np.ndarray,
        covs: np.ndarray | None,
        starts: np.ndarray | None = None,
    ) -> Snapshot:
        """One scan at t (s since the pipeline's epoch); `starts` (k,) bool: which detections
        may start tracks (None: all)."""
        ids = sensors if starts is None else np.where(starts, sensors, sensors + len(SENSORS))
        if self.uses_detection_covariance and covs is not None and len(z):
            tracks = self.tracker.step(t, z, ids, covariances=covs)
        else:
            tracks = self.tracker.step(t, z, ids)
        # the tracker's own NIS of each track's last update
        upd = (tracks.nis_dof > 0) & (tracks.times == t) & (tracks.detection >= 0)
        nis = [
            (int(i), int(sensors[d]), float(v))
            for i, d, v in zip(
                tracks.ids[upd].tolist(),
                tracks.detection[upd].tolist(),
                tracks.nis[upd].tolist(),
                strict=True,
            )
        ]
        # the state's first four entries: [n, v_n, e, v_e] (a camera offset may follow)
        return Snapshot(tracks.ids, tracks.states[:, :4], tracks.covariances[:, :4, :4], nis)


class StoneSoupTracker(_Base):
    """Stone Soup's own tracker with the same components (thesis Codes 5.7-5.8); with
    `initiate_in_gates = false` its `MultiMeasurementInitiator` is wrapped in
    `usvfast.pipeline.stonesoup_gates.InGateInitiator` (the native duplicate suppression)."""

    def __init__(self, settings: dict[str, Any]) -> None:
        super().__init__(settings)
        try:
            import stonesoup  # noqa: F401
        except ImportError as exc:  # pragma: no cover - optional dependency
            raise ValueError(
                "tracker.backend: 'stonesoup' needs Stone Soup (pip install usvfast[stonesoup])"
            ) from exc
        from scipy.stats import chi2
        from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
        from stonesoup.dataassociator.probability import JPDA
        from stonesoup.deleter.error import CovarianceBasedDeleter
        from stonesoup.deleter.multi import CompositeDeleter
        from stonesoup.deleter.time import UpdateTimeDeleter, UpdateTimeStepsDeleter
        from stonesoup.hypothesiser.distance import DistanceHypothesiser
        from stonesoup.hypothesiser.probability import PDAHypothesiser
        from stonesoup.measures import Mahalanobis
        from stonesoup.models.measurement.linear import LinearGaussian
        from stonesoup.models.transition.linear import (
            CombinedLinearGaussianTransitionModel,
            ConstantVelocity,
        )
        from stonesoup.predictor.kalman import KalmanPredictor
        from stonesoup.tracker.simple import MultiTargetMixtureTracker, MultiTargetTracker
        from stonesoup.types.state import GaussianState
        from stonesoup.updater.kalman import KalmanUpdater

        from usvfast.pipeline.stonesoup_gates import (
            GateRecorder,
            InGateInitiator,
            StartingInitiator,
            duplicate_gate,
        )

        s = settings
        self._LinearGaussian = LinearGaussian
        from stonesoup.types.detection import Detection

        self._Detection = Detection
        self.models = [LinearGaussian(4, [0, 2], r) for r in self.r]
        transition = CombinedLinearGaussianTransitionModel(
            [ConstantVelocity(s["q"]), ConstantVelocity(s["q"])]
        )
        predictor = KalmanPredictor(transition)
        # Every pipeline detection carries its own model; the updater's is never used.
        updater = KalmanUpdater(self.models[0])

        def by_time(seconds: float | None, steps: int) -> Any:
            if s["deletion"] == "steps":
                return UpdateTimeStepsDeleter(time_steps_since_update=steps)
            assert seconds is not None  # a time deleter always has its seconds
            return UpdateTimeDeleter(timedelta(seconds=seconds))

        deleter: Any = by_time(s["delete_after_s"], s["delete_steps"])
        if s["covariance_trace"] is not None:
            deleter = CompositeDeleter(
                [CovarianceBasedDeleter(covar_trace_thresh=s["covariance_trace"]), deleter],
                intersect=False,
            )
        initiator: Any = StartingInitiator(
            prior_state=GaussianState(
                np.zeros((4, 1)),
                np.diag([0.0, s["prior_velocity_var"], 0.0, s["prior_velocity_var"]]),
            ),
            measurement_model=None,
            deleter=by_time(s["init_delete_after_s"], s["init_delete_steps"]),
            data_associator=GNNWith2DAssignment(
                DistanceHypothesiser(
                    predictor, updater, measure=Mahalanobis(), missed_distance=s["missed_distance"]
                )
            ),
            updater=updater,
            min_points=s["min_points"],
        )
        in_gates = bool(s["initiate_in_gates"])
        if s["association"] == "gnn":
            assoc: Any = GNNWith2DAssignment(
                DistanceHypothesiser(
                    predictor,
                    updater,
                    measure=Mahalanobis(),
                    missed_distance=s["gnn_missed_distance"],
                )
            )
            cls: Any = MultiTargetTracker
            gate, recorder = float(s["gnn_missed_distance"]) ** 2, None
        else:
            hyp: Any = PDAHypothesiser(
                predictor=predictor,
                updater=updater,
                clutter_spatial_density=s["clutter_density"],
                prob_detect=s["prob_detect"],
                prob_gate=s["prob_gate"],
            )
            gate, recorder = float(chi2.ppf(float(s["prob_gate"]), 2)), None
            if not in_gates:
                hyp = recorder = GateRecorder(hyp)
            assoc = JPDA(hyp)
            cls = MultiTargetMixtureTracker
        if not in_gates:
            # The native duplicate suppression (usvfast.pipeline.stonesoup_gates).
            initiator = InGateInitiator(
                initiator=initiator,
                updater=updater,
                gate_threshold=duplicate_gate(gate),
                recorder=recorder,
                sensor_models=self.models,
            )
        self.tracker = cls(
            initiator=initiator,
            deleter=deleter,
            detector=None,
            data_associator=assoc,
            updater=updater,
        )
        if not in_gates:
            initiator.confirmed = lambda: self.tracker.tracks
        self._ids: dict[int, int] = {}
        self._next = 0
        self._prev: dict[int, tuple[float, np.ndarray, np.ndarray]] = {}

    def _noise(self, sensors: np.ndarray, covs: np.ndarray | None) -> np.ndarray:
        if self.per_detection and covs is not None:
            return covs
        return np.array([self.r[int(s)] for s in sensors]).reshape(-1, 2, 2)

    def _nis(
        self,
        t: float,
        ids: np.ndarray,
        rows: np.ndarray,
        z: np.ndarray,
        sensors: np.ndarray,
        noise: np.ndarray,
    ) -> list[tuple[int, int, float]]:
        out = []
        for tid, row in zip(ids.tolist(), rows.tolist(), strict=True):
            if row < 0 or tid not in self._prev:
                continue
            t0, x, p = self._prev[tid]
            f, q = _cv(self.s["q"], t - t0)
            xp, pp = f @ x, f @ p @ f.T + q
            y = z[row] - _H @ xp
            s = _H @ pp @ _H.T + noise[row]
            out.append((int(tid), int(sensors[row]), float(y @ np.linalg.solve(s, y))))
        return out

    def _remember(self, t: float, ids: np.ndarray, states: np.ndarray, covs: np.ndarray) -> None:
        self._prev = {int(i): (t, states[k], covs[k]) for k, i in enumerate(ids.tolist())}

    def step(
        self,
        t: float,
        z: np.ndarray,
        sensors: np.ndarray,
        covs: np.ndarray | None,
        starts: np.ndarray | None = None,
    ) -> Snapshot:
        """One scan at t (s since the pipeline's epoch, microsecond resolution); `starts` (k,)
        bool: which detections may start tracks (None: all)."""
        ts = _EPOCH + timedelta(seconds=round(t, 6))
        noise = self._noise(sensors, covs)
        dets = []
        for k in range(len(z)):
            model = (
                self._LinearGaussian(4, [0, 2], noise[k])
                if self.per_detection and covs is not None
                else self.models[int(sensors[k])]
            )
            dets.append(
                self._Detection(
                    z[k].reshape(2, 1),
                    timestamp=ts,
                    measurement_model=model,
                    metadata={
                        "sensor": int(sensors[k]),
                        "row": k,
                        "starts": True if starts is None else bool(starts[k]),
                    },
                )
            )
        row_of = {id(d): k for k, d in enumerate(dets)}
        _, tracks = self.tracker.update_tracker(ts, set(dets))
        from stonesoup.types.update import Update

        new = [tr for tr in tracks if id(tr) not in self._ids]
        new.sort(key=lambda tr: (float(tr.state_vector[0, 0]), float(tr.state_vector[2, 0])))
        for tr in new:
            self._ids[id(tr)] = self._next
            self._next += 1
        # Forget deleted tracks (their id() may be reused by new objects).
        self._ids = {id(tr): self._ids[id(tr)] for tr in tracks}
        order = sorted(tracks, key=lambda tr: self._ids[id(tr)])
        ids = np.array([self._ids[id(tr)] for tr in order], dtype=np.int64)
        states = np.array([np.asarray(tr.state_vector, float).ravel() for tr in order]).reshape(
            -1, 4
        )
        pp = np.array([np.asarray(tr.covar, float) for tr in order]).reshape(-1, 4, 4)
        rows = np.full(len(order), -1, dtype=np.int64)
        for i, tr in enumerate(order):
            st: Any = tr.state  # Stone Soup's State; an Update carries its hypothesis
            if not isinstance(st, Update) or tr.timestamp != ts:
                continue
            hyp: Any = st.hypothesis
            if hasattr(hyp, "measurement"):  # a single hypothesis (GNN, the initiator)
                best = hyp if hyp else None
            else:  # JPDA: the most probable detection of the mixture
                best = max((h for h in hyp if h), key=lambda h: h.probability, default=None)
            if best is not None and id(best.measurement) in row_of:
                rows[i] = row_of[id(best.measurement)]
        nis = self._nis(t, ids, rows, z, sensors, noise)
        self._remember(t, ids, states, pp)
        return Snapshot(ids, states, pp, nis)


def make_tracker(settings: dict[str, Any]) -> NativeTracker | StoneSoupTracker:
    """The tracker of the [tracker] table (`backend` "native" or "stonesoup")."""
    if settings["backend"] == "stonesoup":
        return StoneSoupTracker(settings)
    return NativeTracker(settings)


def make_vessel_tracker(settings: dict[str, Any]) -> NativeTracker | StoneSoupTracker | None:
    """The moving vessels' tracker of the [tracker] table (`vessels = true`; None otherwise):
    the same tracker with the vessel_* settings (config.py) for q, the velocity prior, the
    time and covariance-trace deletion."""
    if not settings.get("vessels"):
        return None
    s = dict(settings)
    s["q"] = settings["vessel_q"]
    s["prior_velocity_var"] = settings["vessel_prior_velocity_var"]
    s["camera_offset_std"] = settings["vessel_camera_offset_std"]
    s["lidar_offset_std"] = 0.0
    s["covariance_trace"] = settings["vessel_covariance_trace"]
    if s["deletion"] == "time":
        s["delete_after_s"] = settings["vessel_delete_after_s"]
    return make_tracker(s)


def join_snapshots(floats: Snapshot, vessels: Snapshot, offset: int) -> Snapshot:
    """One Snapshot of two trackers' scans: the second's track ids shifted by `offset`."""
    ids = np.concatenate([floats.ids, vessels.ids + offset]).astype(np.int64)
    inn = floats.innovations + [(i + offset, k, v) for i, k, v in vessels.innovations]
    return Snapshot(
        ids,
        np.vstack([floats.states.reshape(-1, 4), vessels.states.reshape(-1, 4)]),
        np.concatenate(
            [floats.covariances.reshape(-1, 4, 4), vessels.covariances.reshape(-1, 4, 4)]
        ),
        inn,
    )
