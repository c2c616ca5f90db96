//! Bindings of the multi-target tracker (`TrackerCore`) and of its association kernels
//! (`linear_sum_assignment`, `jpda_marginals`, `chi2_gate`). The Python API is
//! `usvfast.tracking`; these take pre-validated float64 C-contiguous arrays.

use super::kalman::motion_model_from_spec;
use super::to_py_err;
use crate::error::Error;
use crate::tracking::gating::chi2_quantile;
use crate::tracking::imm::{ImmConfig, Mode};
use crate::tracking::jpda::{marginals, Method, TrackHypotheses};
use crate::tracking::polar::{Polar, PolarUpdate};
use crate::tracking::track::{Deleter, Track};
use crate::tracking::tracker::{
    Association, Confirmation, GnnParams, InitiatorConfig, JpdaParams, Measure, OutOfOrder, Sensor,
    Tracker, TrackerConfig,
};
use nalgebra::{DMatrix, DVector};
use numpy::{
    PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

fn arr_f<'py>(py: Python<'py>, data: Vec<f64>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, data).reshape(shape)?.into_any())
}

fn arr_i<'py>(py: Python<'py>, data: Vec<i64>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, data).reshape(shape)?.into_any())
}

fn slice<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    name: &str,
    a: &'a numpy::PyReadonlyArray<'_, T, D>,
) -> PyResult<&'a [T]> {
    super::slice(name, a)
}

fn matrix(name: &str, a: &PyReadonlyArray2<'_, f64>) -> PyResult<DMatrix<f64>> {
    let s = a.shape();
    Ok(DMatrix::from_row_slice(s[0], s[1], slice(name, a)?))
}

fn item<'py>(d: &Bound<'py, PyDict>, key: &str) -> PyResult<Bound<'py, PyAny>> {
    d.get_item(key)?
        .ok_or_else(|| PyValueError::new_err(format!("missing configuration key {key:?}")))
}

fn get_f64(d: &Bound<'_, PyDict>, key: &str) -> PyResult<f64> {
    item(d, key)?.extract()
}

fn get_bool(d: &Bound<'_, PyDict>, key: &str) -> PyResult<bool> {
    item(d, key)?.extract()
}

fn get_str(d: &Bound<'_, PyDict>, key: &str) -> PyResult<String> {
    item(d, key)?.extract()
}

fn measure(s: &str) -> PyResult<Measure> {
    match s {
        "mahalanobis" => Ok(Measure::Mahalanobis),
        "squared_mahalanobis" => Ok(Measure::SquaredMahalanobis),
        other => Err(PyValueError::new_err(format!(
            "measure: expected 'mahalanobis' or 'squared_mahalanobis', got {other:?}"
        ))),
    }
}

fn method(s: &str) -> PyResult<Method> {
    match s {
        "ehm" => Ok(Method::Ehm),
        "brute_force" => Ok(Method::BruteForce),
        "lbp" => Ok(Method::Lbp),
        other => Err(PyValueError::new_err(format!(
            "method: expected 'ehm', 'brute_force' or 'lbp', got {other:?}"
        ))),
    }
}

/// Parses `("steps", n) | ("time", s) | ("trace", thr, mapping|None) | ("any", [..]) |
/// ("all", [..]) | ("never",)`.
fn deleter(spec: &Bound<'_, PyAny>) -> PyResult<Deleter> {
    let t = spec.cast::<PyTuple>().map_err(|_| {
        PyValueError::new_err("deleter: expected a tuple spec such as ('steps', 3)")
    })?;
    let kind: String = t.get_item(0)?.extract()?;
    Ok(match kind.as_str() {
        "steps" => Deleter::StepsSinceUpdate(t.get_item(1)?.extract()?),
        "time" => Deleter::TimeSinceUpdate(t.get_item(1)?.extract()?),
        "trace" => Deleter::CovarianceTrace {
            threshold: t.get_item(1)?.extract()?,
            mapping: t.get_item(2)?.extract()?,
        },
        "any" | "all" => {
            let list = t.get_item(1)?;
            let list = list
                .cast::<PyList>()
                .map_err(|_| PyValueError::new_err("deleter: composite needs a list"))?;
            Deleter::Composite {
                deleters: list.iter().map(|d| deleter(&d)).collect::<PyResult<_>>()?,
                intersect: kind == "all",
            }
        }
        "never" => Deleter::Never,
        other => {
            return Err(PyValueError::new_err(format!(
                "deleter: unknown kind {other:?}"
            )))
        }
    })
}

/// The fields of `usvfast.tracking.JPDA`, read by attribute (typed: a wrong type is a
/// TypeError naming the field).
#[derive(FromPyObject)]
struct JpdaArgs {
    prob_detect: f64,
    prob_gate: f64,
    clutter_density: Option<f64>,
    include_all: bool,
    method: String,
    max_hypotheses: Option<i64>,
}

/// The fields of `usvfast.tracking.GNN`, read by attribute.
#[derive(FromPyObject)]
struct GnnArgs {
    measure: String,
    missed_distance: f64,
    include_all: bool,
}

/// A `JPDA` or a `GNN` association object.
enum AssociationArgs {
    Jpda(JpdaArgs),
    Gnn(GnnArgs),
}

impl AssociationArgs {
    /// A `JPDA` (it has `prob_detect`) or a `GNN`; a field of the wrong type is a TypeError
    /// naming it.
    fn from_object(a: &Bound<'_, PyAny>) -> PyResult<Self> {
        let named = |e: PyErr| {
            pyo3::exceptions::PyTypeError::new_err(format!("association: {}", e.value(a.py())))
        };
        if a.hasattr("prob_detect")? {
            Ok(Self::Jpda(a.extract().map_err(named)?))
        } else {
            Ok(Self::Gnn(a.extract().map_err(named)?))
        }
    }

    fn into_core(self) -> PyResult<Association> {
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

/// `(i, j, "ekf" | "ukf", alpha, beta, kappa)` of a range–bearing sensor.
type PolarSpec = (usize, usize, String, f64, f64, Option<f64>);

/// `(modes, transition (r, r), initial (r,))`; a mode is `("linear", motion model spec)` or
/// `("turn", q_x, q_y, omega)`.
type ImmSpec<'py> = (
    Vec<Bound<'py, PyTuple>>,
    PyReadonlyArray2<'py, f64>,
    Vec<f64>,
);

fn imm_from_spec(spec: &ImmSpec<'_>) -> PyResult<ImmConfig> {
    let modes = spec
        .0
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let kind: String = t.get_item(0)?.extract()?;
            match kind.as_str() {
                "linear" => Ok(Mode::Linear(motion_model_from_spec(
                    &t.get_item(1)?.extract::<Vec<(String, f64)>>()?,
                )?)),
                "turn" => Ok(Mode::KnownTurnRate {
                    q: [t.get_item(1)?.extract()?, t.get_item(2)?.extract()?],
                    omega: t.get_item(3)?.extract()?,
                }),
                other => Err(PyValueError::new_err(format!(
                    "imm.modes[{i}]: unknown kind {other:?}"
                ))),
            }
        })
        .collect::<PyResult<Vec<_>>>()?;
    Ok(ImmConfig {
        modes,
        transition: matrix("imm.transition", &spec.1)?,
        initial: spec.2.clone(),
    })
}

/// `(survival, initial, delete, vis_stay, invis_stay, confirm, birth)`.
type ExistenceSpec = (f64, f64, f64, f64, f64, Option<f64>, f64);

type SensorSpec<'py> = (
    PyReadonlyArray2<'py, f64>,
    PyReadonlyArray2<'py, f64>,
    Option<PyReadonlyArray2<'py, f64>>,
    Option<PyReadonlyArray2<'py, f64>>,
    Option<PolarSpec>,
);

fn history_dict<'py>(py: Python<'py>, tr: &Track, ndim: usize) -> PyResult<Bound<'py, PyDict>> {
    let h = &tr.history;
    let k = h.len();
    let d = PyDict::new(py);
    d.set_item("id", tr.id)?;
    d.set_item("times", arr_f(py, h.times.clone(), &[k])?)?;
    d.set_item("states", arr_f(py, h.states.clone(), &[k, ndim])?)?;
    d.set_item(
        "covariances",
        arr_f(py, h.covariances.clone(), &[k, ndim, ndim])?,
    )?;
    let upd: Vec<bool> = h.is_update.clone();
    d.set_item("is_update", PyArray1::from_vec(py, upd))?;
    d.set_item("scan", arr_i(py, h.scan.clone(), &[k])?)?;
    d.set_item("sensor", arr_i(py, h.sensor.clone(), &[k])?)?;
    d.set_item("detection", arr_i(py, h.detection.clone(), &[k])?)?;
    d.set_item("nis", arr_f(py, h.nis.clone(), &[k])?)?;
    d.set_item(
        "missed_probability",
        arr_f(py, h.missed_probability.clone(), &[k])?,
    )?;
    let offs: Vec<i64> = if h.assoc_offsets.is_empty() {
        vec![0]
    } else {
        h.assoc_offsets.iter().map(|&o| o as i64).collect()
    };
    let no = offs.len();
    d.set_item("assoc_offsets", arr_i(py, offs, &[no])?)?;
    let na = h.assoc_detection.len();
    d.set_item(
        "assoc_detection",
        arr_i(py, h.assoc_detection.clone(), &[na])?,
    )?;
    d.set_item(
        "assoc_probability",
        arr_f(py, h.assoc_probability.clone(), &[na])?,
    )?;
    d.set_item("confirmed_time", tr.confirmed_time)?;
    d.set_item("deleted_time", tr.deleted_time)?;
    Ok(d)
}

/// Sensor `i` from its arrays: H, R and optional initiation H/R (each defaulting to the
/// measurement one when only the other is given), checked against an `n`-state model.
fn sensor_from_arrays(
    h: &PyReadonlyArray2<'_, f64>,
    r: &PyReadonlyArray2<'_, f64>,
    hi: Option<&PyReadonlyArray2<'_, f64>>,
    ri: Option<&PyReadonlyArray2<'_, f64>>,
    polar: Option<&PolarSpec>,
    n: usize,
    i: usize,
) -> PyResult<Sensor> {
    let h = matrix("measurement_matrix", h)?;
    let r = matrix("measurement_noise", r)?;
    let hi = hi.map(|a| matrix("initiation_matrix", a)).transpose()?;
    let ri = ri.map(|a| matrix("initiation_noise", a)).transpose()?;
    let arg = format!("sensors[{i}]");
    match polar {
        None => Sensor::new(h, r, hi, ri, n, &arg).map_err(to_py_err),
        Some((a, b, kind, alpha, beta, kappa)) => {
            let update = match kind.as_str() {
                "ekf" => PolarUpdate::Extended,
                "ukf" => PolarUpdate::Unscented {
                    alpha: *alpha,
                    beta: *beta,
                    kappa: *kappa,
                },
                other => {
                    return Err(PyValueError::new_err(format!(
                        "{arg}.update: expected 'ekf' or 'ukf', got {other:?}"
                    )))
                }
            };
            let pol = Polar {
                mapping: [*a, *b],
                update,
            };
            Sensor::polar(pol, r, ri, n, &arg).map_err(to_py_err)
        }
    }
}

/// Ctrl-C polling for core code running without the GIL: [`SignalCheck::poll`] re-attaches
/// at most every 20 ms to run Python's signal handlers and keeps the exception they raise.
struct SignalCheck {
    last: std::time::Instant,
    err: Option<PyErr>,
}

impl SignalCheck {
    fn new() -> Self {
        Self {
            last: std::time::Instant::now(),
            err: None,
        }
    }

    /// True once a signal handler has raised (then always).
    fn poll(&mut self) -> bool {
        if self.err.is_some() {
            return true;
        }
        if self.last.elapsed() < std::time::Duration::from_millis(20) {
            return false;
        }
        self.last = std::time::Instant::now();
        if let Err(e) = Python::attach(|py| py.check_signals()) {
            self.err = Some(e);
        }
        self.err.is_some()
    }

    /// The core's result, with the signal handler's own exception for an interruption.
    fn result<T>(self, r: crate::Result<T>) -> PyResult<T> {
        match (r, self.err) {
            (Err(Error::Interrupted), Some(e)) => Err(e),
            (r, _) => r.map_err(to_py_err),
        }
    }
}

/// The multi-target tracker core; build it through `usvfast.tracking.Tracker`.
#[pyclass(module = "usvfast._core")]
pub struct TrackerCore {
    inner: Tracker,
}

#[pymethods]
impl TrackerCore {
    #[new]
    #[pyo3(signature = (
        motion_model, sensors, association, deleter_spec, initiator, *,
        use_joseph_cov=false, delete_last_prediction=false, out_of_order="raise",
        initiate_in_gates=true, symmetric_covariance=false, imm=None, existence=None,
        max_deleted=None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        motion_model: Vec<(String, f64)>,
        sensors: Vec<SensorSpec<'_>>,
        association: &Bound<'_, PyAny>,
        deleter_spec: &Bound<'_, PyAny>,
        initiator: &Bound<'_, PyDict>,
        use_joseph_cov: bool,
        delete_last_prediction: bool,
        out_of_order: &str,
        initiate_in_gates: bool,
        symmetric_covariance: bool,
        imm: Option<ImmSpec<'_>>,
        existence: Option<ExistenceSpec>,
        max_deleted: Option<usize>,
    ) -> PyResult<Self> {
        let model = motion_model_from_spec(&motion_model)?;
        let n = model.ndim();
        let sensors = sensors
            .iter()
            .enumerate()
            .map(|(i, (h, r, hi, ri, pol))| {
                sensor_from_arrays(h, r, hi.as_ref(), ri.as_ref(), pol.as_ref(), n, i)
            })
            .collect::<PyResult<Vec<_>>>()?;
        let association = AssociationArgs::from_object(association)?.into_core()?;
        let prior_state: Vec<f64> = item(initiator, "prior_state")?.extract()?;
        let prior_cov: PyReadonlyArray2<'_, f64> =
            item(initiator, "prior_covariance")?.extract()?;
        let m_of_n: Option<(usize, usize)> = item(initiator, "m_of_n")?.extract()?;
        let confirmation = match m_of_n {
            Some((m, n)) => Confirmation::MOfN { m, n },
            None => Confirmation::MinPoints {
                min_points: item(initiator, "min_points")?.extract()?,
                updates_only: get_bool(initiator, "updates_only")?,
            },
        };
        let init_model: Option<Vec<(String, f64)>> = item(initiator, "motion_model")?.extract()?;
        let init = InitiatorConfig {
            prior_state: DVector::from_vec(prior_state),
            prior_covariance: matrix("prior_covariance", &prior_cov)?,
            diag_load: get_f64(initiator, "diag_load")?,
            confirmation,
            deleter: deleter(&item(initiator, "deleter")?)?,
            gnn: GnnParams {
                measure: measure(&get_str(initiator, "measure")?)?,
                missed_distance: get_f64(initiator, "missed_distance")?,
                include_all: get_bool(initiator, "include_all")?,
            },
            motion_model: init_model.map(|m| motion_model_from_spec(&m)).transpose()?,
            use_joseph_cov: get_bool(initiator, "use_joseph_cov")?,
            symmetric_covariance: get_bool(initiator, "symmetric_covariance")?,
            max_new_tentative: item(initiator, "max_new_tentative")?.extract()?,
        };
        let out_of_order = match out_of_order {
            "raise" => OutOfOrder::Raise,
            "drop" => OutOfOrder::Drop,
            other => {
                return Err(PyValueError::new_err(format!(
                    "out_of_order: expected 'raise' or 'drop', got {other:?}"
                )))
            }
        };
        let cfg = TrackerConfig {
            motion_model: model,
            sensors,
            association,
            use_joseph_cov,
            symmetric_covariance,
            deleter: deleter(deleter_spec)?,
            delete_last_prediction,
            initiator: init,
            out_of_order,
            initiate_in_gates,
            imm: imm.map(|s| imm_from_spec(&s)).transpose()?,
            max_deleted,
            existence: existence.map(
                |(survival, initial, delete, vis_stay, invis_stay, confirm, birth)| {
                    crate::tracking::config::Existence {
                        survival,
                        initial,
                        delete,
                        vis_stay,
                        invis_stay,
                        confirm,
                        birth,
                    }
                },
            ),
        };
        Ok(Self {
            inner: Tracker::new(cfg).map_err(to_py_err)?,
        })
    }

    /// Processes one scan (detections with their own noise covariances `(k, m, m)` when
    /// given); returns `(processed, clusters, approximated_clusters, largest_cluster)`,
    /// processed False when it was dropped as out of order. Ctrl-C between JPDA clusters
    /// raises KeyboardInterrupt and leaves the tracker as before the scan.
    #[pyo3(signature = (t, measurements, sensor_ids, covariances=None, origins=None))]
    fn step(
        &mut self,
        py: Python<'_>,
        t: f64,
        measurements: PyReadonlyArray2<'_, f64>,
        sensor_ids: PyReadonlyArray1<'_, i64>,
        covariances: Option<PyReadonlyArray3<'_, f64>>,
        origins: Option<PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<(bool, usize, usize, usize)> {
        let z = slice("measurements", &measurements)?;
        let ids = to_usize("sensor_ids", slice("sensor_ids", &sensor_ids)?)?;
        let covs = covariances
            .as_ref()
            .map(|c| slice("covariances", c))
            .transpose()?;
        let orig = origins.as_ref().map(|o| slice("origins", o)).transpose()?;
        let inner = &mut self.inner;
        let mut signals = SignalCheck::new();
        let res =
            py.detach(|| inner.step_interruptible(t, z, &ids, covs, orig, &mut || signals.poll()));
        let r = signals.result(res)?;
        Ok((
            r.outcome == crate::tracking::tracker::StepOutcome::Processed,
            r.clusters,
            r.approximated_clusters,
            r.largest_cluster,
        ))
    }

    /// Runs a whole recording: scan `i` at `times[i]` holds the detections with
    /// `scan_index == i` (with their own noise covariances `(d, m, m)` when given). Returns,
    /// per scan, the confirmed tracks after it.
    #[pyo3(signature = (times, measurements, sensor_ids, scan_index, covariances=None, origins=None))]
    #[allow(clippy::too_many_arguments)]
    fn run<'py>(
        &mut self,
        py: Python<'py>,
        times: PyReadonlyArray1<'py, f64>,
        measurements: PyReadonlyArray2<'py, f64>,
        sensor_ids: PyReadonlyArray1<'py, i64>,
        scan_index: PyReadonlyArray1<'py, i64>,
        covariances: Option<PyReadonlyArray3<'py, f64>>,
        origins: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let t = slice("times", &times)?;
        let z = slice("measurements", &measurements)?;
        let covs = covariances
            .as_ref()
            .map(|c| slice("covariances", c))
            .transpose()?;
        let orig = origins.as_ref().map(|o| slice("origins", o)).transpose()?;
        let m = self.inner.measurement_dim();
        let ids = to_usize("sensor_ids", slice("sensor_ids", &sensor_ids)?)?;
        let scans = to_usize("scan_index", slice("scan_index", &scan_index)?)?;
        if measurements.shape()[1] != m && !z.is_empty() {
            return Err(to_py_err(Error::dim(
                "measurements",
                format!("{m} columns"),
                measurements.shape()[1],
            )));
        }
        let nd = ids.len();
        if scans.len() != nd || z.len() != nd * m {
            return Err(to_py_err(Error::dim(
                "scan_index",
                format!("{nd} entries, one per measurement row"),
                scans.len(),
            )));
        }
        if let Some(o) = orig {
            if o.len() != nd * 2 {
                return Err(to_py_err(Error::dim(
                    "origins",
                    format!("({nd}, 2) values, one sensor position per measurement row"),
                    o.len(),
                )));
            }
        }
        if let Some(c) = covs {
            if c.len() != nd * m * m {
                return Err(to_py_err(Error::dim(
                    "covariances",
                    format!("({nd}, {m}, {m}) values, one matrix per measurement row"),
                    c.len(),
                )));
            }
        }
        if let Some(p) = scans.iter().position(|&s| s >= t.len()) {
            return Err(to_py_err(Error::param(
                "scan_index",
                format!(
                    "element {p} is {}, but there are {} scans",
                    scans[p],
                    t.len()
                ),
            )));
        }
        let n = self.inner.config().motion_model.ndim();
        let inner = &mut self.inner;
        let input = crate::tracking::run::RunInput {
            times: t,
            z,
            sensor_ids: &ids,
            scan_index: &scans,
            covariances: covs,
            origins: orig,
        };
        let mut signals = SignalCheck::new();
        let res = py.detach(|| inner.run(&input, &mut || signals.poll()));
        let o = signals.result(res)?;
        let r = o.scan.len();
        let (scan, id, time, st, cv, upd) = (
            o.scan,
            o.track_id,
            o.time,
            o.state,
            o.covariance,
            o.is_update,
        );
        let (dropped, approx) = (o.dropped_scans, o.approximated_clusters);
        let d = PyDict::new(py);
        d.set_item("scan", arr_i(py, scan, &[r])?)?;
        d.set_item("track_id", arr_i(py, id, &[r])?)?;
        d.set_item("time", arr_f(py, time, &[r])?)?;
        d.set_item("state", arr_f(py, st, &[r, n])?)?;
        d.set_item("covariance", arr_f(py, cv, &[r, n, n])?)?;
        d.set_item("is_update", PyArray1::from_vec(py, upd))?;
        let nd_ = dropped.len();
        d.set_item("dropped_scans", arr_i(py, dropped, &[nd_])?)?;
        let na = approx.len();
        d.set_item("approximated_clusters", arr_i(py, approx, &[na])?)?;
        Ok(d)
    }

    /// Registers one more sensor between scans; returns its index.
    #[pyo3(signature = (measurement_matrix, measurement_noise, initiation_matrix=None, initiation_noise=None, polar=None))]
    fn add_sensor(
        &mut self,
        measurement_matrix: PyReadonlyArray2<'_, f64>,
        measurement_noise: PyReadonlyArray2<'_, f64>,
        initiation_matrix: Option<PyReadonlyArray2<'_, f64>>,
        initiation_noise: Option<PyReadonlyArray2<'_, f64>>,
        polar: Option<PolarSpec>,
    ) -> PyResult<usize> {
        let n = self.inner.config().motion_model.ndim();
        let i = self.inner.config().sensors.len();
        let sensor = sensor_from_arrays(
            &measurement_matrix,
            &measurement_noise,
            initiation_matrix.as_ref(),
            initiation_noise.as_ref(),
            polar.as_ref(),
            n,
            i,
        )?;
        self.inner.add_sensor(sensor).map_err(to_py_err)
    }

    /// Adds a confirmed track; returns its id.
    fn add_track(
        &mut self,
        state: PyReadonlyArray1<'_, f64>,
        covariance: PyReadonlyArray2<'_, f64>,
        time: f64,
    ) -> PyResult<u64> {
        self.inner
            .add_track(
                slice("state", &state)?,
                slice("covariance", &covariance)?,
                time,
            )
            .map_err(to_py_err)
    }

    /// Current confirmed tracks (or tentative ones) as arrays.
    #[pyo3(signature = (tentative=false))]
    fn snapshot<'py>(&self, py: Python<'py>, tentative: bool) -> PyResult<Bound<'py, PyDict>> {
        let n = self.inner.config().motion_model.ndim();
        let list = if tentative {
            &self.inner.tentative
        } else {
            &self.inner.tracks
        };
        let k = list.len();
        let d = PyDict::new(py);
        d.set_item(
            "ids",
            arr_i(py, list.iter().map(|t| t.id as i64).collect(), &[k])?,
        )?;
        d.set_item(
            "times",
            arr_f(py, list.iter().map(|t| t.t).collect(), &[k])?,
        )?;
        d.set_item(
            "states",
            arr_f(
                py,
                list.iter().flat_map(|t| t.x.iter().copied()).collect(),
                &[k, n],
            )?,
        )?;
        d.set_item(
            "covariances",
            arr_f(
                py,
                list.iter()
                    .flat_map(|t| t.p.transpose().iter().copied().collect::<Vec<_>>())
                    .collect(),
                &[k, n, n],
            )?,
        )?;
        d.set_item(
            "is_update",
            PyArray1::from_vec(
                py,
                list.iter()
                    .map(|t| *t.history.is_update.last().unwrap_or(&false))
                    .collect::<Vec<bool>>(),
            ),
        )?;
        d.set_item(
            "n_updates",
            arr_i(
                py,
                list.iter().map(|t| t.n_updates() as i64).collect(),
                &[k],
            )?,
        )?;
        // The newest history entry's association data, flattened over the tracks.
        let last = |t: &Track| t.history.len().saturating_sub(1);
        let lasti = |f: fn(&crate::tracking::track::History) -> &Vec<i64>| -> Vec<i64> {
            list.iter().map(|t| f(&t.history)[last(t)]).collect()
        };
        d.set_item("scan", arr_i(py, lasti(|h| &h.scan), &[k])?)?;
        d.set_item(
            "first_scan",
            arr_i(
                py,
                list.iter()
                    .map(|t| *t.history.scan.first().unwrap_or(&-1))
                    .collect(),
                &[k],
            )?,
        )?;
        d.set_item("detection", arr_i(py, lasti(|h| &h.detection), &[k])?)?;
        // NIS of the newest entry where it is an update with a detection's innovation (the
        // most probable detection under JPDA), 0 with 0 degrees of freedom elsewhere.
        let m = self.inner.measurement_dim();
        let nis: Vec<f64> = list
            .iter()
            .map(|t| t.history.nis[last(t)])
            .map(|v| if v.is_finite() { v } else { 0.0 })
            .collect();
        let dof: Vec<i64> = list
            .iter()
            .map(|t| {
                let h = &t.history;
                if h.is_update[last(t)] && h.nis[last(t)].is_finite() {
                    m as i64
                } else {
                    0
                }
            })
            .collect();
        d.set_item("nis", arr_f(py, nis, &[k])?)?;
        // IMM mode probabilities (k, r); (k, 0) without an IMM.
        let imm = self.inner.config().imm.as_ref();
        let r = imm.map_or(0, |c| c.modes.len());
        let mu: Vec<f64> = list
            .iter()
            .flat_map(|t| match (&t.imm, imm) {
                (Some(st), _) => st.mu.clone(),
                (None, Some(c)) => c.initial.clone(),
                (None, None) => vec![],
            })
            .collect();
        d.set_item("mode_probabilities", arr_f(py, mu, &[k, r])?)?;
        // Existence / visibility (1 without an existence model or before the first scan).
        let init = self.inner.config().existence.map_or(1.0, |e| e.initial);
        let ex: Vec<(f64, f64)> = list
            .iter()
            .map(|t| t.existence.unwrap_or((init, 1.0)))
            .collect();
        d.set_item(
            "existence",
            arr_f(py, ex.iter().map(|e| e.0).collect(), &[k])?,
        )?;
        d.set_item(
            "visibility",
            arr_f(py, ex.iter().map(|e| e.1).collect(), &[k])?,
        )?;
        d.set_item("nis_dof", arr_i(py, dof, &[k])?)?;
        d.set_item(
            "missed_probability",
            arr_f(
                py,
                list.iter()
                    .map(|t| t.history.missed_probability[last(t)])
                    .collect(),
                &[k],
            )?,
        )?;
        let mut offsets = Vec::with_capacity(k + 1);
        let (mut dets, mut probs) = (Vec::new(), Vec::new());
        offsets.push(0i64);
        for t in list {
            let h = &t.history;
            let (a, b) = (h.assoc_offsets[last(t)], h.assoc_offsets[last(t) + 1]);
            dets.extend_from_slice(&h.assoc_detection[a..b]);
            probs.extend_from_slice(&h.assoc_probability[a..b]);
            offsets.push(dets.len() as i64);
        }
        let nd = dets.len();
        d.set_item("assoc_offsets", arr_i(py, offsets, &[k + 1])?)?;
        d.set_item("assoc_detection", arr_i(py, dets, &[nd])?)?;
        d.set_item("assoc_probability", arr_f(py, probs, &[nd])?)?;
        Ok(d)
    }

    /// Ids of alive confirmed tracks and of deleted ones.
    fn track_ids<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let a: Vec<i64> = self.inner.tracks.iter().map(|t| t.id as i64).collect();
        let b: Vec<i64> = self.inner.deleted.iter().map(|t| t.id as i64).collect();
        let (na, nb) = (a.len(), b.len());
        Ok((arr_i(py, a, &[na])?, arr_i(py, b, &[nb])?))
    }

    /// Full history of a confirmed (alive or deleted) track.
    fn history<'py>(&self, py: Python<'py>, track_id: u64) -> PyResult<Bound<'py, PyDict>> {
        let n = self.inner.config().motion_model.ndim();
        let tr = self
            .inner
            .tracks
            .iter()
            .chain(self.inner.deleted.iter())
            .find(|t| t.id == track_id)
            .ok_or_else(|| PyValueError::new_err(format!("track_id: no track {track_id}")))?;
        history_dict(py, tr, n)
    }

    /// An independent copy of the whole tracker state (configuration, tracks, histories).
    fn copy(&self) -> Self {
        Self {
            inner: self.inner.clone(),
        }
    }

    /// The whole tracker state as bytes (for pickling; see `from_bytes`).
    fn to_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, pyo3::types::PyBytes>> {
        let b = self.inner.to_bytes().map_err(to_py_err)?;
        Ok(pyo3::types::PyBytes::new(py, &b))
    }

    /// A tracker core from `to_bytes` output; it continues exactly as the saved one.
    #[staticmethod]
    fn from_bytes(state: &[u8]) -> PyResult<Self> {
        Ok(Self {
            inner: Tracker::from_bytes(state).map_err(to_py_err)?,
        })
    }

    /// Removes the deleted tracks kept so far and returns their histories.
    fn drain_deleted<'py>(&mut self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let n = self.inner.config().motion_model.ndim();
        self.inner
            .drain_deleted()
            .iter()
            .map(|t| history_dict(py, t, n))
            .collect()
    }

    /// Detections that started no tentative track because of the per-scan cap.
    #[getter]
    fn capped_detections(&self) -> usize {
        self.inner.capped_detections
    }

    /// Scans dropped for being out of order.
    #[getter]
    fn dropped_scans(&self) -> usize {
        self.inner.dropped_scans
    }

    /// Time of the last processed scan (None before the first).
    #[getter]
    fn last_time(&self) -> Option<f64> {
        self.inner.last_time()
    }
}

fn to_usize(name: &str, v: &[i64]) -> PyResult<Vec<usize>> {
    if let Some(p) = v.iter().position(|&x| x < 0) {
        return Err(to_py_err(Error::param(
            name,
            format!("element {p} is negative ({})", v[p]),
        )));
    }
    Ok(v.iter().map(|&x| x as usize).collect())
}

/// Optimal assignment of a `(nr, nc)` cost matrix (`nr <= nc`, `inf` forbidden): the column
/// of each row.
#[pyfunction]
fn linear_sum_assignment<'py>(
    py: Python<'py>,
    cost: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let s = cost.shape();
    let (nr, nc) = (s[0], s[1]);
    let c = slice("cost", &cost)?;
    let sol = py
        .detach(|| crate::tracking::assign::linear_sum_assignment(c, nr, nc))
        .map_err(to_py_err)?;
    arr_i(py, sol.into_iter().map(|j| j as i64).collect(), &[nr])
}

/// JPDA marginals of one cluster: `likelihoods` is `(tracks, 1 + detections)`, column 0 the
/// missed-detection weight, a weight `<= 0` in another column meaning "not gated".
#[pyfunction]
#[pyo3(signature = (likelihoods, method="ehm"))]
fn jpda_marginals<'py>(
    py: Python<'py>,
    likelihoods: PyReadonlyArray2<'py, f64>,
    method: &str,
) -> PyResult<Bound<'py, PyAny>> {
    let meth = self::method(method)?;
    let s = likelihoods.shape();
    let (nt, nc) = (s[0], s[1]);
    if nc == 0 {
        return Err(to_py_err(Error::dim(
            "likelihoods",
            "at least one column",
            0,
        )));
    }
    let l = slice("likelihoods", &likelihoods)?;
    let cluster: Vec<TrackHypotheses> = (0..nt)
        .map(|t| TrackHypotheses {
            missed: l[t * nc],
            detections: (1..nc)
                .filter(|&j| l[t * nc + j] > 0.0 || l[t * nc + j].is_nan())
                .map(|j| (j - 1, l[t * nc + j]))
                .collect(),
        })
        .collect();
    let m = py.detach(|| marginals(&cluster, meth)).map_err(to_py_err)?;
    let mut out = vec![0.0; nt * nc];
    for (t, (mm, h)) in m.iter().zip(&cluster).enumerate() {
        out[t * nc] = mm.missed;
        for (p, &(j, _)) in mm.detections.iter().zip(&h.detections) {
            out[t * nc + j + 1] = *p;
        }
    }
    arr_f(py, out, &[nt, nc])
}

/// The chi-square quantile `chi2.ppf(prob_gate, dof)`.
#[pyfunction]
fn chi2_gate(prob_gate: f64, dof: i64) -> PyResult<f64> {
    if dof < 1 {
        return Err(to_py_err(crate::Error::param(
            "dof",
            format!("must be an integer >= 1, got {dof}"),
        )));
    }
    chi2_quantile(prob_gate, dof as usize).map_err(to_py_err)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<TrackerCore>()?;
    m.add_function(wrap_pyfunction!(linear_sum_assignment, m)?)?;
    m.add_function(wrap_pyfunction!(jpda_marginals, m)?)?;
    m.add_function(wrap_pyfunction!(chi2_gate, m)?)?;
    Ok(())
}
