//! Binding of the Velodyne packet decoder (`crate::velodyne`): one call per rotation, the
//! packets as one contiguous array.

use super::{slice, to_py_err, ByteArg};
use crate::error::Error;
use crate::velodyne::{self, VelodyneModel, PACKET_SIZE, POINT_COLUMNS};
use numpy::{
    PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArray,
    PyUntypedArrayMethods,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// What `obj` is, for an error message: "uint16 array of shape (3, 1206)" or its type name.
pub(crate) fn describe(obj: &Bound<'_, PyAny>) -> String {
    match obj.cast::<PyUntypedArray>() {
        Ok(a) => format!("{} array of shape {:?}", a.dtype(), a.shape()),
        Err(_) => obj
            .get_type()
            .name()
            .map_or_else(|_| "an object".into(), |n| n.to_string()),
    }
}

/// Decodes one rotation of Velodyne data packets to velodyne-decoder's `(n, 8)` float32
/// columns; returns `((host_stamp, device_stamp), points)` as `ScanDecoder.decode` does.
#[pyfunction]
#[pyo3(signature = (payloads, packet_times, model))]
fn decode_velodyne_scan<'py>(
    py: Python<'py>,
    payloads: &Bound<'py, PyAny>,
    packet_times: &Bound<'py, PyAny>,
    model: &str,
) -> PyResult<((f64, f64), Bound<'py, PyAny>)> {
    let model = VelodyneModel::from_name(model).ok_or_else(|| {
        let names: Vec<_> = VelodyneModel::ALL.iter().map(|m| m.name()).collect();
        PyValueError::new_err(format!("model: expected one of {names:?}, got {model:?}"))
    })?;
    let payloads: PyReadonlyArray2<'py, u8> = payloads.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "payloads: expected a uint8 array of shape (k, {PACKET_SIZE}), got {}",
            describe(payloads)
        ))
    })?;
    let packet_times: PyReadonlyArray1<'py, f64> = packet_times.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "packet_times: expected a float64 array of shape (k,), got {}",
            describe(packet_times)
        ))
    })?;
    if payloads.shape()[1] != PACKET_SIZE || payloads.shape()[0] != packet_times.len() {
        return Err(to_py_err(Error::dim(
            "payloads",
            format!(
                "shape (k, {PACKET_SIZE}) with k = len(packet_times) = {}",
                packet_times.len()
            ),
            format!("{:?}", payloads.shape()),
        )));
    }
    let bytes = slice("payloads", &payloads)?;
    let times = slice("packet_times", &packet_times)?;
    let scan = py
        .detach(|| velodyne::decode_scan(model, bytes, times))
        .map_err(to_py_err)?;
    let n = scan.len();
    let points = PyArray1::from_vec(py, scan.points)
        .reshape([n, POINT_COLUMNS])?
        .into_any();
    Ok(((scan.host_stamp, scan.device_stamp), points))
}

/// Whether each packet passed, and `(index, label)` of each refused one.
type PacketCheck<'py> = (Bound<'py, PyArray1<bool>>, Vec<(usize, &'static str)>);

/// Checks a stream of data packets, `data[o:o + 1206]` for each of `offsets` (`data`: bytes or
/// a 1-D uint8 array; `offsets`: int64, bytes), each against the model id of the last one that
/// passed: `(passed, problems)`, a bool per packet and `(index, label)` of each refused one
/// (labels of `usvfast.lidar.packets.velodyne_packet_problem`).
#[pyfunction]
#[pyo3(signature = (data, offsets))]
fn velodyne_packet_check<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
    offsets: &Bound<'py, PyAny>,
) -> PyResult<PacketCheck<'py>> {
    let data = ByteArg::extract("data", data)?;
    let bytes = data.bytes("data")?;
    let offsets: PyReadonlyArray1<'py, i64> = offsets.extract().map_err(|_| {
        PyValueError::new_err(format!(
            "offsets: expected an int64 array of shape (k,), got {}",
            describe(offsets)
        ))
    })?;
    let offsets = slice("offsets", &offsets)?;
    let offsets: Vec<usize> = offsets
        .iter()
        .map(|&o| usize::try_from(o))
        .collect::<Result<_, _>>()
        .map_err(|_| PyValueError::new_err("offsets: must be non-negative"))?;
    let problems = py.detach(|| velodyne::stream_problems(bytes, &offsets));
    let refused = problems
        .iter()
        .enumerate()
        .filter_map(|(k, p)| p.map(|p| (k, p.label())))
        .collect();
    let passed = problems.iter().map(Option::is_none).collect();
    Ok((PyArray1::from_vec(py, passed), refused))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(decode_velodyne_scan, m)?)?;
    m.add_function(wrap_pyfunction!(velodyne_packet_check, m)?)?;
    Ok(())
}
