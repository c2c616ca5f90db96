//! The drop-in trackers' per-scan calls on the core (`usvfast.stonesoup`): a scan's Stone Soup
//! detections read and stepped in one call, and the core's track lists the drop-in reads every
//! scan.

use super::tracker::TrackerCore;
use numpy::{PyArray2, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::intern;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};

/// One scan of a drop-in tracker in one call, when its detections allow the short way: every
/// detection of a class in `plain` (classes whose `timestamp`, `measurement_model`,
/// `state_vector` and `metadata` are plain Stone Soup properties, so their `__dict__` entries
/// `_property_<name>` are what those attributes read), at `timestamp`, with a measurement
/// model already in `known` (`id(model) -> (core sensor, its own noise covariance (m, m) or
/// None for the sensor's, None)`: no sensor position) and a float64 `(m, 1)` state vector.
/// Then the detections are stepped on `core` at `t` seconds (as `TrackerCore.step(t, z,
/// sensor_ids, covariances)`, with the detections' own covariances, or those of their sensors
/// `noises`, when one has its own) and the result is (the
/// alive confirmed track ids in the core's order, z `(k, m)` the measurements, the
/// detections' measurement models, whether a detection carries metadata). Otherwise nothing
/// is stepped and the result is None (the caller takes the long way, which registers new
/// models and reports bad detections).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
#[allow(clippy::type_complexity)]
fn stonesoup_step<'py>(
    py: Python<'py>,
    mut core: PyRefMut<'py, TrackerCore>,
    t: f64,
    detections: Bound<'py, PyList>,
    timestamp: Bound<'py, PyAny>,
    known: Bound<'py, PyDict>,
    plain: Bound<'py, PyAny>,
    noises: Bound<'py, PyList>,
    m: usize,
) -> PyResult<
    Option<(
        Bound<'py, PyList>,
        Bound<'py, PyAny>,
        Bound<'py, PyList>,
        bool,
    )>,
> {
    let k = detections.len();
    let mut z = Vec::with_capacity(k * m);
    let mut ids = Vec::with_capacity(k);
    let mut own_noise: Vec<Option<Bound<'py, PyAny>>> = Vec::with_capacity(k);
    let models = PyList::empty(py);
    let mut metadata = false;
    let mut plain_type: Option<*mut pyo3::ffi::PyObject> = None;
    // (id of a model, its core sensor, its own noise covariance)
    let mut seen: Vec<(usize, usize, Option<Bound<'py, PyAny>>)> = Vec::new();
    let attr = |d: &Bound<'py, PyAny>, name: &Bound<'py, PyString>| -> PyResult<Option<_>> {
        match d.getattr(name) {
            Ok(v) => Ok(Some(v)),
            Err(e) if e.is_instance_of::<pyo3::exceptions::PyAttributeError>(py) => Ok(None),
            Err(e) => Err(e),
        }
    };
    for d in detections.iter() {
        let ty = d.get_type();
        if plain_type != Some(ty.as_ptr()) {
            if !plain.contains(&ty)? {
                return Ok(None);
            }
            plain_type = Some(ty.as_ptr());
        }
        let Some(ts) = attr(&d, intern!(py, "_property_timestamp"))? else {
            return Ok(None);
        };
        if !ts.eq(&timestamp)? {
            return Ok(None);
        }
        let Some(model) = attr(&d, intern!(py, "_property_measurement_model"))? else {
            return Ok(None);
        };
        // The scan's models, looked up in `known` once each (a scan has one or a few).
        let key = model.as_ptr() as usize;
        let (idx, own) = match seen.iter().find(|(k, _, _)| *k == key) {
            Some((_, idx, own)) => (*idx, own.clone()),
            None => {
                let Some(hit) = known.get_item(key)? else {
                    return Ok(None);
                };
                let Ok((idx, own, origin)) =
                    hit.extract::<(usize, Bound<'py, PyAny>, Bound<'py, PyAny>)>()
                else {
                    return Ok(None);
                };
                if !origin.is_none() {
                    return Ok(None);
                }
                let own = (!own.is_none()).then_some(own);
                seen.push((key, idx, own.clone()));
                (idx, own)
            }
        };
        let Some(sv) = attr(&d, intern!(py, "_property_state_vector"))? else {
            return Ok(None);
        };
        let Ok(sv) = sv.cast::<PyArray2<f64>>() else {
            return Ok(None);
        };
        if sv.shape() != [m, 1] || !sv.is_c_contiguous() {
            return Ok(None);
        }
        // SAFETY: a C-contiguous float64 array, read here while nothing writes to it (the GIL
        // is held).
        z.extend_from_slice(
            unsafe { sv.as_slice() }.map_err(|_| {
                PyValueError::new_err("detections: a state vector is not contiguous")
            })?,
        );
        let Some(md) = attr(&d, intern!(py, "_property_metadata"))? else {
            return Ok(None);
        };
        metadata = metadata || md.is_truthy()?;
        ids.push(idx);
        own_noise.push(own);
        models.append(model)?;
    }
    let mut covs: Option<Vec<f64>> = None;
    if own_noise.iter().any(Option::is_some) {
        let mut c = Vec::with_capacity(k * m * m);
        for (own, &idx) in own_noise.iter().zip(&ids) {
            let r = match own {
                Some(r) => r.clone(),
                None => match noises.get_item(idx) {
                    Ok(r) => r,
                    Err(_) => return Ok(None),
                },
            };
            let Ok(r) = r.cast_into::<PyArray2<f64>>() else {
                return Ok(None);
            };
            if r.shape() != [m, m] || !r.is_c_contiguous() {
                return Ok(None);
            }
            // SAFETY: as for the state vectors.
            c.extend_from_slice(
                unsafe { r.as_slice() }
                    .map_err(|_| PyValueError::new_err("noises: a covariance is not contiguous"))?,
            );
        }
        covs = Some(c);
    }
    core.step_slices(py, t, &z, &ids, covs.as_deref(), None)?;
    let alive = PyList::new(py, core.inner.tracks.iter().map(|t| t.id))?;
    let z = numpy::PyArray1::from_vec(py, z).reshape([k, m])?.into_any();
    Ok(Some((alive, z, models, metadata)))
}

/// Ids of the alive confirmed tracks of `core`, in the core's order, as a list (what the
/// drop-in reads every scan; `TrackerCore.track_ids` also lists the deleted ones).
#[pyfunction]
fn confirmed_ids<'py>(
    py: Python<'py>,
    core: PyRef<'py, TrackerCore>,
) -> PyResult<Bound<'py, PyList>> {
    PyList::new(py, core.inner.tracks.iter().map(|t| t.id))
}

/// The oldest first scan of `core`'s tentative tracks (their histories refer to the detections
/// of that scan on), None without tentative tracks.
#[pyfunction]
fn tentative_first_scan(core: PyRef<'_, TrackerCore>) -> Option<i64> {
    core.inner
        .tentative
        .iter()
        .filter_map(|t| t.history.scan.first().copied())
        .min()
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(confirmed_ids, m)?)?;
    m.add_function(wrap_pyfunction!(stonesoup_step, m)?)?;
    m.add_function(wrap_pyfunction!(tentative_first_scan, m)?)?;
    Ok(())
}
