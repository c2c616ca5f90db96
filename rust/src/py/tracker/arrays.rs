//! The tracker's state as numpy arrays: the snapshot of the current tracks and a track's
//! history, as `usvfast.tracking.Tracker` reads them (times in s, states and covariances in the
//! motion model's frame and units).

use super::to_py_err;
use crate::error::Error;
use crate::tracking::track::Track;
use crate::tracking::tracker::Tracker;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

pub(super) fn arr_f<'py>(
    py: Python<'py>,
    data: Vec<f64>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, data).reshape(shape)?.into_any())
}

pub(super) fn arr_i<'py>(
    py: Python<'py>,
    data: Vec<i64>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    Ok(PyArray1::from_vec(py, data).reshape(shape)?.into_any())
}

/// History entries `start..` of a track as arrays (its association CSR rebased to start at 0).
pub(super) fn history_dict<'py>(
    py: Python<'py>,
    tr: &Track,
    ndim: usize,
    start: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let h = &tr.history;
    let len = h.len();
    if start > len {
        return Err(to_py_err(Error::param(
            "start",
            format!("must be <= the {len} history entries, got {start}"),
        )));
    }
    let k = len - start;
    let d = PyDict::new(py);
    d.set_item("id", tr.id)?;
    d.set_item("times", arr_f(py, h.times[start..].to_vec(), &[k])?)?;
    d.set_item(
        "states",
        arr_f(py, h.states[start * ndim..].to_vec(), &[k, ndim])?,
    )?;
    d.set_item(
        "covariances",
        arr_f(
            py,
            h.covariances[start * ndim * ndim..].to_vec(),
            &[k, ndim, ndim],
        )?,
    )?;
    let upd: Vec<bool> = h.is_update[start..].to_vec();
    d.set_item("is_update", PyArray1::from_vec(py, upd))?;
    d.set_item("scan", arr_i(py, h.scan[start..].to_vec(), &[k])?)?;
    d.set_item("sensor", arr_i(py, h.sensor[start..].to_vec(), &[k])?)?;
    d.set_item("detection", arr_i(py, h.detection[start..].to_vec(), &[k])?)?;
    d.set_item("nis", arr_f(py, h.nis[start..].to_vec(), &[k])?)?;
    d.set_item(
        "missed_probability",
        arr_f(py, h.missed_probability[start..].to_vec(), &[k])?,
    )?;
    let offs: &[usize] = if h.assoc_offsets.is_empty() {
        &[0]
    } else {
        &h.assoc_offsets[start..]
    };
    let (a0, a1) = (offs[0], offs[offs.len() - 1]);
    let rebased: Vec<i64> = offs.iter().map(|&o| (o - a0) as i64).collect();
    let no = rebased.len();
    d.set_item("assoc_offsets", arr_i(py, rebased, &[no])?)?;
    d.set_item(
        "assoc_detection",
        arr_i(py, h.assoc_detection[a0..a1].to_vec(), &[a1 - a0])?,
    )?;
    d.set_item(
        "assoc_probability",
        arr_f(py, h.assoc_probability[a0..a1].to_vec(), &[a1 - a0])?,
    )?;
    d.set_item("confirmed_time", tr.confirmed_time)?;
    d.set_item("deleted_time", tr.deleted_time)?;
    Ok(d)
}

/// Confirmed tracks (or tentative ones) of `tracker` as arrays: the newest state, covariance,
/// association, NIS, IMM mode probabilities and existence of each.
pub(super) fn snapshot_dict<'py>(
    py: Python<'py>,
    tracker: &Tracker,
    tentative: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let n = tracker.config().motion_model.ndim();
    let list = if tentative {
        &tracker.tentative
    } else {
        &tracker.tracks
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
    let m = tracker.measurement_dim();
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
    let imm = tracker.config().imm.as_ref();
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
    let init = tracker.config().existence.map_or(1.0, |e| e.initial);
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
