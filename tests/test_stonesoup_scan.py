"""The drop-in's one-call scan (`usvfast._core.stonesoup_step`): plain Stone Soup detections
are read from their `__dict__`, stepped and the alive ids listed in one native call, and the
tracks stay Stone Soup's own tracker's (births, deaths, states to 1e-6 as the other parity
tests); detections it cannot read that way (a class with its own attribute access, a model not
seen before, a late timestamp, integer state vectors) go the long way, with nothing stepped, and
give the same tracks or the same errors."""

from __future__ import annotations

from datetime import timedelta

import numpy as np
import pytest
from stonesoup.types.detection import Detection
from test_stonesoup_dropin import SHORT, dropin_for

from usvfast import _core
from usvfast.stonesoup_tracker import _plain_detection_class

import ssharness as H


class Watched(Detection):
    """A detection whose attribute reads go through Python (here: counted), as a user's
    subclass may: the one-call scan must not read its `__dict__` behind its back."""

    reads = 0

    def __getattribute__(self, name):
        if name == "state_vector":
            Watched.reads += 1
        return super().__getattribute__(name)


def _counting(tracker) -> list:
    """Wraps the tracker's one-call scan; the list gets one bool per call (True: it stepped)."""
    calls: list = []
    real = tracker._fast_step

    def counted(*args):
        out = real(*args)
        calls.append(out is not None)
        return out

    tracker._fast_step = counted
    return calls


def _run(scans, cfg):
    ref = H.run_tracker(H.build_stonesoup(cfg, detector=scans)[0])
    tracker = dropin_for(H.build_stonesoup(cfg)[0], scans)
    calls = _counting(tracker)
    return ref, H.run_tracker(tracker), tracker, calls


@pytest.mark.parametrize("associator", ["jpda", "gnn"])
def test_one_call_scans_give_stonesoups_tracks(associator):
    sc = H.two_sensors(5)  # two sensors, two noise covariances on one core sensor
    ref, ours, tracker, calls = _run(H.stonesoup_scans(sc), H.Code57(associator=associator))
    assert H.compare_runs(ours, ref) == []
    assert len(ref) >= 2
    # Every scan once the core exists (the first scan builds it) took the one call, but for
    # the scan where the second sensor's model first appears (the long way registers it).
    assert len(calls) == sc.n_scans - 1 and calls.count(False) == 1
    assert any(own is not None for _, own, _ in tracker._sensor_of_model.values())


def test_detections_with_their_own_attribute_access_go_the_long_way():
    assert _plain_detection_class(Detection)
    assert not _plain_detection_class(Watched)
    sc = H.crossing(4)
    scans = [
        (
            t,
            {
                Watched(d.state_vector, timestamp=t, measurement_model=d.measurement_model)
                for d in dets
            },
        )
        for t, dets in H.stonesoup_scans(sc)
    ]
    before = Watched.reads
    ref, ours, _, calls = _run(scans, H.Code57(**SHORT))
    assert H.compare_runs(ours, ref) == []
    assert calls and not any(calls)
    assert Watched.reads > before


def test_what_the_one_call_cannot_read_is_not_stepped():
    scans = H.stonesoup_scans(H.two_sensors(6))
    tracker = dropin_for(H.build_stonesoup(H.Code57())[0], None)
    for time, dets in scans[:5]:
        tracker.update_tracker(time, dets)
    raw, known, plain = tracker._raw, tracker._sensor_of_model, tracker._plain
    noises = tracker._noises
    time, dets = scans[5]
    det = next(iter(dets))
    t = (time - tracker._t0).total_seconds()
    last = raw.last_time

    def step(detections, timestamp=time):
        return _core.stonesoup_step(raw, t, detections, timestamp, known, plain, noises, 2)

    model = det.measurement_model
    late = Detection(
        det.state_vector, timestamp=time + timedelta(seconds=1), measurement_model=model
    )
    other = type(model)(ndim_state=4, mapping=[0, 2], noise_covar=np.eye(2))
    unseen = Detection(det.state_vector, timestamp=time, measurement_model=other)
    ints = Detection(np.array([[3], [4]]), timestamp=time, measurement_model=model)
    watched = Watched(det.state_vector, timestamp=time, measurement_model=model)
    for odd in (late, unseen, ints, watched):
        assert step([det, odd]) is None
        assert raw.last_time == last  # nothing stepped
    assert step([det], timestamp=time + timedelta(seconds=2)) is None
    # The long way then reports or handles them as before.
    with pytest.raises(ValueError, match="scan time"):
        tracker.update_tracker(time, {det, late})
    _, tracks = tracker.update_tracker(time, {det, unseen, ints})
    assert raw.last_time == t and isinstance(tracks, set)
    later = time + timedelta(seconds=1)
    nan = Detection(np.array([[np.nan], [0.0]]), timestamp=later, measurement_model=model)
    with pytest.raises(ValueError, match="measurements"):  # the core's check, named
        tracker.update_tracker(later, {nan})
