"""Building the drop-in trackers' Stone Soup states from the usvfast core, when a track is
first read (see `usvfast.stonesoup_lazy`): `StateBuilder` is the part of the drop-in tracker
(`usvfast.stonesoup_tracker`) that does it, `Filler` the per-track callable its lazy lists
call.

A track's newest state alone (the common case of a user reading every track each scan): the
first such read in a scan builds the newest states of every alive track that lacks only that
one, in one native call (`usvfast._core.StoneSoupKit.newest`: the core's history, the same
Stone Soup classes and `__dict__` entries as `usvfast.stonesoup_objects` makes, checked
against Stone Soup's constructors when the kit is made); a track the kit cannot build exactly
(a non-linear measurement model, another GNN measure) is built in Python from one snapshot of
the core per scan, with the predictions batched per time step. Anything older (a track read
after several scans, a new track with its tentative history, a deleted track) comes from the
core's history of that track: the entries after its confirmation in one native call per track
(`StoneSoupKit.entries`, each state the next one's prior; the scans' detections, models and
measurements remembered per scan), the tentative ones (the initiator's GNN) and whatever the
kit cannot build exactly in Python. Either way the objects are
the ones Stone Soup's tracker would have appended: Update or Prediction with the same mean,
covariance and time; for updates their hypotheses — the prediction from the previous state
by the tracker's (after confirmation) or the initiator's (before) transition model (with
that model and the previous state as its prior), the scan's own Detection objects, the
measurement predictions of the detection's measurement model, the GNN distance or the JPDA
probabilities — and the track metadata merged by Stone Soup's own `Track.append` whenever a
detection of that scan carries metadata. The hypotheses and measurement predictions of each
state come from `usvfast.stonesoup_hypotheses`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from usvfast.stonesoup_hypotheses import CACHE_ENTRIES, HypothesisParts

# The snapshot entries `StateBuilder._newest` reads, as lists.
_NEWEST_LISTS = (
    "ids",
    "is_update",
    "detection",
    "missed_probability",
    "assoc_offsets",
    "assoc_detection",
    "assoc_probability",
)

# A Track's own attributes without Stone Soup's `StateMutableSequence.__getattribute__` (a
# Python function that falls back on the newest state; `__dict__` is the track's own).
_attribute = object.__getattribute__


class StateBuilder(HypothesisParts):
    """Mixin of the drop-in tracker: the attributes below are the tracker's."""

    _raw: Any
    _core: Any
    _scan: int
    _scan_time: list
    _scan_dets: list
    _t0: Any
    _tracks: dict
    _fillers: dict
    _scan_md: dict
    _history_start: bool
    _newest_cache: dict | None
    _newest_models: list  # the newest scan's detections' measurement models
    _newest_z: np.ndarray  # and their measurements (k, m)
    _batch_scan: int  # the scan `_newest_batch` last ran at
    _kit: Any  # see `_native_kit` (None: not made yet, False: unavailable)
    _track_cls: Any  # stonesoup.types.track.Track
    _scan_seconds: tuple[float, float]  # the last two scans' times, seconds since the first
    _newest_md: tuple[int, bool]  # (scan, whether a detection of it carries metadata)
    _fq: dict  # see `_transition`
    _inputs: dict  # see `_scan_inputs`
    hypotheses: bool

    def _noise(self, idx: int) -> np.ndarray:
        raise NotImplementedError

    @staticmethod
    def _measurements(dets: list, m: int) -> np.ndarray:
        raise NotImplementedError

    def _transition(self, initiator: bool, dt: float) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

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
            hit = any(d.metadata for d in self._dets_of(scan))  # None and {} alike: none
            self._scan_md[scan] = hit
            if len(self._scan_md) > CACHE_ENTRIES:
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

    def _build(self, f: Filler) -> None:
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
        xs, ps = hist["states"], hist["covariances"]
        times, scans = hist["times"].tolist(), hist["scan"].tolist()
        upds, dets = hist["is_update"].tolist(), hist["detection"].tolist()
        offs, missed = hist["assoc_offsets"].tolist(), hist["missed_probability"].tolist()
        assoc_det, assoc_p = hist["assoc_detection"].tolist(), hist["assoc_probability"].tolist()
        if not all(0 <= k < len(self._scan_time) for k in scans):
            raise RuntimeError(f"usvfast.stonesoup: history entry of track {f.tid} at unknown scan")
        fast = ob.append_plain
        states = track.__dict__["_property_states"]
        prior = list.__getitem__(states, -1) if list.__len__(states) else None
        # The entries after the confirmation, natively (as far as the kit can build them).
        j0 = next((j for j, k in enumerate(scans) if k > f.birth_scan), n)
        if j0 == 0 and prior is None:
            j0 = n
        native: list = []
        preds: dict = {}
        svs: Any = None
        cms: Any = None
        for j in range(n):
            scan = scans[j]
            if j == j0:  # its prior is built now
                native = self._native_entries(f, j0, prior, times, scans)
            if j0 <= j < j0 + len(native):
                state = native[j - j0]
                if upds[j] and self._has_metadata(scan):
                    Track.append(track, state)
                else:
                    fast(track, state)
                prior = state
                continue
            if svs is None:  # the Python builders, from here on
                preds = self._predictions(f, xs, ps, times, scans, upds) if self.hypotheses else {}
                svs, cms = ob.rows(xs, ps)
            time = self._scan_time[scan]
            initiator = scan <= f.birth_scan
            hyp = None
            if upds[j]:
                det = dets[j]
                scan_dets = self._dets_of(scan)
                if self.hypotheses:
                    pred = None
                    if j in preds:
                        model = self._phase(initiator)[0]
                        pred = ob.prediction(*preds[j], time, model, prior)
                    elif det >= 0:  # the first state: its detection, no prediction
                        hyp = ob.single(None, scan_dets[det])
                    if hyp is None:
                        a, b = offs[j], offs[j + 1]
                        hyp = self._make_hypothesis(
                            pred,
                            scan_dets,
                            time,
                            (assoc_det[a:b], assoc_p[a:b], missed[j], det),
                            initiator,
                        )
                if hyp is None:
                    hyp = self._placeholder(time)
                state = ob.state_of(True, svs[j], cms[j], time, hyp)
            else:
                state = self._prediction_state(initiator, svs[j], cms[j], time, prior)
            if upds[j] and self._has_metadata(scan):
                Track.append(track, state)
            else:
                fast(track, state)
            prior = state
        f.prev = (times[-1], xs[-1], ps[-1])
        f.have += n
        f.next_scan = scans[-1] + 1

    def _native_entries(self, f: Filler, j0: int, prior: Any, times: list, scans: list) -> list:
        """The states of history entries `f.have` + j0.. of track `f` (all after its
        confirmation; `times`, `scans` of the entries from `f.have`), built by the native kit
        in one call as far as it can build them exactly (see `StoneSoupKit.entries`), `prior`
        the state before the first."""
        if self._raw is None:
            return []
        kit = self._kit if self._kit is not None else self._native_kit()
        if not kit:
            return []
        dts, fqs, dets, models, zs, stamps = [], [], [], [], [], []
        t_prev = times[j0 - 1] if j0 else f.prev[0] if f.prev is not None else None
        if t_prev is None:
            return []
        for j in range(j0, len(times)):
            dt = times[j] - t_prev
            t_prev = times[j]
            scan_dets, scan_models, z = self._scan_inputs(scans[j])
            dts.append(dt)
            fqs.append(self._transition(False, dt))
            dets.append(scan_dets)
            models.append(scan_models)
            zs.append(z)
            stamps.append(self._scan_time[scans[j]])
        return kit.entries(
            self._raw,
            f.tid,
            f.have + j0,
            prior,
            dts,
            fqs,
            dets,
            models,
            zs,
            stamps,
            self._phase(False)[0],
            self._mixture,
            self.hypotheses,
        )

    def _scan_inputs(self, scan: int) -> tuple[list, list, np.ndarray]:
        """(detections, their measurement models, their measurements (k, m)) of a kept scan,
        remembered for the scans of the last `CACHE_ENTRIES` calls."""
        hit = self._inputs.get(scan)
        if hit is None:
            dets = self._dets_of(scan)
            m = self._noise(0).shape[0]
            hit = (dets, [d.measurement_model for d in dets], self._measurements(dets, m))
            if len(self._inputs) > CACHE_ENTRIES:
                self._inputs.clear()
            self._inputs[scan] = hit
        return hit

    def _predictions(self, f: Filler, xs, ps, times, scans, upds) -> dict:
        """{j: (mean, covariance)} predicted to history entry j (of those given, an update)
        from the entry before it (or `f.prev`), batched per transition model and time step;
        entries up to the confirmation scan by the initiator's model."""
        groups: dict[tuple[bool, float], list[int]] = {}
        # Entry 0's prior is `f.prev` (a new track's entry 0 has none and is skipped).
        t_p, x_p, p_p = f.prev if f.prev is not None else (0.0, xs[0], ps[0])
        x_p = np.asarray(x_p, dtype=np.float64).reshape(-1)  # also a StateVector (n, 1)
        for j, upd in enumerate(upds):
            if not upd or (j == 0 and f.prev is None):
                continue
            t0 = times[j - 1] if j else t_p
            groups.setdefault((scans[j] <= f.birth_scan, times[j] - t0), []).append(j)
        out = {}
        for (initiator, dt), idx in groups.items():
            fm, q = self._transition(initiator, dt)
            x0 = np.array([xs[j - 1] if j else x_p for j in idx])
            p0 = np.array([ps[j - 1] if j else p_p for j in idx])
            psv, pcm = self._objects.rows(x0 @ fm.T, fm @ p0 @ fm.T + q)
            for k, j in enumerate(idx):
                out[j] = (psv[k], pcm[k])
        return out

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
        nw["sv"], nw["cm"] = self._objects.rows(snap["states"], snap["covariances"])
        nw["scan"] = self._scan
        nw["row"] = row = {tid: r for r, tid in enumerate(nw["ids"])}
        nw["pred"] = pred = {}
        nw["mp"] = {}  # see `_newest_measurement_predictions`
        if self.hypotheses:
            t = (self._scan_time[-1] - self._t0).total_seconds()
            by_dt: dict[float, list[Any]] = {}
            for tid, r in row.items():
                f = self._fillers.get(tid)
                if f is not None and f.prev is not None and f.next_scan == self._scan - 1:
                    by_dt.setdefault(t - f.prev[0], []).append((r, f.prev))
            for dt, group in by_dt.items():
                fm, q = self._transition(False, dt)
                xp = np.array([np.asarray(g[1][1]).reshape(-1) for g in group]) @ fm.T
                pp = fm @ np.array([g[1][2] for g in group]) @ fm.T + q
                psv, pcm = self._objects.rows(xp, pp)
                rows = [r for r, _ in group]
                for k, r in enumerate(rows):
                    pred[r] = (psv[k], pcm[k])
                nw["mp"].update(self._newest_measurement_predictions(xp, pp, rows))
        self._newest_cache = nw
        return nw

    def _newest_measurement_predictions(self, xp: np.ndarray, pp: np.ndarray, rows: list) -> dict:
        """{row: {id(model): (z, S, C)}}: the measurement predictions, for each linear
        measurement model of the newest scan's detections, of the predicted means xp (k, n)
        and covariances pp (k, n, n) of the tracks in `rows`, batched (see
        `_measurement_prediction`)."""
        updater = self._phase(False)[1]
        models = {id(d.measurement_model): d.measurement_model for d in self._scan_dets[-1] or ()}
        out: dict[int, dict] = {}
        for key, model in models.items():
            hr = self._linear_model(model, updater)
            if hr is None:
                continue
            h, ht, noise = hr
            c = pp @ ht
            zs, ss, cs = self._objects.measurement_rows(xp @ ht, h @ c + noise, c)
            for i, r in enumerate(rows):
                out.setdefault(r, {})[key] = (zs[i], ss[i], cs[i])
        return out

    def _build_newest(self, f: Filler) -> None:
        """Append the newest scan's state of alive track `f` (see `_build`): the first time in
        a scan, together with those of every alive track missing only that state, in one
        native call (`_newest_batch`); in Python when that could not build it."""
        if self._batch_scan != self._scan:
            self._batch_scan = self._scan
            self._newest_batch()
            if f.next_scan == self._scan:
                return
        self._build_newest_py(f)

    def _native_kit(self) -> Any:
        """The tracker's `usvfast._core.StoneSoupKit` (see `StoneSoupObjects.kit`), or None."""
        kit = self._kit
        if kit is None:
            from stonesoup.measures import Mahalanobis, SquaredMahalanobis

            _, updater, measure = self._phase(False)
            kinds = {Mahalanobis: 1, SquaredMahalanobis: 2}
            kind = kinds.get(type(measure), 0) if getattr(measure, "mapping", 0) is None else 0
            kit = self._objects.kit(lambda model: self._linear_model(model, updater), kind)
            self._kit = kit if kit is not None else False
        return kit or None

    def _newest_batch(self) -> None:
        """Append the newest scan's state to every alive track that lacks only that one, built
        by the native kit in one call (tracks it cannot build stay armed for
        `_build_newest_py`); their lists are disarmed."""
        scan = self._scan - 1
        if self._raw is None or scan < 1:
            return
        kit = self._kit
        if kit is None:
            kit = self._native_kit()
        if not kit:
            return
        fillers = [f for f in self._fillers.values() if f.prev is not None and f.next_scan == scan]
        if not fillers:
            return
        t_prev, t_now = self._scan_seconds  # of the scans `scan` - 1 and `scan`
        dt = t_now - t_prev
        get = list.__getitem__
        lists = [_attribute(f.track, "__dict__") for f in fillers]
        md_scan, md = self._newest_md
        fq = self._fq.get((False, dt))
        dets = self._scan_dets[scan]
        md, states = kit.newest(
            self._raw,
            scan,
            [f.tid for f in fillers],
            [get(d["_property_states"], -1) for d in lists],
            dt,
            fq if fq is not None else self._transition(False, dt),
            dets if dets is not None else self._dets_of(scan),
            self._newest_models,
            self._newest_z,
            self._scan_time[scan],
            self._phase(False)[0],
            self._mixture,
            self.hypotheses,
            md if md_scan == scan else None,
        )
        self._scan_md[scan] = md  # as `_has_metadata`
        if len(self._scan_md) > CACHE_ENTRIES:
            self._scan_md.clear()
            self._scan_md[scan] = md
        # `append_plain` written out on the lists' own methods (they are disarmed first: an
        # armed list would fill itself).
        slow = not self._objects._fast_append
        append, size = list.append, list.__len__
        nxt = scan + 1
        for f, d, state in zip(fillers, lists, states, strict=True):
            if state is None:
                continue
            sts, mds = d["_property_states"], d["metadatas"]
            sts._fill = mds._fill = None
            if slow or (md and hasattr(state, "_property_hypothesis")):
                self._track_cls.append(f.track, state)
            else:
                append(mds, (get(mds, -1) if size(mds) else d["_property_init_metadata"]).copy())
                append(sts, state)
            f.prev = (t_now, state._property_state_vector, state._property_covar)
            f.have += 1
            f.next_scan = nxt

    def _build_newest_py(self, f: Filler) -> None:
        """`_build_newest` in Python, from the newest scan's snapshot (`_newest`)."""
        from stonesoup.types.track import Track

        nw = self._newest()
        r = nw["row"][f.tid]
        scan = self._scan - 1
        time = self._scan_time[scan]
        ob = self._objects
        x, p, upd = nw["states"][r], nw["covariances"][r], nw["is_update"][r]
        hyp = None
        prior = list.__getitem__(f.track.__dict__["_property_states"], -1)
        if upd:
            if self.hypotheses:
                pred = ob.prediction(*nw["pred"][r], time, self._phase(False)[0], prior)
                a, b = nw["assoc_offsets"][r], nw["assoc_offsets"][r + 1]
                assoc = (
                    nw["assoc_detection"][a:b],
                    nw["assoc_probability"][a:b],
                    nw["missed_probability"][r],
                    nw["detection"][r],
                )
                pre = nw["mp"].get(r)
                hyp = self._make_hypothesis(pred, self._dets_of(scan), time, assoc, False, pre)
            if hyp is None:
                hyp = self._placeholder(time)
            state = ob.state_of(True, nw["sv"][r], nw["cm"][r], time, hyp)
        else:
            state = self._prediction_state(False, nw["sv"][r], nw["cm"][r], time, prior)
        if upd and self._has_metadata(scan):
            Track.append(f.track, state)
        else:
            ob.append_plain(f.track, state)
        f.prev = ((time - self._t0).total_seconds(), x, p)
        f.have += 1
        f.next_scan = scan + 1


class Filler:
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
        d = _attribute(self.track, "__dict__")
        d["_property_states"]._fill = d["metadatas"]._fill = self

    def force(self) -> None:
        """Build now what is missing (the lists are plain lists meanwhile)."""
        d = _attribute(self.track, "__dict__")
        states, mds = d["_property_states"], d["metadatas"]
        states._fill = mds._fill = None
        before = (list.__len__(states), list.__len__(mds), self.have, self.prev, self.next_scan)
        owner = self.owner
        try:
            if (
                owner._batch_scan != owner._scan
                and self.next_scan == owner._scan - 1
                and self.prev is not None
                and owner._raw is not None
                and self.tid in owner._tracks
            ):
                # The first read of the newest scan (the common case): the batch of
                # `_build_newest`, without the calls on the way.
                owner._batch_scan = owner._scan
                owner._newest_batch()
                if self.next_scan == owner._scan:
                    return
            owner._build(self)
        except BaseException:
            # Nothing half-built passes for the whole track: back to before, armed again.
            list.__delitem__(states, slice(before[0], None))
            list.__delitem__(mds, slice(before[1], None))
            self.have, self.prev, self.next_scan = before[2:]
            self.arm()
            raise
        if self.tid not in self.owner._tracks:
            self.done = True  # deleted: its history does not grow any more

    __call__ = force
