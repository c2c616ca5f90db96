//! Bindings of the camera core: non-maximum suppression and water-plane georeferencing.

use super::{slice, to_py_err};
use crate::error::Error;
use crate::georef::{georeference, GeorefInput, GeorefNoise};
use crate::nms::{batched_nms, nms};
use numpy::{
    PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use pyo3::prelude::*;

fn check_cols(name: &str, shape: &[usize], cols: usize) -> PyResult<()> {
    if shape[1] != cols {
        return Err(to_py_err(Error::dim(
            name,
            format!("shape (n, {cols})"),
            format!("{shape:?}"),
        )));
    }
    Ok(())
}

/// NMS over `boxes (n, 4)` xyxy and `scores (n,)`; per class when `classes (n,)` is given.
/// Returns kept indices (int64) in descending score order.
#[pyfunction]
#[pyo3(signature = (boxes, scores, iou_threshold, classes=None))]
fn nms_indices<'py>(
    py: Python<'py>,
    boxes: PyReadonlyArray2<'py, f64>,
    scores: PyReadonlyArray1<'py, f64>,
    iou_threshold: f64,
    classes: Option<PyReadonlyArray1<'py, i64>>,
) -> PyResult<Bound<'py, PyArray1<i64>>> {
    check_cols("boxes", boxes.shape(), 4)?;
    let b = slice("boxes", &boxes)?;
    let s = slice("scores", &scores)?;
    let kept = match &classes {
        None => py.detach(|| nms(b, s, iou_threshold)),
        Some(c) => {
            let c = slice("classes", c)?;
            py.detach(|| batched_nms(b, s, c, iou_threshold))
        }
    }
    .map_err(to_py_err)?;
    Ok(PyArray1::from_vec(
        py,
        kept.into_iter().map(|k| k as i64).collect(),
    ))
}

type GeorefResult<'py> = (
    Bound<'py, PyAny>,
    Bound<'py, PyAny>,
    Bound<'py, PyArray1<u8>>,
);

/// Ray–water-plane intersection with covariance for `n` detections (see `georef.rs`).
/// Returns `(positions (n, 2), covariances (n, 2, 2), status (n,) uint8)`.
#[pyfunction]
#[pyo3(signature = (
    normalized, jacobian, roll, pitch, height, r_body_cam, cam_position, *,
    heading=None, vessel_ne=None, min_depression=0.0,
    sigma_px=(0.0, 0.0), sigma_roll_pitch=(0.0, 0.0), sigma_height=0.0, sigma_heading=0.0
))]
#[allow(clippy::too_many_arguments)]
fn georeference_rays<'py>(
    py: Python<'py>,
    normalized: PyReadonlyArray2<'py, f64>,
    jacobian: PyReadonlyArray3<'py, f64>,
    roll: PyReadonlyArray1<'py, f64>,
    pitch: PyReadonlyArray1<'py, f64>,
    height: PyReadonlyArray1<'py, f64>,
    r_body_cam: PyReadonlyArray2<'py, f64>,
    cam_position: [f64; 3],
    heading: Option<PyReadonlyArray1<'py, f64>>,
    vessel_ne: Option<PyReadonlyArray2<'py, f64>>,
    min_depression: f64,
    sigma_px: (f64, f64),
    sigma_roll_pitch: (f64, f64),
    sigma_height: f64,
    sigma_heading: f64,
) -> PyResult<GeorefResult<'py>> {
    check_cols("normalized", normalized.shape(), 2)?;
    let js = jacobian.shape();
    if js[1] != 2 || js[2] != 2 {
        return Err(to_py_err(Error::dim(
            "jacobian",
            "shape (n, 2, 2)",
            format!("{js:?}"),
        )));
    }
    if r_body_cam.shape() != [3usize, 3] {
        return Err(to_py_err(Error::dim(
            "r_body_cam",
            "shape (3, 3)",
            format!("{:?}", r_body_cam.shape()),
        )));
    }
    let mut r = [0.0; 9];
    r.copy_from_slice(slice("r_body_cam", &r_body_cam)?);
    if let Some(v) = &vessel_ne {
        check_cols("vessel_ne", v.shape(), 2)?;
    }
    let input = GeorefInput {
        normalized: slice("normalized", &normalized)?,
        jacobian: slice("jacobian", &jacobian)?,
        roll: slice("roll", &roll)?,
        pitch: slice("pitch", &pitch)?,
        height: slice("height", &height)?,
        r_body_cam: r,
        cam_position,
        heading: heading.as_ref().map(|h| slice("heading", h)).transpose()?,
        vessel_ne: vessel_ne
            .as_ref()
            .map(|v| slice("vessel_ne", v))
            .transpose()?,
        min_depression,
        noise: GeorefNoise {
            sigma_px: [sigma_px.0, sigma_px.1],
            sigma_roll_pitch: [sigma_roll_pitch.0, sigma_roll_pitch.1],
            sigma_height,
            sigma_heading,
        },
    };
    let n = input.normalized.len() / 2;
    let out = py.detach(|| georeference(&input)).map_err(to_py_err)?;
    Ok((
        PyArray1::from_vec(py, out.positions)
            .reshape([n, 2])?
            .into_any(),
        PyArray1::from_vec(py, out.covariances)
            .reshape([n, 2, 2])?
            .into_any(),
        PyArray1::from_vec(py, out.status),
    ))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(nms_indices, m)?)?;
    m.add_function(wrap_pyfunction!(georeference_rays, m)?)?;
    Ok(())
}
