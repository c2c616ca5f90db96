//! Bindings of the frames core: batch sensor → NED transform of point arrays.

use super::{slice, to_py_err};
use crate::error::Error;
use crate::frames::{self, Se3};
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

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(sensor_to_ned, m)?)?;
    Ok(())
}
