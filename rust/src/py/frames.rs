//! Bindings of the frames core: batch sensor → NED transform of point arrays, and the
//! sharpness of a point map under trial heading corrections.

use super::{slice, to_py_err};
use crate::error::Error;
use crate::frames::{self, Se3};
use crate::sharpness;
use nalgebra::{Matrix3, Vector3};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// Points (n, 3) in a sensor frame → NED (n, 3): mount body ← sensor given as a row-major
/// (3, 3) rotation and a (3,) lever arm; vessel roll/pitch/yaw (m,) and position (m, 3) with
/// m = 1 or n.
#[pyfunction]
#[pyo3(signature = (points, mount_rotation, mount_translation, roll, pitch, yaw, position))]
#[allow(clippy::too_many_arguments)]
fn sensor_to_ned<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    mount_rotation: PyReadonlyArray2<'py, f64>,
    mount_translation: PyReadonlyArray1<'py, f64>,
    roll: PyReadonlyArray1<'py, f64>,
    pitch: PyReadonlyArray1<'py, f64>,
    yaw: PyReadonlyArray1<'py, f64>,
    position: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    if points.shape()[1] != 3 || position.shape()[1] != 3 {
        return Err(to_py_err(Error::dim(
            "points/position",
            "shape (n, 3)",
            format!("{:?} and {:?}", points.shape(), position.shape()),
        )));
    }
    let r = slice("mount_rotation", &mount_rotation)?;
    let t = slice("mount_translation", &mount_translation)?;
    if r.len() != 9 || t.len() != 3 {
        return Err(to_py_err(Error::dim(
            "mount_rotation/mount_translation",
            "(3, 3) and (3,)",
            format!("{} and {} values", r.len(), t.len()),
        )));
    }
    let mount = Se3 {
        rotation: Matrix3::from_row_slice(r),
        translation: Vector3::new(t[0], t[1], t[2]),
    };
    let (p, ro, pi, ya, po) = (
        slice("points", &points)?,
        slice("roll", &roll)?,
        slice("pitch", &pitch)?,
        slice("yaw", &yaw)?,
        slice("position", &position)?,
    );
    let n = points.shape()[0];
    let out = py
        .detach(|| frames::sensor_to_ned(p, &mount, ro, pi, ya, po))
        .map_err(to_py_err)?;
    Ok(PyArray1::from_vec(py, out).reshape([n, 3])?.into_any())
}

/// Σ n² / (Σ n)² of the NED cell counts (`cell` m, two grids half a cell apart, their mean)
/// of points `xy` (n, 2: body FRD x forward, y starboard, m) placed with their frames' poses
/// `north`, `east` (m) and `heading` (rad clockwise) plus each of `offsets` (rad): (m,).
#[pyfunction]
#[pyo3(signature = (xy, north, east, heading, offsets, cell))]
fn map_sharpness<'py>(
    py: Python<'py>,
    xy: PyReadonlyArray2<'py, f64>,
    north: PyReadonlyArray1<'py, f64>,
    east: PyReadonlyArray1<'py, f64>,
    heading: PyReadonlyArray1<'py, f64>,
    offsets: PyReadonlyArray1<'py, f64>,
    cell: f64,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    if xy.shape()[1] != 2 {
        return Err(to_py_err(Error::dim(
            "xy",
            "shape (n, 2)",
            format!("{:?}", xy.shape()),
        )));
    }
    let (p, n, e, h, o) = (
        slice("xy", &xy)?,
        slice("north", &north)?,
        slice("east", &east)?,
        slice("heading", &heading)?,
        slice("offsets", &offsets)?,
    );
    let out = py
        .detach(|| sharpness::map_sharpness(p, n, e, h, o, cell))
        .map_err(to_py_err)?;
    Ok(PyArray1::from_vec(py, out))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sensor_to_ned, m)?)?;
    m.add_function(wrap_pyfunction!(map_sharpness, m)?)?;
    Ok(())
}
