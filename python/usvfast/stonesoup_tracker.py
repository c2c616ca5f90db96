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
from usvfast.stonesoup_objects import StoneSoupObjects


def _raw_core(tracker: Any) -> Any:
    """The Rust core behind a `usvfast.tracking.Tracker` when it offers `step(t, z, ids,
    covariances, origins)` and `snapshot(tentative=False)` (dict of arrays), else None (the
    public `Tracker` API is used then). The drop-in owns its tracker and calls it from one
    thread, so it can skip the wrapper's argument checks (the core validates again) and its
    dataclass snapshot: ~20 µs per scan."""
    raw = getattr(tracker, "_core", None)
    ok = callable(getattr(raw, "step", None)) and callable(getattr(raw, "snapshot", None))
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
        self._tracks: dict[int, Any] = {}
        self._prev: dict[int, tuple[float, np.ndarray, np.ndarray]] = {}

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
        snap = None
        if self._raw is not None:
            # The core's own validation applies (NaN, sensor ids, covariances).
            self._raw.step(t, z, sids, covs, origins)
            snap = self._raw.snapshot()
        elif self._core is not None:
            snap = vars(self._core.step(t, z, sids, covs, origins))
        else:
            self._replay.append((t, z, sids))
        self._scan_time.append(time)
        self._scan_dets.append(dets)
        self._scan += 1
        if snap is not None:
            self._collect(time, snap)
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
        # Later states refer to this scan's detections or to those of the tentative tracks'
        # first scans (a track confirmed later brings its whole tentative history).
        if self._raw is not None:
            first = self._raw.snapshot(tentative=True)["first_scan"]
        else:
            first = self._core.tentative_tracks.first_scan
        oldest = min(int(first.min()) if len(first) else self._scan, self._scan - 1)
        for k in range(self._freed, max(oldest, self._freed)):
            self._scan_dets[k] = None
        self._freed = max(oldest, self._freed)

    def _collect(self, time: Any, snap: Any) -> None:
        from stonesoup.types.track import Track

        core = self._core
        alive = snap["ids"].tolist()
        alive_set = set(alive)
        xs, ps, is_update = snap["states"], snap["covariances"], snap["is_update"]
        t_now = (time - self._t0).total_seconds()
        # Deleted this scan: their final state(s) come from the core's history.
        for tid in [k for k in self._tracks if k not in alive_set]:
            tr = self._tracks.pop(tid)
            hist = vars(core.history(tid))
            n_have = len(tr.states)
            for j in range(n_have, len(hist["times"])):
                tr.append(self._state_from_history(hist, j, tid))
            self._prev.pop(tid, None)
        updated = []  # (row, track) of known tracks, in snapshot order
        for row, tid in enumerate(alive):
            tr = self._tracks.get(tid)
            if tr is None:
                hist = vars(core.history(tid))
                states = [self._state_from_history(hist, j, tid) for j in range(len(hist["times"]))]
                tr = Track(states)
                self._tracks[tid] = tr
                self._prev[tid] = (
                    float(hist["times"][-1]),
                    hist["states"][-1],
                    hist["covariances"][-1],
                )
                continue
            updated.append((row, tid, tr))
        upd = is_update.tolist()
        hyps = self._hypotheses(snap, [(r, tid) for r, tid, _ in updated if upd[r]], time, t_now)
        ob = self._objects
        # Stone Soup's Track.append merges the metadata of the hypotheses' detections into
        # the track's; without any (the usual case) it only copies it.
        plain = not any(d.metadata for d in self._dets_of(-1) if d.metadata is not None)
        append = ob.append_plain if plain else Track.append
        for row, tid, tr in updated:
            hyp = None
            if upd[row]:
                hyp = hyps.get(row)
                if hyp is None:
                    hyp = self._placeholder(time)
            x, p = xs[row], ps[row]
            append(tr, ob.state(upd[row], x, p, time, hyp))
            # Plain arrays (fresh per snapshot): Stone Soup's matrix types are slow in `@`.
            self._prev[tid] = (t_now, x, p)

    def _dets_of(self, scan: int) -> list:
        """The detections of a scan still kept (the newest scan's and those a tentative
        history can refer to, see `_free_scans`)."""
        dets = self._scan_dets[scan]
        if dets is None:
            raise RuntimeError(f"usvfast.stonesoup: detections of scan {scan} already freed")
        return dets

    def _placeholder(self, time: Any) -> Any:
        return self._objects.single(None, self._objects.missed(time))

    def _hypotheses(self, snap: dict, rows: list[tuple[int, int]], time: Any, t: float) -> dict:
        """{row: hypothesis} of the updated tracks (row, id) of a snapshot: each track's
        prediction from its previous state (batched per time step) and its association
        probabilities from the snapshot; empty with hypotheses=False."""
        if not self.hypotheses or not rows:
            return {}
        by_dt: dict[float, list[int]] = {}
        prevs = []
        for i, (_, tid) in enumerate(rows):
            t0, x0, p0 = self._prev[tid]
            prevs.append((x0, p0))
            by_dt.setdefault(t - t0, []).append(i)
        preds: list[Any] = [None] * len(rows)
        ob = self._objects
        for dt, idx in by_dt.items():
            f, q = self._transition(False, dt)
            x0 = np.array([prevs[i][0] for i in idx])
            p0 = np.array([prevs[i][1] for i in idx])
            xp = x0 @ f.T
            pp = f @ p0 @ f.T + q
            for k, i in enumerate(idx):
                preds[i] = ob.state(False, xp[k], pp[k], time)
        offs = snap["assoc_offsets"].tolist()
        det_all = snap["assoc_detection"].tolist()
        prob_all = snap["assoc_probability"].tolist()
        missed = snap["missed_probability"].tolist()
        best = snap["detection"].tolist()
        scan_dets = self._dets_of(-1)
        out = {}
        for i, (row, _) in enumerate(rows):
            a, b = offs[row], offs[row + 1]
            out[row] = self._make_hypothesis(
                preds[i], scan_dets, time, det_all[a:b], prob_all[a:b], missed[row], best[row]
            )
        return out

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

    def _state_from_history(self, hist: dict, j: int, tid: int) -> Any:
        scan = int(hist["scan"][j])
        time = self._scan_time[scan] if 0 <= scan < len(self._scan_time) else None
        if time is None:
            raise RuntimeError(f"usvfast.stonesoup: history entry of track {tid} at unknown scan")
        upd = bool(hist["is_update"][j])
        hyp = None
        if upd:
            det = int(hist["detection"][j])
            scan_dets = self._dets_of(scan)
            if self.hypotheses:
                if j == 0 and det >= 0:
                    hyp = self._objects.single(None, scan_dets[det])
                else:
                    pred = None
                    if j > 0:
                        t_prev = float(hist["times"][j - 1])
                        f, q = self._transition(True, float(hist["times"][j]) - t_prev)
                        x0, p0 = hist["states"][j - 1], hist["covariances"][j - 1]
                        pred = self._objects.state(False, f @ x0, f @ p0 @ f.T + q, time)
                    a, b = hist["assoc_offsets"][j], hist["assoc_offsets"][j + 1]
                    hyp = self._make_hypothesis(
                        pred,
                        scan_dets,
                        time,
                        hist["assoc_detection"][a:b],
                        hist["assoc_probability"][a:b],
                        float(hist["missed_probability"][j]),
                        det,
                    )
            if hyp is None:
                hyp = self._placeholder(time)
        return self._objects.state(upd, hist["states"][j], hist["covariances"][j], time, hyp)


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
