//! The pyo3 layer: the private extension module `usvfast._core`. Only conversions, input
//! checks that need Python types, and thin wrappers over the pyo3-free core live here.

use pyo3::prelude::*;

mod camera;
mod cascade;
mod errors;
mod frames;
mod geodesy;
mod kalman;
mod lidar;
mod particle;
mod pcap;
mod stonesoup;
mod stonesoup_scan;
mod tracker;
mod tracker_config;
mod velodyne;

pub use errors::to_py_err;

/// The data of a C-contiguous numpy array, or a `ValueError` naming the argument `name`.
/// Every binding reads its arrays through this one helper: a Fortran-order (or strided)
/// array is refused, never read in the wrong order (numpy's `as_slice` accepts both orders).
pub(crate) fn slice<'a, T: numpy::Element, D: numpy::ndarray::Dimension>(
    name: &str,
    a: &'a numpy::PyReadonlyArray<'_, T, D>,
) -> PyResult<&'a [T]> {
    use numpy::PyUntypedArrayMethods;
    let c_order = a.is_c_contiguous();
    a.as_slice().ok().filter(|_| c_order).ok_or_else(|| {
        pyo3::exceptions::PyValueError::new_err(format!("{name}: must be a C-contiguous array"))
    })
}

/// A bytes-like argument: a `bytes` object or a C-contiguous 1-D uint8 array (e.g. the
/// `np.frombuffer` view of an mmap), held for the duration of a call.
pub(crate) enum ByteArg<'py> {
    Bytes(Bound<'py, pyo3::types::PyBytes>),
    Array(numpy::PyReadonlyArray1<'py, u8>),
}

impl<'py> ByteArg<'py> {
    /// `obj` as bytes, or a `TypeError` naming the argument `name`.
    pub(crate) fn extract(name: &str, obj: &Bound<'py, PyAny>) -> PyResult<Self> {
        if let Ok(b) = obj.cast::<pyo3::types::PyBytes>() {
            return Ok(Self::Bytes(b.clone()));
        }
        obj.extract().map(Self::Array).map_err(|_| {
            pyo3::exceptions::PyTypeError::new_err(format!(
                "{name}: expected bytes or a 1-D uint8 array, got {}",
                velodyne::describe(obj)
            ))
        })
    }

    /// The bytes, or a `ValueError` naming `name` for an array that is not C-contiguous.
    pub(crate) fn bytes(&self, name: &str) -> PyResult<&[u8]> {
        match self {
            Self::Bytes(b) => Ok(b.as_bytes()),
            Self::Array(a) => slice(name, a),
        }
    }
}

/// The native module `usvfast._core`; import the public API from `usvfast` instead.
#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    frames::register(m)?;
    geodesy::register(m)?;
    kalman::register(m)?;
    lidar::register(m)?;
    camera::register(m)?;
    cascade::register(m)?;
    tracker::register(m)?;
    particle::register(m)?;
    stonesoup::register(m)?;
    stonesoup_scan::register(m)?;
    velodyne::register(m)?;
    pcap::register(m)?;
    Ok(())
}
