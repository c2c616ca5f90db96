//! Bindings of the LiDAR hot paths: the line-of-sight filter (sweep and naive reference) and
//! the flat-kernel mean shift.

use super::to_py_err;
use crate::error::Error;
use crate::line_of_sight;
use numpy::{PyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
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
    a.as_slice().map_err(|_| {
        pyo3::exceptions::PyValueError::new_err(format!("{name}: must be a C-contiguous array"))
    })
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

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(line_of_sight_filter, m)?)?;
    m.add_function(wrap_pyfunction!(line_of_sight_filter_naive, m)?)?;
    Ok(())
}
