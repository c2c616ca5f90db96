"""The Stone Soup drop-in trackers (`usvfast.stonesoup.MultiTargetMixtureTracker` and
`MultiTargetTracker`): Stone Soup's tracker protocol on the usvfast core.

Per scan the drop-in hands the detections to the core in one call, takes one snapshot of the
confirmed tracks, and builds only the Stone Soup objects of that scan (one state per track and,
with `hypotheses=True`, its association hypotheses) by the fast constructors of
`usvfast.stonesoup_objects`. Transition matrices are cached per time step; detections of old
scans are freed in batches.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from usvfast import kalman
from usvfast.stonesoup import (
    PolarSensor,
    UnsupportedComponentError,
    build_native,
    detection_model,
    read_components,
)
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


# The snapshot entries `_DropInTracker._newest` reads, as lists.
_NEWEST_LISTS = (
    "ids",
    "is_update",
    "detection",
    "missed_probability",
    "assoc_offsets",
    "assoc_detection",
    "assoc_probability",
)

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


class _DropInTracker:
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
        self._fillers: dict[int, _Filler] = {}  # of the alive tracks
        # Fillers of tracks that may lack states (alive ones, deleted ones not read since).
        self._pending: dict[int, _Filler] = {}
        self._scan_md: dict[int, bool] = {}  # scan -> a detection of it carries metadata
        self._history_start = True  # the core's history(track_id, start) is available
        self._newest_cache: dict | None = None  # see `_newest`

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
        for d in dets:
            if d.timestamp != time:
                raise ValueError(
                    f"detections: a detection at {d.timestamp} in the scan at {time}; usvfast "
                    "needs every detection of a scan to carry the scan time"
                )
        found = [self._sensor_index(d.measurement_model) for d in dets]
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
            alive = self._raw.track_ids()[0].tolist()
        elif self._core is not None:
            alive = self._core.step(t, z, sids, covs, origins).ids.tolist()
        else:
            self._replay.append((t, z, sids))
        self._scan_time.append(time)
        self._scan_dets.append(dets)
        self._scan += 1
        if alive is not None:
            self._collect(alive)
            if self._scan % _FREE_EVERY == 0:
                self._free_scans()
        return time, self.tracks

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
            first = self._raw.snapshot(tentative=True)["first_scan"]
        else:
            first = self._core.tentative_tracks.first_scan
        oldest = min(int(first.min()) if len(first) else self._scan, self._scan - 1)
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
        self._freed = max(oldest, self._freed)

    def _collect(self, alive: list[int]) -> None:
        """Follow the confirmed tracks of the newest scan (core ids `alive`): new tracks get
        a lazy Track, deleted ones keep theirs (built when read) and every alive one is armed
        to build its newest state when read."""
        from stonesoup.types.track import Track

        tracks = self._tracks
        if len(alive) != len(tracks) or any(tid not in tracks for tid in alive):
            alive_set = set(alive)
            for tid in [k for k in tracks if k not in alive_set]:
                del tracks[tid]
                # Its last state(s) are built when read; the filler stays pending until then.
                self._fillers.pop(tid).arm()
            for tid in alive:
                if tid not in tracks:
                    tr = Track()
                    d = tr.__dict__
                    states, mds = LazyList(), LazyList()
                    d["_property_states"], d["metadatas"] = states, mds
                    f = _Filler(self, tid, tr, self._scan - 1, self._freed)
                    tracks[tid] = tr
                    self._fillers[tid] = f
                    self._pending[tid] = f
        fillers = self._fillers
        for tid in alive:
            fillers[tid].arm()

    def _dets_of(self, scan: int) -> list:
        """The detections of a scan still kept (see `_free_scans`)."""
        dets = self._scan_dets[scan]
        if dets is None:
            raise RuntimeError(f"usvfast.stonesoup: detections of scan {scan} already freed")
        return dets

    def _has_metadata(self, scan: int) -> bool:
        """Whether a detection of `scan` carries metadata (Track.append then merges it)."""
        hit = self._scan_md.get(scan)
        if hit is None:
            hit = any(d.metadata for d in self._dets_of(scan) if d.metadata is not None)
            self._scan_md[scan] = hit
            if len(self._scan_md) > 4 * _LAZY_HORIZON:
                self._scan_md.clear()
                self._scan_md[scan] = hit
        return hit

    def _history(self, tid: int, start: int) -> dict:
        """History entries `start`.. of core track `tid` (dict of arrays; assoc_offsets from
        0)."""
        if self._raw is not None:
            if self._history_start:
                try:
                    return self._raw.history(tid, start)
                except TypeError:  # a core without `start`
                    self._history_start = False
            hist = self._raw.history(tid)
        else:
            hist = vars(self._core.history(tid))
        if start == 0:
            return hist
        offs = hist["assoc_offsets"]
        a = int(offs[start])
        out = {k: v[start:] for k, v in hist.items() if isinstance(v, np.ndarray)}
        out["assoc_offsets"] = offs[start:] - a
        out["assoc_detection"] = hist["assoc_detection"][a:]
        out["assoc_probability"] = hist["assoc_probability"][a:]
        return out

    def _build(self, f: _Filler) -> None:
        """Append the states of track `f.tid` the Stone Soup track lacks (history entries
        f.have..), with their hypotheses and metadata, as Stone Soup's tracker appends them."""
        from stonesoup.types.track import Track

        if (
            f.prev is not None
            and f.next_scan == self._scan - 1
            and self._raw is not None
            and f.tid in self._tracks
        ):
            # Only the newest scan's state is missing: from this scan's snapshot.
            self._build_newest(f)
            return
        hist = self._history(f.tid, f.have)
        n = len(hist["times"])
        if n == 0:
            return
        ob = self._objects
        track = f.track
        times, xs, ps = hist["times"], hist["states"], hist["covariances"]
        scans, upds, dets = hist["scan"].tolist(), hist["is_update"].tolist(), hist["detection"]
        offs, missed = hist["assoc_offsets"], hist["missed_probability"]
        fast = ob.append_plain
        for j in range(n):
            scan = scans[j]
            if not 0 <= scan < len(self._scan_time):
                raise RuntimeError(
                    f"usvfast.stonesoup: history entry of track {f.tid} at unknown scan"
                )
            time = self._scan_time[scan]
            hyp = None
            if upds[j]:
                det = int(dets[j])
                scan_dets = self._dets_of(scan)
                if self.hypotheses:
                    if f.prev is None:
                        if det >= 0:
                            hyp = ob.single(None, scan_dets[det])
                        pred = None
                    else:
                        # States up to the confirmation come from the initiator's models.
                        t0, x0, p0 = f.prev
                        fm, q = self._transition(scan <= f.birth_scan, float(times[j]) - t0)
                        pred = ob.state(False, fm @ x0, fm @ p0 @ fm.T + q, time)
                    if hyp is None:
                        a, b = int(offs[j]), int(offs[j + 1])
                        hyp = self._make_hypothesis(
                            pred,
                            scan_dets,
                            time,
                            hist["assoc_detection"][a:b],
                            hist["assoc_probability"][a:b],
                            float(missed[j]),
                            det,
                        )
                if hyp is None:
                    hyp = self._placeholder(time)
            state = ob.state(upds[j], xs[j], ps[j], time, hyp)
            if upds[j] and self._has_metadata(scan):
                Track.append(track, state)
            else:
                fast(track, state)
            f.prev = (float(times[j]), xs[j], ps[j])
        f.have += n
        f.next_scan = scans[-1] + 1

    def _newest(self) -> dict:
        """The newest scan's snapshot of the confirmed tracks (lists), with `row` (track id ->
        row) and `pred` (row -> predicted mean and covariance, from each track's previous
        state; batched over the tracks whose previous state is built), made once per scan."""
        nw = self._newest_cache
        if nw is not None and nw["scan"] == self._scan:
            return nw
        snap = self._raw.snapshot()
        nw = {k: snap[k].tolist() for k in _NEWEST_LISTS}
        nw["states"], nw["covariances"] = snap["states"], snap["covariances"]
        nw["scan"] = self._scan
        nw["row"] = row = {tid: r for r, tid in enumerate(nw["ids"])}
        nw["pred"] = pred = {}
        if self.hypotheses:
            t = (self._scan_time[-1] - self._t0).total_seconds()
            by_dt: dict[float, list[Any]] = {}
            for tid, r in row.items():
                f = self._fillers.get(tid)
                if f is not None and f.prev is not None and f.next_scan == self._scan - 1:
                    by_dt.setdefault(t - f.prev[0], []).append((r, f.prev))
            for dt, group in by_dt.items():
                fm, q = self._transition(False, dt)
                xp = np.array([g[1][1] for g in group]) @ fm.T
                pp = fm @ np.array([g[1][2] for g in group]) @ fm.T + q
                for k, (r, _) in enumerate(group):
                    pred[r] = (xp[k], pp[k])
        self._newest_cache = nw
        return nw

    def _build_newest(self, f: _Filler) -> None:
        """Append the newest scan's state of alive track `f` (see `_build`)."""
        from stonesoup.types.track import Track

        nw = self._newest()
        r = nw["row"][f.tid]
        scan = self._scan - 1
        time = self._scan_time[scan]
        ob = self._objects
        x, p, upd = nw["states"][r], nw["covariances"][r], nw["is_update"][r]
        hyp = None
        if upd:
            if self.hypotheses:
                px, pp = nw["pred"][r]
                pred = ob.state(False, px, pp, time)
                a, b = nw["assoc_offsets"][r], nw["assoc_offsets"][r + 1]
                hyp = self._make_hypothesis(
                    pred,
                    self._dets_of(scan),
                    time,
                    nw["assoc_detection"][a:b],
                    nw["assoc_probability"][a:b],
                    nw["missed_probability"][r],
                    nw["detection"][r],
                )
            if hyp is None:
                hyp = self._placeholder(time)
        state = ob.state(upd, x, p, time, hyp)
        if upd and self._has_metadata(scan):
            Track.append(f.track, state)
        else:
            ob.append_plain(f.track, state)
        f.prev = ((time - self._t0).total_seconds(), x, p)
        f.have += 1
        f.next_scan = scan + 1

    def _placeholder(self, time: Any) -> Any:
        return self._objects.single(None, self._objects.missed(time))

    def _make_hypothesis(self, pred, scan_dets, time, dets, probs, missed, det) -> Any:
        ob = self._objects
        if self._mixture and np.isfinite(missed):
            prob = ob.probability
            hyps = [prob(pred, ob.missed(time), float(missed))]
            hyps += [
                prob(pred, scan_dets[int(j)], float(p)) for j, p in zip(dets, probs, strict=True)
            ]
            return ob.multiple(hyps)
        if det >= 0:
            return ob.single(pred, scan_dets[det])
        return None


class _Filler:
    """Builds the missing states of one drop-in track when its lists are first read (see
    `usvfast.stonesoup_lazy`): `have` history entries built so far, `prev` (t, x, P) of the
    last of them, `next_scan` a scan index no unbuilt entry is older than."""

    __slots__ = ("birth_scan", "done", "have", "next_scan", "owner", "prev", "tid", "track")

    def __init__(self, owner: Any, tid: int, track: Any, birth_scan: int, first: int) -> None:
        self.owner = owner
        self.tid = tid
        self.track = track
        self.birth_scan = birth_scan
        self.have = 0
        self.prev: tuple[float, np.ndarray, np.ndarray] | None = None
        self.next_scan = first
        self.done = False  # built, and not alive any more

    def arm(self) -> None:
        d = self.track.__dict__
        d["_property_states"]._fill = self
        d["metadatas"]._fill = self

    def __call__(self) -> None:
        self.force()

    def force(self) -> None:
        """Build now what is missing (the lists are plain lists meanwhile)."""
        d = self.track.__dict__
        d["_property_states"]._fill = None
        d["metadatas"]._fill = None
        self.owner._build(self)
        if self.tid not in self.owner._tracks:
            self.done = True  # deleted: its history does not grow any more


class MultiTargetMixtureTracker(_DropInTracker):
    """Stone Soup's `MultiTargetMixtureTracker` (JPDA) run by the usvfast core.

    Same keywords (`initiator`, `deleter`, `detector`, `data_associator`, `updater`), same
    protocol: iterating yields `(datetime, set of Track)` per scan of `detector`;
    `update_tracker(time, detections)` processes one scan. Update states carry a
    `MultipleHypothesis` of `SingleProbabilityHypothesis` (prediction, detection or
    MissedDetection, JPDA probability; `measurement_prediction` is None). `hypotheses=False`
    skips building them (2-3x faster): update states then carry a placeholder
    `SingleHypothesis(None, MissedDetection)`, so do not feed such tracks to Stone Soup
    deleters. Raises UnsupportedComponentError for components usvfast cannot reproduce
    exactly, ValueError for detections off the scan time or of another dimension.

    Memory: a scan's detections are kept while a tentative track's history refers to them (a
    track confirmed later brings its tentative states). A detection with a new measurement
    matrix H registers one more core sensor (`Tracker.add_sensor`); no scan is replayed.
    Detections whose models share H but not the noise covariance (each detection with its own
    `LinearGaussian`, e.g. range-dependent noise) share that sensor and reach the core with
    their own covariance (`Tracker.step(..., covariances=...)`), exactly as Stone Soup uses
    each detection's model for gating, hypotheses, updates and initiation.
    """

    _mixture = True


class MultiTargetTracker(_DropInTracker):
    """Stone Soup's `MultiTargetTracker` (GNN: DistanceHypothesiser + GNNWith2DAssignment) run
    by the usvfast core; same keywords and protocol as `MultiTargetMixtureTracker`."""

    _mixture = False
