//! The one error type of the core. Every fallible public function returns [`Result`];
//! the Python layer maps each variant to a `ValueError` subclass (see `py::errors`).

/// What went wrong, naming the offending argument.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// An array had the wrong shape or length.
    #[error("{arg}: expected {expected}, got {actual}")]
    Dimension {
        arg: String,
        expected: String,
        actual: String,
    },
    /// A NaN or infinite value where finite numbers are required.
    #[error("{arg}: contains a non-finite value (NaN or inf) at {at}")]
    NonFinite { arg: String, at: String },
    /// A covariance that is not symmetric or not positive (semi-)definite.
    #[error("{arg}: {reason}")]
    NotPositiveDefinite { arg: String, reason: String },
    /// Times that go backwards where order matters.
    #[error("{arg}: {reason}")]
    Order { arg: String, reason: String },
    /// A parameter outside its valid range.
    #[error("{arg}: {reason}")]
    InvalidParameter { arg: String, reason: String },
    /// A long computation was stopped by its caller (e.g. Ctrl-C) before changing any state.
    #[error("interrupted")]
    Interrupted,
}

/// Result alias of the core.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Shape error helper.
    pub fn dim(arg: &str, expected: impl ToString, actual: impl ToString) -> Self {
        Error::Dimension {
            arg: arg.into(),
            expected: expected.to_string(),
            actual: actual.to_string(),
        }
    }

    /// Invalid parameter helper.
    pub fn param(arg: &str, reason: impl ToString) -> Self {
        Error::InvalidParameter {
            arg: arg.into(),
            reason: reason.to_string(),
        }
    }
}

/// Fails with [`Error::NonFinite`] when any value is NaN or infinite.
pub fn check_finite(arg: &str, values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::NonFinite {
            arg: arg.into(),
            at: format!("flat index {i}"),
        }),
    }
}

/// Fails with [`Error::Order`] unless `times` is non-decreasing (equal times allowed).
pub fn check_non_decreasing(arg: &str, times: &[f64]) -> Result<()> {
    match times.windows(2).position(|w| w[1] < w[0]) {
        None => Ok(()),
        Some(i) => Err(Error::Order {
            arg: arg.into(),
            reason: format!(
                "must be sorted ascending, but element {} ({}) is before element {} ({})",
                i + 1,
                times[i + 1],
                i,
                times[i]
            ),
        }),
    }
}
