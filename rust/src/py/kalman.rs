//! Bindings of the Kalman core: motion model matrices and the batch filter/smoother.

use super::{slice, to_py_err};
use crate::error::Error;
use crate::kalman::{predict_many, run_batch, run_batch_linear, update_many, BatchInput};
use crate::models::{Component, LinearModel, MotionModel};
use numpy::{
    PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Builds a core model from `[(kind, q), ...]` with kind in
/// `"random_walk" | "constant_velocity" | "constant_acceleration"`.
pub(crate) fn motion_model_from_spec(spec: &[(String, f64)]) -> PyResult<MotionModel> {
    let components = spec
        .iter()
        .map(|(kind, q)| {
            let q = *q;
            match kind.as_str() {
                "random_walk" => Ok(Component::RandomWalk { q }),
                "constant_velocity" => Ok(Component::ConstantVelocity { q }),
                "constant_acceleration" => Ok(Component::ConstantAcceleration { q }),
                other => Err(Error::param(
                    "motion_model",
                    format!(
                        "unknown component {other:?} (expected random_walk, constant_velocity \
                         or constant_acceleration)"
                    ),
                )),
            }
        })
        .collect::<Result<Vec<_>, _>>()
        .map_err(to_py_err)?;
    MotionModel::new(components).map_err(to_py_err)
}

fn array<'py>(py: Python<'py>, data: Vec<f64>, shape: &[usize]) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, data).reshape(shape)?.into_any())
}

/// Transition matrix `F(dt)` and process noise `Q(dt)` of a motion model spec.
#[pyfunction]
fn motion_matrices<'py>(
    py: Python<'py>,
    motion_model: Vec<(String, f64)>,
    dt: f64,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let model = motion_model_from_spec(&motion_model)?;
    if !dt.is_finite() {
        return Err(to_py_err(Error::NonFinite {
            arg: "dt".into(),
            at: "scalar".into(),
        }));
    }
    let (f, q) = model.matrices(dt);
    let n = model.ndim();
    let row_major = |m: nalgebra::DMatrix<f64>| m.transpose().as_slice().to_vec();
    Ok((
        array(py, row_major(f), &[n, n])?,
        array(py, row_major(q), &[n, n])?,
    ))
}

/// Filters and optionally RTS-smooths a sequence; returns a dict of numpy arrays.
#[pyfunction]
#[pyo3(signature = (
    motion_model, times, measurements, measurement_matrix, measurement_noise,
    prior_state, prior_covariance, *, sensor_index=None, prior_time=None, smooth=true
))]
#[allow(clippy::too_many_arguments)]
fn kalman_batch<'py>(
    py: Python<'py>,
    motion_model: Vec<(String, f64)>,
    times: PyReadonlyArray1<'py, f64>,
    measurements: PyReadonlyArray2<'py, f64>,
    measurement_matrix: PyReadonlyArray2<'py, f64>,
    measurement_noise: PyReadonlyArray3<'py, f64>,
    prior_state: PyReadonlyArray1<'py, f64>,
    prior_covariance: PyReadonlyArray2<'py, f64>,
    sensor_index: Option<PyReadonlyArray1<'py, i64>>,
    prior_time: Option<f64>,
    smooth: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let model = motion_model_from_spec(&motion_model)?;
    let inputs = BatchArrays {
        times: &times,
        measurements: &measurements,
        measurement_matrix: &measurement_matrix,
        measurement_noise: &measurement_noise,
        prior_state: &prior_state,
        prior_covariance: &prior_covariance,
        sensor_index: sensor_index.as_ref(),
        prior_time,
    };
    batch_dict(py, model.ndim(), &inputs, smooth, |input| {
        run_batch(&model, input, smooth)
    })
}

/// The numpy inputs shared by the batch bindings.
struct BatchArrays<'a, 'py> {
    times: &'a PyReadonlyArray1<'py, f64>,
    measurements: &'a PyReadonlyArray2<'py, f64>,
    measurement_matrix: &'a PyReadonlyArray2<'py, f64>,
    measurement_noise: &'a PyReadonlyArray3<'py, f64>,
    prior_state: &'a PyReadonlyArray1<'py, f64>,
    prior_covariance: &'a PyReadonlyArray2<'py, f64>,
    sensor_index: Option<&'a PyReadonlyArray1<'py, i64>>,
    prior_time: Option<f64>,
}

/// Checks and converts the batch inputs, runs `run` without the GIL, returns the result dict.
fn batch_dict<'py, F>(
    py: Python<'py>,
    ndim: usize,
    a: &BatchArrays<'_, 'py>,
    smooth: bool,
    run: F,
) -> PyResult<Bound<'py, PyDict>>
where
    F: FnOnce(&BatchInput) -> crate::error::Result<crate::kalman::BatchOutput> + Send,
{
    let (times, measurements, measurement_noise) = (a.times, a.measurements, a.measurement_noise);
    let m = measurements.shape()[1];
    let t = slice("times", times)?;
    let noise_index: Option<Vec<usize>> = match a.sensor_index {
        None => None,
        Some(a) => {
            let s = slice("sensor_index", a)?;
            if let Some(pos) = s.iter().position(|&v| v < 0) {
                return Err(to_py_err(Error::param(
                    "sensor_index",
                    format!("element {pos} is negative ({})", s[pos]),
                )));
            }
            Some(s.iter().map(|&v| v as usize).collect())
        }
    };
    if measurement_noise.shape()[1] != m || measurement_noise.shape()[2] != m {
        return Err(to_py_err(Error::dim(
            "measurement_noise",
            format!("shape (k, {m}, {m})"),
            format!("{:?}", measurement_noise.shape()),
        )));
    }
    let input = BatchInput {
        times: t,
        measurements: slice("measurements", measurements)?,
        measurement_dim: m,
        measurement_matrix: slice("measurement_matrix", a.measurement_matrix)?,
        measurement_noise: slice("measurement_noise", measurement_noise)?,
        noise_index: noise_index.as_deref(),
        prior_state: slice("prior_state", a.prior_state)?,
        prior_covariance: slice("prior_covariance", a.prior_covariance)?,
        prior_time: a
            .prior_time
            .unwrap_or_else(|| t.first().copied().unwrap_or(0.0)),
    };
    let out = py.detach(|| run(&input)).map_err(to_py_err)?;
    let n = t.len();
    let d = PyDict::new(py);
    let states = [n, ndim];
    let covs = [n, ndim, ndim];
    d.set_item(
        "predicted_states",
        array(py, out.predicted_states, &states)?,
    )?;
    d.set_item(
        "predicted_covariances",
        array(py, out.predicted_covariances, &covs)?,
    )?;
    d.set_item("filtered_states", array(py, out.filtered_states, &states)?)?;
    d.set_item(
        "filtered_covariances",
        array(py, out.filtered_covariances, &covs)?,
    )?;
    if smooth {
        d.set_item("smoothed_states", array(py, out.smoothed_states, &states)?)?;
        d.set_item(
            "smoothed_covariances",
            array(py, out.smoothed_covariances, &covs)?,
        )?;
    }
    d.set_item("nis", array(py, out.nis, &[n])?)?;
    d.set_item("log_likelihood", array(py, out.log_likelihood, &[n])?)?;
    Ok(d)
}

/// Like `kalman_batch` with a general linear model: `transition_matrices` and
/// `process_noises` are stacks `(k, n, n)` with `k` = 1 (fixed) or one pair per measurement.
#[pyfunction]
#[pyo3(signature = (
    transition_matrices, process_noises, times, measurements, measurement_matrix,
    measurement_noise, prior_state, prior_covariance, *, sensor_index=None, prior_time=None,
    smooth=true
))]
#[allow(clippy::too_many_arguments)]
fn kalman_batch_linear<'py>(
    py: Python<'py>,
    transition_matrices: PyReadonlyArray3<'py, f64>,
    process_noises: PyReadonlyArray3<'py, f64>,
    times: PyReadonlyArray1<'py, f64>,
    measurements: PyReadonlyArray2<'py, f64>,
    measurement_matrix: PyReadonlyArray2<'py, f64>,
    measurement_noise: PyReadonlyArray3<'py, f64>,
    prior_state: PyReadonlyArray1<'py, f64>,
    prior_covariance: PyReadonlyArray2<'py, f64>,
    sensor_index: Option<PyReadonlyArray1<'py, i64>>,
    prior_time: Option<f64>,
    smooth: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let fs = transition_matrices.shape();
    if fs[1] != fs[2] {
        return Err(to_py_err(Error::dim(
            "transition_matrices",
            "shape (k, n, n)",
            format!("{fs:?}"),
        )));
    }
    if process_noises.shape() != fs {
        return Err(to_py_err(Error::dim(
            "process_noises",
            format!("{fs:?} (as transition_matrices)"),
            format!("{:?}", process_noises.shape()),
        )));
    }
    let model = LinearModel::new(
        fs[1],
        slice("transition_matrices", &transition_matrices)?.to_vec(),
        slice("process_noises", &process_noises)?.to_vec(),
    )
    .map_err(to_py_err)?;
    let inputs = BatchArrays {
        times: &times,
        measurements: &measurements,
        measurement_matrix: &measurement_matrix,
        measurement_noise: &measurement_noise,
        prior_state: &prior_state,
        prior_covariance: &prior_covariance,
        sensor_index: sensor_index.as_ref(),
        prior_time,
    };
    batch_dict(py, fs[1], &inputs, smooth, |input| {
        run_batch_linear(&model, input, smooth)
    })
}

/// Predicts a stack of states `(k, n)` and covariances `(k, n, n)` with one `F`, `Q` `(n, n)`.
#[pyfunction]
fn kalman_predict<'py>(
    py: Python<'py>,
    states: PyReadonlyArray2<'py, f64>,
    covariances: PyReadonlyArray3<'py, f64>,
    transition_matrix: PyReadonlyArray2<'py, f64>,
    process_noise: PyReadonlyArray2<'py, f64>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let (k, n) = (states.shape()[0], states.shape()[1]);
    let (x, p) = predict_many(
        slice("states", &states)?,
        slice("covariances", &covariances)?,
        n,
        slice("transition_matrix", &transition_matrix)?,
        slice("process_noise", &process_noise)?,
    )
    .map_err(to_py_err)?;
    Ok((array(py, x, &[k, n])?, array(py, p, &[k, n, n])?))
}

/// Updates state `i` of a stack with measurement row `i`; returns (states, covariances, nis).
#[pyfunction]
fn kalman_update<'py>(
    py: Python<'py>,
    states: PyReadonlyArray2<'py, f64>,
    covariances: PyReadonlyArray3<'py, f64>,
    measurements: PyReadonlyArray2<'py, f64>,
    measurement_matrix: PyReadonlyArray2<'py, f64>,
    measurement_noise: PyReadonlyArray2<'py, f64>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let (k, n) = (states.shape()[0], states.shape()[1]);
    let (x, p, nis) = update_many(
        slice("states", &states)?,
        slice("covariances", &covariances)?,
        n,
        slice("measurements", &measurements)?,
        slice("measurement_matrix", &measurement_matrix)?,
        slice("measurement_noise", &measurement_noise)?,
    )
    .map_err(to_py_err)?;
    Ok((
        array(py, x, &[k, n])?,
        array(py, p, &[k, n, n])?,
        array(py, nis, &[k])?,
    ))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(motion_matrices, m)?)?;
    m.add_function(wrap_pyfunction!(kalman_batch, m)?)?;
    m.add_function(wrap_pyfunction!(kalman_batch_linear, m)?)?;
    m.add_function(wrap_pyfunction!(kalman_predict, m)?)?;
    m.add_function(wrap_pyfunction!(kalman_update, m)?)?;
    Ok(())
}
