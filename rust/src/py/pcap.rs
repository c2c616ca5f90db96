//! Binding of the libpcap reader (`crate::pcap`): a whole capture to its UDP/IPv4 datagrams
//! in one call, payloads located by offset so Python slices them out of its own buffer.

use super::{to_py_err, ByteArg};
use crate::pcap;
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn as_i64(values: &[usize]) -> Vec<i64> {
    // offsets and counts within a buffer held in memory: always below i64::MAX
    values.iter().map(|&v| v as i64).collect()
}

/// Every UDP/IPv4 datagram of a libpcap capture (`data`: the whole file as `bytes` or a 1-D
/// uint8 array, e.g. `np.frombuffer` of an mmap), as a dict: per datagram `times` (its
/// record's capture time, UNIX s), `ports` (destination), `offsets` and `lengths` (of its
/// payload in `data`, bytes), `record_counts` (records seen up to its record); `records`, the
/// records seen; `damage`, `(datagrams before it, label)` of each damaged record or frame.
#[pyfunction]
#[pyo3(signature = (data))]
fn pcap_udp_datagrams<'py>(
    py: Python<'py>,
    data: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let data = ByteArg::extract("data", data)?;
    let bytes = data.bytes("data")?;
    let found = py
        .detach(|| pcap::udp_datagrams(bytes))
        .map_err(to_py_err)?;
    let damage: Vec<(usize, &str)> = found
        .damaged
        .iter()
        .map(|&(at, kind)| (at, kind.label()))
        .collect();
    let out = PyDict::new(py);
    out.set_item("times", PyArray1::from_vec(py, found.times))?;
    out.set_item("ports", PyArray1::from_vec(py, found.ports))?;
    out.set_item("offsets", PyArray1::from_vec(py, as_i64(&found.offsets)))?;
    out.set_item("lengths", PyArray1::from_vec(py, as_i64(&found.lengths)))?;
    let counts = as_i64(&found.record_counts);
    out.set_item("record_counts", PyArray1::from_vec(py, counts))?;
    out.set_item("records", found.records)?;
    out.set_item("damage", damage)?;
    Ok(out)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(pcap_udp_datagrams, m)?)?;
    Ok(())
}
