"""The Stone Soup drop-in against Stone Soup itself: the thesis's Code 5.7 JPDA configuration
(and the GNN one) run through Stone Soup and through `usvfast.stonesoup` on the same detections
give the same tracks — births and deaths at the same scans, the same Update/Prediction kinds,
states and covariances within 1e-6, the same JPDA association probabilities — and components
usvfast cannot reproduce are refused by name."""

from __future__ import annotations

from datetime import timedelta

import numpy as np
import pytest

from usvfast import TimeOrderError
from usvfast import stonesoup as us

import ssharness as H

SEEDS = (0, 1)
# Short deletion horizons so that deaths happen within the short scenarios.
SHORT = dict(delete_steps=4, covar_trace=1.0)


def dropin_for(tracker, detector, **kw):
    cls = (
        us.MultiTargetMixtureTracker
        if tracker.__class__.__name__ == "MultiTargetMixtureTracker"
        else us.MultiTargetTracker
    )
    return cls(
        initiator=tracker.initiator,
        deleter=tracker.deleter,
        detector=detector,
        data_associator=tracker.data_associator,
        updater=tracker.updater,
        **kw,
    )


def both(scenario, cfg, build=H.build_stonesoup):
    """Run Stone Soup and the drop-in (on fresh, equal components) over the same Detection
    objects; returns (ours, ref) canonical records and the raw track objects."""
    scans = H.stonesoup_scans(scenario)
    ref_tracker, _ = build(cfg, detector=scans)
    ref_seen = []
    ref = H.run_tracker(_spy(ref_tracker, ref_seen))
    our_tracker, _ = build(cfg)
    ours_seen = []
    ours = H.run_tracker(_spy(dropin_for(our_tracker, scans), ours_seen))
    return ours, ref, ours_seen, ref_seen


def _spy(tracker, sink):
    for time, tracks in tracker:
        sink.append((time, [(t, t.state) for t in tracks]))
        yield time, tracks


def scenario_cases():
    out = []
    for seed in SEEDS:
        out += [
            H.crossing(seed),
            H.parallel(4, seed=seed),
            H.separated(3, seed=seed),
            H.two_sensors(seed),
        ]
    return out


CASES = scenario_cases()


@pytest.mark.parametrize("scenario", CASES, ids=[f"{s.name}" for s in CASES])
@pytest.mark.parametrize("associator", ["jpda", "gnn"])
def test_same_tracks_as_stonesoup(scenario, associator):
    ours, ref, _, _ = both(scenario, H.Code57(associator=associator, **SHORT))
    assert H.compare_runs(ours, ref) == []
    assert ours, "the scenario produced no track: the comparison proves nothing"


@pytest.mark.parametrize("associator", ["jpda", "gnn"])
def test_thesis_parameters_unchanged(associator):
    # Code 5.7 exactly as printed (35-step / trace-1.5 deleters) on a crossing scenario.
    ours, ref, _, _ = both(H.crossing(2), H.Code57(associator=associator))
    assert H.compare_runs(ours, ref) == []


def test_runs_exercise_births_deaths_and_missed_updates():
    # Guard against a parity suite that never deletes or never predicts.
    died = predicted = dup = 0
    for sc in CASES[:4]:
        for associator in ("jpda", "gnn"):
            ref = H.run_stonesoup(sc, H.Code57(associator=associator, **SHORT))
            died += sum(r.died is not None for r in ref)
            predicted += sum(int((~r.is_update).sum()) for r in ref)
            dup += len(ref) != sc.truth.shape[1]
    assert died >= 3 and predicted >= 20 and dup >= 1


def test_yields_stonesoup_types_and_same_association_probabilities():
    from stonesoup.types.multihypothesis import MultipleHypothesis
    from stonesoup.types.prediction import GaussianStatePrediction
    from stonesoup.types.track import Track
    from stonesoup.types.update import GaussianStateUpdate

    _, _, ours_seen, ref_seen = both(H.parallel(4, seed=0), H.Code57(**SHORT))
    assert len(ours_seen) == len(ref_seen)
    n_checked = 0
    for (t_o, tr_o), (t_r, tr_r) in zip(ours_seen, ref_seen, strict=True):
        assert t_o == t_r
        assert len(tr_o) == len(tr_r)
        for track, state in tr_o:
            assert type(track) is Track
            assert state.timestamp == t_o
        # Match current states and compare their JPDA hypotheses.
        for _, a in tr_o:
            b = min(
                (s for _, s in tr_r),
                key=lambda s: np.abs(np.asarray(s.state_vector - a.state_vector)).max(),
            )
            assert np.allclose(a.state_vector, b.state_vector, atol=1e-6)
            assert type(a) in (GaussianStateUpdate, GaussianStatePrediction)
            assert type(a) is type(b)
            if isinstance(b, GaussianStateUpdate) and isinstance(b.hypothesis, MultipleHypothesis):
                assert isinstance(a.hypothesis, MultipleHypothesis)
                pa = {id(h.measurement) if h else None: float(h.probability) for h in a.hypothesis}
                pb = {id(h.measurement) if h else None: float(h.probability) for h in b.hypothesis}
                assert pa.keys() == pb.keys()
                for k in pa:
                    assert pa[k] == pytest.approx(pb[k], abs=1e-9)
                pred_a = next(h.prediction for h in a.hypothesis)
                pred_b = next(h.prediction for h in b.hypothesis)
                assert np.allclose(pred_a.covar, pred_b.covar, atol=1e-9)
                n_checked += 1
    assert n_checked > 20


def test_jpda_with_ehm_and_variants_match_stonesoup():
    from stonesoup.deleter.time import UpdateTimeDeleter

    # pyehm's plugin associator, the volume-based clutter estimate, delete_last_pred and a
    # time-based deleter.
    ours, ref, _, _ = both(H.crossing(1), H.Code57(associator="ehm", **SHORT))
    assert H.compare_runs(ours, ref) == []

    def build_variant(cfg, detector=None):
        tracker, comp = H.build_stonesoup(cfg, detector=detector)
        tracker.data_associator.hypothesiser.clutter_spatial_density = None
        tracker.deleter = UpdateTimeDeleter(timedelta(seconds=3.5), delete_last_pred=True)
        return tracker, comp

    ours, ref, _, _ = both(H.crossing(0), H.Code57(), build=build_variant)
    assert H.compare_runs(ours, ref) == []
    assert any(r.died is not None for r in ref)


@pytest.mark.parametrize("associator", ["jpda", "gnn"])
def test_force_symmetric_covariance_matches_stonesoup(associator):
    # The updater (shared by the tracker and its initiator) symmetrises every update.
    def build_symmetric(cfg, detector=None):
        tracker, comp = H.build_stonesoup(cfg, detector=detector)
        tracker.updater.force_symmetric_covariance = True
        assert tracker.initiator.updater.force_symmetric_covariance
        return tracker, comp

    for scenario in (H.crossing(0), H.two_sensors(1)):
        cfg = H.Code57(associator=associator, **SHORT)
        ours, ref, _, _ = both(scenario, cfg, build=build_symmetric)
        assert H.compare_runs(ours, ref) == []
        assert ours


def test_update_tracker_and_empty_scans():
    scans = H.stonesoup_scans(H.separated(2, seed=3))
    ss, _ = H.build_stonesoup(H.Code57(**SHORT))
    ours = dropin_for(H.build_stonesoup(H.Code57(**SHORT))[0], None)
    # two empty scans first (valid: predict only), then the recording via update_tracker
    t_first = scans[0][0]
    empty = [(t_first - timedelta(seconds=2), set()), (t_first - timedelta(seconds=1), set())]
    for time, dets in empty + scans:
        _, ref_tracks = ss.update_tracker(time, dets)
        _, our_tracks = ours.update_tracker(time, dets)
        assert len(our_tracks) == len(ref_tracks)
    assert len(ours.tracks) == len(ss.tracks) > 0
    with pytest.raises(AttributeError, match="Detector has not been set"):
        iter(ours)


def test_time_going_backwards_raises():
    scans = H.stonesoup_scans(H.separated(2, seed=3))
    ours = dropin_for(H.build_stonesoup(H.Code57())[0], None)
    ours.update_tracker(*scans[3])
    with pytest.raises(TimeOrderError):
        ours.update_tracker(*scans[1])


def test_bad_detections_are_refused():
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
    from stonesoup.types.detection import Detection

    scans = H.stonesoup_scans(H.separated(2, seed=3))
    ours = dropin_for(H.build_stonesoup(H.Code57())[0], None)
    time, dets = scans[0]
    det = next(iter(dets))
    late = Detection(
        det.state_vector,
        timestamp=time + timedelta(seconds=1),
        measurement_model=det.measurement_model,
    )
    with pytest.raises(ValueError, match="scan time"):
        ours.update_tracker(time, {late})
    polar = CartesianToBearingRange(4, [0, 2], np.diag([0.01, 1.0]))
    with pytest.raises(us.UnsupportedComponentError, match="CartesianToBearingRange"):
        ours.update_tracker(
            time, {Detection(det.state_vector, timestamp=time, measurement_model=polar)}
        )


def _refuse(mutate, match):
    tracker, _ = H.build_stonesoup(H.Code57())
    mutate(tracker)
    with pytest.raises((us.UnsupportedComponentError, ValueError), match=match):
        dropin_for(tracker, None)


def test_unsupported_components_are_named():
    from stonesoup.dataassociator.probability import JPDAwithLBP
    from stonesoup.initiator.simple import SimpleMeasurementInitiator
    from stonesoup.measures import Euclidean
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        OrnsteinUhlenbeck,
    )
    from stonesoup.updater.kalman import KalmanUpdater, SqrtKalmanUpdater

    def lbp(t):
        t.data_associator = JPDAwithLBP(t.data_associator.hypothesiser)

    _refuse(lbp, r"data_associator: .*JPDAwithLBP")

    def sqrt(t):
        t.updater = SqrtKalmanUpdater(t.updater.measurement_model)

    _refuse(sqrt, r"updater: .*SqrtKalmanUpdater")

    def ou(t):
        t.data_associator.hypothesiser.predictor.transition_model = (
            CombinedLinearGaussianTransitionModel([OrnsteinUhlenbeck(0.1, 0.5)] * 2)
        )

    _refuse(ou, r"transition_model.model_list\[0\]: .*OrnsteinUhlenbeck")

    def euclid(t):
        t.initiator.data_associator.hypothesiser.measure = Euclidean()

    _refuse(euclid, r"initiator.data_associator.hypothesiser.measure: .*Euclidean")

    def nearest_pd(t):
        t.updater = KalmanUpdater(
            t.updater.measurement_model, force_positive_definite_covariance=True
        )

    _refuse(nearest_pd, "force_positive_definite_covariance")

    def diag_load(t):
        i = t.initiator
        i.initiator = SimpleMeasurementInitiator(i.prior_state, i.measurement_model, diag_load=0.1)

    _refuse(diag_load, "initiator.initiator")

    def bad_pd(t):
        t.data_associator.hypothesiser.prob_detect = 0.0

    _refuse(bad_pd, "prob_detect")

    def gnn_in_mixture(t):
        t.data_associator = t.initiator.data_associator

    _refuse(gnn_in_mixture, r"data_associator: .*GNNWith2DAssignment")


def test_docs_example_runs():
    from pathlib import Path

    text = (Path(__file__).parents[1] / "docs" / "tracker.md").read_text()
    start = text.index("## Stone Soup drop-in")
    block = text[
        text.index("```python", start) + len("```python") : text.index("```\n", start + 10)
    ]
    assert "from usvfast.stonesoup import MultiTargetMixtureTracker" in block
    scope: dict = {}
    exec(compile(block, "docs/tracker.md", "exec"), scope)
    assert len(scope["tracks"]) == 2


@pytest.mark.parametrize("reader", [True, False], ids=["reads-every-scan", "reads-at-end"])
def test_streaming_keeps_only_recent_scans_and_no_replay(reader, monkeypatch):
    # Two sensors: the camera's model first shows up mid-run; it shares the LiDAR's H, so its
    # detections reach the same core sensor with their own R (the core is not rebuilt);
    # detections of scans no tentative track or unbuilt state refers to are freed, and the
    # tracks are still Stone Soup's. A user reading every track each scan leaves only recent
    # scans; one who never reads them, the last `_LAZY_HORIZON` scans (states unread for
    # longer are built then).
    from usvfast import stonesoup_tracker

    monkeypatch.setattr(stonesoup_tracker, "_LAZY_HORIZON", 8)
    scenario = H.two_sensors(0)
    scans = H.stonesoup_scans(scenario)
    ref_tracker, _ = H.build_stonesoup(H.Code57(**SHORT), detector=scans)
    ref = H.run_tracker(ref_tracker)
    our_tracker, _ = H.build_stonesoup(H.Code57(**SHORT))
    dropin = dropin_for(our_tracker, scans)
    cores = set()
    most_kept = 0

    def spy():
        nonlocal most_kept
        for item in dropin:
            cores.add(id(dropin._core))
            if reader:
                for track in item[1]:
                    assert track.state.timestamp == item[0]
            most_kept = max(most_kept, sum(d is not None for d in dropin._scan_dets))
            yield item

    ours = H.run_tracker(spy())
    assert H.compare_runs(ours, ref) == []
    assert len(cores) == 1 and len(dropin._core.sensors) == 1
    assert sum(own is not None for _, own, _ in dropin._sensor_of_model.values()) == 1
    assert len(dropin._scan_dets) > 40 and most_kept <= (8 if reader else 8 + 8 + 4)


@pytest.mark.parametrize("with_metadata", [False, True], ids=["plain", "metadata"])
def test_track_metadata_equals_stonesoups(with_metadata):
    # Stone Soup's Track.append merges the detections' metadata into the track's (most likely
    # hypothesis last); the drop-in's fast append (scans without metadata) and Track.append
    # (scans with) must leave the same `metadatas` as Stone Soup's own run.
    def md(k, i, sensor):
        return {"sensor": sensor, "plot": f"{k}-{i}"} if with_metadata and k % 3 else {}

    scans = H.stonesoup_scans(H.two_sensors(3), metadata=md)
    ref_tracker, _ = H.build_stonesoup(H.Code57(**SHORT), detector=scans)
    ours_tracker, _ = H.build_stonesoup(H.Code57(**SHORT))

    def collect(tracker) -> dict:
        """Every track ever output, by identity."""
        seen: dict = {}
        for _, tracks in tracker:
            seen.update((id(t), t) for t in tracks)
        return seen

    def key(tr):
        return tuple(
            (st.timestamp, *np.round(np.asarray(st.state_vector, float).ravel(), 6))
            for st in tr.states
        )

    # Stone Soup's duplicate tracks on one target can be identical state by state: group them.
    groups: dict = {}
    for t in collect(ref_tracker).values():
        groups.setdefault(key(t), []).append(t.metadatas)
    ours = collect(dropin_for(ours_tracker, scans)).values()
    assert len(ours) == sum(map(len, groups.values())) > 2
    merged = 0
    for tr in ours:
        same = tr.metadatas in groups[key(tr)]
        assert same
        merged += sum(bool(m) for m in tr.metadatas)
    assert (merged > 0) == with_metadata


def test_fast_constructors_equal_stonesoups():
    from datetime import datetime

    from stonesoup.models.transition.linear import ConstantVelocity
    from stonesoup.types.array import Matrix
    from stonesoup.types.detection import MissedDetection
    from stonesoup.types.hypothesis import (
        SingleDistanceHypothesis,
        SingleHypothesis,
        SingleProbabilityHypothesis,
    )
    from stonesoup.types.multihypothesis import MultipleHypothesis
    from stonesoup.types.numeric import Probability
    from stonesoup.types.prediction import GaussianMeasurementPrediction, GaussianStatePrediction
    from stonesoup.types.update import GaussianStateUpdate

    from usvfast.stonesoup_objects import StoneSoupObjects

    ob = StoneSoupObjects()
    assert ob.all_fast  # the checks passed with this Stone Soup: the fast path is in use
    ts = datetime(2024, 5, 1, 12)
    x, p = np.array([1.0, 2.0, 3.0, 4.0]), np.diag([1.0, 2.0, 3.0, 4.0])
    pred = ob.state(False, x, p, ts)
    ref_pred = GaussianStatePrediction(x.reshape(4, 1), p, timestamp=ts)
    miss, ref_miss = ob.missed(ts), MissedDetection(timestamp=ts)
    z, s, c = x[:2], p[:2, :2] + np.eye(2), p[:, :2]
    mp = ob.measurement_prediction(z, s, c, ts)
    ref_mp = GaussianMeasurementPrediction(z.reshape(2, 1), s, ts, cross_covar=Matrix(c))
    hyp = ob.multiple([ob.probability(pred, miss, 0.25), ob.probability(pred, miss, 0.75, mp)])
    ref_hyp = MultipleHypothesis(
        [
            SingleProbabilityHypothesis(ref_pred, ref_miss, Probability(0.25)),
            SingleProbabilityHypothesis(ref_pred, ref_miss, Probability(0.75), ref_mp),
        ],
        normalise=True,
        total_weight=1,
    )
    upd = ob.state(True, x, p, ts, hyp)
    ref_upd = GaussianStateUpdate(x.reshape(4, 1), p, hypothesis=ref_hyp, timestamp=ts)
    first = ob.state(True, x, p, ts, ob.single(pred, miss))
    ref_first = GaussianStateUpdate(
        x.reshape(4, 1), p, hypothesis=SingleHypothesis(ref_pred, ref_miss), timestamp=ts
    )
    cv = ConstantVelocity(0.1)
    # A predictor's prediction from a state whose hypothesis's prediction has a prior: Stone
    # Soup's Prediction constructor turns that prior into a weak reference, so does the drop-in.
    sv, cm = ob.vector(x), ob.matrix(p)
    from_first = ob.prediction(sv, cm, ts, cv, ob.state(True, x, p, ts, ob.single(pred, miss)))
    ref_from_first = GaussianStatePrediction(
        x.reshape(4, 1), p, ts, transition_model=cv, prior=ref_first
    )
    dist = ob.distance(from_first, miss, np.float64(1.5), mp)
    ref_dist = SingleDistanceHypothesis(ref_from_first, ref_miss, np.float64(1.5), ref_mp)
    pairs = (
        (pred, ref_pred),
        (miss, ref_miss),
        (mp, ref_mp),
        (hyp, ref_hyp),
        (upd, ref_upd),
        (from_first, ref_from_first),
        (dist, ref_dist),
    )
    for a, b in pairs:
        assert type(a) is type(b) and list(vars(a)) == list(vars(b))
        assert [type(v) for v in vars(a).values()] == [type(v) for v in vars(b).values()]
    assert repr(first) == repr(ref_first) and repr(dist) == repr(ref_dist)
    # Stone Soup normalises on construction (its log-domain sum moves the last bit).
    assert [type(h.probability) for h in hyp] == [type(h.probability) for h in ref_hyp]
    assert [float(h.probability) for h in hyp] == pytest.approx([0.25, 0.75], abs=1e-15)
    assert [float(h.probability) for h in ref_hyp] == pytest.approx([0.25, 0.75], abs=1e-15)
    assert miss.metadata == {} and miss.metadata is not ob.missed(ts).metadata
    # The weak reference of the prior of an older prediction.
    ref_next = GaussianStatePrediction(x.reshape(4, 1), p, ts, transition_model=cv, prior=ref_upd)
    ours_next = ob.prediction(sv, cm, ts, cv, ob.state(True, x, p, ts, dist))
    assert type(vars(dist)["_property_prediction"].__dict__["_property_prior"]).__name__ == (
        "ReferenceType"
    )
    assert ours_next.prior.hypothesis is dist and ref_next.prior is ref_upd
