"""Building Stone Soup objects quickly, for the drop-in trackers (`usvfast.stonesoup`).

Stone Soup's `Base.__init__` sets every declared property through its descriptor, which costs
tens of µs per object — more than the usvfast core needs for a whole scan. Each class the
drop-in hands out (states, hypotheses, missed detections) is built here by `cls.__new__` and a
direct fill of `__dict__` with the same `_property_<name>` entries, in the same order, that the
public constructor would set. Before the fast path is used for a class, one object is built
both ways and compared (same type, same `__dict__` keys in the same order, values of the same
type and equal); any difference, or an error, switches that class to the public constructor
for good. So a Stone Soup release that changes how these classes are built costs speed, never
correctness.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

import numpy as np


def _same(a: Any, b: Any) -> bool:
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and np.array_equal(a, b)
    return a is b or a == b


class _Builder:
    """One Stone Soup class: `make(**values)` with every property given (in any order)."""

    def __init__(self, cls: type, sample: dict[str, Any]) -> None:
        self.cls = cls
        self.names = tuple(cls.properties)
        self.pairs = tuple((f"_property_{n}", n) for n in self.names)
        self.fast = self._check(sample)

    def _fast(self, values: dict[str, Any]) -> Any:
        obj = self.cls.__new__(self.cls)
        d = obj.__dict__
        for k, n in self.pairs:
            d[k] = values[n]
        return obj

    def _check(self, sample: dict[str, Any]) -> bool:
        try:
            slow = self.cls(**sample)
            fast = self._fast(sample)
            a, b = vars(slow), vars(fast)
            if list(a) != list(b):
                return False
            return all(_same(a[k], b[k]) for k in a)
        except Exception:  # any surprise: the public constructor
            return False

    def make(self, **values: Any) -> Any:
        if self.fast:
            return self._fast(values)
        return self.cls(**values)


class StoneSoupObjects:
    """Factories for the Stone Soup objects of a drop-in run (see the module docstring)."""

    def __init__(self) -> None:
        from stonesoup.types.array import CovarianceMatrix, StateVector
        from stonesoup.types.detection import MissedDetection
        from stonesoup.types.hypothesis import SingleHypothesis, SingleProbabilityHypothesis
        from stonesoup.types.multihypothesis import MultipleHypothesis
        from stonesoup.types.prediction import GaussianStatePrediction
        from stonesoup.types.update import GaussianStateUpdate

        self._sv, self._cm = StateVector, CovarianceMatrix
        ts = datetime(2024, 1, 1)
        x = np.arange(4.0).reshape(4, 1).view(StateVector)
        p = np.eye(4).view(CovarianceMatrix)
        self._pred = _Builder(
            GaussianStatePrediction,
            dict(state_vector=x, covar=p, timestamp=ts, transition_model=None, prior=None),
        )
        self._upd = _Builder(
            GaussianStateUpdate, dict(state_vector=x, covar=p, hypothesis=None, timestamp=ts)
        )
        missed_sample = dict(state_vector=None, timestamp=ts, measurement_model=None, metadata={})
        self._missed = _Builder(MissedDetection, missed_sample)
        pred = self._pred.make(
            state_vector=x, covar=p, timestamp=ts, transition_model=None, prior=None
        )
        miss = MissedDetection(timestamp=ts)
        self._single = _Builder(
            SingleHypothesis,
            dict(prediction=pred, measurement=miss, measurement_prediction=None),
        )
        self._prob = _Builder(
            SingleProbabilityHypothesis,
            dict(prediction=pred, measurement=miss, measurement_prediction=None, probability=0.5),
        )
        self._multi = _Builder(
            MultipleHypothesis, dict(single_hypotheses=[], normalise=False, total_weight=1)
        )

    @property
    def all_fast(self) -> bool:
        """True when every class uses the fast path (the checks passed)."""
        return all(
            b.fast
            for b in (self._pred, self._upd, self._missed, self._single, self._prob, self._multi)
        )

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
            return self._upd.make(state_vector=sv, covar=cm, hypothesis=hypothesis, timestamp=ts)
        return self._pred.make(
            state_vector=sv, covar=cm, timestamp=ts, transition_model=None, prior=None
        )

    def missed(self, ts: Any) -> Any:
        """`MissedDetection(timestamp=ts)`."""
        return self._missed.make(
            state_vector=None, timestamp=ts, measurement_model=None, metadata={}
        )

    def single(self, prediction: Any, measurement: Any) -> Any:
        """`SingleHypothesis(prediction, measurement)`."""
        return self._single.make(
            prediction=prediction, measurement=measurement, measurement_prediction=None
        )

    def probability(self, prediction: Any, measurement: Any, probability: float) -> Any:
        """`SingleProbabilityHypothesis(prediction, measurement, probability)`."""
        return self._prob.make(
            prediction=prediction,
            measurement=measurement,
            measurement_prediction=None,
            probability=probability,
        )

    def multiple(self, hypotheses: list) -> Any:
        """`MultipleHypothesis(hypotheses, normalise=False)` (all SingleHypothesis)."""
        return self._multi.make(single_hypotheses=hypotheses, normalise=False, total_weight=1)
