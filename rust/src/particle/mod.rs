//! The two-tier multi-clustered particle filter of Bloisi et al.'s VTS camera tracker (§V,
//! Figs. 9, 10 and 12; PTracking): a local tier per sensor — sample, SIR-resample,
//! KClusterize, associate by direction, speed and proximity — and a global tier that fuses the
//! sensors' Gaussian mixtures arriving within Δt.
//!
//! Particles are image-plane states `[u, v, du, dv]` (box centre in pixels, x right / y down
//! from the top-left corner, and its velocity in pixels per frame), stored flat with stride
//! [`DIM`]. Every random number comes from the counter-based [`rng::Stream`], so a run is a
//! pure function of its seed (and a numpy re-implementation can draw the same numbers).

pub mod fuse;
pub mod kcluster;
pub mod params;
pub mod rng;
pub mod sir;
pub mod tracker;

/// Values per particle: `[u, v, du, dv]`.
pub const DIM: usize = 4;
