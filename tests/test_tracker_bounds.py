"""Bounded cost and memory: a cap on new tentative tracks per scan under a clutter burst, and
deleted tracks handed out (drain) or kept up to a bound."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast import TimeOrderError
from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d


def make(cap=None, max_deleted=None):
    return T.Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[T.Sensor.position(0.5)],
        association=T.JPDA(0.9, 0.99, 1e-3),
        deleter=T.StepsSinceUpdate(2),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0, 1.0, 0, 1.0]), missed_distance=2.0, max_new_tentative=cap
        ),
        max_deleted=max_deleted,
    )


def test_clutter_burst_starts_at_most_the_cap():
    rng = np.random.default_rng(0)
    burst = rng.uniform(0, 1000, (5000, 2))
    tr = make(cap=50)
    tr.step(0.0, burst)
    assert len(tr.tentative_tracks) == 50 and tr.capped_detections == 4950
    # The first free detections in scan order are kept.
    np.testing.assert_allclose(tr.tentative_tracks.states[:, [0, 2]], burst[:50])
    uncapped = make()
    uncapped.step(0.0, burst)
    assert len(uncapped.tentative_tracks) == 5000 and uncapped.capped_detections == 0


def scans(n):
    """Targets appearing for 4 scans each, one after the other (each becomes a deleted track)."""
    for k in range(n):
        j = k // 6
        yield float(k), (np.array([[j * 100.0, 0.0]]) if k % 6 < 4 else np.zeros((0, 2)))


def test_deleted_tracks_are_drained_or_bounded():
    a, b = make(), make(max_deleted=3)
    drained = []
    for t, z in scans(120):
        a.step(t, z)
        b.step(t, z)
        if t % 30 == 29:
            drained += a.drain_deleted()
    drained += a.drain_deleted()
    assert len(drained) >= 15 and len(a.deleted_track_ids) == 0
    assert sorted(h.id for h in drained) == list(range(len(drained)))
    assert all(np.isfinite(h.deleted_time) for h in drained)
    kept = b.deleted_track_ids
    assert len(kept) == 3 and list(kept) == list(range(len(drained) - 3, len(drained)))
    with pytest.raises(ValueError, match="max_deleted"):
        make(max_deleted=-1)
    with pytest.raises(ValueError, match="max_new_tentative"):
        make(cap=-1)
    with pytest.raises(TypeError, match="max_new_tentative"):  # a count is an integer
        make(cap=1.5)


def test_copies_are_independent_and_continue_exactly():
    import copy

    sc = list(scans(40))
    a = make()
    for t, z in sc[:20]:
        a.step(t, z)
    b, c = copy.deepcopy(a), copy.copy(a)
    for t, z in sc[20:]:
        ra, rb = a.step(t, z), b.step(t, z)
        np.testing.assert_array_equal(ra.states, rb.states)
        np.testing.assert_array_equal(ra.ids, rb.ids)
    # c was not advanced by a or b.
    assert c.last_time == sc[19][0] and a.last_time == sc[-1][0]


def test_two_threads_get_a_clear_error():
    import threading

    tr = make(cap=20)
    with tr._busy:  # another thread is inside the core
        with pytest.raises(RuntimeError, match="two threads"):
            tr.step(0.0, [[0.0, 0.0]])
    # Real threads: every failure is the clear error, never pyo3's "Already borrowed".
    rng = np.random.default_rng(1)
    z = rng.uniform(0, 1000, (300, 2))
    errors = []

    def work(k):
        try:
            for i in range(5):
                tr.step(float(10 * k + i), z)
        except Exception as e:
            errors.append(e)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    # Interleaved threads also step the shared tracker back in time: TimeOrderError.
    assert all(
        (isinstance(e, RuntimeError) and "two threads" in str(e)) or isinstance(e, TimeOrderError)
        for e in errors
    ), errors


def test_history_from_an_entry_is_the_tail_of_the_full_history():
    # `_core.TrackerCore.history(id, start)` copies only entries start.. (a reader following a
    # track scan by scan pays O(new entries)), its association CSR rebased to 0.
    tr = make()
    rng = np.random.default_rng(5)
    for k in range(15):
        z = np.array([[k * 1.0, 0.0], [0.0, 40.0 - k]]) + rng.normal(0, 0.3, (2, 2))
        near = z[:1] + rng.normal(0, 1.0, (1, 2))  # a second detection in its gate
        tr.step(float(k), np.vstack([z, near, rng.uniform(-5, 45, (3, 2))]))
    tid = int(tr.tracks.ids[0])
    full = tr._core.history(tid)
    n = len(full["times"])
    assert n > 10 and full["assoc_offsets"][-1] > n
    for start in (0, 1, n // 2, n - 1, n):
        tail = tr._core.history(tid, start)
        for key in ("times", "states", "covariances", "is_update", "scan", "nis"):
            np.testing.assert_array_equal(tail[key], full[key][start:])
        offs = full["assoc_offsets"]
        np.testing.assert_array_equal(tail["assoc_offsets"], offs[start:] - offs[start])
        a, b = offs[start], offs[-1]
        np.testing.assert_array_equal(tail["assoc_detection"], full["assoc_detection"][a:b])
        np.testing.assert_array_equal(tail["assoc_probability"], full["assoc_probability"][a:b])
    assert list(tr._core.history(tid, n)["assoc_offsets"]) == [0]
    with pytest.raises(ValueError, match="start"):
        tr._core.history(tid, n + 1)
