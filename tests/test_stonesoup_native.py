"""The drop-in's native Stone Soup object factory (`usvfast._core.StoneSoupKit`): a scan's newest
states, built in one call when a track is first read in that scan, are Stone Soup's own
tracker's (JPDA and GNN, with and without detection metadata), attribute by attribute, and the
Python builders' (which remain the fallback); the kit is really used, not silently bypassed;
bad arguments are ValueErrors naming them; the two small core readers equal the snapshot."""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from test_stonesoup_dropin import SHORT, dropin_for
from test_stonesoup_lazy import _collect, _match, _same_track, same_tracks_deeply

from usvfast import _core
from usvfast.stonesoup_build import StateBuilder

import ssharness as H


def _scans(with_metadata: bool) -> list:
    """Two sensors with clutter; every third scan's detections without metadata."""

    def md(k, i, _sensor):
        return {"plot": f"{k}-{i}"} if with_metadata and k % 3 else {}

    return H.stonesoup_scans(H.two_sensors(3), metadata=md)


@pytest.fixture
def python_builds(monkeypatch) -> list:
    """Counts the newest states built in Python (the native kit's fallback)."""
    calls: list = []
    real = StateBuilder._build_newest_py

    def counted(self, f):
        calls.append(f.tid)
        return real(self, f)

    monkeypatch.setattr(StateBuilder, "_build_newest_py", counted)
    return calls


@pytest.mark.parametrize("associator", ["jpda", "gnn"])
@pytest.mark.parametrize("with_metadata", [False, True], ids=["plain", "metadata"])
def test_native_newest_states_are_stonesoups(associator, with_metadata, python_builds):
    scans = _scans(with_metadata)
    cfg = H.Code57(associator=associator, **SHORT)
    ref = _collect(H.build_stonesoup(cfg, detector=scans)[0], 1)
    tracker = dropin_for(H.build_stonesoup(cfg)[0], scans)
    ours = _collect(tracker, 1)  # every scan, one track in two read first
    assert isinstance(tracker._kit, _core.StoneSoupKit)
    assert python_builds == []  # every newest state came from the kit
    pairs = _match(ours, ref)
    kinds = sum((_same_track(a, b) for a, b in pairs), Counter())
    confirmed = "MultipleHypothesis" if associator == "jpda" else "SingleDistanceHypothesis"
    assert kinds["confirmed", "GaussianStateUpdate", confirmed] > 20
    assert sum(v for k, v in kinds.items() if k[1] == "GaussianStatePrediction") > 0
    merged = sum(bool(m) for a, _ in pairs for m in a.metadatas)
    assert (merged > 0) == with_metadata


@pytest.mark.parametrize("associator", ["jpda", "gnn"])
def test_native_equals_python_builders(associator, python_builds):
    scans = _scans(False)
    cfg = H.Code57(associator=associator, **SHORT)
    runs = []
    for native in (True, False):
        tracker = dropin_for(H.build_stonesoup(cfg)[0], scans)
        if not native:
            tracker._kit = False  # the Python builders only
        seen: dict = {}
        for _, tracks in tracker:
            for t in tracks:
                seen[id(t)] = t
                t.state  # noqa: B018 (a read: builds the newest state)
        runs.append(list(seen.values()))
    assert len(python_builds) > 50  # the second run built in Python
    assert same_tracks_deeply(runs[0], runs[1], 1e-12) > 100


def test_kit_rejects_bad_arguments():
    with pytest.raises(ValueError, match="builders"):
        _core.StoneSoupKit([], (np.ndarray, np.ndarray, np.ndarray), lambda m: None, 1)
    scans = _scans(False)
    tracker = dropin_for(H.build_stonesoup(H.Code57(**SHORT))[0], scans)
    for _, tracks in tracker:
        for t in tracks:
            t.state  # noqa: B018
    kit = tracker._kit
    with pytest.raises(ValueError, match="index"):
        kit.make(99, [])
    with pytest.raises(ValueError, match="values"):
        kit.make(0, [])
    scan = tracker._scan - 1
    args = dict(
        core=tracker._raw,
        scan=scan,
        ids=[],
        priors=[],
        dt=1.0,
        transition=(np.eye(3), np.eye(3)),
        detections=tracker._dets_of(scan),
        models=tracker._newest_models,
        z=tracker._newest_z,
        timestamp=tracker._scan_time[scan],
        transition_model=None,
        mixture=True,
        hypotheses=True,
    )
    with pytest.raises(ValueError, match="transition"):
        kit.newest(**args)
    args["transition"] = (np.eye(4), np.eye(4))
    with pytest.raises(ValueError, match="priors"):
        kit.newest(**{**args, "ids": [0]})
    with pytest.raises(ValueError, match="models"):
        kit.newest(**{**args, "models": []})
    # An id the core does not have is left to the Python builders (None).
    assert kit.newest(**{**args, "ids": [10**6], "priors": [None]})[1] == [None]


def test_core_readers_equal_the_snapshot():
    scans = _scans(False)
    tracker = dropin_for(H.build_stonesoup(H.Code57(**SHORT))[0], scans)
    looked = 0
    for _ in tracker:
        raw = tracker._raw
        if raw is None:
            continue
        assert _core.confirmed_ids(raw) == raw.snapshot()["ids"].tolist()
        first = raw.snapshot(tentative=True)["first_scan"]
        want = int(first.min()) if len(first) else None
        assert _core.tentative_first_scan(raw) == want
        looked += want is not None
    assert looked > 10


@pytest.mark.parametrize("associator", ["jpda", "gnn"])
def test_whole_histories_built_natively_equal_python_and_stonesoup(associator, monkeypatch):
    """Nothing read until the end: every state of every track (alive and deleted) is built
    then, the entries after confirmation in one native call per track
    (`StoneSoupKit.entries`), equal to the Python builders to 1e-12 and Stone Soup's tracks."""
    scans = _scans(True)
    cfg = H.Code57(associator=associator, **SHORT)
    native_states = []
    real = StateBuilder._native_entries

    def counted(self, *args):
        out = real(self, *args)
        native_states.append(len(out))
        return out

    monkeypatch.setattr(StateBuilder, "_native_entries", counted)
    runs = []
    for native in (True, False):
        tracker = dropin_for(H.build_stonesoup(cfg)[0], scans)
        if not native:
            tracker._kit = False
        seen: dict = {}
        for _, tracks in tracker:
            for t in tracks:
                seen[id(t)] = t
        built = sum(len(t) for t in seen.values())  # builds every state
        runs.append(list(seen.values()))
        if native:
            n_native = sum(native_states)
            assert 50 < n_native < built  # the tentative histories: in Python
    assert sum(native_states) == n_native  # the second run: Python only
    compared = same_tracks_deeply(runs[0], runs[1], 1e-12)
    assert compared == built
    ref = H.run_tracker(H.build_stonesoup(cfg, detector=scans)[0])
    tracker = dropin_for(H.build_stonesoup(cfg)[0], scans)
    problems = H.compare_runs(H.run_tracker(tracker), ref)
    assert problems == []


def test_entries_rejects_bad_arguments():
    scans = _scans(False)
    tracker = dropin_for(H.build_stonesoup(H.Code57(**SHORT))[0], scans)
    for _ in tracker:
        pass
    kit = tracker._native_kit()
    args = dict(
        core=tracker._raw,
        track_id=0,
        first=1,
        prior=None,
        dts=[1.0],
        transitions=[],
        detections=[],
        models=[],
        zs=[],
        timestamps=[],
        transition_model=None,
        mixture=True,
        hypotheses=True,
    )
    with pytest.raises(ValueError, match="transitions"):
        kit.entries(**args)
    scan = tracker._scan - 1
    one = dict(
        transitions=[(np.eye(3), np.eye(3))],
        detections=[tracker._dets_of(scan)],
        models=[tracker._newest_models],
        zs=[tracker._newest_z],
        timestamps=[tracker._scan_time[scan]],
    )
    tid = next(iter(tracker._fillers))
    with pytest.raises(ValueError, match="transitions"):
        kit.entries(**{**args, **one, "track_id": tid})
    # A track the core does not have: nothing built (the Python builders then).
    assert kit.entries(**{**args, **one, "track_id": 10**6}) == []
