//! Stone Soup objects for the drop-in trackers (`usvfast.stonesoup`), built in one call per
//! scan: `StoneSoupKit.newest` appends nothing itself; it returns, for each confirmed track
//! asked for, the Stone Soup state its newest history entry becomes — a `GaussianStateUpdate`
//! with its association hypothesis (JPDA `MultipleHypothesis` of `SingleProbabilityHypothesis`
//! with `Probability` values, or GNN `SingleDistanceHypothesis`), the predictor's prediction
//! from the track's previous state, the measurement predictions (H x, H P Hᵀ + R, P Hᵀ) — or a
//! `GaussianStatePrediction` for a missed scan.
//!
//! Objects are made as `usvfast.stonesoup_objects` makes them (its "fast path"): `cls.__new__`
//! and a `__dict__` of `_property_<name>` entries in the class's order, from the builder
//! specifications that module checked against Stone Soup's own constructors. Arrays are views
//! (rows of one array per scan) of Stone Soup's `StateVector`, `CovarianceMatrix` and `Matrix`.
//! A track this cannot build exactly (a non-linear measurement model, a measure other than
//! (squared) Mahalanobis, a history that is not one entry per scan) comes back as None; the
//! Python builder makes it.

use super::tracker::TrackerCore;
use nalgebra::{DMatrix, DVector};
use numpy::npyffi::{npy_intp, PY_ARRAY_API};
use numpy::{Element, PyArrayDescrMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyType};
use std::collections::HashMap;

mod builder;
mod gather;

use builder::Builder;

// Builder order (`usvfast.stonesoup_objects.StoneSoupObjects.kit_specs`).
const PRED: usize = 0; // GaussianStatePrediction(state_vector, covar, timestamp)
const PRED_OF: usize = 1; // ... (state_vector, covar, timestamp, transition_model, prior)
const MPRED: usize = 2; // GaussianMeasurementPrediction(state_vector, covar, timestamp, cross_covar)
const UPD: usize = 3; // GaussianStateUpdate(state_vector, covar, hypothesis, timestamp)
const MISSED: usize = 4; // MissedDetection(timestamp, metadata)
const SINGLE: usize = 5; // SingleHypothesis(prediction, measurement)
const PROB: usize = 6; // SingleProbabilityHypothesis(prediction, measurement, probability, mp)
const DIST: usize = 7; // SingleDistanceHypothesis(prediction, measurement, distance, mp)
const MULTI: usize = 8; // MultipleHypothesis(single_hypotheses)
const PROBABILITY: usize = 9; // Probability: `_log_value`
const N_BUILDERS: usize = 10;

/// A linear measurement model's H (m, n) and R (m, m), None for any other model.
type Linear = Option<std::sync::Arc<(DMatrix<f64>, DMatrix<f64>)>>;

/// At most this many measurement models remembered (one per detection for a moving radar).
const MODEL_CACHE: usize = 4096;

/// The Stone Soup object factory of one drop-in tracker (see the module docs).
#[pyclass(module = "usvfast._core")]
pub struct StoneSoupKit {
    b: Vec<Builder>,
    /// `StateVector`, `CovarianceMatrix`, `Matrix`.
    arrays: [Py<PyAny>; 3],
    float64: Py<PyAny>,
    weakref: Py<PyAny>,
    /// `linear_model(model) -> (H, Hᵀ, R) | None` of the tracker's updater.
    linear_model: Py<PyAny>,
    /// The tracker's GNN measure: 1 Mahalanobis, 2 squared Mahalanobis, 0 other.
    measure: u8,
    models: HashMap<usize, (Py<PyAny>, Linear)>,
}

/// A measurement prediction of one model (by pointer): z = H x (m), S = H P Hᵀ + R (m, m),
/// C = P Hᵀ (n, m).
struct MeasurementPrediction {
    model: usize,
    z: DVector<f64>,
    s: DMatrix<f64>,
    c: DMatrix<f64>,
}

/// What one track's newest state needs, gathered before any object is made.
struct Row {
    /// History entry (row-major state and covariance) of the newest state.
    last: usize,
    update: bool,
    /// Predicted mean and covariance, when a prediction object is made.
    pred: Option<(DVector<f64>, DMatrix<f64>)>,
    /// Detections (rows of the scan) with their probabilities, the missed probability, the
    /// chosen detection.
    assoc: Vec<(usize, f64)>,
    missed: f64,
    det: i64,
    /// The GNN measure between the chosen detection and its measurement prediction.
    distance: f64,
    /// Measurement predictions of the distinct models of the gated detections, and per gated
    /// detection its index there.
    mps: Vec<MeasurementPrediction>,
    mp_of: Vec<usize>,
}

/// `m` as row-major values (what [`StoneSoupKit::array`] takes).
fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

impl StoneSoupKit {
    /// H and R of a detection's measurement model (cached by identity).
    fn linear<'py>(&mut self, model: &Bound<'py, PyAny>) -> PyResult<Linear> {
        let key = model.as_ptr() as usize;
        if let Some((_, hr)) = self.models.get(&key) {
            return Ok(hr.clone());
        }
        let got = self.linear_model.bind(model.py()).call1((model,))?;
        let hr = if got.is_none() {
            None
        } else {
            let (h, _ht, r): (
                PyReadonlyArray2<'py, f64>,
                Bound<'py, PyAny>,
                PyReadonlyArray2<'py, f64>,
            ) = got.extract()?;
            let (hs, rs) = (h.shape(), r.shape());
            let h = DMatrix::from_row_slice(hs[0], hs[1], super::slice("H", &h)?);
            let r = DMatrix::from_row_slice(rs[0], rs[1], super::slice("R", &r)?);
            Some(std::sync::Arc::new((h, r)))
        };
        if self.models.len() >= MODEL_CACHE {
            self.models.clear();
        }
        self.models
            .insert(key, (model.clone().unbind(), hr.clone()));
        Ok(hr)
    }

    /// A new C-contiguous float64 array `(rows, cols)` of class `arrays[cls]` (an ndarray
    /// subclass: numpy makes it as it makes that class's views) holding `data` (row-major).
    fn array<'py>(
        &self,
        py: Python<'py>,
        cls: usize,
        rows: usize,
        cols: usize,
        data: &[f64],
    ) -> PyResult<Bound<'py, PyAny>> {
        debug_assert_eq!(data.len(), rows * cols);
        let mut dims = [rows as npy_intp, cols as npy_intp];
        let sub = self.arrays[cls].bind(py).cast::<PyType>()?;
        // SAFETY: numpy's constructor with a float64 descriptor, two dimensions, no strides
        // and no data allocates a fresh C-contiguous (rows, cols) float64 array (of the
        // subclass `sub`); nothing else sees it before its rows * cols values are written.
        unsafe {
            let ptr = PY_ARRAY_API.PyArray_NewFromDescr(
                py,
                sub.as_type_ptr(),
                f64::get_dtype(py).into_dtype_ptr(),
                2,
                dims.as_mut_ptr(),
                std::ptr::null_mut(),
                std::ptr::null_mut(),
                0,
                std::ptr::null_mut(),
            );
            let obj = Bound::from_owned_ptr_or_err(py, ptr)?;
            let out = (*ptr.cast::<numpy::npyffi::PyArrayObject>())
                .fields
                .data
                .cast::<f64>();
            std::ptr::copy_nonoverlapping(data.as_ptr(), out, data.len());
            Ok(obj)
        }
    }

    /// Stone Soup's `Prediction` constructor's change to its prior: the prior's hypothesis's
    /// prediction keeps its own prior as a weak reference.
    fn predicted_from(&self, py: Python<'_>, prior: &Bound<'_, PyAny>) -> PyResult<()> {
        let hyp = if prior.get_type().is(self.b[UPD].cls.bind(py)) {
            // Its `__dict__` entry, read without materialising the dict.
            prior.getattr(intern!(py, "_property_hypothesis"))?
        } else if prior.get_type().is(self.b[PRED].cls.bind(py)) {
            return Ok(()); // a GaussianStatePrediction has no hypothesis
        } else {
            match prior.getattr(intern!(py, "hypothesis")) {
                Ok(h) => h,
                Err(e) if e.is_instance_of::<pyo3::exceptions::PyAttributeError>(py) => {
                    return Ok(())
                }
                Err(e) => return Err(e),
            }
        };
        if hyp.is_none() || hyp.get_type().is(self.b[MULTI].cls.bind(py)) {
            return Ok(()); // a MultipleHypothesis has no prediction
        }
        let older = match hyp.getattr(intern!(py, "prediction")) {
            Ok(o) => o,
            Err(e) if e.is_instance_of::<pyo3::exceptions::PyAttributeError>(py) => return Ok(()),
            Err(e) => return Err(e),
        };
        if older.is_none() {
            return Ok(());
        }
        let d = older.getattr(intern!(py, "__dict__"))?;
        let d = d.cast::<PyDict>()?;
        if let Some(back) = d.get_item(intern!(py, "_property_prior"))? {
            let weak = self.weakref.bind(py);
            if !back.is_none() && !back.is_instance(weak)? {
                d.set_item(intern!(py, "_property_prior"), weak.call1((back,))?)?;
            }
        }
        Ok(())
    }

    fn probability<'py>(&self, py: Python<'py>, p: f64) -> PyResult<Bound<'py, PyAny>> {
        let b = &self.b[PROBABILITY];
        if p > 0.0 {
            let v = p.ln().into_pyobject(py)?.into_any();
            return b.make(py, &[&v]);
        }
        b.cls.bind(py).call1((p,))
    }
}

#[pymethods]
impl StoneSoupKit {
    /// A kit from the builder specifications `(cls.__new__, cls, keys, template or None)` of
    /// `usvfast.stonesoup_objects` (order: see there), the array classes `(StateVector,
    /// CovarianceMatrix, Matrix)`, the tracker's `linear_model(model) -> (H, Hᵀ, R) | None`
    /// and its measure (1 Mahalanobis, 2 squared Mahalanobis, 0 other).
    #[new]
    fn new(
        builders: Vec<Bound<'_, PyAny>>,
        arrays: (Bound<'_, PyAny>, Bound<'_, PyAny>, Bound<'_, PyAny>),
        linear_model: Bound<'_, PyAny>,
        measure: u8,
    ) -> PyResult<Self> {
        if builders.len() != N_BUILDERS {
            return Err(PyValueError::new_err(format!(
                "builders: expected {N_BUILDERS} specifications, got {}",
                builders.len()
            )));
        }
        let py = linear_model.py();
        let np = py.import("numpy")?;
        Ok(Self {
            b: builders
                .iter()
                .map(Builder::from_spec)
                .collect::<PyResult<_>>()?,
            arrays: [arrays.0.unbind(), arrays.1.unbind(), arrays.2.unbind()],
            float64: np.getattr("float64")?.unbind(),
            weakref: py.import("weakref")?.getattr("ref")?.unbind(),
            linear_model: linear_model.unbind(),
            measure,
            models: HashMap::new(),
        })
    }

    /// One object of builder `index` with `values` (to check the kit against Stone Soup's
    /// constructors).
    fn make<'py>(
        &self,
        py: Python<'py>,
        index: usize,
        values: Vec<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let b = self.b.get(index).ok_or_else(|| {
            PyValueError::new_err(format!("index: expected < {N_BUILDERS}, got {index}"))
        })?;
        let refs: Vec<&Bound<'py, PyAny>> = values.iter().collect();
        b.make(py, &refs)
    }

    /// The newest states of confirmed tracks `ids` of `core` at scan `scan` (their previous
    /// states `priors`, built at scan − 1, `dt` seconds earlier): (whether a detection of the
    /// scan carries metadata, a list with, per track, its Stone Soup state or None where this
    /// cannot build it exactly (see the module docs)).
    /// `transition` (F, Q) over dt; `detections` the scan's Detection objects, `models` their
    /// measurement models, `z` (k, m) their measurements; `timestamp` the scan's datetime,
    /// `transition_model` the predictor's; `mixture`: JPDA hypotheses (else GNN);
    /// `hypotheses` False: updates carry `SingleHypothesis(None, MissedDetection)`;
    /// `has_metadata` the caller's answer to whether a detection carries metadata (None: read
    /// here).
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (
        core, scan, ids, priors, dt, transition, detections, models, z, timestamp,
        transition_model, mixture, hypotheses, has_metadata=None
    ))]
    fn newest<'py>(
        &mut self,
        py: Python<'py>,
        core: PyRef<'py, TrackerCore>,
        scan: i64,
        ids: Vec<u64>,
        priors: Vec<Bound<'py, PyAny>>,
        dt: f64,
        transition: (PyReadonlyArray2<'py, f64>, PyReadonlyArray2<'py, f64>),
        detections: Bound<'py, PyList>,
        models: Bound<'py, PyList>,
        z: PyReadonlyArray2<'py, f64>,
        timestamp: Bound<'py, PyAny>,
        transition_model: Bound<'py, PyAny>,
        mixture: bool,
        hypotheses: bool,
        has_metadata: Option<bool>,
    ) -> PyResult<(bool, Bound<'py, PyList>)> {
        let inner = &core.inner;
        let n = inner.config().motion_model.ndim();
        let (fm, q) = (&transition.0, &transition.1);
        if fm.shape() != [n, n] || q.shape() != [n, n] {
            return Err(PyValueError::new_err(format!(
                "transition: expected two ({n}, {n}) matrices"
            )));
        }
        if ids.len() != priors.len() {
            return Err(PyValueError::new_err("priors: one per track id"));
        }
        let k_det = detections.len();
        if models.len() != k_det || z.shape()[0] != k_det {
            return Err(PyValueError::new_err(
                "models, z: one per detection of the scan",
            ));
        }
        let fm = DMatrix::from_row_slice(n, n, super::slice("F", fm)?);
        let q = DMatrix::from_row_slice(n, n, super::slice("Q", q)?);
        let zm = z.shape()[1];
        let zs = super::slice("z", &z)?;
        // Index of a confirmed track by id: the core keeps them in order of id (binary
        // search), with a scan as the fallback should that order ever not hold.
        let index_of = |id: u64| {
            let ts = &inner.tracks;
            ts.binary_search_by_key(&id, |t| t.id)
                .ok()
                .or_else(|| ts.iter().position(|t| t.id == id))
        };

        // Gather every number first (no object is made for a track that falls back).
        let mut rows: Vec<Option<Row>> = Vec::with_capacity(ids.len());
        for id in &ids {
            let track = index_of(*id).map(|i| &inner.tracks[i]);
            let newest = track.and_then(|t| {
                let len = t.history.times.len();
                (len > 0 && t.history.scan[len - 1] == scan).then_some((t, len - 1))
            });
            rows.push(match newest {
                Some((t, last)) => self.gather(
                    &models,
                    t,
                    last,
                    dt,
                    (&fm, &q),
                    (zs, zm),
                    mixture,
                    hypotheses,
                )?,
                None => None,
            });
        }

        // Whether a detection carries metadata (Stone Soup's `Track.append` then merges it).
        let has_metadata = match has_metadata {
            Some(md) => md,
            None => {
                let mut md = false;
                for d in detections.iter() {
                    if d.getattr(intern!(py, "metadata"))?.is_truthy()? {
                        md = true;
                        break;
                    }
                }
                md
            }
        };
        let out = PyList::empty(py);
        let ctx = Scan {
            detections: &detections,
            timestamp: &timestamp,
            transition_model: &transition_model,
            mixture,
            hypotheses,
        };
        for ((row, prior), id) in rows.iter().zip(&priors).zip(&ids) {
            match (row, index_of(*id)) {
                (Some(r), Some(i)) => {
                    let h = &inner.tracks[i].history;
                    out.append(self.state(py, r, h, prior, &ctx, (n, zm))?)?;
                }
                _ => out.append(py.None())?,
            }
        }
        Ok((has_metadata, out))
    }

    /// The Stone Soup states of history entries `first`, `first` + 1, ... of track `track_id`
    /// of `core` (alive or deleted), each after the tracker's confirmation (JPDA or GNN as in
    /// `newest`), built one after the other: `prior` the state before entry `first`, then
    /// each state the next one's prior. Per entry: `dts` seconds since the entry before,
    /// `transitions` (F, Q) over it, its scan's `detections`, their `models` and measurements
    /// `zs` (k, m), `timestamps` the scan's datetime. Stops before the first entry it cannot
    /// build exactly (see the module docs): the list may be shorter than `dts`.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (
        core, track_id, first, prior, dts, transitions, detections, models, zs, timestamps,
        transition_model, mixture, hypotheses
    ))]
    fn entries<'py>(
        &mut self,
        py: Python<'py>,
        core: PyRef<'py, TrackerCore>,
        track_id: u64,
        first: usize,
        prior: Bound<'py, PyAny>,
        dts: Vec<f64>,
        transitions: Vec<(PyReadonlyArray2<'py, f64>, PyReadonlyArray2<'py, f64>)>,
        detections: Vec<Bound<'py, PyList>>,
        models: Vec<Bound<'py, PyList>>,
        zs: Vec<PyReadonlyArray2<'py, f64>>,
        timestamps: Vec<Bound<'py, PyAny>>,
        transition_model: Bound<'py, PyAny>,
        mixture: bool,
        hypotheses: bool,
    ) -> PyResult<Bound<'py, PyList>> {
        let k = dts.len();
        if [
            transitions.len(),
            detections.len(),
            models.len(),
            zs.len(),
            timestamps.len(),
        ]
        .iter()
        .any(|&l| l != k)
        {
            return Err(PyValueError::new_err(
                "transitions, detections, models, zs, timestamps: one per entry of dts",
            ));
        }
        let inner = &core.inner;
        let n = inner.config().motion_model.ndim();
        let out = PyList::empty(py);
        let Some(tr) = inner
            .tracks
            .iter()
            .chain(inner.deleted.iter())
            .find(|t| t.id == track_id)
        else {
            return Ok(out);
        };
        let mut prior = prior;
        for i in 0..k {
            let (fm, q) = (&transitions[i].0, &transitions[i].1);
            if fm.shape() != [n, n] || q.shape() != [n, n] {
                return Err(PyValueError::new_err(format!(
                    "transitions: expected two ({n}, {n}) matrices"
                )));
            }
            let (dets, mods, z) = (&detections[i], &models[i], &zs[i]);
            if mods.len() != dets.len() || z.shape()[0] != dets.len() {
                return Err(PyValueError::new_err(
                    "models, zs: one per detection of the entry's scan",
                ));
            }
            let fm = DMatrix::from_row_slice(n, n, super::slice("F", fm)?);
            let q = DMatrix::from_row_slice(n, n, super::slice("Q", q)?);
            let zm = z.shape()[1];
            let zsl = super::slice("zs", z)?;
            let last = first + i;
            let Some(row) = self.gather(
                mods,
                tr,
                last,
                dts[i],
                (&fm, &q),
                (zsl, zm),
                mixture,
                hypotheses,
            )?
            else {
                break;
            };
            let ctx = Scan {
                detections: dets,
                timestamp: &timestamps[i],
                transition_model: &transition_model,
                mixture,
                hypotheses,
            };
            let state = self.state(py, &row, &tr.history, &prior, &ctx, (n, zm))?;
            out.append(&state)?;
            prior = state;
        }
        Ok(out)
    }
}

/// What the states of one scan share: its Detection objects and datetime, the predictor's
/// transition model, JPDA (else GNN) hypotheses, whether hypotheses are built at all.
struct Scan<'a, 'py> {
    detections: &'a Bound<'py, PyList>,
    timestamp: &'a Bound<'py, PyAny>,
    transition_model: &'a Bound<'py, PyAny>,
    mixture: bool,
    hypotheses: bool,
}

impl StoneSoupKit {
    /// The Stone Soup state of history entry `r.last` of `h` (see `newest`), `prior` the
    /// state before it; `dims` (n, m) the state and measurement dimensions.
    fn state<'py>(
        &self,
        py: Python<'py>,
        r: &Row,
        h: &crate::tracking::track::History,
        prior: &Bound<'py, PyAny>,
        ctx: &Scan<'_, 'py>,
        (n, zm): (usize, usize),
    ) -> PyResult<Bound<'py, PyAny>> {
        let arr = |cls: usize, rows: usize, cols: usize, data: &[f64]| {
            self.array(py, cls, rows, cols, data)
        };
        let none = py.None().into_bound(py);
        let (timestamp, transition_model) = (ctx.timestamp, ctx.transition_model);
        let empty_md = || PyDict::new(py).into_any();
        let sv = arr(0, n, 1, &h.states[r.last * n..(r.last + 1) * n])?;
        let cm = arr(
            1,
            n,
            n,
            &h.covariances[r.last * n * n..(r.last + 1) * n * n],
        )?;
        if !r.update {
            self.predicted_from(py, prior)?;
            return if ctx.mixture {
                self.b[PRED].make(py, &[&sv, &cm, timestamp])
            } else {
                self.b[PRED_OF].make(py, &[&sv, &cm, timestamp, transition_model, prior])
            };
        }
        let mut hyp: Option<Bound<'py, PyAny>> = None;
        if let (true, Some((xp, pp))) = (ctx.hypotheses, &r.pred) {
            let (a, b) = (arr(0, n, 1, xp.as_slice())?, arr(1, n, n, &row_major(pp))?);
            self.predicted_from(py, prior)?;
            let pred = self.b[PRED_OF].make(py, &[&a, &b, timestamp, transition_model, prior])?;
            let mut mp_objs = Vec::with_capacity(r.mps.len());
            for MeasurementPrediction {
                z: zp,
                s: sp,
                c: cp,
                ..
            } in &r.mps
            {
                let (a, b, c) = (
                    arr(0, zm, 1, zp.as_slice())?,
                    arr(1, zm, zm, &row_major(sp))?,
                    arr(2, n, zm, &row_major(cp))?,
                );
                mp_objs.push(self.b[MPRED].make(py, &[&a, &b, timestamp, &c])?);
            }
            if ctx.mixture && r.missed.is_finite() {
                let miss = self.b[MISSED].make(py, &[timestamp, &empty_md()])?;
                let pm = self.probability(py, r.missed)?;
                let hyps = PyList::empty(py);
                hyps.append(self.b[PROB].make(py, &[&pred, &miss, &pm, &none])?)?;
                for (j, &(d, p)) in r.assoc.iter().enumerate() {
                    let det = ctx.detections.get_item(d)?;
                    let pj = self.probability(py, p)?;
                    let mp = &mp_objs[r.mp_of[j]];
                    hyps.append(self.b[PROB].make(py, &[&pred, &det, &pj, mp])?)?;
                }
                hyp = Some(self.b[MULTI].make(py, &[&hyps.into_any()])?);
            } else if r.det >= 0 {
                let d = r.det as usize;
                let det = ctx.detections.get_item(d)?;
                let dist = self.float64.bind(py).call1((r.distance,))?;
                hyp = Some(self.b[DIST].make(py, &[&pred, &det, &dist, &mp_objs[0]])?);
            }
        }
        let hyp = match hyp {
            Some(h) => h,
            None => {
                let miss = self.b[MISSED].make(py, &[timestamp, &empty_md()])?;
                self.b[SINGLE].make(py, &[&none, &miss])?
            }
        };
        self.b[UPD].make(py, &[&sv, &cm, &hyp, timestamp])
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<StoneSoupKit>()?;
    Ok(())
}
