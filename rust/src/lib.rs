//! usvfast core: the algorithms behind the `usvfast` Python package.
//!
//! Every module here is free of pyo3, so `cargo test` and `cargo bench` never link
//! Python; the bindings live in [`py`] behind the `python` cargo feature.
//! Conventions (see `docs/design.md`): SI units, radians, NED world frame, 2-D constant-velocity
//! state `[n, v_n, e, v_e]`.

pub mod cascade;
pub mod error;
pub mod fastmath;
pub mod frames;
pub mod geodesy;
pub mod georef;
pub mod kalman;
pub mod line_of_sight;
pub mod mean_shift;
pub mod models;
pub mod nms;
pub mod particle;
pub mod pcap;
pub mod sharpness;
pub mod tracking;
pub mod velodyne;

#[cfg(feature = "python")]
pub mod py;

pub use error::{Error, Result};
