"""The drop-in's lazily built Stone Soup tracks against Stone Soup's own tracker: every way a
Stone Soup user reads a track (`len`, `state`, `states`, indexing by position and by time,
slices, iteration, proxied state attributes, `metadata(s)`, copies and pickles) gives what
Stone Soup's `MultiTargetMixtureTracker` and `MultiTargetTracker` give, whether the tracks are
read every scan, now and then, or only at the end; every state and its hypothesis compared
class by class and attribute by attribute (predictions with transition model and prior,
detections, measurement predictions, distances, probabilities) in the tentative and the
confirmed phase; plus the list type itself."""

from __future__ import annotations

import copy
import pickle
from collections import Counter

import numpy as np
import pytest
from test_stonesoup_dropin import SHORT, dropin_for

from usvfast.stonesoup_lazy import LazyList

import ssharness as H

ATOL = 1e-6
MIN_POINTS = H.Code57().min_points  # the initiator's updates before confirmation


def _collect(tracker, read_every: int | None) -> list:
    """[(born scan, track)] of every track a run outputs; with `read_every` k, tracks are read
    (`track.state`) every k-th scan, one in two of them (by position in the id order)."""
    seen: dict = {}
    for k, (time, tracks) in enumerate(tracker):
        for t in tracks:
            seen.setdefault(id(t), (k, t))
        if read_every and k % read_every == 0:
            for i, t in enumerate(sorted(tracks, key=lambda t: t.id)):
                if i % 2 == 0:
                    assert t.state.timestamp == time
    return list(seen.values())


def _match(ours: list, ref: list) -> list[tuple]:
    """Pairs (our track, Stone Soup's) with the same birth scan, length and first state (the
    lazy tracks are read here, through `states`, before anything else)."""
    pairs, left = [], list(ref)
    for born, t in ours:
        for item in left:
            b_born, r = item
            if b_born != born or len(r.states) != len(t.states):
                continue
            if np.allclose(t.states[0].state_vector, r.states[0].state_vector, atol=ATOL):
                pairs.append((t, r))
                left.remove(item)
                break
        else:
            raise AssertionError(f"track born at scan {born} has no Stone Soup counterpart")
    assert not left
    return pairs


def _same_state(a, b) -> None:
    assert type(a) is type(b)
    assert a.timestamp == b.timestamp
    assert type(a.state_vector) is type(b.state_vector)
    assert type(a.covar) is type(b.covar)
    assert np.allclose(a.state_vector, b.state_vector, atol=ATOL)
    assert np.allclose(a.covar, b.covar, atol=ATOL)


# Hypothesis attributes (predictions, measurement predictions, distances, probabilities).
HYP_TOL = 1e-9


def _same_value(va, vb, where: str, priors: dict, tol: float = HYP_TOL) -> None:
    """One attribute of a Stone Soup object: the same class and the same value (arrays and
    numbers within `tol`, relative or absolute), recursively for Stone Soup objects."""
    from stonesoup.base import Base
    from stonesoup.types.detection import Detection, MissedDetection
    from stonesoup.types.state import State

    assert type(va) is type(vb), f"{where}: {type(va).__name__} != {type(vb).__name__}"
    if isinstance(vb, Detection) and not isinstance(vb, MissedDetection):
        assert va is vb, where  # the very Detection objects of the scan
    elif isinstance(vb, State) and id(vb) in priors:
        assert va is priors[id(vb)], where  # a prior: the track's previous state
    elif isinstance(vb, Base):
        _same_object(va, vb, where, priors, tol)
    elif isinstance(vb, np.ndarray):
        assert va.shape == vb.shape and va.dtype == vb.dtype, where
        if vb.dtype == object:  # e.g. Bearing elements of a bearing-range prediction
            assert [type(x) for x in va.flat] == [type(x) for x in vb.flat], where
            va, vb = va.astype(float), vb.astype(float)
        np.testing.assert_allclose(va, vb, rtol=tol, atol=tol, err_msg=where)
    elif isinstance(vb, list):
        assert len(va) == len(vb), where
        for k, (x, y) in enumerate(zip(va, vb, strict=True)):
            _same_value(x, y, f"{where}[{k}]", priors, tol)
    elif isinstance(vb, (float, np.floating)) or type(vb).__name__ == "Probability":
        assert float(va) == pytest.approx(float(vb), rel=tol, abs=tol), where
    else:
        assert va == vb, where


def _same_object(a, b, where: str, priors: dict, tol: float = HYP_TOL) -> None:
    """Every declared property of two Stone Soup objects (states, hypotheses, predictions,
    measurement predictions, missed detections), stored the same way (same `__dict__` keys
    in the same order, values of the same class: e.g. a prior kept as a weak reference where
    Stone Soup keeps one) and of the same value; transition models by their parameters."""
    from stonesoup.models.base import Model

    assert type(a) is type(b), f"{where}: {type(a).__name__} != {type(b).__name__}"
    da, db = vars(a), vars(b)
    assert list(da) == list(db), where
    assert [type(v) for v in da.values()] == [type(v) for v in db.values()], where
    for name in type(b).properties:
        va, vb = getattr(a, name), getattr(b, name)
        if isinstance(vb, Model):
            assert type(va) is type(vb) and repr(va) == repr(vb), f"{where}.{name}"
        else:
            _same_value(va, vb, f"{where}.{name}", priors, tol)


def _sharing(objs: list) -> list:
    """Which of `objs` are the same object: the index of each one's first occurrence."""
    first: dict = {}
    return [None if o is None else first.setdefault(id(o), len(first)) for o in objs]


def _same_track(a, b) -> Counter:
    """Every read of two tracks agrees; returns how many states of each kind were compared:
    (phase, state class, hypothesis class or whether a prediction has a prior), the phase
    "tentative" up to the initiator's `min_points`-th update, then "confirmed"."""
    from stonesoup.types.multihypothesis import MultipleHypothesis
    from stonesoup.types.update import Update

    assert type(a) is type(b)
    assert len(a) == len(b) == len(a.states) == len(list(a))
    _same_state(a.state, b.state)
    assert a.state is a.states[-1] is a[-1]
    assert a.timestamp == b.timestamp  # proxied to the newest state
    assert np.allclose(a.state_vector, b.state_vector, atol=ATOL)
    assert a.metadata == b.metadata and a.metadatas == b.metadatas
    kinds: Counter = Counter()
    updates = 0
    priors = {id(sb): sa for sa, sb in zip(a.states, b.states, strict=True)}
    for i, (sa, sb) in enumerate(zip(a, b, strict=True)):
        _same_state(sa, sb)
        assert a[i] is sa and sa in a.states and a.states.index(sa) == i
        _same_object(sa, sb, f"state {i}", priors)
        phase = "tentative" if updates < MIN_POINTS else "confirmed"
        if isinstance(sb, Update):
            updates += 1
            if isinstance(sb.hypothesis, MultipleHypothesis):
                # Which hypotheses share their prediction / measurement prediction object.
                for name in ("prediction", "measurement_prediction"):
                    shared = _sharing([getattr(h, name) for h in sa.hypothesis])
                    assert shared == _sharing([getattr(h, name) for h in sb.hypothesis]), name
            kinds[phase, type(sb).__name__, type(sb.hypothesis).__name__] += 1
        else:
            kinds[phase, type(sb).__name__, sb.prior is not None] += 1
    mid = b.states[len(b) // 2].timestamp
    assert a[mid] is a.states[len(a) // 2] or a[mid].timestamp == mid
    assert len(a[mid:]) == len(b[mid:]) and len(a[1:3]) == len(b[1:3])
    assert list(reversed(a.states)) == a.states[::-1]
    assert [s.timestamp for s in a.last_timestamp_generator()] == [
        s.timestamp for s in b.last_timestamp_generator()
    ]
    c = copy.copy(a)
    assert c.states == a.states and c.states is not a.states and c.metadatas == a.metadatas
    assert type(c.states) is list
    return kinds


@pytest.mark.parametrize(
    ("read_every", "associator"),
    [(None, "jpda"), (1, "jpda"), (3, "jpda"), (None, "gnn"), (1, "gnn"), (3, "gnn")],
    ids=[
        "read-at-end",
        "every-scan",
        "now-then",
        "gnn-read-at-end",
        "gnn-every-scan",
        "gnn-now-then",
    ],
)
def test_lazy_tracks_read_like_stonesoups(read_every, associator):
    scenario = H.two_sensors(1)  # two sensors, clutter, births and deaths
    scans = H.stonesoup_scans(scenario)
    cfg = H.Code57(associator=associator, **SHORT)
    ref_tracker, _ = H.build_stonesoup(cfg, detector=scans)
    ref = _collect(ref_tracker, read_every)
    ours_tracker, _ = H.build_stonesoup(cfg)
    ours = _collect(dropin_for(ours_tracker, scans), read_every)
    pairs = _match(ours, ref)
    assert len(pairs) > 2 and any(len(a) < len(scans) - 5 for a, _ in pairs)
    kinds = sum((_same_track(a, b) for a, b in pairs), Counter())
    # Every kind of state both phases give was compared, attribute by attribute.
    upd, pred = "GaussianStateUpdate", "GaussianStatePrediction"
    confirmed = "MultipleHypothesis" if associator == "jpda" else "SingleDistanceHypothesis"
    assert kinds["tentative", upd, "SingleHypothesis"] == len(pairs)  # the first states
    assert kinds["tentative", upd, "SingleDistanceHypothesis"] >= len(pairs)
    assert kinds["confirmed", upd, confirmed] > 30
    # Missed scans: a predictor's prediction under GNN, JPDA's bare mixture prediction.
    assert kinds["confirmed", pred, associator == "gnn"] > 0
    assert kinds["confirmed", pred, associator != "gnn"] == 0
    assert kinds["tentative", pred, True] > 0


@pytest.mark.parametrize("associator", ["ehm", "gnn"])
def test_hypotheses_of_detections_without_a_model(associator):
    # Detections without a measurement model (the updater's is used), JPDA by pyehm's EHM.
    scenario = H.crossing(2)
    scans = H.stonesoup_scans(scenario, models=[None] * 4)
    assert all(d.measurement_model is None for _, dets in scans for d in dets)
    cfg = H.Code57(associator=associator, **SHORT)
    ref = _collect(H.build_stonesoup(cfg, detector=scans)[0], 2)
    ours = _collect(dropin_for(H.build_stonesoup(cfg)[0], scans), 2)
    pairs = _match(ours, ref)
    kinds = sum((_same_track(a, b) for a, b in pairs), Counter())
    confirmed = "MultipleHypothesis" if associator == "ehm" else "SingleDistanceHypothesis"
    assert kinds["confirmed", "GaussianStateUpdate", confirmed] > 20


def test_tracks_read_by_stonesoup_code_and_appended_to():
    # Stone Soup's own readers (a deleter on the drop-in's tracks) and a user's Track.append
    # onto a lazy track behave as on Stone Soup's tracks.
    from stonesoup.deleter.error import CovarianceBasedDeleter
    from stonesoup.types.state import GaussianState

    scans = H.stonesoup_scans(H.crossing(3))
    ours_tracker, _ = H.build_stonesoup(H.Code57())
    tracker = dropin_for(ours_tracker, scans)
    ref_tracker, _ = H.build_stonesoup(H.Code57(), detector=scans)
    deleter = CovarianceBasedDeleter(covar_trace_thresh=0.5)
    for (_, ours), (_, ref) in zip(tracker, ref_tracker, strict=True):
        assert len(ours) == len(ref)
        assert len(deleter.delete_tracks(ours)) == len(deleter.delete_tracks(ref))
    track = next(iter(tracker.tracks))
    n = len(track)
    extra = GaussianState(np.zeros((4, 1)), np.eye(4), timestamp=track.timestamp)
    track.append(extra)
    assert len(track) == n + 1 and track.state is extra and len(track.metadatas) == n + 1
    back = pickle.loads(pickle.dumps(track))
    assert type(back.states) is list and len(back) == n + 1 and back.metadatas == track.metadatas


def test_a_failed_build_leaves_the_track_unbuilt(monkeypatch):
    scans = H.stonesoup_scans(H.crossing(3))
    tracker = dropin_for(H.build_stonesoup(H.Code57())[0], scans)
    for _ in tracker:
        pass
    track = next(iter(tracker.tracks))
    real = tracker._dets_of
    calls = []

    def flaky(scan):
        calls.append(scan)
        if len(calls) == 5:
            raise RuntimeError("detections gone")
        return real(scan)

    monkeypatch.setattr(tracker, "_dets_of", flaky)
    with pytest.raises(RuntimeError, match="detections gone"):
        len(track)
    assert list.__len__(track.states) == 0  # nothing half-built is visible
    monkeypatch.setattr(tracker, "_dets_of", real)
    ref = H.run_tracker(H.build_stonesoup(H.Code57(), detector=scans)[0])
    assert len(track) in {len(r.times) for r in ref}


def test_lazy_list_fills_once_before_any_read():
    calls = []

    def fill():
        calls.append(1)
        lst.extend([1, 2, 3])

    reads = [
        len,
        lambda x: x[0],
        list,
        lambda x: 2 in x,
        lambda x: x == [1, 2, 3],
        repr,
        lambda x: [0] + x,  # noqa: RUF005 (list + LazyList is what is tested)
        lambda x: x + [4],  # noqa: RUF005
        lambda x: list(reversed(x)),
        copy.copy,
        copy.deepcopy,
        lambda x: pickle.loads(pickle.dumps(x)),
        lambda x: x.index(2),
        lambda x: x.count(1),
        sorted,
        np.asarray,
        bool,
    ]
    for read in reads:
        lst = LazyList()
        lst._fill = fill
        calls.clear()
        out = read(lst)
        assert calls == [1], read
        assert list.__len__(lst) == 3
        if isinstance(out, list):
            assert out in ([1, 2, 3], [0, 1, 2, 3], [1, 2, 3, 4], [3, 2, 1])
            assert type(out) is list  # copies, pickles and sums are plain lists
        read(lst)
        assert calls == [1]  # disarmed after filling
    lst = LazyList([5])
    lst._fill = fill
    lst.append(6)
    assert list(lst) == [5, 1, 2, 3, 6]


def same_tracks_deeply(ours: list, ref: list, tol: float) -> int:
    """Match the final tracks of two runs (by first state) and compare every state and
    hypothesis attribute within `tol`; returns the number of states compared."""
    n = 0
    left = list(ref)
    for t in ours:
        b = next(
            r
            for r in left
            if len(r) == len(t)
            and np.allclose(r.states[0].state_vector, t.states[0].state_vector, atol=tol)
        )
        left.remove(b)
        priors = {id(sb): sa for sa, sb in zip(t.states, b.states, strict=True)}
        for i, (sa, sb) in enumerate(zip(t.states, b.states, strict=True)):
            _same_object(sa, sb, f"state {i}", priors, tol)
            n += 1
    assert not left
    return n
