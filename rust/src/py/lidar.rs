//! Bindings of the LiDAR hot paths: the line-of-sight filter (sweep and naive reference) and
//! the flat-kernel mean shift.

use super::{slice, to_py_err};
use crate::error::Error;
use crate::line_of_sight;
use crate::mean_shift::{self as ms, MeanShiftParams};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// Flat row-major view of an `(n, cols)` array, or a `DimensionError` naming `name`.
fn rows<'a>(name: &str, a: &'a PyReadonlyArray2<'_, f64>, cols: usize) -> PyResult<&'a [f64]> {
    if a.shape()[1] != cols {
        return Err(to_py_err(Error::dim(
            name,
            format!("shape (n, {cols})"),
            format!("{:?}", a.shape()),
        )));
    }
    slice(name, a)
}

type LosFn = fn(&[f64], &[f64], [f64; 2], f64) -> crate::Result<Vec<bool>>;

fn run_los<'py>(
    py: Python<'py>,
    f: LosFn,
    points: &PyReadonlyArray2<'py, f64>,
    segments: &PyReadonlyArray2<'py, f64>,
    sensor: (f64, f64),
    tolerance: f64,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let p = rows("points", points, 2)?;
    let s = rows("segments", segments, 4)?;
    let keep = py
        .detach(|| f(p, s, [sensor.0, sensor.1], tolerance))
        .map_err(to_py_err)?;
    Ok(PyArray1::from_vec(py, keep))
}

/// Keep-mask of `points` (n, 2) not hidden behind nor within `tolerance` of `segments`
/// (m, 4); bearing sweep, O((n + m) log(n + m)).
#[pyfunction]
#[pyo3(signature = (points, segments, *, sensor=(0.0, 0.0), tolerance=0.1))]
fn line_of_sight_filter<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    segments: PyReadonlyArray2<'py, f64>,
    sensor: (f64, f64),
    tolerance: f64,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    run_los(
        py,
        line_of_sight::line_of_sight_filter,
        &points,
        &segments,
        sensor,
        tolerance,
    )
}

/// The O(n·m) reference of `line_of_sight_filter` (same contract and result).
#[pyfunction]
#[pyo3(signature = (points, segments, *, sensor=(0.0, 0.0), tolerance=0.1))]
fn line_of_sight_filter_naive<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    segments: PyReadonlyArray2<'py, f64>,
    sensor: (f64, f64),
    tolerance: f64,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    run_los(
        py,
        line_of_sight::line_of_sight_filter_naive,
        &points,
        &segments,
        sensor,
        tolerance,
    )
}

type MeanShiftOut<'py> = (Bound<'py, PyAny>, Bound<'py, PyArray1<i64>>, usize, bool);

/// Flat-kernel mean shift equal to scikit-learn's `MeanShift`; returns
/// `(cluster_centers (k, d), labels (n,), n_iter, bin_seeding_fell_back)`.
#[pyfunction]
#[pyo3(signature = (
    points, *, bandwidth=2.0, seeds=None, bin_seeding=false, min_bin_freq=1,
    cluster_all=true, max_iter=300
))]
#[allow(clippy::too_many_arguments)]
fn mean_shift<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    bandwidth: f64,
    seeds: Option<PyReadonlyArray2<'py, f64>>,
    bin_seeding: bool,
    min_bin_freq: usize,
    cluster_all: bool,
    max_iter: usize,
) -> PyResult<MeanShiftOut<'py>> {
    let dim = points.shape()[1];
    let p = rows("points", &points, dim)?;
    let s = match &seeds {
        None => None,
        Some(a) => Some(rows("seeds", a, dim)?),
    };
    let params = MeanShiftParams {
        bandwidth,
        bin_seeding,
        min_bin_freq,
        cluster_all,
        max_iter,
    };
    let out = py
        .detach(|| ms::mean_shift(p, dim, s, &params))
        .map_err(to_py_err)?;
    let k = out.centers.len() / dim.max(1);
    let centers = PyArray1::from_vec(py, out.centers)
        .reshape([k, dim])?
        .into_any();
    Ok((
        centers,
        PyArray1::from_vec(py, out.labels),
        out.n_iter,
        out.bin_seeding_fell_back,
    ))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(mean_shift, m)?)?;
    m.add_function(wrap_pyfunction!(line_of_sight_filter, m)?)?;
    m.add_function(wrap_pyfunction!(line_of_sight_filter_naive, m)?)?;
    Ok(())
}
