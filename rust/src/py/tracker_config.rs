//! The tracker's configuration objects (the dataclasses of `usvfast.tracking`) read by
//! attribute into typed structs, then into the core's [`TrackerConfig`] parts.
//!
//! The Python field names are the only names: each `*Args` struct below mirrors one dataclass
//! field for field. A field of the wrong type is a TypeError naming its path
//! (`initiator.deleter.steps: ...`); a count out of range a ValueError; arrays go through
//! `usvfast._validate.as_float_array` (TypeError, DimensionError, NonFiniteError naming them).

use super::kalman::motion_model_from_spec;
use super::to_py_err;
use crate::error::Error;
use crate::models::MotionModel;
use crate::tracking::config::Existence;
use crate::tracking::imm::{ConstantTurn, ImmConfig, Mode, TurnPredictor};
use crate::tracking::jpda::Method;
use crate::tracking::polar::{Polar, PolarUpdate};
use crate::tracking::track::Deleter;
use crate::tracking::tracker::{
    Association, Confirmation, GnnParams, InitiatorConfig, JpdaParams, Measure, Sensor,
};
use nalgebra::{DMatrix, DVector};
use numpy::{PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyAttributeError, PyOverflowError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyString};

/// `obj` read into `T` by attribute; a failure names the field path under `what`, keeping the
/// innermost exception's type (an AttributeError on `obj` itself — not a `expected` at all —
/// becomes a TypeError).
pub(crate) fn typed<'py, T>(obj: &Bound<'py, PyAny>, what: &str, expected: &str) -> PyResult<T>
where
    T: for<'a> FromPyObject<'a, 'py, Error = PyErr>,
{
    obj.extract::<T>()
        .map_err(|e| field_error(obj, e, what, expected))
}

/// One error naming the field path, from pyo3's chain of "failed to extract field S.f" errors.
fn field_error(obj: &Bound<'_, PyAny>, err: PyErr, what: &str, expected: &str) -> PyErr {
    let py = obj.py();
    let mut path = what.to_owned();
    let mut e = err;
    loop {
        let msg = e.value(py).to_string();
        let field = msg.strip_prefix("failed to extract field ");
        match (field, e.cause(py)) {
            (Some(f), Some(cause)) => {
                path.push('.');
                path.push_str(f.rsplit('.').next().unwrap_or(f));
                e = cause;
            }
            _ => break,
        }
    }
    let msg = e.value(py).to_string();
    if e.is_instance_of::<PyAttributeError>(py) {
        let got = obj
            .get_type()
            .name()
            .map_or_else(|_| "?".to_owned(), |n| n.to_string());
        return if path == what {
            PyTypeError::new_err(format!("{what}: expected {expected}, got {got} ({msg})"))
        } else {
            PyTypeError::new_err(format!("{path}: {msg}"))
        };
    }
    let text = format!("{path}: {msg}");
    match e.get_type(py).call1((text.clone(),)) {
        Ok(v) => PyErr::from_value(v),
        Err(_) => PyTypeError::new_err(text),
    }
}

/// A count: a Python int (or numpy integer) in [0, 2⁶³ − 1]. A bool or a float is a
/// TypeError, a negative or larger value a ValueError.
pub(crate) struct Count(pub usize);

impl<'a, 'py> FromPyObject<'a, 'py> for Count {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if obj.is_instance_of::<PyBool>() {
            return Err(PyTypeError::new_err("expected an integer, got bool"));
        }
        match obj.extract::<i64>() {
            Ok(v) => usize::try_from(v).map(Count).map_err(|_| {
                PyValueError::new_err(format!("must be an integer in [0, 2^63 - 1], got {v}"))
            }),
            Err(e) if e.is_instance_of::<PyOverflowError>(obj.py()) => Err(PyValueError::new_err(
                format!("must be an integer in [0, 2^63 - 1], got {}", obj.as_any()),
            )),
            Err(e) => Err(e),
        }
    }
}

/// Any real array-like as a C-contiguous float64 array (`usvfast._validate.as_float_array`,
/// errors naming `name`), with `ndim` dimensions when given.
fn real_array<'py>(
    obj: &Bound<'py, PyAny>,
    name: &str,
    ndim: Option<usize>,
) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    // A finite C-contiguous float64 array of the right rank is what the check returns (the
    // same array): read it here. Anything else (and every error) goes through the check.
    if let Ok(a) = obj.cast::<numpy::PyArrayDyn<f64>>() {
        if a.is_c_contiguous() && ndim.is_none_or(|d| a.ndim() == d) {
            if let Ok(ro) = numpy::PyArrayMethods::try_readonly(a) {
                if ro.as_slice().is_ok_and(|v| v.iter().all(|x| x.is_finite())) {
                    return Ok(ro);
                }
            }
        }
    }
    let check = obj
        .py()
        .import("usvfast._validate")?
        .getattr("as_float_array")?;
    check.call1((name, obj, ndim))?.extract()
}

/// A 2-D real array-like as a matrix.
fn matrix(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<DMatrix<f64>> {
    let a = real_array(obj, name, Some(2))?;
    let s = a.shape();
    Ok(DMatrix::from_row_slice(s[0], s[1], super::slice(name, &a)?))
}

/// A real array-like of any shape, flattened in C order.
fn flat(obj: &Bound<'_, PyAny>, name: &str, ndim: Option<usize>) -> PyResult<Vec<f64>> {
    let a = real_array(obj, name, ndim)?;
    Ok(super::slice(name, &a)?.to_vec())
}

/// A Stone Soup distance measure by name.
pub(crate) fn measure(s: &str) -> PyResult<Measure> {
    match s {
        "mahalanobis" => Ok(Measure::Mahalanobis),
        "squared_mahalanobis" => Ok(Measure::SquaredMahalanobis),
        other => Err(PyValueError::new_err(format!(
            "measure: expected 'mahalanobis' or 'squared_mahalanobis', got {other:?}"
        ))),
    }
}

/// A JPDA marginal method by name.
pub(crate) fn method(s: &str) -> PyResult<Method> {
    match s {
        "ehm" => Ok(Method::Ehm),
        "brute_force" => Ok(Method::BruteForce),
        "lbp" => Ok(Method::Lbp),
        other => Err(PyValueError::new_err(format!(
            "method: expected 'ehm', 'brute_force' or 'lbp', got {other:?}"
        ))),
    }
}

/// One `usvfast.kalman` motion-model component (`RandomWalk`, `ConstantVelocity`,
/// `ConstantAcceleration`): its class-level `kind` and `noise_diff_coeff` q.
#[derive(FromPyObject)]
struct ComponentArgs {
    kind: String,
    noise_diff_coeff: f64,
}

/// A `usvfast.kalman` motion model: one component or a sequence of them (block diagonal).
pub(crate) struct ModelArgs(Vec<ComponentArgs>);

impl<'a, 'py> FromPyObject<'a, 'py> for ModelArgs {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if obj.hasattr("kind")? {
            return Ok(Self(vec![obj.extract()?]));
        }
        if obj.hasattr("transition_matrix")? {
            return Err(PyTypeError::new_err(
                "a LinearModel has no component spec (the tracker takes RandomWalk, \
                 ConstantVelocity and ConstantAcceleration components)",
            ));
        }
        if obj.is_instance_of::<PyString>() {
            return Err(PyTypeError::new_err("expected a motion model, got str"));
        }
        Ok(Self(obj.extract()?))
    }
}

impl ModelArgs {
    pub(crate) fn into_core(self) -> PyResult<MotionModel> {
        let spec: Vec<(String, f64)> = self
            .0
            .into_iter()
            .map(|c| (c.kind, c.noise_diff_coeff))
            .collect();
        motion_model_from_spec(&spec)
    }
}

/// The fields of `usvfast.tracking.JPDA`.
#[derive(FromPyObject)]
pub(crate) struct JpdaArgs {
    prob_detect: f64,
    prob_gate: f64,
    clutter_density: Option<f64>,
    include_all: bool,
    method: String,
    max_hypotheses: Option<i64>,
}

/// The fields of `usvfast.tracking.GNN`.
#[derive(FromPyObject)]
pub(crate) struct GnnArgs {
    measure: String,
    missed_distance: f64,
    include_all: bool,
}

/// A `JPDA` or a `GNN` association object.
pub(crate) enum AssociationArgs {
    Jpda(JpdaArgs),
    Gnn(GnnArgs),
}

impl AssociationArgs {
    /// A `JPDA` (it has `prob_detect`) or a `GNN`.
    pub(crate) fn from_object(a: &Bound<'_, PyAny>) -> PyResult<Self> {
        if a.hasattr("prob_detect")? {
            Ok(Self::Jpda(typed(a, "association", "JPDA")?))
        } else {
            Ok(Self::Gnn(typed(a, "association", "JPDA or GNN")?))
        }
    }

    pub(crate) fn into_core(self) -> PyResult<Association> {
        Ok(match self {
            Self::Jpda(j) => Association::Jpda(JpdaParams {
                prob_detect: j.prob_detect,
                prob_gate: j.prob_gate,
                clutter_density: j.clutter_density,
                include_all: j.include_all,
                method: method(&j.method)?,
                max_hypotheses: match j.max_hypotheses {
                    None => None,
                    Some(v) if v >= 1 => Some(usize::try_from(v).unwrap_or(usize::MAX)),
                    Some(v) => {
                        return Err(PyValueError::new_err(format!(
                            "max_hypotheses: must be >= 1 or None, got {v}"
                        )))
                    }
                },
            }),
            Self::Gnn(g) => Association::Gnn(GnnParams {
                measure: measure(&g.measure)?,
                missed_distance: g.missed_distance,
                include_all: g.include_all,
            }),
        })
    }
}

/// The fields of `StepsSinceUpdate`.
#[derive(FromPyObject)]
struct StepsArgs {
    steps: Count,
}

/// The fields of `TimeSinceUpdate`.
#[derive(FromPyObject)]
struct TimeArgs {
    seconds: f64,
}

/// The fields of `CovarianceTrace`.
#[derive(FromPyObject)]
struct TraceArgs {
    threshold: f64,
    mapping: Option<Vec<Count>>,
}

/// The fields of `AnyOf` / `AllOf`.
#[derive(FromPyObject)]
struct CompositeArgs {
    deleters: Vec<DeleterArgs>,
}

/// A deleter, told apart by its `usvfast.tracking` class: `StepsSinceUpdate`,
/// `TimeSinceUpdate`, `CovarianceTrace`, `AnyOf`, `AllOf` or `NeverDelete`.
pub(crate) struct DeleterArgs(pub Deleter);

impl<'a, 'py> FromPyObject<'a, 'py> for DeleterArgs {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        let module = obj.py().import("usvfast.tracking")?;
        let is = |name: &str| -> PyResult<bool> { obj.is_instance(&module.getattr(name)?) };
        let d = if is("StepsSinceUpdate")? {
            Deleter::StepsSinceUpdate(obj.extract::<StepsArgs>()?.steps.0)
        } else if is("TimeSinceUpdate")? {
            Deleter::TimeSinceUpdate(obj.extract::<TimeArgs>()?.seconds)
        } else if is("CovarianceTrace")? {
            let t: TraceArgs = obj.extract()?;
            Deleter::CovarianceTrace {
                threshold: t.threshold,
                mapping: t.mapping.map(|m| m.into_iter().map(|c| c.0).collect()),
            }
        } else if is("AnyOf")? || is("AllOf")? {
            Deleter::Composite {
                deleters: obj
                    .extract::<CompositeArgs>()?
                    .deleters
                    .into_iter()
                    .map(|d| d.0)
                    .collect(),
                intersect: is("AllOf")?,
            }
        } else if is("NeverDelete")? {
            Deleter::Never
        } else {
            let got = obj.get_type().name()?;
            return Err(PyTypeError::new_err(format!(
                "expected StepsSinceUpdate, TimeSinceUpdate, CovarianceTrace, AnyOf, AllOf or \
                 NeverDelete, got {got}"
            )));
        };
        Ok(Self(d))
    }
}

/// The fields of `usvfast.tracking.MultiMeasurementInitiator`.
#[derive(FromPyObject)]
pub(crate) struct InitiatorArgs<'py> {
    prior_state: Bound<'py, PyAny>,
    prior_covariance: Bound<'py, PyAny>,
    min_points: Count,
    deleter: DeleterArgs,
    missed_distance: f64,
    measure: String,
    include_all: bool,
    updates_only: bool,
    diag_load: f64,
    m_of_n: Option<(Count, Count)>,
    motion_model: Option<ModelArgs>,
    use_joseph_cov: bool,
    symmetric_covariance: bool,
    max_new_tentative: Option<Count>,
    imm: bool,
}

impl InitiatorArgs<'_> {
    pub(crate) fn into_core(self) -> PyResult<InitiatorConfig> {
        let confirmation = match self.m_of_n {
            Some((m, n)) => Confirmation::MOfN { m: m.0, n: n.0 },
            None => Confirmation::MinPoints {
                min_points: self.min_points.0,
                updates_only: self.updates_only,
            },
        };
        Ok(InitiatorConfig {
            // A column vector (Stone Soup's StateVector) is accepted: flattened.
            prior_state: DVector::from_vec(flat(&self.prior_state, "prior_state", None)?),
            prior_covariance: matrix(&self.prior_covariance, "prior_covariance")?,
            diag_load: self.diag_load,
            confirmation,
            deleter: self.deleter.0,
            gnn: GnnParams {
                measure: measure(&self.measure)?,
                missed_distance: self.missed_distance,
                include_all: self.include_all,
            },
            motion_model: self.motion_model.map(ModelArgs::into_core).transpose()?,
            use_joseph_cov: self.use_joseph_cov,
            symmetric_covariance: self.symmetric_covariance,
            max_new_tentative: self.max_new_tentative.map(|c| c.0),
            imm: self.imm,
        })
    }
}

/// `KnownTurnRate.q`: one float for both axes or `(q_x, q_y)`.
struct TurnNoise([f64; 2]);

impl<'a, 'py> FromPyObject<'a, 'py> for TurnNoise {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if let Ok(q) = obj.extract::<f64>() {
            return Ok(Self([q, q]));
        }
        match obj.extract::<Vec<f64>>() {
            Ok(v) if v.len() == 1 => Ok(Self([v[0], v[0]])),
            Ok(v) if v.len() == 2 => Ok(Self([v[0], v[1]])),
            _ => Err(PyTypeError::new_err(format!(
                "expected a float or (q_x, q_y), got {}",
                obj.as_any()
            ))),
        }
    }
}

/// The fields of `usvfast.tracking.KnownTurnRate`.
#[derive(FromPyObject)]
struct TurnArgs {
    q: TurnNoise,
    omega: f64,
}

/// The fields of `usvfast.tracking.ConstantTurn`.
#[derive(FromPyObject)]
struct ConstantTurnArgs {
    q: TurnNoise,
    q_turn: f64,
    predictor: String,
    alpha: f64,
    beta: f64,
    kappa: Option<f64>,
}

impl ConstantTurnArgs {
    /// The core mode named `arg` (e.g. `imm.modes[1]`).
    fn into_core(self, arg: &str) -> PyResult<ConstantTurn> {
        let predictor = match self.predictor.as_str() {
            "ekf" => TurnPredictor::Extended,
            "ukf" => TurnPredictor::Unscented {
                alpha: self.alpha,
                beta: self.beta,
                kappa: self.kappa,
            },
            other => {
                return Err(to_py_err(Error::param(
                    &format!("{arg}.predictor"),
                    format!("expected 'ekf' or 'ukf', got {other:?}"),
                )))
            }
        };
        let ct = ConstantTurn {
            q: self.q.0,
            q_turn: self.q_turn,
            predictor,
        };
        ct.validate(arg).map_err(to_py_err)?;
        Ok(ct)
    }
}

/// An IMM mode: a `KnownTurnRate` (it has `omega`), a `ConstantTurn` (it has `q_turn`) or a
/// `usvfast.kalman` motion model.
enum ModeArgs {
    Turn(TurnArgs),
    ConstantTurn(ConstantTurnArgs),
    Linear(ModelArgs),
}

impl<'a, 'py> FromPyObject<'a, 'py> for ModeArgs {
    type Error = PyErr;

    fn extract(obj: Borrowed<'a, 'py, PyAny>) -> PyResult<Self> {
        if obj.hasattr("omega")? {
            Ok(Self::Turn(obj.extract()?))
        } else if obj.hasattr("q_turn")? {
            Ok(Self::ConstantTurn(obj.extract()?))
        } else {
            Ok(Self::Linear(obj.extract()?))
        }
    }
}

/// The fields of `usvfast.tracking.IMM`.
#[derive(FromPyObject)]
pub(crate) struct ImmArgs<'py> {
    modes: Vec<ModeArgs>,
    transition: Bound<'py, PyAny>,
    initial: Option<Bound<'py, PyAny>>,
}

impl ImmArgs<'_> {
    pub(crate) fn into_core(self) -> PyResult<ImmConfig> {
        let modes = self
            .modes
            .into_iter()
            .enumerate()
            .map(|(i, m)| {
                Ok(match m {
                    ModeArgs::Turn(t) => Mode::KnownTurnRate {
                        q: t.q.0,
                        omega: t.omega,
                    },
                    ModeArgs::ConstantTurn(c) => {
                        Mode::ConstantTurn(c.into_core(&format!("imm.modes[{i}]"))?)
                    }
                    ModeArgs::Linear(l) => Mode::Linear(l.into_core()?),
                })
            })
            .collect::<PyResult<Vec<_>>>()?;
        let r = modes.len();
        let initial = match &self.initial {
            None => vec![1.0 / r.max(1) as f64; r],
            Some(v) => flat(v, "imm.initial", Some(1))?,
        };
        Ok(ImmConfig {
            modes,
            transition: matrix(&self.transition, "imm.transition")?,
            initial,
        })
    }
}

/// The fields of `usvfast.tracking.Existence` (those of the core's [`Existence`]).
#[derive(FromPyObject)]
pub(crate) struct ExistenceArgs {
    survival: f64,
    initial: f64,
    delete: f64,
    vis_stay: f64,
    invis_stay: f64,
    confirm: Option<f64>,
    birth: f64,
    joint: bool,
}

impl ExistenceArgs {
    pub(crate) fn into_core(self) -> Existence {
        Existence {
            survival: self.survival,
            initial: self.initial,
            delete: self.delete,
            vis_stay: self.vis_stay,
            invis_stay: self.invis_stay,
            confirm: self.confirm,
            birth: self.birth,
            joint: self.joint,
        }
    }
}

/// The fields of `usvfast.tracking.BearingRange`.
#[derive(FromPyObject)]
struct BearingRangeArgs {
    mapping: (Count, Count),
    update: String,
    alpha: f64,
    beta: f64,
    kappa: Option<f64>,
}

/// The fields of `usvfast.tracking.Sensor`.
#[derive(FromPyObject)]
pub(crate) struct SensorArgs<'py> {
    measurement_matrix: Bound<'py, PyAny>,
    measurement_noise: Bound<'py, PyAny>,
    initiation_matrix: Option<Bound<'py, PyAny>>,
    initiation_noise: Option<Bound<'py, PyAny>>,
    polar: Option<BearingRangeArgs>,
    starts_tracks: bool,
}

impl SensorArgs<'_> {
    /// The sensor named `arg` (e.g. `sensors[0]`), checked against an `n`-state model; the
    /// initiation model defaults to the measurement one.
    pub(crate) fn into_core(self, n: usize, arg: &str) -> PyResult<Sensor> {
        let name = |f: &str| format!("{arg}.{f}");
        let h = matrix(&self.measurement_matrix, &name("measurement_matrix"))?;
        let r = matrix(&self.measurement_noise, &name("measurement_noise"))?;
        let opt = |o: &Option<Bound<'_, PyAny>>, f: &str| -> PyResult<Option<DMatrix<f64>>> {
            o.as_ref().map(|a| matrix(a, &name(f))).transpose()
        };
        let hi = opt(&self.initiation_matrix, "initiation_matrix")?;
        let ri = opt(&self.initiation_noise, "initiation_noise")?;
        let starts_tracks = self.starts_tracks;
        let Some(p) = self.polar else {
            let mut s = Sensor::new(h, r, hi, ri, n, arg).map_err(to_py_err)?;
            s.starts_tracks = starts_tracks;
            return Ok(s);
        };
        let update = match p.update.as_str() {
            "ekf" => PolarUpdate::Extended,
            "ukf" => PolarUpdate::Unscented {
                alpha: p.alpha,
                beta: p.beta,
                kappa: p.kappa,
            },
            other => {
                return Err(to_py_err(Error::param(
                    &name("update"),
                    format!("expected 'ekf' or 'ukf', got {other:?}"),
                )))
            }
        };
        let pol = Polar {
            mapping: [p.mapping.0 .0, p.mapping.1 .0],
            update,
        };
        let mut s = Sensor::polar(pol, r, ri, n, arg).map_err(to_py_err)?;
        s.starts_tracks = starts_tracks;
        Ok(s)
    }
}
