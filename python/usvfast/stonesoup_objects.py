"""Building Stone Soup objects quickly, for the drop-in trackers (`usvfast.stonesoup`).

Stone Soup's `Base.__init__` sets every declared property through its descriptor, which costs
tens of µs per object — more than the usvfast core needs for a whole scan. Each class the
drop-in hands out (states, hypotheses, missed detections) is built here by `cls.__new__` and a
direct fill of `__dict__` with the same `_property_<name>` entries, in the same order, that the
public constructor would set. Before the fast path is used for a class, one object is built
both ways and compared (same type, same `__dict__` keys in the same order, values of the same
type and equal); any difference, or an error, switches that class to the public constructor
for good. So a Stone Soup release that changes how these classes are built costs speed, never
correctness. `StoneSoupObjects.kit` hands the same class specifications to the native factory
(`usvfast._core.StoneSoupKit`), checked the same way, which builds a scan's newest states in
one call.
"""

from __future__ import annotations

import math
import weakref
from datetime import datetime
from typing import Any

import numpy as np


def _same(a: Any, b: Any) -> bool:
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and np.array_equal(a, b)
    return a is b or a == b


_IMMUTABLE = (type(None), bool, int, float, str)

# Outcomes of `StoneSoupObjects.kit`'s checks against Stone Soup's constructors, by the classes
# and `__dict__` layouts checked (one check per process, not one per tracker).
_KITS_CHECKED: dict[tuple, bool] = {}


class _Builder:
    """One Stone Soup class built from positional `args` (property names) plus `constants`
    (the other properties; immutable values only, so that objects can share them)."""

    def __init__(
        self, cls: Any, args: tuple[str, ...], constants: dict[str, Any], sample: tuple
    ) -> None:
        self.cls = cls
        self.args = args
        self.constants = constants
        self.keys = tuple(f"_property_{n}" for n in args)
        names = tuple(cls.properties)
        ok = set(names) == set(args) | set(constants) and not set(args) & set(constants)
        ok = ok and all(isinstance(v, _IMMUTABLE) for v in constants.values())
        # Properties in the class's order: a copy of it per object keeps that order.
        self.template = {f"_property_{n}": constants.get(n) for n in names}
        self.plain = not constants and self.keys == tuple(self.template)
        self.sample = sample
        self.fast = ok and self._check(sample)

    def _fast(self, values: tuple) -> Any:
        obj = self.cls.__new__(self.cls)
        if self.plain:  # no constants, arguments in the class's order
            obj.__dict__ = dict(zip(self.keys, values, strict=True))
            return obj
        d = self.template.copy()
        for k, v in zip(self.keys, values, strict=True):
            d[k] = v
        obj.__dict__ = d
        return obj

    def _check(self, sample: tuple) -> bool:
        try:
            return self.matches(self._fast(sample), sample)
        except Exception:  # any surprise: the public constructor
            return False

    def matches(self, obj: Any, sample: tuple) -> bool:
        """Whether `obj` is what the public constructor makes of `sample`: same type, same
        `__dict__` keys in the same order, values of the same type and equal."""
        slow = self.cls(**self.constants, **dict(zip(self.args, sample, strict=True)))
        if type(obj) is not type(slow):
            return False
        a, b = vars(slow), vars(obj)
        if list(a) != list(b):
            return False
        return all(_same(a[k], b[k]) for k in a)

    def spec(self) -> tuple:
        """(cls.__new__, cls, `__dict__` keys of the arguments, template or None): how
        `usvfast._core.StoneSoupKit` builds the class as `_fast` does."""
        return (self.cls.__new__, self.cls, self.keys, None if self.plain else self.template)

    def make(self, *values: Any) -> Any:
        """An object with the properties `args` = values (and the constants)."""
        if self.fast:
            return self._fast(values)
        return self.cls(**self.constants, **dict(zip(self.args, values, strict=True)))


class StoneSoupObjects:
    """Factories for the Stone Soup objects of a drop-in run (see the module docstring)."""

    def __init__(self) -> None:
        from stonesoup.types.array import CovarianceMatrix, Matrix, StateVector
        from stonesoup.types.detection import MissedDetection
        from stonesoup.types.hypothesis import (
            SingleDistanceHypothesis,
            SingleHypothesis,
            SingleProbabilityHypothesis,
        )
        from stonesoup.types.multihypothesis import MultipleHypothesis
        from stonesoup.types.numeric import Probability
        from stonesoup.types.prediction import (
            GaussianMeasurementPrediction,
            GaussianStatePrediction,
        )
        from stonesoup.types.update import GaussianStateUpdate

        self._sv, self._cm, self._mat = StateVector, CovarianceMatrix, Matrix
        self._p = Probability
        ts = datetime(2024, 1, 1)
        x = np.arange(4.0).reshape(4, 1).view(StateVector)
        p = np.eye(4).view(CovarianceMatrix)
        none2 = {"transition_model": None, "prior": None}
        self._pred = _Builder(
            GaussianStatePrediction, ("state_vector", "covar", "timestamp"), none2, (x, p, ts)
        )
        # A predictor's prediction (hypotheses; GNN's missed scans): with its transition model
        # and prior state.
        self._pred_of = _Builder(
            GaussianStatePrediction,
            ("state_vector", "covar", "timestamp", "transition_model", "prior"),
            {},
            (x, p, ts, None, None),
        )
        self._mpred = _Builder(
            GaussianMeasurementPrediction,
            ("state_vector", "covar", "timestamp", "cross_covar"),
            {},
            (x[:2], p[:2, :2], ts, np.zeros((4, 2)).view(Matrix)),
        )
        self._upd = _Builder(
            GaussianStateUpdate,
            ("state_vector", "covar", "hypothesis", "timestamp"),
            {},
            (x, p, None, ts),
        )
        self._missed = _Builder(
            MissedDetection,
            ("timestamp", "metadata"),
            {"state_vector": None, "measurement_model": None},
            (ts, {}),
        )
        pred = self._pred.make(x, p, ts)
        miss = MissedDetection(timestamp=ts)
        self._single = _Builder(
            SingleHypothesis,
            ("prediction", "measurement"),
            {"measurement_prediction": None},
            (pred, miss),
        )
        self._prob = _Builder(
            SingleProbabilityHypothesis,
            ("prediction", "measurement", "probability", "measurement_prediction"),
            {},
            (pred, miss, Probability(0.5), None),
        )
        self._dist = _Builder(
            SingleDistanceHypothesis,
            ("prediction", "measurement", "distance", "measurement_prediction"),
            {},
            (pred, miss, np.float64(1.5), None),
        )
        # Normalised on construction by Stone Soup; the core's probabilities come normalised.
        self._multi = _Builder(
            MultipleHypothesis,
            ("single_hypotheses",),
            {"normalise": True, "total_weight": 1},
            ([self._prob.make(pred, miss, Probability(1.0), None)],),
        )
        self._fast_append = self._check_append()

    def _check_append(self) -> bool:
        """True when `append_plain` equals `Track.append` on a sample (see there)."""
        try:
            from stonesoup.types.track import Track

            ts = datetime(2024, 1, 1)
            x, p = np.zeros(4), np.eye(4)
            det = self.missed(ts)  # a measurement without metadata
            pred = self.state(False, x, p, ts)
            hyp = self.multiple([self.probability(pred, det, 1.0)])
            a, b = Track([pred], init_metadata={"k": 1}), Track([pred], init_metadata={"k": 1})
            upd = self.state(True, x, p, ts, hyp)
            a.append(upd)
            self.append_plain(b, upd, check=False)
            da, db = vars(a), vars(b)
            return (
                list(da) == list(db)
                and da["metadatas"] == db["metadatas"]
                and da["metadatas"][-1] is not da["metadatas"][-2]
                and db["metadatas"][-1] is not db["metadatas"][-2]
                and da["_property_states"] == db["_property_states"]
            )
        except Exception:  # any surprise: Track.append
            return False

    def append_plain(self, track: Any, state: Any, check: bool = True) -> None:
        """`track.append(state)` when no measurement of the state's hypotheses carries
        metadata (the caller knows): Stone Soup's `Track.append` then only appends a copy of
        the track's current metadata and the state, which this does without sorting the
        hypotheses. Falls back to `Track.append` when the check at construction failed."""
        if check and not self._fast_append:
            track.append(state)
            return
        d = track.__dict__
        mds = d["metadatas"]
        mds.append((mds[-1] if mds else d["_property_init_metadata"]).copy())
        d["_property_states"].append(state)

    def _builders(self) -> tuple[_Builder, ...]:
        # The order `usvfast._core.StoneSoupKit` expects.
        return (
            self._pred,
            self._pred_of,
            self._mpred,
            self._upd,
            self._missed,
            self._single,
            self._prob,
            self._dist,
            self._multi,
        )

    @property
    def all_fast(self) -> bool:
        """True when every class uses the fast path (the checks passed)."""
        return all(b.fast for b in self._builders())

    def kit(self, linear_model: Any, measure: int) -> Any:
        """The native factory `usvfast._core.StoneSoupKit` on these classes (it builds a scan's
        newest states in one call, as the fast paths here build them), or None when a class is
        not on its fast path or an object the kit makes differs from the public constructor's
        on the samples (same checks as the fast paths). `linear_model(model)` gives (H, Hᵀ, R)
        or None for a detection's measurement model; `measure` is 1 (Mahalanobis), 2 (squared
        Mahalanobis) or 0 (another measure: GNN updates fall back to Python)."""
        if not self.all_fast:
            return None
        try:
            from usvfast._core import StoneSoupKit

            builders = self._builders()
            p = self._p
            specs = [b.spec() for b in builders] + [(p.__new__, p, ("_log_value",), None)]
            arrays = (self._sv, self._cm, self._mat)
            kit = StoneSoupKit(specs, arrays, linear_model, measure)
            # The same classes, keys and templates were checked before in this process.
            key = (tuple((b.cls, b.keys, tuple(b.template.items())) for b in builders), arrays)
            known = _KITS_CHECKED.get(key)
            if known is None:
                known = self._kit_matches(kit, builders)
                _KITS_CHECKED[key] = known
        except Exception:  # any surprise (or an older core): the Python builders
            return None
        return kit if known else None

    def _kit_matches(self, kit: Any, builders: tuple) -> bool:
        """Whether every object `kit` makes of the builders' samples is what the public
        constructor makes (see `_Builder.matches`), `Probability` included."""
        for i, b in enumerate(builders):
            if not b.matches(kit.make(i, list(b.sample)), b.sample):
                return False
        p = self._p
        got, ref = kit.make(len(builders), [-0.5]), p(-0.5, log_value=True)
        return type(got) is type(ref) and vars(got) == vars(ref)

    def vector(self, x: np.ndarray) -> Any:
        """A StateVector (n, 1) on `x` (a view when x is float64: pass arrays nobody else
        changes, e.g. the rows of a fresh core snapshot)."""
        return np.asarray(x, dtype=np.float64).reshape(-1, 1).view(self._sv)

    def matrix(self, p: np.ndarray) -> Any:
        """A CovarianceMatrix on `p` (a view when p is float64, as `vector`)."""
        return np.asarray(p, dtype=np.float64).view(self._cm)

    def state(self, is_update: bool, x: Any, p: Any, ts: Any, hypothesis: Any = None) -> Any:
        """A GaussianStateUpdate (with `hypothesis`) or GaussianStatePrediction on x (n,) and
        p (n, n) at `ts` (views, see `vector`)."""
        sv, cm = self.vector(x), self.matrix(p)
        if is_update:
            return self._upd.make(sv, cm, hypothesis, ts)
        return self._pred.make(sv, cm, ts)

    def rows(self, xs: np.ndarray, ps: np.ndarray) -> tuple[list, list]:
        """The StateVectors (n, 1) and CovarianceMatrices of the rows of xs (k, n) and ps
        (k, n, n), float64 arrays nobody else changes (views, as `vector`), for
        `state_of_rows`."""
        k, n = xs.shape
        sv = np.asarray(xs, dtype=np.float64).reshape(k, n, 1).view(self._sv)
        cm = np.asarray(ps, dtype=np.float64).view(self._cm)
        # ndarray's own indexing (StateVector's returns scalars for single elements).
        get = np.ndarray.__getitem__
        return [get(sv, i) for i in range(k)], [get(cm, i) for i in range(k)]

    def state_of(self, is_update: bool, sv: Any, cm: Any, ts: Any, hypothesis: Any = None) -> Any:
        """As `state`, on a StateVector and CovarianceMatrix already made (see `rows`)."""
        if is_update:
            return self._upd.make(sv, cm, hypothesis, ts)
        return self._pred.make(sv, cm, ts)

    def missed(self, ts: Any) -> Any:
        """`MissedDetection(timestamp=ts)`."""
        return self._missed.make(ts, {})

    def single(self, prediction: Any, measurement: Any) -> Any:
        """`SingleHypothesis(prediction, measurement)`."""
        return self._single.make(prediction, measurement)

    def probability(
        self, prediction: Any, measurement: Any, probability: float, mpred: Any = None
    ) -> Any:
        """`SingleProbabilityHypothesis(prediction, measurement, Probability(probability),
        mpred)` (`mpred` the measurement prediction, None for a missed detection)."""
        if probability > 0:
            value = self._p(math.log(probability), log_value=True)
        else:
            value = self._p(probability)
        return self._prob.make(prediction, measurement, value, mpred)

    def distance(self, prediction: Any, measurement: Any, distance: Any, mpred: Any) -> Any:
        """`SingleDistanceHypothesis(prediction, measurement, distance, mpred)`."""
        return self._dist.make(prediction, measurement, distance, mpred)

    def multiple(self, hypotheses: list) -> Any:
        """`MultipleHypothesis(hypotheses, normalise=True, total_weight=1)` of
        SingleProbabilityHypothesis whose probabilities already sum to 1 (Stone Soup would
        normalise them on construction; this keeps them)."""
        return self._multi.make(hypotheses)

    def prediction(self, sv: Any, cm: Any, ts: Any, model: Any, prior: Any) -> Any:
        """A predictor's `GaussianStatePrediction` (with `transition_model` and `prior`), on a
        StateVector and CovarianceMatrix already made; like Stone Soup's `Prediction`
        constructor it turns the prior's own hypothesis prediction's prior into a weak
        reference."""
        self.predicted_from(prior)
        return self._pred_of.make(sv, cm, ts, model, prior)

    @staticmethod
    def predicted_from(prior: Any) -> None:
        """What Stone Soup's `Prediction` constructor does to its prior: the prior of the
        prior's hypothesis's prediction becomes a weak reference. Stone Soup's hypothesisers
        predict every track every scan, also when the mixture tracker then appends a bare
        prediction: call this for each state a track's next state was predicted from."""
        hyp = getattr(prior, "hypothesis", None)
        older = getattr(hyp, "prediction", None)
        if older is not None:
            d = older.__dict__
            back = d.get("_property_prior")
            if back is not None and not isinstance(back, weakref.ReferenceType):
                d["_property_prior"] = weakref.ref(back)

    def measurement_rows(self, zs: np.ndarray, ss: np.ndarray, cs: np.ndarray) -> tuple:
        """StateVectors, CovarianceMatrices and cross-covariance Matrices of the rows of zs
        (k, m), ss (k, m, m) and cs (k, n, m), fresh float64 arrays (views, as `rows`), for
        `measurement_prediction_of`."""
        k, m = zs.shape
        get = np.ndarray.__getitem__
        z = zs.reshape(k, m, 1).view(self._sv)
        s, c = ss.view(self._cm), cs.view(self._mat)
        return (
            [get(z, i) for i in range(k)],
            [get(s, i) for i in range(k)],
            [get(c, i) for i in range(k)],
        )

    def measurement_prediction_of(self, z: Any, s: Any, cross: Any, ts: Any) -> Any:
        """As `measurement_prediction`, on arrays already made (see `measurement_rows`)."""
        return self._mpred.make(z, s, ts, cross)

    def measurement_prediction(self, z: Any, s: Any, cross: Any, ts: Any) -> Any:
        """`GaussianMeasurementPrediction(z, s, ts, cross_covar=cross)`: z (m,) or (m, 1) the
        predicted measurement, s (m, m) the innovation covariance, cross (n, m) the
        state-measurement cross covariance."""
        return self._mpred.make(
            np.asarray(z, dtype=np.float64).reshape(-1, 1).view(self._sv),
            np.asarray(s, dtype=np.float64).view(self._cm),
            ts,
            np.asarray(cross, dtype=np.float64).view(self._mat),
        )
