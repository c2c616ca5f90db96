"""The Stone Soup drop-in trackers (`usvfast.stonesoup.MultiTargetMixtureTracker` and
`MultiTargetTracker`): Stone Soup's tracker protocol on the usvfast core.

Per scan the drop-in hands the detections to the core and reads the ids of the confirmed
tracks in one native call (`usvfast._core.stonesoup_step`: plain Stone Soup detections of
known measurement models, read from their `__dict__`; any other scan goes through Python,
which registers new models and reports bad detections); a new id gets a Stone Soup `Track`, a
vanished one is dropped from the set.
The tracks' states (and their association hypotheses and metadata) are built when a track is
first read (`usvfast.stonesoup_lazy`, `usvfast.stonesoup_build`), exactly as Stone Soup would
have appended them; a track nobody reads is built at the latest `_LAZY_HORIZON` scans later,
so that the detections it refers to can be freed. Transition matrices are cached per time
step; detections of old scans are freed in batches.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from usvfast import _core, kalman
from usvfast.stonesoup import (
    PolarSensor,
    UnsupportedComponentError,
    build_native,
    detection_model,
    read_components,
)
from usvfast.stonesoup_build import Filler, StateBuilder, _attribute
from usvfast.stonesoup_lazy import LazyList
from usvfast.stonesoup_objects import StoneSoupObjects


def _raw_core(tracker: Any) -> Any:
    """The Rust core behind a `usvfast.tracking.Tracker` when it offers `step(t, z, ids,
    covariances, origins)` and `snapshot(tentative=False)` (dict of arrays), else None (the
    public `Tracker` API is used then). The drop-in owns its tracker and calls it from one
    thread, so it can skip the wrapper's argument checks (the core validates again) and its
    dataclass snapshot: ~20 µs per scan."""
    raw = getattr(tracker, "_core", None)
    ok = all(callable(getattr(raw, k, None)) for k in ("step", "snapshot", "track_ids", "history"))
    return raw if ok else None


# At most this many measurement models remembered by identity (one per detection when a radar
# moves and each detection carries its own translation).
_MODEL_CACHE = 4096


def _core_sensor(spec: tuple) -> Any:
    """The `usvfast.tracking.Sensor` of a sensor spec: ("linear", H, R, H_init, R_init) or
    ("polar", mapping, ndim, R, update kind)."""
    from usvfast import tracking as tk

    if spec[0] == "linear":
        return tk.Sensor(*spec[1:])
    _, mapping, ndim, noise, kind = spec
    if kind[0] == "ekf":
        return tk.Sensor.bearing_range(noise=noise, update="ekf", ndim_state=ndim, mapping=mapping)
    _, alpha, beta, kappa = kind
    return tk.Sensor.bearing_range(
        noise=noise,
        update="ukf",
        ndim_state=ndim,
        mapping=mapping,
        alpha=alpha,
        beta=beta,
        kappa=kappa,
    )


# Scans between two looks at the tentative tracks to free old detections (a look costs a
# snapshot of the tentative tracks).
_FREE_EVERY = 4
# A track's states are built when first read, or at the latest this many scans later (so
# that the detections they refer to can be freed).
_LAZY_HORIZON = 64


class _DropInTracker(StateBuilder):
    """Shared machinery of the two drop-in trackers (see the module docstring)."""

    _mixture = True

    def __init__(
        self,
        initiator: Any,
        deleter: Any,
        detector: Any = None,
        data_associator: Any = None,
        updater: Any = None,
        *,
        hypotheses: bool = True,
    ) -> None:
        for name, value in (
            ("initiator", initiator),
            ("deleter", deleter),
            ("data_associator", data_associator),
            ("updater", updater),
        ):
            if value is None:
                raise TypeError(f"{name}: a Stone Soup component is required")
        self.initiator = initiator
        self.deleter = deleter
        self.detector = detector
        self.data_associator = data_associator
        self.updater = updater
        self.hypotheses = bool(hypotheses)
        self.config = read_components(
            initiator=initiator,
            deleter=deleter,
            data_associator=data_associator,
            updater=updater,
            mixture=self._mixture,
        )
        self.detector_iter = None
        self._objects = StoneSoupObjects()
        self._raw: Any = None  # the Rust core of `_core` when its fast calls are available
        # Transition matrices (F, Q) of the tracker's and the initiator's models per time step.
        self._fq: dict[tuple[bool, float], tuple[np.ndarray, np.ndarray]] = {}
        self._core: Any = None
        self._sensor_specs: list[tuple] = []  # per core sensor, see `_core_sensor`
        # id(model) -> (core sensor index, the model's R if it differs from the sensor's)
        self._sensor_of_model: dict[int, tuple] = {}
        self._models: list[Any] = []  # keeps the models alive while their id() is used
        # Empty scans seen before the core exists (it is built at the first detection).
        self._replay: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._t0: Any = None
        self._scan = 0
        self._scan_time: list[Any] = []
        # Detections per scan; scans no history entry can refer to any more are freed (None).
        self._scan_dets: list[list[Any] | None] = []
        self._freed = 0
        self._tracks: dict[int, Any] = {}  # alive confirmed tracks by core id
        self._fillers: dict[int, Filler] = {}  # of the alive tracks
        # Fillers of tracks that may lack states (alive ones, deleted ones not read since).
        self._pending: dict[int, Filler] = {}
        self._scan_md: dict[int, bool] = {}  # scan -> a detection of it carries metadata
        self._history_start = True  # the core's history(track_id, start) is available
        self._newest_cache: dict | None = None  # see `_newest`
        self._newest_models: list = []  # see `StateBuilder._newest_batch`
        self._newest_z = np.empty((0, 2))
        self._batch_scan = -1
        self._scan_seconds = (0.0, 0.0)
        self._kit: Any = None  # see `StateBuilder._native_kit`
        from stonesoup.types.track import Track

        self._track_cls = Track
        # A scan in one native call (see `_step`), for the detection classes in `_plain`
        # (see `_plain_detection_class`).
        self._fast_step = _core.stonesoup_step
        self._plain: set[type] = set()
        self._noises: list[np.ndarray] = []  # the core sensors' noise covariances R
        self._inputs: dict[int, tuple] = {}  # see `StateBuilder._scan_inputs`
        self._newest_md: tuple[int, bool] = (-1, False)  # (scan, a detection has metadata)
        self._phases: dict = {}  # see `StateBuilder._phase`
        self._hr: dict = {}  # see `StateBuilder._linear_model`

    # -- Stone Soup's Tracker protocol -------------------------------------------------------

    @property
    def tracks(self) -> set:
        """The current confirmed tracks (set of stonesoup Track)."""
        return set(self._tracks.values())

    def __iter__(self):
        if self.detector is None:
            raise AttributeError(
                "Detector has not been set. A detector attribute is required to iterate over a "
                "tracker."
            )
        if self.detector_iter is None:
            self.detector_iter = iter(self.detector)
        return self

    def __next__(self):
        if self.detector_iter is None:
            iter(self)
        it: Any = self.detector_iter
        time, detections = next(it)
        return self._step(time, detections)

    def update_tracker(self, time: Any, detections: Any):
        """Process one scan (datetime, set of Detection) without a detector; returns
        (time, tracks) like iterating does."""
        return self._step(time, detections)

    # -- internals ---------------------------------------------------------------------------

    def _sensor_index(self, model: Any) -> tuple[int, np.ndarray | None, np.ndarray | None]:
        """(core sensor, the model's noise R when it differs from that sensor's or None, the
        sensor position for a range-bearing model or None) of a detection's measurement
        model. Linear models with the same H share one core sensor, range-bearing models with
        the same mapping too; their own R goes to the core as a per-detection covariance."""
        key = id(model)
        hit = self._sensor_of_model.get(key)
        if hit is not None:
            return hit
        cfg = self.config
        origin = None
        if model is None:
            main, init = cfg.fallback_sensor, cfg.init_fallback_sensor
            if main is None or init is None:
                raise ValueError(
                    "detections: a detection has no measurement_model and the updater or the "
                    "initiator has none to fall back on"
                )
            upd = cfg.init_update_fallback_sensor
            if upd is not None and not upd.same_as(main):
                raise UnsupportedComponentError(
                    "initiator.updater.measurement_model differs from updater.measurement_model:"
                    " detections without a model would be updated with two different models"
                )
            spec: tuple = ("linear", main.matrix, main.noise, init.matrix, init.noise)
        else:
            s, where = detection_model(model, "detection.measurement_model")
            ndim = s.ndim if isinstance(s, PolarSensor) else s.matrix.shape[1]
            if ndim != len(cfg.prior_state):
                raise ValueError(
                    f"detection.measurement_model: ndim_state {ndim} differs from the "
                    f"transition model's {len(cfg.prior_state)}"
                )
            if isinstance(s, PolarSensor):
                spec = ("polar", s.mapping, s.ndim, s.noise, cfg.radar_update())
                origin = where
            else:
                spec = ("linear", s.matrix, s.noise, None, None)
        idx = self._find_or_add(spec)
        noise = spec[2] if spec[0] == "linear" else spec[3]
        have = self._sensor_specs[idx]
        own = None if np.array_equal(have[2] if have[0] == "linear" else have[3], noise) else noise
        if len(self._sensor_of_model) >= _MODEL_CACHE:
            # One model per detection (a moving radar): keep the cache bounded.
            self._sensor_of_model.clear()
            self._models.clear()
        self._sensor_of_model[key] = (idx, own, origin)
        self._models.append(model)
        return idx, own, origin

    def _find_or_add(self, spec: tuple) -> int:
        """Index of the core sensor for `spec` (same kind, same H / mapping and initiation
        model; R may differ), registering a new one when none fits."""

        def same(a: Any, b: Any) -> bool:
            return (a is None and b is None) or (
                a is not None and b is not None and np.array_equal(a, b)
            )

        for i, old in enumerate(self._sensor_specs):
            if old[0] != spec[0]:
                continue
            if spec[0] == "linear":
                if same(old[1], spec[1]) and same(old[3], spec[3]) and same(old[4], spec[4]):
                    return i
            elif old[1] == spec[1] and old[2] == spec[2] and old[4] == spec[4]:
                return i
        self._sensor_specs.append(spec)
        if self._core is not None:
            self._core.add_sensor(_core_sensor(spec))
        return len(self._sensor_specs) - 1

    def _new_core(self) -> Any:
        sensors = [_core_sensor(spec) for spec in self._sensor_specs]
        return build_native(self.config, sensors)

    def _noise(self, idx: int) -> np.ndarray:
        spec = self._sensor_specs[idx]
        return spec[2] if spec[0] == "linear" else spec[3]

    def _step(self, time: Any, detections: Any):
        dets = list(detections)
        if self._raw is not None:
            # Every detection of a known class, model and shape: read, stepped and the alive
            # ids listed in one native call (else None, and the long way below).
            t = (time - self._t0).total_seconds()
            noises = self._noises
            if len(noises) != len(self._sensor_specs):
                noises[:] = [self._noise(i) for i in range(len(self._sensor_specs))]
            m = noises[0].shape[0]
            got = self._fast_step(
                self._raw, t, dets, time, self._sensor_of_model, self._plain, noises, m
            )
            if got is not None:
                alive, z, models, md = got
                self._newest_models, self._newest_z = models, z
                self._newest_md = (self._scan, md)
                return self._stepped(time, t, dets, alive)
        for d in dets:
            cls = type(d)
            if cls not in self._plain and _plain_detection_class(cls):
                self._plain.add(cls)
        known = self._sensor_of_model
        found = []
        models = []
        for d in dets:
            if d.timestamp != time:
                raise ValueError(
                    f"detections: a detection at {d.timestamp} in the scan at {time}; usvfast "
                    "needs every detection of a scan to carry the scan time"
                )
            model = d.measurement_model
            models.append(model)
            hit = known.get(id(model))
            found.append(hit if hit is not None else self._sensor_index(model))
        sids = np.fromiter((f[0] for f in found), dtype=np.int64, count=len(dets))
        m = self._noise(0).shape[0] if self._sensor_specs else 2
        covs = origins = None
        if any(f[1] is not None for f in found):
            covs = np.array(
                [self._noise(i) if r is None else r for i, r, _ in found], dtype=np.float64
            ).reshape(len(dets), m, m)
        if any(f[2] is not None for f in found):
            origins = np.array(
                [(0.0, 0.0) if o is None else o for _, _, o in found], dtype=np.float64
            ).reshape(len(dets), 2)
        z = self._measurements(dets, m)
        self._newest_models, self._newest_z = models, z
        if self._t0 is None:
            self._t0 = time
        t = (time - self._t0).total_seconds()
        if self._core is None and self._sensor_specs:
            # Built at the first scan with a detection; earlier (empty) scans are replayed so
            # that the core's scan indices are the drop-in's.
            self._core = self._new_core()
            self._raw = _raw_core(self._core)
            for args in self._replay:
                self._core.step(*args)
            self._replay.clear()
        alive = None
        if self._raw is not None:
            # The core's own validation applies (NaN, sensor ids, covariances).
            self._raw.step(t, z, sids, covs, origins)
            alive = _core.confirmed_ids(self._raw)
        elif self._core is not None:
            alive = self._core.step(t, z, sids, covs, origins).ids.tolist()
        else:
            self._replay.append((t, z, sids))
        return self._stepped(time, t, dets, alive)

    def _stepped(self, time: Any, t: float, dets: list, alive: list[int] | None):
        """The bookkeeping after the core's step of scan `time` (`t` s since the first scan)
        with detections `dets` and the alive confirmed ids `alive` (None: no core yet)."""
        self._scan_time.append(time)
        self._scan_seconds = (self._scan_seconds[1], t)
        self._scan_dets.append(dets)
        self._scan += 1
        if alive is not None:
            self._collect(alive)
            if self._scan % _FREE_EVERY == 0:
                self._free_scans()
        return time, set(self._tracks.values())

    @staticmethod
    def _measurements(dets: list, m: int) -> np.ndarray:
        """(k, m) measurement vectors of the detections."""
        if not dets:
            return np.empty((0, m))
        try:
            z = np.array([d.state_vector for d in dets], dtype=np.float64)
        except ValueError:  # ragged: report the first odd one below
            z = None
        if z is not None and z.shape in ((len(dets), m, 1), (len(dets), m)):
            return z.reshape(len(dets), m)
        for d in dets:
            sv = np.asarray(d.state_vector, dtype=np.float64).ravel()
            if sv.shape != (m,):
                raise ValueError(
                    f"detections: state vector of length {sv.size}, expected {m} (all sensors "
                    "must share the measurement dimension)"
                )
        raise ValueError(f"detections: state vectors must be ({m}, 1) columns")

    def _transition(self, initiator: bool, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """(F, Q) of the tracker's (or the initiator's) transition model over dt seconds."""
        key = (initiator, dt)
        hit = self._fq.get(key)
        if hit is None:
            model = self.config.init_motion_model if initiator else self.config.motion_model
            hit = kalman.transition_matrices(model, dt)
            if len(self._fq) > 4096:
                self._fq.clear()
            self._fq[key] = hit
        return hit

    def _free_scans(self) -> None:
        # Unbuilt states refer to the detections of their scans; so do the states of the
        # tentative tracks (a track confirmed later brings its whole tentative history). A
        # track confirmed since the last look was tentative then or started later: its first
        # scan is at least the boundary of that look (`_freed`).
        if self._raw is not None:
            first = _core.tentative_first_scan(self._raw)
            oldest = min(self._scan if first is None else first, self._scan - 1)
        else:
            firsts = self._core.tentative_tracks.first_scan
            oldest = min(int(firsts.min()) if len(firsts) else self._scan, self._scan - 1)
        pending = self._pending
        stale = [f for f in pending.values() if f.next_scan < self._scan - _LAZY_HORIZON]
        for f in stale:  # unread for long: built now, so that memory stays bounded
            f.force()
        for tid in [tid for tid, f in pending.items() if f.done]:
            del pending[tid]
        if pending:
            oldest = min(oldest, min(f.next_scan for f in pending.values()))
        for k in range(self._freed, max(oldest, self._freed)):
            self._scan_dets[k] = None
            self._inputs.pop(k, None)
        self._freed = max(oldest, self._freed)

    def _collect(self, alive: list[int]) -> None:
        """Follow the confirmed tracks of the newest scan (core ids `alive`): new tracks get
        a lazy Track, deleted ones keep theirs (built when read) and every alive one is armed
        to build its newest state when read."""
        tracks = self._tracks
        if len(alive) != len(tracks) or not all(map(tracks.__contains__, alive)):
            alive_set = set(alive)
            for tid in [k for k in tracks if k not in alive_set]:
                del tracks[tid]
                # Its last state(s) are built when read; the filler stays pending until then.
                self._fillers.pop(tid).arm()
            for tid in alive:
                if tid not in tracks:
                    tr = self._track_cls()
                    d: Any = tr.__dict__
                    states, mds = LazyList(), LazyList()
                    d["_property_states"], d["metadatas"] = states, mds
                    f = Filler(self, tid, tr, self._scan - 1, self._freed)
                    tracks[tid] = tr
                    self._fillers[tid] = f
                    self._pending[tid] = f
        fillers = self._fillers
        for tid in alive:
            f = fillers[tid]
            d = _attribute(f.track, "__dict__")
            d["_property_states"]._fill = d["metadatas"]._fill = f


def _plain_detection_class(cls: type) -> bool:
    """Whether the detections of class `cls` read `timestamp`, `measurement_model`,
    `state_vector` and `metadata` as plain Stone Soup properties (the `__dict__` entries
    `_property_<name>`, no getter of their own, no `__getattribute__` or `__getattr__` of the
    class's), so that `usvfast._core.stonesoup_step` may read those entries."""
    from stonesoup.base import Property

    if cls.__getattribute__ is not object.__getattribute__ or hasattr(cls, "__getattr__"):
        return False
    for name in ("timestamp", "measurement_model", "state_vector", "metadata"):
        desc = next((k.__dict__[name] for k in cls.__mro__ if name in k.__dict__), None)
        if not (
            type(desc) is Property
            and desc._getter is None
            and desc._property_name == f"_property_{name}"
        ):
            return False
    return True


class MultiTargetMixtureTracker(_DropInTracker):
    """Stone Soup's `MultiTargetMixtureTracker` (JPDA) run by the usvfast core.

    Same keywords (`initiator`, `deleter`, `detector`, `data_associator`, `updater`), same
    protocol: iterating yields `(datetime, set of Track)` per scan of `detector`;
    `update_tracker(time, detections)` processes one scan. The states and their hypotheses
    are Stone Soup's, class by class and attribute by attribute (tests/test_stonesoup_lazy.py,
    1e-9): the first state carries `SingleHypothesis(None, detection)`; the initiator's
    tentative updates its GNN's `SingleDistanceHypothesis` (prediction, detection, the
    hypothesiser's Mahalanobis distance, measurement prediction) and its missed scans the
    predictor's `GaussianStatePrediction` (with `transition_model` and `prior`, the previous
    state); confirmed updates a `MultipleHypothesis` (`normalise=True`, `total_weight=1`)
    of `SingleProbabilityHypothesis` — MissedDetection first, then the gated detections in
    the scan's order — with `Probability` JPDA probabilities, the predictor's prediction and,
    for detections, the updater's `GaussianMeasurementPrediction` (mean H x, innovation
    covariance H P Hᵀ + R, cross covariance P Hᵀ; one per measurement model, as the updater's
    cache shares it; from the updater's own `predict_measurement` for non-linear models). A
    prior's older predictions keep their priors as weak references, as Stone Soup's
    `Prediction` makes them. What is not bit for bit: the probabilities (Stone Soup
    renormalises in log space; ours come normalised from the core, within 1e-15) and, for
    bearing-range detections, everything built on the state (Stone Soup's finite-difference
    Jacobian, ~1e-4). `hypotheses=False` skips building hypotheses: update states then
    carry a placeholder `SingleHypothesis(None, MissedDetection)`, so do not feed such
    tracks to Stone Soup deleters.

    Laziness: a track's `states` and `metadatas` are `usvfast.stonesoup_lazy.LazyList`s (list
    subclasses; copies and pickles are plain lists) that build the missing states on any read
    — `len(track)`, `track.state`, indexing, iterating, `track.metadata`, `Track.append` — so
    what a user sees is what Stone Soup's tracker holds at that scan; the cost of the states
    moves from the scan to the first read. The first read of a scan's newest state builds that
    state for every alive track lacking only it, in one native call (a user reading one track
    a scan pays for all of them, ~µs each). Raises UnsupportedComponentError for components
    usvfast cannot reproduce exactly, ValueError for detections off the scan time or of
    another dimension.

    Memory: a scan's detections are kept while a tentative track's history or a state not yet
    built refers to them (a track confirmed later brings its tentative states; states nobody
    reads are built 64 scans later, so at most about 64 scans are kept). A detection with a
    new measurement matrix H registers one more core sensor (`Tracker.add_sensor`); no scan
    is replayed.
    Detections whose models share H but not the noise covariance (each detection with its own
    `LinearGaussian`, e.g. range-dependent noise) share that sensor and reach the core with
    their own covariance (`Tracker.step(..., covariances=...)`), exactly as Stone Soup uses
    each detection's model for gating, hypotheses, updates and initiation.
    """

    _mixture = True


class MultiTargetTracker(_DropInTracker):
    """Stone Soup's `MultiTargetTracker` (GNN: DistanceHypothesiser + GNNWith2DAssignment) run
    by the usvfast core; same keywords and protocol as `MultiTargetMixtureTracker`. Confirmed
    updates carry the chosen `SingleDistanceHypothesis` and missed scans the predictor's
    prediction, as in the initiator's tentative phase (see `MultiTargetMixtureTracker`)."""

    _mixture = False
