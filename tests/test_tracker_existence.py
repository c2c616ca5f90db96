"""Track existence with visibility (IPDA per track): the update against the closed form fed
with Stone Soup's PDA hypothesis weights, deletion by existence, visibility keeping a
temporarily unseen target, and invariants (probabilities in [0, 1])."""

from __future__ import annotations

from datetime import datetime, timedelta

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d

PD, PG, LAM = 0.85, 0.99, 0.01


def tracker(existence, deleter=None):
    return T.Tracker(
        motion_model=constant_velocity_2d(0.1),
        sensors=[T.Sensor.position(0.5)],
        association=T.JPDA(PD, PG, LAM),
        deleter=deleter or T.StepsSinceUpdate(1000),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0, 1.0, 0, 1.0]), missed_distance=2.0
        ),
        existence=existence,
    )


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(0, 5), vis=st.booleans())
def test_existence_update_equals_closed_form_with_stonesoup_weights(seed, n, vis):
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )
    from stonesoup.predictor.kalman import KalmanPredictor
    from stonesoup.types.detection import Detection
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track
    from stonesoup.updater.kalman import KalmanUpdater

    rng = np.random.default_rng(seed)
    x, p = np.array([0.0, 1.0, 0.0, 0.5]), np.diag([0.5, 0.2, 0.5, 0.2])
    z = np.array([1.0, 0.5]) + rng.normal(0, 1.0, (n, 2))
    ex = T.Existence(0.95, 0.7, 0.0, 0.8, 0.6) if vis else T.Existence(0.95, 0.7, 0.0)
    tr = tracker(ex)
    tr.add_track(x, p, 0.0)
    got = tr.step(1.0, z)

    epoch = datetime(2024, 1, 1)
    model = LinearGaussian(4, [0, 2], np.eye(2) * 0.25)
    hyp = PDAHypothesiser(
        KalmanPredictor(
            CombinedLinearGaussianTransitionModel([ConstantVelocity(0.1), ConstantVelocity(0.1)])
        ),
        KalmanUpdater(model),
        clutter_spatial_density=LAM,
        prob_detect=PD,
        prob_gate=PG,
        normalise=False,
    )
    ts = epoch + timedelta(seconds=1)
    dets = {Detection(zi.reshape(2, 1), timestamp=ts, measurement_model=model) for zi in z}
    mh = hyp.hypothesise(Track([GaussianState(x.reshape(4, 1), p, timestamp=epoch)]), dets, ts)
    big_l = sum(float(h.probability) for h in mh)  # missed weight 1 - PdPg + detection weights
    r0 = ex.survival * ex.initial
    v0 = 1.0 * ex.vis_stay + 0.0 * (1 - ex.invis_stay)
    e = v0 * big_l + 1 - v0
    want_r = r0 * e / (r0 * e + 1 - r0)
    want_v = v0 * big_l / e
    np.testing.assert_allclose(got.existence, [want_r], rtol=1e-9)
    np.testing.assert_allclose(got.visibility, [want_v], rtol=1e-9)


def run(existence, deleter=None, gap=(20, 26), stop=40):
    """A target detected every scan except during `gap`, disappearing at `stop`, in clutter."""
    rng = np.random.default_rng(0)
    tr = tracker(existence, deleter)
    out = []
    for k in range(60):
        z = [] if gap[0] <= k < gap[1] or k >= stop else [[k * 1.0, 0.5 * k]]
        z = np.array(z + list(rng.uniform(-20, 80, (rng.poisson(1.0), 2)))).reshape(-1, 2)
        got = tr.step(float(k), z + (rng.normal(0, 0.5, z.shape) if len(z) else 0))
        out.append(got)
        for r, v in zip(got.existence, got.visibility, strict=True):
            assert 0.0 <= r <= 1.0 and 0.0 <= v <= 1.0
    return out


def near_target(tracks, k):
    d = np.hypot(tracks.states[:, 0] - k, tracks.states[:, 2] - 0.5 * k)
    return np.flatnonzero(d < 5.0)


def test_existence_deletes_a_vanished_target_and_visibility_bridges_a_gap():
    # IPDA: the 6-scan gap kills the track (r < 0.05 after a few missed scans).
    ipda = run(T.Existence(0.98, 0.9, 0.05))
    assert len(near_target(ipda[19], 19)) == 1
    assert (
        len(near_target(ipda[30], 30)) == 0
        or ipda[30].ids[near_target(ipda[30], 30)][0]
        != (ipda[19].ids[near_target(ipda[19], 19)][0])
    )
    # With visibility the same gap is bridged: the target exists but is unseen.
    vis = run(T.Existence(0.98, 0.9, 0.05, vis_stay=0.9, invis_stay=0.9))
    tid = vis[19].ids[near_target(vis[19], 19)][0]
    assert tid in vis[30].ids
    i = list(vis[25].ids).index(tid)
    assert vis[25].visibility[i] < 0.5 < vis[25].existence[i]
    # After the target is gone for good its existence falls scan after scan (an unseen
    # target may still exist, so more slowly than under IPDA, which deleted it within the gap).
    r = [t.existence[list(t.ids).index(tid)] for t in vis[42:] if tid in t.ids]
    assert len(r) > 5 and np.all(np.diff(r) < 0) and r[-1] < 0.3


def test_existence_needs_jpda_and_valid_probabilities():
    with pytest.raises(ValueError, match="existence"):
        T.Tracker(
            motion_model=constant_velocity_2d(0.1),
            sensors=[T.Sensor.position(0.5)],
            association=T.GNN(missed_distance=3.0),
            deleter=T.StepsSinceUpdate(3),
            initiator=T.MultiMeasurementInitiator(np.zeros(4), np.eye(4)),
            existence=T.Existence(),
        )
    with pytest.raises(ValueError, match="existence"):
        tracker(T.Existence(survival=1.5))
    with pytest.raises(ValueError, match="existence"):
        tracker(T.Existence(initial=0.0))
    with pytest.raises(TypeError, match="existence"):
        tracker((0.9, 0.5, 0.1, 1.0, 0.0, None, 0.5))
