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

- predictor: `KalmanPredictor` (or `ExtendedKalmanPredictor` / `UnscentedKalmanPredictor`,
  which equal it on these linear models) without control; transition model
  `ConstantVelocity`, `RandomWalk`, `ConstantAcceleration` or a
  `CombinedLinearGaussianTransitionModel` of them;
- updater: `KalmanUpdater`, `ExtendedKalmanUpdater` or `UnscentedKalmanUpdater`
  (`use_joseph_cov`, `force_symmetric_covariance` either way; not
  `force_positive_definite_covariance`);
- measurement models: `LinearGaussian` (on the detections — each its own if you like,
  its own `noise_covar` included — or the updater's/initiator's), and radar plots with
  `CartesianToBearingRange` on the detections (`translation_offset` = the sensor position
  of each detection, e.g. a moving own ship; no `rotation_offset`): usvfast's
  `Sensor.bearing_range` with the EKF or UKF update of the updaters, which must then all
  (tracker, hypothesisers, initiator) be the same `ExtendedKalmanUpdater` or the same
  `UnscentedKalmanUpdater` (alpha, beta, kappa). Stone Soup's `CartesianToBearingRange`
  Jacobian (EKF updates, and the initiator's covariance with either updater) is a forward
  finite difference, usvfast's is analytic: radar tracks agree with Stone Soup's to ~1e-5
  relative (the finite-difference error), not to rounding;
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
    # Where -> ("kf",), ("ekf",) or ("ukf", alpha, beta, kappa) of every updater read.
    updater_kinds: dict[str, tuple] = field(default_factory=dict)

    def radar_update(self) -> tuple:
        """("ekf",) or ("ukf", alpha, beta, kappa): the one nonlinear update all updaters
        share, for range-bearing detections; UnsupportedComponentError otherwise."""
        kinds = set(self.updater_kinds.values())
        if len(kinds) == 1:
            kind = next(iter(kinds))
            if kind[0] != "kf":
                return kind
        names = ", ".join(f"{w}: {k[0]}" for w, k in self.updater_kinds.items())
        raise UnsupportedComponentError(
            "detection.measurement_model: CartesianToBearingRange detections need the same "
            "ExtendedKalmanUpdater or UnscentedKalmanUpdater (same alpha, beta, kappa) for the "
            f"tracker, its hypothesiser and the initiator; got {names}"
        )


@dataclass(frozen=True)
class PolarSensor:
    """A `CartesianToBearingRange` model without its translation: state indices `mapping`
    of (x, y), state dimension `ndim`, noise R (2, 2) in (rad², m²)."""

    mapping: tuple[int, int]
    ndim: int
    noise: np.ndarray


def detection_model(model: Any, where: str) -> tuple[LinearSensor | PolarSensor, np.ndarray]:
    """A detection's own measurement model: (sensor, origin (2,)) — origin the
    `translation_offset` of a `CartesianToBearingRange`, zeros for a `LinearGaussian`."""
    from stonesoup.models.measurement.linear import LinearGaussian
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange

    _require(model, where, LinearGaussian, CartesianToBearingRange)
    if type(model) is LinearGaussian:
        lin = _sensor(model, where)
        assert lin is not None
        return lin, np.zeros(2)
    rot = np.asarray(model.rotation_offset, dtype=np.float64).ravel()
    if np.any(rot != 0):
        raise UnsupportedComponentError(
            f"{where}.rotation_offset: a rotated CartesianToBearingRange is not supported"
        )
    mapping = tuple(int(i) for i in model.mapping)
    origin = np.asarray(model.translation_offset, dtype=np.float64).ravel()
    if len(mapping) != 2 or origin.shape != (2,):
        raise UnsupportedComponentError(
            f"{where}: CartesianToBearingRange with a 2-element mapping and translation_offset only"
        )
    noise = np.asarray(model.covar(), dtype=np.float64).copy()
    return PolarSensor((mapping[0], mapping[1]), int(model.ndim_state), noise), origin.copy()


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
        q = float(getattr(m, "noise_diff_coeff"))  # noqa: B009 (a property of these models)
        if not np.isfinite(q) or q < 0:
            raise ValueError(f"{name}.noise_diff_coeff: must be finite and >= 0, got {q}")
        out.append(simple[type(m)](q))
    return tuple(out)


def _predictor(predictor: Any, where: str) -> tuple[kalman.Component, ...]:
    from stonesoup.models.control.linear import LinearControlModel
    from stonesoup.predictor.kalman import (
        ExtendedKalmanPredictor,
        KalmanPredictor,
        UnscentedKalmanPredictor,
    )

    # On linear transition models the extended and unscented predictors give the Kalman
    # prediction (the unscented transform is exact for a linear map).
    _require(predictor, where, KalmanPredictor, ExtendedKalmanPredictor, UnscentedKalmanPredictor)
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


def _update_kind(updater: Any) -> tuple:
    """("kf",), ("ekf",) or ("ukf", alpha, beta, kappa) of an accepted updater."""
    from stonesoup.updater.kalman import ExtendedKalmanUpdater, UnscentedKalmanUpdater

    if type(updater) is ExtendedKalmanUpdater:
        return ("ekf",)
    if type(updater) is UnscentedKalmanUpdater:
        kappa = None if updater.kappa is None else float(updater.kappa)
        return ("ukf", float(updater.alpha), float(updater.beta), kappa)
    return ("kf",)


def _updater(
    updater: Any, where: str, kinds: dict[str, tuple] | None = None
) -> tuple[bool, bool, LinearSensor | None]:
    """(use_joseph_cov, force_symmetric_covariance, fallback measurement model); the update
    kind goes to `kinds[where]`. On linear models the extended update is the Kalman update
    and the unscented one equals it to rounding."""
    from stonesoup.updater.kalman import (
        ExtendedKalmanUpdater,
        KalmanUpdater,
        UnscentedKalmanUpdater,
    )

    _require(updater, where, KalmanUpdater, ExtendedKalmanUpdater, UnscentedKalmanUpdater)
    if kinds is not None:
        kinds[where] = _update_kind(updater)
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


def _initiator(initiator: Any, where: str, kinds: dict[str, tuple]) -> dict[str, Any]:
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
    _, _, hyp_fallback = _updater(
        hyp.updater, f"{where}.data_associator.hypothesiser.updater", kinds
    )
    joseph, symmetric, upd_fallback = _updater(initiator.updater, f"{where}.updater", kinds)
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
    kinds: dict[str, tuple] = {}
    _, _, hyp_fallback = _updater(hyp.updater, "data_associator.hypothesiser.updater", kinds)
    joseph, symmetric, upd_fallback = _updater(updater, "updater", kinds)
    _same_fallback(
        hyp_fallback,
        upd_fallback,
        "data_associator.hypothesiser.updater.measurement_model",
        "updater.measurement_model",
    )
    init = _initiator(initiator, "initiator", kinds)
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
        updater_kinds=kinds,
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
    from usvfast import tracking as tk

    instance("cfg", cfg, StoneSoupConfig)

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


# The trackers live in their own module; imported here so that
# `from usvfast.stonesoup import MultiTargetMixtureTracker` keeps working.
from usvfast.stonesoup_tracker import MultiTargetMixtureTracker, MultiTargetTracker  # noqa: E402

__all__ = [
    "MultiTargetMixtureTracker",
    "MultiTargetTracker",
    "StoneSoupConfig",
    "UnsupportedComponentError",
    "build_native",
    "read_components",
]
