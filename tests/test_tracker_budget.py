"""JPDA per-cluster budget: past it, belief-propagation marginals (Williams & Lau 2014) —
bounded cost on dense clutter, counted approximations, a known error against exact EHM, and
Ctrl-C between clusters."""

from __future__ import annotations

import os
import resource
import signal
import threading
import time

import numpy as np
import pytest

from usvfast import _core
from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d


def clutter_tracker(budget, method="ehm"):
    return T.Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[T.Sensor.position(0.5)],
        association=T.JPDA(0.9, 0.99, 1e-3, max_hypotheses=budget, method=method),
        deleter=T.StepsSinceUpdate(3),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0, 1.0, 0, 1.0]), missed_distance=3.0
        ),
    )


def test_dense_clutter_completes_with_approximated_clusters():
    # 2,000 uniform plots a scan in 250 m x 250 m: clutter tracks confirm and merge into
    # clusters of thousands of tracks (exact EHM on them exhausts memory).
    rng = np.random.default_rng(0)
    tr = clutter_tracker(200_000)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    approx, largest, worst = 0, 0, 0.0
    for k in range(8):
        t0 = time.perf_counter()
        tr.step(float(k), rng.uniform(0, 250, (2000, 2)))
        worst = max(worst, time.perf_counter() - t0)
        approx += tr.last_step.approximated_clusters
        largest = max(largest, tr.last_step.largest_cluster)
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1e3
    assert largest > 1000 and approx >= 3
    assert worst < 5.0 and grown_mb < 300, (worst, grown_mb)
    assert tr.last_step.processed and tr.last_step.clusters > 0


def grid_cluster(rng, n, spacing, sigma=0.25, pd=0.9, pg=0.99, lam=0.125):
    side = int(np.ceil(np.sqrt(n)))
    x = np.column_stack([np.arange(n) % side, np.arange(n) // side]) * spacing
    z = x[rng.random(n) < pd]
    z = z + rng.normal(0, sigma, z.shape)
    s = 2 * sigma**2
    d2 = ((x[:, None, :] - z[None, :, :]) ** 2).sum(-1) / s
    w = np.where(d2 <= _core.chi2_gate(pg, 2), pd / lam * np.exp(-d2 / 2) / (2 * np.pi * s), 0)
    return np.ascontiguousarray(np.column_stack([np.full(n, 1 - pd * pg), w]))


def test_belief_propagation_error_against_exact_ehm():
    # Clusters of 9 and 16 tracks 0.5 m apart (σ 0.25 m): both methods run.
    rng = np.random.default_rng(2)
    errs = []
    for n in (9, 16):
        for _ in range(20):
            w = grid_cluster(rng, n, 0.5)
            exact = _core.jpda_marginals(w, "ehm")
            approx = _core.jpda_marginals(w, "lbp")
            np.testing.assert_allclose(approx.sum(1), 1.0, atol=1e-12)
            errs.append(np.abs(exact - approx).ravel())
    e = np.concatenate(errs)
    assert e.max() < 0.15 and e.mean() < 0.01, (e.max(), e.mean())
    # Separated tracks (a forest): exact.
    w = grid_cluster(rng, 9, 5.0)
    np.testing.assert_allclose(_core.jpda_marginals(w, "lbp"), _core.jpda_marginals(w, "ehm"))


def test_kbest_marginals_against_exact_ehm():
    # Murty's k-best: exact once k exceeds the joint hypotheses; on 16 tracks 1 m apart (where
    # belief propagation is furthest off, and the weight sits on few joint hypotheses) the
    # 1,000 best come closer than belief propagation.
    rng = np.random.default_rng(4)
    w = grid_cluster(rng, 4, 0.5)
    np.testing.assert_allclose(
        _core.jpda_marginals(w, "kbest", 10**6), _core.jpda_marginals(w, "ehm"), atol=1e-12
    )
    e_lbp, e_kb = [], []
    for _ in range(10):
        w = grid_cluster(rng, 16, 1.0)
        exact = _core.jpda_marginals(w, "ehm")
        kb = _core.jpda_marginals(w, "kbest", 1000)
        np.testing.assert_allclose(kb.sum(1), 1.0, atol=1e-12)
        e_kb.append(np.abs(exact - kb).max())
        e_lbp.append(np.abs(exact - _core.jpda_marginals(w, "lbp")).max())
    assert max(e_kb) < 0.05 and max(e_kb) < max(e_lbp), (max(e_kb), max(e_lbp))
    with pytest.raises(ValueError, match="k_best"):
        _core.jpda_marginals(w, "kbest", 0)
    with pytest.raises(ValueError, match="method"):
        _core.jpda_marginals(w, "murty")


def test_tracker_with_every_cluster_approximated_stays_close():
    # 16 targets 0.5 m apart: the tracker with a budget of 1 (every shared cluster by belief
    # propagation) keeps the exact tracker's tracks within 5 cm.
    rng = np.random.default_rng(1)
    pos = np.column_stack([np.arange(16) % 4, np.arange(16) // 4]) * 0.5

    def make(budget):
        return T.code_5_7(
            [T.Sensor.position(0.25)], T.JPDA(0.85, 0.95, 0.125, max_hypotheses=budget)
        )

    exact, approx = make(None), make(1)
    n_approx = 0
    for k in range(1, 30):
        z = pos + np.array([0, 0.2 * k]) + rng.normal(0, 0.25, pos.shape)
        a, b = exact.step(k, z), approx.step(k, z)
        assert exact.last_step.approximated_clusters == 0
        n_approx += approx.last_step.approximated_clusters
        np.testing.assert_array_equal(a.ids, b.ids)
        if len(a.ids):
            assert np.abs(a.states - b.states).max() < 0.05
    assert n_approx > 10
    res = make(1).run(np.arange(1.0, 4.0), np.tile(pos, (3, 1)), None, np.repeat(np.arange(3), 16))
    assert res.approximated_clusters.shape == (3,)


def test_bad_budget_and_method_are_clear_errors():
    with pytest.raises(ValueError, match="max_hypotheses"):
        clutter_tracker(0)
    with pytest.raises(ValueError, match="max_hypotheses"):
        clutter_tracker(-1)
    with pytest.raises(ValueError, match="method"):
        clutter_tracker(10, method="murty")
    # The association crosses into Rust as a typed object: a wrong field type names the field.
    with pytest.raises(TypeError, match="prob_detect"):
        T.Tracker(
            motion_model=constant_velocity_2d(1.0),
            sensors=[T.Sensor.position(1.0)],
            association=T.JPDA(prob_detect="high"),
            deleter=T.StepsSinceUpdate(2),
            initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
        )


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(), reason="signals")
def test_ctrl_c_between_clusters_leaves_the_tracker_as_before():
    # 600 separate clusters of 7 tracks all gating 7 detections, by brute force (~1 ms each).
    tr = clutter_tracker(None, method="brute_force")
    rng = np.random.default_rng(3)
    centres = np.column_stack([np.arange(600) * 100.0, np.zeros(600)])
    offs = rng.normal(0, 0.3, (7, 2))
    for c in centres:
        for o in offs:
            tr.add_track(np.array([c[0] + o[0], 0, c[1] + o[1], 0]), np.eye(4), 0.0)
    z = (centres[:, None, :] + rng.normal(0, 0.3, (600, 7, 2))).reshape(-1, 2)
    before = tr.tracks
    # Ctrl-C every 50 ms until the step returns (one lost signal cannot pass the test); the
    # handler raises KeyboardInterrupt once, as Python's own does, and ignores the rest.
    raised: list[int] = []

    def handler(signum, frame):
        if not raised:
            raised.append(signum)
            raise KeyboardInterrupt

    done = threading.Event()

    def press_ctrl_c():
        while not done.wait(0.05):
            os.kill(os.getpid(), signal.SIGINT)

    previous = signal.signal(signal.SIGINT, handler)
    sender = threading.Thread(target=press_ctrl_c)
    try:
        sender.start()
        t0 = time.perf_counter()
        with pytest.raises(KeyboardInterrupt):
            tr.step(1.0, z)
        assert time.perf_counter() - t0 < 0.5
    finally:
        done.set()
        sender.join()
        signal.signal(signal.SIGINT, previous)
    after = tr.tracks
    np.testing.assert_array_equal(before.states, after.states)
    assert tr.last_time == 0.0 or tr.last_time is None
    tr.step(1.0, z[:10])
    assert tr.last_time == 1.0


def test_time_deleter_boundary_equals_stonesoup():
    # Scans at k · 0.1 s, a 5 s UpdateTimeDeleter: 6.3 − 1.3 is 5.000000000000001 in floats,
    # exactly 5 s in Stone Soup's datetimes — the track is deleted at the same scan by both.
    from datetime import datetime, timedelta

    from stonesoup.deleter.time import UpdateTimeDeleter
    from stonesoup.types.detection import Detection
    from stonesoup.types.hypothesis import SingleHypothesis
    from stonesoup.types.prediction import GaussianStatePrediction
    from stonesoup.types.track import Track
    from stonesoup.types.update import GaussianStateUpdate

    tr = T.Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[T.Sensor.position(0.5)],
        association=T.GNN(missed_distance=5.0),
        deleter=T.TimeSinceUpdate(5.0),
        initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
    )
    tr.add_track(np.zeros(4), np.eye(4), 13 * 0.1)
    tr.step(13 * 0.1, [[0.0, 0.0]])
    ours = next(k for k in range(14, 100) if len(tr.step(k * 0.1)) == 0)
    epoch = datetime(2024, 1, 1)
    ts = [epoch + timedelta(seconds=round(k * 0.1, 6)) for k in range(13, 100)]
    hyp = SingleHypothesis(None, Detection(np.zeros((2, 1)), timestamp=ts[0]))
    track = Track([GaussianStateUpdate(np.zeros((4, 1)), np.eye(4), hyp, timestamp=ts[0])])
    deleter = UpdateTimeDeleter(time_since_update=timedelta(seconds=5.0))
    theirs = None
    for k, t in zip(range(14, 100), ts[1:], strict=False):
        track.append(GaussianStatePrediction(np.zeros((4, 1)), np.eye(4), timestamp=t))
        if deleter.check_for_deletion(track):
            theirs = k
            break
    assert ours == theirs == 64
