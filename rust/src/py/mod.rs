//! The pyo3 layer: the private extension module `usvfast._core`. Only conversions, input
//! checks that need Python types, and thin wrappers over the pyo3-free core live here.

use pyo3::prelude::*;

mod camera;
mod errors;
mod frames;
mod geodesy;
mod kalman;
mod lidar;
mod tracker;

pub use errors::to_py_err;

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
    tracker::register(m)?;
    Ok(())
}
