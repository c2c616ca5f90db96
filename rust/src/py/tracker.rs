//! Bindings of the multi-target tracker (`TrackerCore`) and of its association kernels
//! (`linear_sum_assignment`, `jpda_marginals`, `chi2_gate`). The Python API is
//! `usvfast.tracking`; these take pre-validated float64 C-contiguous arrays.

use super::to_py_err;
use super::tracker_config::{
    typed, AssociationArgs, DeleterArgs, ExistenceArgs, ImmArgs, InitiatorArgs, ModelArgs,
    SensorArgs,
};
use crate::error::Error;
use crate::tracking::tracker::{OutOfOrder, Tracker, TrackerConfig};
use numpy::{
    PyArray1, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

mod arrays;
mod association;

use arrays::{arr_f, arr_i, history_dict};

fn slice<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    name: &str,
    a: &'a numpy::PyReadonlyArray<'_, T, D>,
) -> PyResult<&'a [T]> {
    super::slice(name, a)
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
    pub(crate) inner: Tracker,
}

impl TrackerCore {
    /// `step` on validated slices (for the other bindings, e.g. the Stone Soup drop-in's
    /// one-call scan): the core runs without the GIL, Ctrl-C between JPDA clusters raises.
    pub(crate) fn step_slices(
        &mut self,
        py: Python<'_>,
        t: f64,
        z: &[f64],
        ids: &[usize],
        covs: Option<&[f64]>,
        orig: Option<&[f64]>,
    ) -> PyResult<crate::tracking::tracker::StepReport> {
        let inner = &mut self.inner;
        let mut signals = SignalCheck::new();
        let res =
            py.detach(|| inner.step_interruptible(t, z, ids, covs, orig, &mut || signals.poll()));
        signals.result(res)
    }
}

#[pymethods]
impl TrackerCore {
    /// A tracker from the `usvfast.tracking` configuration objects, each read by attribute
    /// (see `tracker_config`): a motion model, `Sensor`s, `JPDA`/`GNN`, a deleter,
    /// `MultiMeasurementInitiator`, and optionally `IMM` and `Existence`.
    #[new]
    #[pyo3(signature = (
        motion_model, sensors, association, deleter, initiator, *,
        use_joseph_cov=false, delete_last_prediction=false, out_of_order="raise",
        initiate_in_gates=true, symmetric_covariance=false, imm=None, existence=None,
        max_deleted=None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        motion_model: &Bound<'_, PyAny>,
        sensors: Vec<Bound<'_, PyAny>>,
        association: &Bound<'_, PyAny>,
        deleter: &Bound<'_, PyAny>,
        initiator: &Bound<'_, PyAny>,
        use_joseph_cov: bool,
        delete_last_prediction: bool,
        out_of_order: &str,
        initiate_in_gates: bool,
        symmetric_covariance: bool,
        imm: Option<Bound<'_, PyAny>>,
        existence: Option<Bound<'_, PyAny>>,
        max_deleted: Option<usize>,
    ) -> PyResult<Self> {
        let model =
            typed::<ModelArgs>(motion_model, "motion_model", "a motion model")?.into_core()?;
        let n = model.ndim();
        let sensors = sensors
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let arg = format!("sensors[{i}]");
                typed::<SensorArgs>(s, &arg, "Sensor")?.into_core(n, &arg)
            })
            .collect::<PyResult<Vec<_>>>()?;
        let association = AssociationArgs::from_object(association)?.into_core()?;
        let init = typed::<InitiatorArgs>(initiator, "initiator", "MultiMeasurementInitiator")?
            .into_core()?;
        let deleter = typed::<DeleterArgs>(deleter, "deleter", "a deleter")?.0;
        let imm = imm
            .map(|o| typed::<ImmArgs>(&o, "imm", "IMM")?.into_core())
            .transpose()?;
        let existence = existence
            .map(|o| typed::<ExistenceArgs>(&o, "existence", "Existence").map(|e| e.into_core()))
            .transpose()?;
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
            deleter,
            delete_last_prediction,
            initiator: init,
            out_of_order,
            initiate_in_gates,
            imm,
            max_deleted,
            existence,
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
        let r = self.step_slices(py, t, z, &ids, covs, orig)?;
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

    /// Registers one more `Sensor` between scans; returns its index.
    fn add_sensor(&mut self, sensor: &Bound<'_, PyAny>) -> PyResult<usize> {
        let n = self.inner.config().motion_model.ndim();
        let sensor = typed::<SensorArgs>(sensor, "sensor", "Sensor")?.into_core(n, "sensor")?;
        self.inner.add_sensor(sensor).map_err(to_py_err)
    }

    /// The measurement dimension `m` shared by the sensors.
    #[getter]
    fn measurement_dim(&self) -> usize {
        self.inner.measurement_dim()
    }

    /// Adds a confirmed track, with its existence and visibility `(r, v)` if given; returns
    /// its id.
    #[pyo3(signature = (state, covariance, time, existence=None))]
    fn add_track(
        &mut self,
        state: PyReadonlyArray1<'_, f64>,
        covariance: PyReadonlyArray2<'_, f64>,
        time: f64,
        existence: Option<(f64, f64)>,
    ) -> PyResult<u64> {
        self.inner
            .add_track_with(
                slice("state", &state)?,
                slice("covariance", &covariance)?,
                time,
                existence,
            )
            .map_err(to_py_err)
    }

    /// Current confirmed tracks (or tentative ones) as arrays.
    #[pyo3(signature = (tentative=false))]
    fn snapshot<'py>(&self, py: Python<'py>, tentative: bool) -> PyResult<Bound<'py, PyDict>> {
        arrays::snapshot_dict(py, &self.inner, tentative)
    }

    /// Ids of alive confirmed tracks and of deleted ones.
    fn track_ids<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
        let a: Vec<i64> = self.inner.tracks.iter().map(|t| t.id as i64).collect();
        let b: Vec<i64> = self.inner.deleted.iter().map(|t| t.id as i64).collect();
        let (na, nb) = (a.len(), b.len());
        Ok((arr_i(py, a, &[na])?, arr_i(py, b, &[nb])?))
    }

    /// History of a confirmed (alive or deleted) track: its entries `start..` (all by
    /// default), `assoc_offsets` rebased to the first of them.
    #[pyo3(signature = (track_id, start=0))]
    fn history<'py>(
        &self,
        py: Python<'py>,
        track_id: u64,
        start: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let n = self.inner.config().motion_model.ndim();
        let tr = self
            .inner
            .tracks
            .iter()
            .chain(self.inner.deleted.iter())
            .find(|t| t.id == track_id)
            .ok_or_else(|| PyValueError::new_err(format!("track_id: no track {track_id}")))?;
        history_dict(py, tr, n, start)
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
            .map(|t| history_dict(py, t, n, 0))
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

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<TrackerCore>()?;
    m.add_function(wrap_pyfunction!(association::linear_sum_assignment, m)?)?;
    m.add_function(wrap_pyfunction!(association::jpda_marginals, m)?)?;
    m.add_function(wrap_pyfunction!(association::chi2_gate, m)?)?;
    Ok(())
}
