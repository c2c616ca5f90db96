//! The single conversion point from core errors to Python exceptions.

use crate::error::Error;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

pyo3::create_exception!(
    usvfast,
    DimensionError,
    PyValueError,
    "An array argument has the wrong shape or length."
);
pyo3::create_exception!(
    usvfast,
    NonFiniteError,
    PyValueError,
    "An argument contains NaN or infinity where finite numbers are required."
);
pyo3::create_exception!(
    usvfast,
    NotPositiveDefiniteError,
    PyValueError,
    "A covariance is not symmetric positive (semi-)definite."
);
pyo3::create_exception!(
    usvfast,
    TimeOrderError,
    PyValueError,
    "Timestamps go backwards where order matters."
);

/// Maps a core [`Error`] to the matching `ValueError` subclass, keeping its message.
pub fn to_py_err(e: Error) -> PyErr {
    let msg = e.to_string();
    match e {
        Error::Dimension { .. } => DimensionError::new_err(msg),
        Error::NonFinite { .. } => NonFiniteError::new_err(msg),
        Error::NotPositiveDefinite { .. } => NotPositiveDefiniteError::new_err(msg),
        Error::Order { .. } => TimeOrderError::new_err(msg),
        Error::InvalidParameter { .. } => PyValueError::new_err(msg),
        Error::Interrupted => pyo3::exceptions::PyKeyboardInterrupt::new_err(msg),
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("DimensionError", py.get_type::<DimensionError>())?;
    m.add("NonFiniteError", py.get_type::<NonFiniteError>())?;
    m.add(
        "NotPositiveDefiniteError",
        py.get_type::<NotPositiveDefiniteError>(),
    )?;
    m.add("TimeOrderError", py.get_type::<TimeOrderError>())?;
    Ok(())
}
