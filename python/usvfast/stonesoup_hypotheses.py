"""The Stone Soup objects of one drop-in track's update or prediction, built from the usvfast
core's arrays (see `usvfast.stonesoup_build`): the hypothesis (JPDA's probabilities or GNN's
distance), its measurement predictions and the hypothesiser's measure, with Stone Soup's own
models, updater and measure, computed here for linear models and by Stone Soup otherwise.
"""

from __future__ import annotations

from typing import Any

import numpy as np

# Entries kept by the per-model caches before they are cleared.
CACHE_ENTRIES = 256


class HypothesisParts:
    """Mixin of the drop-in tracker (through `StateBuilder`): the attributes below are the
    tracker's."""

    _objects: Any  # usvfast.stonesoup_objects' factory of Stone Soup objects
    _phases: dict  # see `_phase`
    _hr: dict  # see `_linear_model`
    initiator: Any
    data_associator: Any
    _mixture: bool

    def _placeholder(self, time: Any) -> Any:
        return self._objects.single(None, self._objects.missed(time))

    def _prediction_state(self, initiator: bool, sv: Any, cm: Any, time: Any, prior: Any) -> Any:
        """The state of a scan without update: under GNN (the initiator's, or the tracker's
        when it is not a mixture tracker) Stone Soup appends its predictor's prediction
        (transition model, prior); the mixture tracker a bare `GaussianStatePrediction`."""
        if initiator or not self._mixture:
            return self._objects.prediction(sv, cm, time, self._phase(initiator)[0], prior)
        self._objects.predicted_from(prior)  # Stone Soup's hypothesiser predicted from it
        return self._objects.state_of(False, sv, cm, time)

    def _phase(self, initiator: bool) -> tuple:
        """(transition model, updater, measure or None) of the initiator's hypothesiser or the
        tracker's: the Stone Soup objects its predictions and measurement predictions name."""
        hit = self._phases.get(initiator)
        if hit is None:
            owner = self.initiator if initiator else self
            hyp = owner.data_associator.hypothesiser
            hit = (hyp.predictor.transition_model, hyp.updater, getattr(hyp, "measure", None))
            self._phases[initiator] = hit
        return hit

    def _linear_model(self, model: Any, updater: Any) -> tuple | None:
        """(H, R) of a detection's measurement model (or the updater's when it has none) when
        the updater predicts measurements as a Kalman updater does (linear model, Kalman or
        extended Kalman updater), else None."""
        key = (id(model), id(updater))
        hit = self._hr.get(key)
        if hit is not None:
            return hit[0]
        from stonesoup.models.base import LinearModel
        from stonesoup.updater.kalman import ExtendedKalmanUpdater, KalmanUpdater

        own = updater.measurement_model if model is None else model
        hr = None
        if isinstance(own, LinearModel) and type(updater) in (KalmanUpdater, ExtendedKalmanUpdater):
            own_any: Any = own  # a LinearModel that is also a measurement model (covar)
            h = np.array(own.matrix(), dtype=np.float64)
            hr = (h, h.T.copy(), np.array(own_any.covar(), dtype=np.float64))
        if len(self._hr) > CACHE_ENTRIES:
            self._hr.clear()
        self._hr[key] = (hr, model, updater)  # keeps the ids alive
        return hr

    def _measurement_predictions(
        self, initiator: bool, pred: Any, dets: list, pre: dict | None = None
    ) -> list:
        """Stone Soup's measurement prediction of `pred` for each detection, one object per
        measurement model (as the updater's cache gives): mean H x, innovation covariance
        H P Hᵀ + R, cross covariance P Hᵀ (linear models; `pre`: id(model) -> those arrays
        when already computed), or the updater's own `predict_measurement` otherwise."""
        updater = self._phase(initiator)[1]
        if len(dets) == 1:
            return [self._measurement_prediction(updater, pred, dets[0].measurement_model, pre)]
        out, mine = [], {}
        for d in dets:
            model = d.measurement_model
            mp = mine.get(id(model))
            if mp is None:
                mp = mine[id(model)] = self._measurement_prediction(updater, pred, model, pre)
            out.append(mp)
        return out

    def _measurement_prediction(self, updater: Any, pred: Any, model: Any, pre: Any) -> Any:
        hit = pre.get(id(model)) if pre is not None else None
        if hit is not None:
            return self._objects.measurement_prediction_of(*hit, pred.timestamp)
        hr = self._linear_model(model, updater)
        if hr is None:
            return updater.predict_measurement(pred, model)
        h, ht, r = hr
        d = pred.__dict__
        x = d["_property_state_vector"].view(np.ndarray)
        cross = d["_property_covar"].view(np.ndarray) @ ht
        ts = d["_property_timestamp"]
        return self._objects.measurement_prediction(h @ x, h @ cross + r, cross, ts)

    def _distance(self, initiator: bool, mp: Any, det: Any) -> Any:
        """The hypothesiser's measure (Mahalanobis or its square) between the measurement
        prediction and the detection: computed here for linear models (Stone Soup's
        pseudo-inverse of the innovation covariance equals its inverse: R is positive
        definite), by the measure itself otherwise (bearings wrap, Stone Soup's `Bearing`)."""
        from stonesoup.measures import Mahalanobis, SquaredMahalanobis

        _, updater, measure = self._phase(initiator)
        kind = type(measure)
        if (
            kind not in (Mahalanobis, SquaredMahalanobis)
            or measure.mapping is not None
            or self._linear_model(det.measurement_model, updater) is None
        ):
            return measure(mp, det)
        v = (
            np.asarray(det.state_vector, dtype=np.float64).ravel()
            - np.asarray(mp.state_vector, dtype=np.float64).ravel()
        )
        s = np.asarray(mp.covar, dtype=np.float64)
        if v.shape == (2,):
            a, b, c, e = s[0, 0], s[0, 1], s[1, 0], s[1, 1]
            d2 = (e * v[0] * v[0] - (b + c) * v[0] * v[1] + a * v[1] * v[1]) / (a * e - b * c)
        else:
            d2 = v @ np.linalg.pinv(s) @ v
        d2 = np.float64(d2)
        return np.sqrt(d2) if kind is Mahalanobis else d2

    def _make_hypothesis(
        self, pred, scan_dets, time, assoc: tuple, initiator: bool, pre: dict | None = None
    ) -> Any:
        """The hypothesis of an update: JPDA (mixture tracker after confirmation) a
        MultipleHypothesis of SingleProbabilityHypothesis (missed detection first), GNN (the
        initiator, `MultiTargetTracker`) the chosen SingleDistanceHypothesis; each detection's
        with its measurement prediction. `assoc` is (detections, probabilities, missed
        probability, chosen detection) from the core; `pre` as `_measurement_predictions`."""
        dets, probs, missed, det = assoc
        ob = self._objects
        if self._mixture and not initiator and np.isfinite(missed):
            measured = [scan_dets[int(j)] for j in dets]
            mps = self._measurement_predictions(False, pred, measured, pre)
            prob = ob.probability
            hyps = [prob(pred, ob.missed(time), float(missed))]
            hyps += [
                prob(pred, d, float(q), mp) for d, q, mp in zip(measured, probs, mps, strict=True)
            ]
            return ob.multiple(hyps)
        if det >= 0:
            d = scan_dets[det]
            mp = self._measurement_predictions(initiator, pred, [d], pre)[0]
            return ob.distance(pred, d, self._distance(initiator, mp, d), mp)
        return None
