//! Binding of the libpcap reader (`crate::pcap`): a whole capture to its UDP/IPv4 datagrams
//! in one call, payloads located by offset so Python slices them out of its own buffer.

use super::{to_py_err, ByteArg};
use crate::pcap::{self, Damage};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Arrays of the datagrams (times, ports, payload offsets, payload lengths), records seen and
/// damage counts by label.
type Datagrams<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<u16>>,
    Bound<'py, PyArray1<i64>>,
    Bound<'py, PyArray1<i64>>,
    usize,
    Bound<'py, PyDict>,
);

/// Every UDP/IPv4 datagram of a libpcap capture (`data`: the whole file as `bytes` or a 1-D
/// uint8 array, e.g. `np.frombuffer` of an mmap): `(times, ports, offsets, lengths, records,
/// damage)` — record times (UNIX s), destination ports, payload offsets and lengths in `data`
/// (bytes), the number of records seen and the damage skipped, `{label: count}`.
#[pyfunction]
#[pyo3(signature = (data))]
fn pcap_udp_datagrams<'py>(py: Python<'py>, data: &Bound<'py, PyAny>) -> PyResult<Datagrams<'py>> {
    let data = ByteArg::extract("data", data)?;
    let bytes = data.bytes("data")?;
    let found = py
        .detach(|| pcap::udp_datagrams(bytes))
        .map_err(to_py_err)?;
    let damage = PyDict::new(py);
    for kind in Damage::ALL {
        let count = found.damaged(kind);
        if count > 0 {
            damage.set_item(kind.label(), count)?;
        }
    }
    let as_i64 = |v: &[usize]| v.iter().map(|&x| x as i64).collect::<Vec<_>>();
    Ok((
        PyArray1::from_vec(py, found.times),
        PyArray1::from_vec(py, found.ports),
        PyArray1::from_vec(py, as_i64(&found.offsets)),
        PyArray1::from_vec(py, as_i64(&found.lengths)),
        found.records,
        damage,
    ))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(pcap_udp_datagrams, m)?)?;
    Ok(())
}
