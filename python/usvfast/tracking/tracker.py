"""`usvfast.tracking.Tracker`: the native JPDA / GNN multi-target tracker and what its steps
return (tracks, histories, step statistics, batch results)."""

from __future__ import annotations

import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from usvfast import _core
from usvfast._validate import as_float_array, as_index_array
from usvfast.kalman import MotionModel
from usvfast.tracking.components import (
    GNN,
    JPDA,
    AnyOf,
    CovarianceTrace,
    MultiMeasurementInitiator,
    Sensor,
    StepsSinceUpdate,
    _non_negative_int,
    _probability,
)
from usvfast.tracking.models import IMM, Existence


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
            ids = as_index_array("sensor_ids", ids, len(z))
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
        si = as_index_array("scan_index", scan_index, len(z))
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
