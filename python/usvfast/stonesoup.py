"""Stone Soup drop-in: the same trackers, the same tracks, run by the usvfast core.

Replace one import line::

    # from stonesoup.tracker.simple import MultiTargetMixtureTracker
    from usvfast.stonesoup import MultiTargetMixtureTracker

and keep the rest: the tracker takes the same keywords (`initiator`, `deleter`, `detector`,
`data_associator`, `updater`) built from your Stone Soup components, iterating it yields
`(time, set of stonesoup Track)` per scan, and the tracks hold `GaussianStateUpdate` /
`GaussianStatePrediction` states equal to Stone Soup's to rounding. `MultiTargetTracker` is the
GNN counterpart.

The drop-in reads the parameters of the components (transition model, the measurement model of
each detection, P_D, P_G, clutter density, distance gates, the initiator's prior, `min_points`
and deleter, the tracker's deleter) and runs `usvfast.tracking` with them. It reproduces only
what it can reproduce exactly: any other component or setting raises
`UnsupportedComponentError` naming it (nothing is approximated silently). Supported:

- predictor: `KalmanPredictor` without control; transition model `ConstantVelocity`,
  `RandomWalk`, `ConstantAcceleration` or a `CombinedLinearGaussianTransitionModel` of them;
- updater: `KalmanUpdater` (`use_joseph_cov`, `force_symmetric_covariance` either way; not
  `force_positive_definite_covariance`);
- measurement models: `LinearGaussian` (on the detections — each its own if you like,
  its own `noise_covar` included — or the updater's/initiator's);
- JPDA: `PDAHypothesiser` + `JPDA`, `JPDAwithEHM`, `JPDAwithEHM2` (or pyehm's plugins);
- GNN: `DistanceHypothesiser` (`Mahalanobis` / `SquaredMahalanobis` without mapping) +
  `GNNWith2DAssignment`;
- initiator: `MultiMeasurementInitiator` (its own GNN, updater and deleter);
- deleters: `UpdateTimeStepsDeleter`, `UpdateTimeDeleter`, `CovarianceBasedDeleter`,
  `CompositeDeleter` of these.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from usvfast import kalman
from usvfast._validate import instance


class UnsupportedComponentError(TypeError):
    """A Stone Soup component or setting the drop-in cannot reproduce exactly."""


def _fullname(obj: Any) -> str:
    cls = type(obj)
    return f"{cls.__module__}.{cls.__qualname__}"


def _require(obj: Any, where: str, *allowed: type) -> None:
    """Exact-type check (subclasses may change behaviour, so they are refused too)."""
    if type(obj) not in allowed:
        names = ", ".join(c.__name__ for c in allowed)
        raise UnsupportedComponentError(
            f"{where}: {_fullname(obj)} is not supported by usvfast.stonesoup (supported: "
            f"{names}); use Stone Soup's own tracker for it"
        )


# --------------------------------------------------------------------------------------------
# Reading the user's components
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LinearSensor:
    """A linear-Gaussian measurement model: H (m, ndim), R (m, m)."""

    matrix: np.ndarray
    noise: np.ndarray

    def same_as(self, other: LinearSensor) -> bool:
        """True when both the measurement matrix and the noise covariance are exactly equal."""
        return np.array_equal(self.matrix, other.matrix) and np.array_equal(self.noise, other.noise)


@dataclass(frozen=True)
class DeleterSpec:
    """A deleter: kind "steps" (value: time steps), "time" (value: seconds), "trace" (value:
    threshold, mapping), "composite" (children, intersect)."""

    kind: str
    value: float = 0.0
    mapping: tuple[int, ...] | None = None
    children: tuple[DeleterSpec, ...] = ()
    intersect: bool = True


@dataclass(frozen=True)
class GnnSpec:
    """Distance hypothesiser + GNN 2-D assignment."""

    squared: bool
    missed_distance: float
    include_all: bool


@dataclass(frozen=True)
class JpdaSpec:
    """PDA hypothesiser + exact JPDA."""

    prob_detect: float
    prob_gate: float
    clutter_density: float | None
    include_all: bool


@dataclass(frozen=True)
class StoneSoupConfig:
    """Everything the drop-in read from the components (all plain values)."""

    motion_model: tuple[kalman.Component, ...]
    association: JpdaSpec | GnnSpec
    use_joseph_cov: bool
    fallback_sensor: LinearSensor | None
    deleter: DeleterSpec
    delete_last_pred: bool
    init_motion_model: tuple[kalman.Component, ...]
    init_gnn: GnnSpec
    init_use_joseph_cov: bool
    init_fallback_sensor: LinearSensor | None
    init_update_fallback_sensor: LinearSensor | None
    prior_state: np.ndarray
    prior_covariance: np.ndarray
    min_points: int
    updates_only: bool
    init_deleter: DeleterSpec
    init_delete_last_pred: bool
    notes: list[str] = field(default_factory=list)
    symmetric_covariance: bool = False
    init_symmetric_covariance: bool = False


def _motion_model(transition_model: Any, where: str) -> tuple[kalman.Component, ...]:
    from stonesoup.models.transition import linear as tl

    simple = {
        tl.ConstantVelocity: kalman.ConstantVelocity,
        tl.RandomWalk: kalman.RandomWalk,
        tl.ConstantAcceleration: kalman.ConstantAcceleration,
    }
    if type(transition_model) is tl.CombinedLinearGaussianTransitionModel:
        parts = list(transition_model.model_list)
    else:
        parts = [transition_model]
    out = []
    for i, m in enumerate(parts):
        name = where if len(parts) == 1 else f"{where}.model_list[{i}]"
        _require(m, name, *simple, tl.CombinedLinearGaussianTransitionModel)
        if type(m) is tl.CombinedLinearGaussianTransitionModel:
            raise UnsupportedComponentError(f"{name}: nested combined models are not supported")
        q = float(m.noise_diff_coeff)  # pyright: ignore[reportAttributeAccessIssue]
        if not np.isfinite(q) or q < 0:
            raise ValueError(f"{name}.noise_diff_coeff: must be finite and >= 0, got {q}")
        out.append(simple[type(m)](q))
    return tuple(out)


def _predictor(predictor: Any, where: str) -> tuple[kalman.Component, ...]:
    from stonesoup.models.control.linear import LinearControlModel
    from stonesoup.predictor.kalman import KalmanPredictor

    _require(predictor, where, KalmanPredictor)
    ctrl = predictor.control_model
    if ctrl is not None:
        zero = type(ctrl) is LinearControlModel and not np.any(ctrl.control_matrix)
        if not zero:
            raise UnsupportedComponentError(
                f"{where}.control_model: a control input is not supported (only the default "
                "zero-effect model)"
            )
    return _motion_model(predictor.transition_model, f"{where}.transition_model")


def _sensor(model: Any, where: str) -> LinearSensor | None:
    from stonesoup.models.measurement.linear import LinearGaussian

    if model is None:
        return None
    _require(model, where, LinearGaussian)
    return LinearSensor(
        np.asarray(model.matrix(), dtype=np.float64).copy(),
        np.asarray(model.covar(), dtype=np.float64).copy(),
    )


def _updater(updater: Any, where: str) -> tuple[bool, bool, LinearSensor | None]:
    """(use_joseph_cov, force_symmetric_covariance, fallback measurement model)."""
    from stonesoup.updater.kalman import KalmanUpdater

    _require(updater, where, KalmanUpdater)
    if getattr(updater, "force_positive_definite_covariance", False):
        raise UnsupportedComponentError(
            f"{where}.force_positive_definite_covariance=True is not supported"
        )
    return (
        bool(updater.use_joseph_cov),
        bool(updater.force_symmetric_covariance),
        _sensor(updater.measurement_model, f"{where}.measurement_model"),
    )


def _measure(measure: Any, where: str) -> bool:
    """True for SquaredMahalanobis, False for Mahalanobis."""
    from stonesoup.measures import Mahalanobis, SquaredMahalanobis

    _require(measure, where, Mahalanobis, SquaredMahalanobis)
    if measure.mapping is not None or measure.mapping2 is not None:
        raise UnsupportedComponentError(
            f"{where}.mapping: measures with a mapping are not supported"
        )
    return type(measure) is SquaredMahalanobis


def _gnn(associator: Any, where: str) -> tuple[GnnSpec, Any]:
    """(spec, hypothesiser) of a GNNWith2DAssignment + DistanceHypothesiser."""
    from stonesoup.dataassociator.neighbour import GNNWith2DAssignment
    from stonesoup.hypothesiser.distance import DistanceHypothesiser

    _require(associator, where, GNNWith2DAssignment)
    hyp = associator.hypothesiser
    _require(hyp, f"{where}.hypothesiser", DistanceHypothesiser)
    missed = float(hyp.missed_distance)
    if np.isnan(missed):
        raise ValueError(f"{where}.hypothesiser.missed_distance: NaN")
    spec = GnnSpec(
        squared=_measure(hyp.measure, f"{where}.hypothesiser.measure"),
        missed_distance=missed,
        include_all=bool(hyp.include_all),
    )
    return spec, hyp


def _jpda(associator: Any, where: str) -> tuple[JpdaSpec, Any]:
    from stonesoup.dataassociator import probability as dp
    from stonesoup.hypothesiser.probability import PDAHypothesiser

    allowed: list[type] = [dp.JPDA, dp.JPDAwithEHM, dp.JPDAwithEHM2]
    try:
        from pyehm.plugins.stonesoup import JPDAWithEHM, JPDAWithEHM2

        allowed += [JPDAWithEHM, JPDAWithEHM2]
    except ImportError:  # pragma: no cover - pyehm is optional
        pass
    _require(associator, where, *allowed)
    hyp = associator.hypothesiser
    _require(hyp, f"{where}.hypothesiser", PDAHypothesiser)
    pd, pg = float(hyp.prob_detect), float(hyp.prob_gate)
    for name, p in (("prob_detect", pd), ("prob_gate", pg)):
        if not 0 < p <= 1:
            raise ValueError(f"{where}.hypothesiser.{name}: must be in (0, 1], got {p}")
    lam = hyp.clutter_spatial_density
    if lam is not None:
        lam = float(lam)
        if not (np.isfinite(lam) and lam > 0):
            raise ValueError(
                f"{where}.hypothesiser.clutter_spatial_density: must be finite and > 0, got {lam}"
            )
    return JpdaSpec(pd, pg, lam, bool(hyp.include_all)), hyp


def _deleter(deleter: Any, where: str) -> DeleterSpec:
    from stonesoup.deleter.error import CovarianceBasedDeleter
    from stonesoup.deleter.multi import CompositeDeleter
    from stonesoup.deleter.time import UpdateTimeDeleter, UpdateTimeStepsDeleter

    _require(
        deleter,
        where,
        UpdateTimeStepsDeleter,
        UpdateTimeDeleter,
        CovarianceBasedDeleter,
        CompositeDeleter,
    )
    if type(deleter) is UpdateTimeStepsDeleter:
        steps = int(deleter.time_steps_since_update)
        if steps < 0:
            raise ValueError(f"{where}.time_steps_since_update: must be >= 0, got {steps}")
        return DeleterSpec("steps", steps)
    if type(deleter) is UpdateTimeDeleter:
        return DeleterSpec("time", deleter.time_since_update.total_seconds())
    if type(deleter) is CovarianceBasedDeleter:
        mapping = None if not deleter.mapping else tuple(int(i) for i in deleter.mapping)
        return DeleterSpec("trace", float(deleter.covar_trace_thresh), mapping)
    children = []
    for i, d in enumerate(deleter.deleters):
        if d.delete_last_pred:
            raise UnsupportedComponentError(
                f"{where}.deleters[{i}].delete_last_pred=True inside a CompositeDeleter is not "
                "supported (set it on the composite)"
            )
        children.append(_deleter(d, f"{where}.deleters[{i}]"))
    return DeleterSpec("composite", children=tuple(children), intersect=bool(deleter.intersect))


def _initiator(initiator: Any, where: str) -> dict[str, Any]:
    from stonesoup.initiator.simple import MultiMeasurementInitiator, SimpleMeasurementInitiator

    _require(initiator, where, MultiMeasurementInitiator)
    inner = initiator.initiator
    _require(inner, f"{where}.initiator", SimpleMeasurementInitiator)
    if inner.prior_state is not initiator.prior_state or (
        inner.measurement_model is not initiator.measurement_model
    ):
        raise UnsupportedComponentError(
            f"{where}.initiator: a custom inner initiator is not supported (leave it None)"
        )
    if float(inner.diag_load) != 0.0:
        raise UnsupportedComponentError(f"{where}.initiator.diag_load != 0 is not supported")
    gnn, hyp = _gnn(initiator.data_associator, f"{where}.data_associator")
    init_motion = _predictor(hyp.predictor, f"{where}.data_associator.hypothesiser.predictor")
    _, _, hyp_fallback = _updater(hyp.updater, f"{where}.data_associator.hypothesiser.updater")
    joseph, symmetric, upd_fallback = _updater(initiator.updater, f"{where}.updater")
    _same_fallback(
        hyp_fallback,
        upd_fallback,
        f"{where}.data_associator.hypothesiser.updater.measurement_model",
        f"{where}.updater.measurement_model",
    )
    prior = initiator.prior_state
    x0 = np.asarray(prior.state_vector, dtype=np.float64).ravel().copy()
    p0 = np.asarray(prior.covar, dtype=np.float64).copy()
    min_points = int(initiator.min_points)
    if min_points < 1:
        raise ValueError(f"{where}.min_points: must be >= 1, got {min_points}")
    return dict(
        init_motion_model=init_motion,
        init_gnn=gnn,
        init_use_joseph_cov=joseph,
        init_symmetric_covariance=symmetric,
        init_fallback_sensor=_sensor(initiator.measurement_model, f"{where}.measurement_model"),
        init_update_fallback_sensor=upd_fallback,
        prior_state=x0,
        prior_covariance=p0,
        min_points=min_points,
        updates_only=bool(initiator.updates_only),
        init_deleter=_deleter(initiator.deleter, f"{where}.deleter"),
        init_delete_last_pred=bool(initiator.deleter.delete_last_pred),
    )


def _same_fallback(a: LinearSensor | None, b: LinearSensor | None, wa: str, wb: str) -> None:
    if a is None or b is None:
        return
    if not a.same_as(b):
        raise UnsupportedComponentError(
            f"{wa} and {wb} differ: detections without a measurement model would be handled "
            "with two different models, which usvfast does not reproduce"
        )


def read_components(
    *, initiator: Any, deleter: Any, data_associator: Any, updater: Any, mixture: bool
) -> StoneSoupConfig:
    """Read Stone Soup components into a `StoneSoupConfig` (mixture=True: JPDA tracker).

    Raises UnsupportedComponentError naming the first component or setting that usvfast does
    not reproduce exactly, ValueError for invalid parameter values.
    """
    if mixture:
        assoc, hyp = _jpda(data_associator, "data_associator")
    else:
        assoc, hyp = _gnn(data_associator, "data_associator")
    motion = _predictor(hyp.predictor, "data_associator.hypothesiser.predictor")
    _, _, hyp_fallback = _updater(hyp.updater, "data_associator.hypothesiser.updater")
    joseph, symmetric, upd_fallback = _updater(updater, "updater")
    _same_fallback(
        hyp_fallback,
        upd_fallback,
        "data_associator.hypothesiser.updater.measurement_model",
        "updater.measurement_model",
    )
    init = _initiator(initiator, "initiator")
    ndim = sum(
        {"random_walk": 1, "constant_velocity": 2, "constant_acceleration": 3}[c.kind]
        for c in motion
    )
    init_ndim = sum(
        {"random_walk": 1, "constant_velocity": 2, "constant_acceleration": 3}[c.kind]
        for c in init["init_motion_model"]
    )
    if init_ndim != ndim or init["prior_state"].shape != (ndim,):
        raise ValueError(
            f"initiator: state dimension {init['prior_state'].shape} / initiator transition "
            f"model {init_ndim} differ from the tracker's transition model ({ndim})"
        )
    return StoneSoupConfig(
        motion_model=motion,
        association=assoc,
        use_joseph_cov=joseph,
        symmetric_covariance=symmetric,
        fallback_sensor=upd_fallback if upd_fallback is not None else hyp_fallback,
        deleter=_deleter(deleter, "deleter"),
        delete_last_pred=bool(deleter.delete_last_pred),
        **init,
    )


# --------------------------------------------------------------------------------------------
# Mapping the read configuration onto the core
# --------------------------------------------------------------------------------------------


def _native_deleter(spec: DeleterSpec) -> Any:
    from usvfast import tracking as tk

    if spec.kind == "steps":
        return tk.StepsSinceUpdate(int(spec.value))
    if spec.kind == "time":
        return tk.TimeSinceUpdate(float(spec.value))
    if spec.kind == "trace":
        return tk.CovarianceTrace(float(spec.value), spec.mapping)
    children = [_native_deleter(c) for c in spec.children]
    return tk.AllOf(*children) if spec.intersect else tk.AnyOf(*children)


def build_native(
    cfg: StoneSoupConfig, sensors: list[Any], *, initiate_in_gates: bool = True
) -> Any:
    """The `usvfast.tracking.Tracker` equal to a read Stone Soup configuration, with `sensors`
    (list of `usvfast.tracking.Sensor`). initiate_in_gates=False switches on the native
    option that withholds detections inside confirmed tracks' gates from the initiator (no
    duplicate tracks; no longer Stone Soup's behaviour)."""
    instance("cfg", cfg, StoneSoupConfig)
    from usvfast import tracking as tk

    if isinstance(cfg.association, JpdaSpec):
        a = cfg.association
        association: Any = tk.JPDA(
            prob_detect=a.prob_detect,
            prob_gate=a.prob_gate,
            clutter_density=a.clutter_density,
            include_all=a.include_all,
            method="ehm",
        )
    else:
        g = cfg.association
        association = tk.GNN(
            missed_distance=g.missed_distance,
            measure="squared_mahalanobis" if g.squared else "mahalanobis",
            include_all=g.include_all,
        )
    ig = cfg.init_gnn
    initiator = tk.MultiMeasurementInitiator(
        prior_state=cfg.prior_state,
        prior_covariance=cfg.prior_covariance,
        min_points=cfg.min_points,
        deleter=_native_deleter(cfg.init_deleter),
        missed_distance=ig.missed_distance,
        measure="squared_mahalanobis" if ig.squared else "mahalanobis",
        include_all=ig.include_all,
        updates_only=cfg.updates_only,
        motion_model=None if cfg.init_motion_model == cfg.motion_model else cfg.init_motion_model,
        use_joseph_cov=cfg.init_use_joseph_cov,
        symmetric_covariance=cfg.init_symmetric_covariance,
    )
    return tk.Tracker(
        motion_model=cfg.motion_model,
        sensors=sensors,
        association=association,
        deleter=_native_deleter(cfg.deleter),
        initiator=initiator,
        use_joseph_cov=cfg.use_joseph_cov,
        symmetric_covariance=cfg.symmetric_covariance,
        delete_last_prediction=cfg.delete_last_pred,
        out_of_order="raise",
        initiate_in_gates=initiate_in_gates,
    )


# --------------------------------------------------------------------------------------------
# Building Stone Soup states quickly
# --------------------------------------------------------------------------------------------


class _StateFactory:
    """Builds Stone Soup states. Stone Soup's `Base.__init__` costs tens of µs per object; when
    the fast path builds objects whose attributes equal the slow path's (checked once on first
    use), it fills `__dict__` directly."""

    def __init__(self) -> None:
        from stonesoup.types.array import CovarianceMatrix, StateVector
        from stonesoup.types.prediction import GaussianStatePrediction
        from stonesoup.types.update import GaussianStateUpdate

        self._sv, self._cm = StateVector, CovarianceMatrix
        self._pred, self._upd = GaussianStatePrediction, GaussianStateUpdate
        self._fast = self._check_fast()

    def _fast_new(self, cls: type, props: dict[str, Any]) -> Any:
        obj = cls.__new__(cls)  # pyright: ignore[reportCallIssue]
        obj.__dict__.update({f"_property_{k}": v for k, v in props.items()})
        return obj

    def _check_fast(self) -> bool:
        from datetime import datetime

        x, p, ts = np.arange(4.0).reshape(4, 1), np.eye(4), datetime(2024, 1, 1)
        try:
            for cls, extra in ((self._pred, {}), (self._upd, {"hypothesis": None})):
                slow = cls(x, p, timestamp=ts, **extra)
                fast = self.make(cls is self._upd, x, p, ts, extra.get("hypothesis"), fast=True)
                if type(slow) is not type(fast) or vars(slow).keys() != vars(fast).keys():
                    return False
                for k, v in vars(slow).items():
                    w = vars(fast)[k]
                    if type(v) is not type(w) or (
                        isinstance(v, np.ndarray) and not np.array_equal(v, w)
                    ):
                        return False
        except Exception:  # any surprise: use the public constructors
            return False
        return True

    def make(self, is_update: bool, x, p, ts, hypothesis=None, fast: bool | None = None):
        """A GaussianStateUpdate (with `hypothesis`) or GaussianStatePrediction."""
        fast = self._fast if fast is None else fast
        if not fast:
            if is_update:
                return self._upd(x, p, hypothesis=hypothesis, timestamp=ts)
            return self._pred(x, p, timestamp=ts)
        sv = np.array(x, dtype=np.float64).reshape(-1, 1).view(self._sv)
        cm = np.array(p, dtype=np.float64).view(self._cm)
        if is_update:
            return self._fast_new(
                self._upd,
                {"state_vector": sv, "covar": cm, "hypothesis": hypothesis, "timestamp": ts},
            )
        return self._fast_new(
            self._pred,
            {
                "state_vector": sv,
                "covar": cm,
                "timestamp": ts,
                "transition_model": None,
                "prior": None,
            },
        )


# --------------------------------------------------------------------------------------------
# The trackers
# --------------------------------------------------------------------------------------------


class _DropInTracker:
    """Shared machinery of the two drop-in trackers (see the module docstring)."""

    _mixture = True

    def __init__(
        self,
        initiator: Any,
        deleter: Any,
        detector: Any = None,
        data_associator: Any = None,
        updater: Any = None,
        *,
        hypotheses: bool = True,
    ) -> None:
        for name, value in (
            ("initiator", initiator),
            ("deleter", deleter),
            ("data_associator", data_associator),
            ("updater", updater),
        ):
            if value is None:
                raise TypeError(f"{name}: a Stone Soup component is required")
        self.initiator = initiator
        self.deleter = deleter
        self.detector = detector
        self.data_associator = data_associator
        self.updater = updater
        self.hypotheses = bool(hypotheses)
        self.config = read_components(
            initiator=initiator,
            deleter=deleter,
            data_associator=data_associator,
            updater=updater,
            mixture=self._mixture,
        )
        self.detector_iter = None
        self._states = _StateFactory()
        self._core: Any = None
        self._sensor_specs: list[tuple] = []  # (H, R, H_init, R_init) per core sensor
        # id(model) -> (core sensor index, the model's R if it differs from the sensor's)
        self._sensor_of_model: dict[int, tuple[int, np.ndarray | None]] = {}
        self._models: list[Any] = []  # keeps the models alive while their id() is used
        # Empty scans seen before the core exists (it is built at the first detection).
        self._replay: list[tuple[float, np.ndarray, np.ndarray]] = []
        self._t0: Any = None
        self._scan = 0
        self._scan_time: list[Any] = []
        # Detections per scan; scans no history entry can refer to any more are freed (None).
        self._scan_dets: list[list[Any] | None] = []
        self._freed = 0
        self._tracks: dict[int, Any] = {}
        self._prev: dict[int, tuple[float, np.ndarray, np.ndarray]] = {}

    # -- Stone Soup's Tracker protocol -------------------------------------------------------

    @property
    def tracks(self) -> set:
        """The current confirmed tracks (set of stonesoup Track)."""
        return set(self._tracks.values())

    def __iter__(self):
        if self.detector is None:
            raise AttributeError(
                "Detector has not been set. A detector attribute is required to iterate over a "
                "tracker."
            )
        if self.detector_iter is None:
            self.detector_iter = iter(self.detector)
        return self

    def __next__(self):
        if self.detector_iter is None:
            iter(self)
        assert self.detector_iter is not None  # set by __iter__
        time, detections = next(self.detector_iter)
        return self._step(time, detections)

    def update_tracker(self, time: Any, detections: Any):
        """Process one scan (datetime, set of Detection) without a detector; returns
        (time, tracks) like iterating does."""
        return self._step(time, detections)

    # -- internals ---------------------------------------------------------------------------

    def _sensor_index(self, model: Any) -> tuple[int, np.ndarray | None]:
        """The core sensor of a detection's measurement model, and the model's noise R when it
        differs from that sensor's (None otherwise). Models with the same H share one core
        sensor; their own R goes to the core as a per-detection covariance."""
        key = id(model)
        hit = self._sensor_of_model.get(key)
        if hit is not None:
            return hit
        cfg = self.config
        if model is None:
            main, init = cfg.fallback_sensor, cfg.init_fallback_sensor
            if main is None or init is None:
                raise ValueError(
                    "detections: a detection has no measurement_model and the updater or the "
                    "initiator has none to fall back on"
                )
            upd = cfg.init_update_fallback_sensor
            if upd is not None and not upd.same_as(main):
                raise UnsupportedComponentError(
                    "initiator.updater.measurement_model differs from updater.measurement_model:"
                    " detections without a model would be updated with two different models"
                )
            spec = (main.matrix, main.noise, init.matrix, init.noise)
        else:
            s = _sensor(model, "detection.measurement_model")
            if s is None:
                raise TypeError(
                    "detection.measurement_model: expected a LinearGaussian measurement model"
                )
            if s.matrix.shape[1] != len(cfg.prior_state):
                raise ValueError(
                    f"detection.measurement_model: ndim_state {s.matrix.shape[1]} differs from "
                    f"the transition model's {len(cfg.prior_state)}"
                )
            spec = (s.matrix, s.noise, None, None)

        def same(a: Any, b: Any) -> bool:
            return (a is None and b is None) or (
                a is not None and b is not None and np.array_equal(a, b)
            )

        for i, old in enumerate(self._sensor_specs):
            # Same H and initiation model; R may differ (a detection's own covariance).
            if same(old[0], spec[0]) and same(old[2], spec[2]) and same(old[3], spec[3]):
                idx = i
                break
        else:
            idx = len(self._sensor_specs)
            self._sensor_specs.append(spec)
            self._add_core_sensor(spec)
        own = None if np.array_equal(self._sensor_specs[idx][1], spec[1]) else spec[1]
        self._sensor_of_model[key] = (idx, own)
        self._models.append(model)
        return idx, own

    def _add_core_sensor(self, spec: tuple) -> None:
        if self._core is None:
            return
        from usvfast import tracking as tk

        self._core.add_sensor(tk.Sensor(*spec))

    def _new_core(self) -> Any:
        from usvfast import tracking as tk

        sensors = [tk.Sensor(*spec) for spec in self._sensor_specs]
        return build_native(self.config, sensors)

    def _step(self, time: Any, detections: Any):
        dets = list(detections)
        for d in dets:
            if d.timestamp != time:
                raise ValueError(
                    f"detections: a detection at {d.timestamp} in the scan at {time}; usvfast "
                    "needs every detection of a scan to carry the scan time"
                )
        found = [self._sensor_index(d.measurement_model) for d in dets]
        sids = np.fromiter((f[0] for f in found), dtype=np.int64, count=len(dets))
        m = self._sensor_specs[0][0].shape[0] if self._sensor_specs else 2
        covs = None
        if any(f[1] is not None for f in found):
            covs = np.array(
                [self._sensor_specs[i][1] if r is None else r for i, r in found], dtype=np.float64
            ).reshape(len(dets), m, m)
        z = np.empty((len(dets), m))
        for i, d in enumerate(dets):
            sv = np.asarray(d.state_vector, dtype=np.float64).ravel()
            if sv.shape != (m,):
                raise ValueError(
                    f"detections: state vector of length {sv.size}, expected {m} (all sensors "
                    "must share the measurement dimension)"
                )
            z[i] = sv
        if self._t0 is None:
            self._t0 = time
        t = (time - self._t0).total_seconds()
        if self._core is None and self._sensor_specs:
            # Built at the first scan with a detection; earlier (empty) scans are replayed so
            # that the core's scan indices are the drop-in's.
            self._core = self._new_core()
            for args in self._replay:
                self._core.step(*args)
            self._replay.clear()
        if self._core is not None:
            self._core.step(t, z, sids, covs)
        else:
            self._replay.append((t, z, sids))
        self._scan_time.append(time)
        self._scan_dets.append(dets)
        self._scan += 1
        if self._core is not None:
            self._collect(time)
            self._free_scans()
        return time, self.tracks

    def _free_scans(self) -> None:
        # Later states refer to this scan's detections or to those of the tentative tracks'
        # first scans (a track confirmed later brings its whole tentative history).
        first = self._core.tentative_tracks.first_scan
        oldest = min(int(first.min()) if len(first) else self._scan, self._scan - 1)
        for k in range(self._freed, max(oldest, self._freed)):
            self._scan_dets[k] = None
        self._freed = max(oldest, self._freed)

    def _collect(self, time: Any) -> None:
        from stonesoup.types.track import Track

        core = self._core
        snap = core.tracks
        alive = snap.ids.tolist()
        alive_set = set(alive)
        # Deleted this scan: their final state(s) come from the core's history.
        for tid in [k for k in self._tracks if k not in alive_set]:
            tr = self._tracks.pop(tid)
            hist = vars(core.history(tid))
            n_have = len(tr.states)
            for j in range(n_have, len(hist["times"])):
                tr.append(self._state_from_history(hist, j, tid))
            self._prev.pop(tid, None)
        for row, tid in enumerate(alive):
            tr = self._tracks.get(tid)
            if tr is None:
                hist = vars(core.history(tid))
                states = [self._state_from_history(hist, j, tid) for j in range(len(hist["times"]))]
                tr = Track(states)
                self._tracks[tid] = tr
                self._prev[tid] = (
                    float(hist["times"][-1]),
                    hist["states"][-1].copy(),
                    hist["covariances"][-1].copy(),
                )
                continue
            x, p, upd = snap.states[row], snap.covariances[row], bool(snap.is_update[row])
            hyp = self._hypothesis_for(tid, snap, row, upd) if (upd and self.hypotheses) else None
            if upd and hyp is None:
                hyp = self._placeholder(time)
            tr.append(self._states.make(upd, x, p, time, hyp))
            self._prev[tid] = (float(snap.times[row]), x.copy(), p.copy())

    def _placeholder(self, time: Any) -> Any:
        from stonesoup.types.detection import MissedDetection
        from stonesoup.types.hypothesis import SingleHypothesis

        return SingleHypothesis(None, MissedDetection(timestamp=time))

    def _prediction(self, tid: int, t: float, time: Any) -> Any:
        prev = self._prev.get(tid)
        if prev is None:
            return None
        t0, x0, p0 = prev
        f, q = kalman.transition_matrices(self.config.motion_model, t - t0)
        return self._states.make(False, f @ x0, f @ p0 @ f.T + q, time)

    def _hypothesis_for(self, tid: int, snap: Any, row: int, upd: bool) -> Any:
        # Association data of the newest entry, from the snapshot.
        a, b = snap.assoc_offsets[row], snap.assoc_offsets[row + 1]
        dets = snap.assoc_detection[a:b]
        probs = snap.assoc_probability[a:b]
        missed = float(snap.missed_probability[row])
        det = int(snap.detection[row])
        time = self._scan_time[-1]
        t = (time - self._t0).total_seconds()
        pred = self._prediction(tid, t, time)
        scan_dets = self._scan_dets[-1]
        return self._make_hypothesis(pred, scan_dets, time, dets, probs, missed, det)

    def _make_hypothesis(self, pred, scan_dets, time, dets, probs, missed, det) -> Any:
        from stonesoup.types.detection import MissedDetection
        from stonesoup.types.hypothesis import SingleHypothesis, SingleProbabilityHypothesis
        from stonesoup.types.multihypothesis import MultipleHypothesis

        if self._mixture and np.isfinite(missed):
            hyps = [SingleProbabilityHypothesis(pred, MissedDetection(timestamp=time), missed)]
            hyps += [
                SingleProbabilityHypothesis(pred, scan_dets[int(j)], float(p))
                for j, p in zip(dets, probs, strict=True)
            ]
            return MultipleHypothesis(hyps, normalise=False)
        if det >= 0:
            return SingleHypothesis(pred, scan_dets[det])
        return None

    def _state_from_history(self, hist: dict, j: int, tid: int) -> Any:
        scan = int(hist["scan"][j])
        time = self._scan_time[scan] if 0 <= scan < len(self._scan_time) else None
        if time is None:
            raise RuntimeError(f"usvfast.stonesoup: history entry of track {tid} at unknown scan")
        upd = bool(hist["is_update"][j])
        hyp = None
        if upd:
            det = int(hist["detection"][j])
            scan_dets = self._scan_dets[scan]
            if scan_dets is None:
                raise RuntimeError(
                    f"usvfast.stonesoup: detections of scan {scan} (track {tid}) were released"
                )
            if self.hypotheses:
                from stonesoup.types.hypothesis import SingleHypothesis

                if j == 0 and det >= 0:
                    hyp = SingleHypothesis(None, scan_dets[det])  # pyright: ignore[reportArgumentType]  # (no prediction)
                else:
                    pred = None
                    if j > 0:
                        t_prev = float(hist["times"][j - 1])
                        f, q = kalman.transition_matrices(
                            self.config.init_motion_model, float(hist["times"][j]) - t_prev
                        )
                        x0, p0 = hist["states"][j - 1], hist["covariances"][j - 1]
                        pred = self._states.make(False, f @ x0, f @ p0 @ f.T + q, time)
                    a, b = hist["assoc_offsets"][j], hist["assoc_offsets"][j + 1]
                    hyp = self._make_hypothesis(
                        pred,
                        scan_dets,
                        time,
                        hist["assoc_detection"][a:b],
                        hist["assoc_probability"][a:b],
                        float(hist["missed_probability"][j]),
                        det,
                    )
            if hyp is None:
                hyp = self._placeholder(time)
        return self._states.make(upd, hist["states"][j], hist["covariances"][j], time, hyp)


class MultiTargetMixtureTracker(_DropInTracker):
    """Stone Soup's `MultiTargetMixtureTracker` (JPDA) run by the usvfast core.

    Same keywords (`initiator`, `deleter`, `detector`, `data_associator`, `updater`), same
    protocol: iterating yields `(datetime, set of Track)` per scan of `detector`;
    `update_tracker(time, detections)` processes one scan. Update states carry a
    `MultipleHypothesis` of `SingleProbabilityHypothesis` (prediction, detection or
    MissedDetection, JPDA probability; `measurement_prediction` is None). `hypotheses=False`
    skips building them (2-3x faster): update states then carry a placeholder
    `SingleHypothesis(None, MissedDetection)`, so do not feed such tracks to Stone Soup
    deleters. Raises UnsupportedComponentError for components usvfast cannot reproduce
    exactly, ValueError for detections off the scan time or of another dimension.

    Memory: a scan's detections are kept while a tentative track's history refers to them (a
    track confirmed later brings its tentative states). A detection with a new measurement
    matrix H registers one more core sensor (`Tracker.add_sensor`); no scan is replayed.
    Detections whose models share H but not the noise covariance (each detection with its own
    `LinearGaussian`, e.g. range-dependent noise) share that sensor and reach the core with
    their own covariance (`Tracker.step(..., covariances=...)`), exactly as Stone Soup uses
    each detection's model for gating, hypotheses, updates and initiation.
    """

    _mixture = True


class MultiTargetTracker(_DropInTracker):
    """Stone Soup's `MultiTargetTracker` (GNN: DistanceHypothesiser + GNNWith2DAssignment) run
    by the usvfast core; same keywords and protocol as `MultiTargetMixtureTracker`."""

    _mixture = False
