"""Tracking the real Joyride radar recording: Stone Soup JPDA with the issue's anchor
parameters reproduces the issue's figures; the drop-in and the native tracker give exactly
Stone Soup's tracks on it; the native tracker with the chosen parameters keeps the target in
one track."""

from __future__ import annotations

import numpy as np
import pytest

from usvfast import NotPositiveDefiniteError
from usvfast import stonesoup as us
from usvfast.datasets import load_joyride
from usvfast.metrics import clear_mot, track_quality

import ssharness as H
from conftest import SHARED_DATA

JOYRIDE = SHARED_DATA / "joyride" / "joyride.mat"


@pytest.fixture(scope="module")
def joyride():
    return load_joyride(JOYRIDE)


def _run(tracker):
    """(canonical records, per-scan snapshots) of a Stone Soup-protocol tracker."""
    snaps = []

    def spy():
        for time, tracks in tracker:
            snaps.append(H.snapshot(tracks))
            yield time, tracks

    return H.run_tracker(spy()), snaps


@pytest.fixture(scope="module")
def stonesoup_run(joyride):
    tracker, _ = H.build_stonesoup(H.JOYRIDE_ANCHOR, detector=H.joyride_scans(joyride, 10.0))
    return _run(tracker)


def _quality(joyride, snaps):
    return track_quality(joyride.target[:, [0, 2]], *H.track_rows(snaps), gate=50.0)


def test_stonesoup_anchor_reproduces_the_issue_figures(joyride, stonesoup_run):
    # Issue 3: Stone Soup JPDA (q = 2, sigma = 10 m, P_D 0.8, clutter 7e-8 /m², 3-point
    # initiation): 21.1 m, 89 %, 5 fragments. This validates the reader and the metrics.
    _, snaps = stonesoup_run
    q = _quality(joyride, snaps)
    assert 20.0 < q.rmse < 22.5
    assert 0.86 < q.coverage < 0.92
    assert 3 <= q.fragments <= 7
    scans, ids, pos = H.track_rows(snaps)
    mot = clear_mot(joyride.target[:, [0, 2]], scans, ids, pos)
    assert mot.misses == round((1 - q.coverage) * joyride.n_scans)


def test_dropin_gives_stonesoups_tracks_on_joyride(joyride, stonesoup_run):
    ref, ref_snaps = stonesoup_run
    tracker, _ = H.build_stonesoup(H.JOYRIDE_ANCHOR)
    ours, our_snaps = _run(
        us.MultiTargetMixtureTracker(
            initiator=tracker.initiator,
            deleter=tracker.deleter,
            detector=H.joyride_scans(joyride, 10.0),
            data_associator=tracker.data_associator,
            updater=tracker.updater,
        )
    )
    assert H.compare_runs(ours, ref) == []
    a, b = _quality(joyride, our_snaps), _quality(joyride, ref_snaps)
    assert (a.rmse, a.coverage, a.fragments) == pytest.approx((b.rmse, b.coverage, b.fragments))


def _native(joyride, **params):
    tracker = H.joyride_native(**params)
    scan_index, plots = joyride.scan_arrays()
    res = tracker.run(
        joyride.times - joyride.times[0], plots, np.zeros(len(plots), np.int64), scan_index
    )
    return track_quality(joyride.target[:, [0, 2]], res.scan, res.track_id, res.state[:, [0, 2]])


def test_native_tracker_with_the_anchor_parameters_equals_stonesoup(joyride, stonesoup_run):
    q = _native(joyride, **H.joyride_anchor_native_kwargs())
    ref = _quality(joyride, stonesoup_run[1])
    assert q.rmse == pytest.approx(ref.rmse, abs=1e-6)
    assert np.array_equal(np.isnan(q.errors), np.isnan(ref.errors))
    assert q.fragments == ref.fragments and q.n_tracks == ref.n_tracks


def test_native_tracker_chosen_parameters_keep_one_track_on_the_target(joyride):
    # Chosen parameters (docs/tracker.md, Joyride): one fragment over the whole recording, 93 %
    # coverage, RMSE ~22 m. The issue's aim (>= 95 %, <= 20.7 m) is NOT reached by a
    # single constant-velocity JPDA on this data; these are honest bounds of what it does.
    q = _native(joyride, **H.JOYRIDE_NATIVE)
    assert q.fragments == 1 and q.distinct_tracks == 1
    assert q.coverage >= 0.93
    assert q.rmse < 22.5
    assert q.tracks_elsewhere <= 5
    # Better than Stone Soup's anchor run on coverage and fragmentation.
    anchor = _native(joyride, **H.joyride_anchor_native_kwargs())
    assert q.coverage > anchor.coverage and q.fragments < anchor.fragments


def _constant_acceleration(joyride, **kw):
    from usvfast import tracking as tk
    from usvfast.kalman import ConstantAcceleration as CA

    tracker = tk.Tracker(
        motion_model=(CA(2.0), CA(2.0)),
        sensors=[tk.Sensor.position(25.0, ndim_state=6, mapping=(0, 3))],
        association=tk.JPDA(0.95, 0.999, 1e-8),
        deleter=tk.StepsSinceUpdate(50),
        initiator=tk.MultiMeasurementInitiator(
            np.zeros(6),
            np.diag([0, 100, 10, 0, 100, 10]),
            min_points=2,
            deleter=tk.StepsSinceUpdate(3),
            missed_distance=5.0,
        ),
        **kw,
    )
    scan_index, plots = joyride.scan_arrays()
    times = joyride.times - joyride.times[0]
    return tracker.run(times, plots, np.zeros(len(plots), np.int64), scan_index)


def test_constant_acceleration_needs_symmetric_covariances(joyride):
    # Stone Soup's P - K S K^T leaves rounding asymmetry that F P F^T amplifies polynomially
    # in the coasting time (t^4 with CA): without symmetrisation the target's track loses
    # positive definiteness at t ~ 400 s and the error says what to do.
    with pytest.raises(NotPositiveDefiniteError, match="symmetric_covariance"):
        _constant_acceleration(joyride, symmetric_covariance=False)
    res = _constant_acceleration(joyride)  # symmetric_covariance=True is the native default
    q = track_quality(joyride.target[:, [0, 2]], res.scan, res.track_id, res.state[:, [0, 3]])
    assert q.coverage > 0.8
    for c in res.covariance[::50]:
        np.testing.assert_allclose(c, c.T, rtol=1e-9, atol=1e-9)
        assert np.linalg.eigvalsh(c).min() > 0
