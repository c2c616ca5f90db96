//! The global tier of the two-tier filter (Bloisi et al. Fig. 9): collect the Gaussian
//! mixtures that the sensors sent within Δt, draw particles from their union
//! `π̃ = Σ_s λ_s N(μ_s, σ_s)`, and KClusterize them into the global mixture.

use super::kcluster::{kclusterize, Cluster, ClusterParams};
use super::rng::Stream;
use super::sir::systematic_resample;
use super::DIM;
use crate::error::{Error, Result};

/// One component a sensor sent: its time (s), weight λ, mean and standard deviation of
/// `[u, v, du, dv]` in the common frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Component {
    /// Time of the sensor's estimate (s).
    pub time: f64,
    /// λ: weight of the component in its sensor's mixture.
    pub weight: f64,
    /// Mean `[u, v, du, dv]`.
    pub mean: [f64; DIM],
    /// Standard deviation of `[u, v, du, dv]` (axis-aligned).
    pub std: [f64; DIM],
}

/// The global mixture at time `now` from the components whose time lies in
/// `[now − window, now]`: `n` particles drawn from the weighted union (components picked by
/// systematic resampling on λ, then `mean + std · N(0, 1)` per value in the order u, v, du,
/// dv), clustered by KClusterize. Returns the clusters and the particles (flat rows).
/// Fails on a negative window or weight, or a non-finite value.
pub fn fuse_mixtures(
    components: &[Component],
    now: f64,
    window: f64,
    n: usize,
    params: &ClusterParams,
    seed: u64,
) -> Result<(Vec<Cluster>, Vec<f64>)> {
    if !window.is_finite() || window < 0.0 || !now.is_finite() {
        return Err(Error::param(
            "window",
            "must be finite and ≥ 0 (and now finite)",
        ));
    }
    for c in components {
        let finite = c.time.is_finite()
            && c.weight.is_finite()
            && c.mean.iter().chain(c.std.iter()).all(|v| v.is_finite());
        if !finite || c.weight < 0.0 || c.std.iter().any(|s| *s < 0.0) {
            return Err(Error::param(
                "components",
                "times, weights, means and stds must be finite, weights and stds ≥ 0",
            ));
        }
    }
    let inside: Vec<&Component> = components
        .iter()
        .filter(|c| c.time <= now && now - c.time <= window)
        .collect();
    let w: Vec<f64> = inside.iter().map(|c| c.weight).collect();
    let mut rng = Stream::new(seed);
    let pick = systematic_resample(&w, n, &mut rng);
    let mut particles = Vec::with_capacity(pick.len() * DIM);
    for k in pick {
        let c = inside[k];
        for d in 0..DIM {
            particles.push(c.mean[d] + c.std[d] * rng.normal());
        }
    }
    let weights = vec![1.0; particles.len() / DIM];
    Ok((kclusterize(&particles, &weights, params), particles))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn comp(time: f64, u: f64) -> Component {
        Component {
            time,
            weight: 1.0,
            mean: [u, 100.0, 1.0, 0.0],
            std: [2.0, 2.0, 0.1, 0.1],
        }
    }

    #[test]
    fn two_sensors_on_one_boat_fuse_into_one_component() {
        let c = [comp(0.9, 100.0), comp(1.0, 104.0), comp(0.2, 300.0)];
        let (g, _) = fuse_mixtures(&c, 1.0, 0.5, 400, &ClusterParams::default(), 1).unwrap();
        assert_eq!(g.len(), 1);
        assert!((g[0].mean[0] - 102.0).abs() < 0.6, "{:?}", g[0].mean);
        assert!((g[0].weight - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_window_is_an_error() {
        assert!(fuse_mixtures(&[], 0.0, -1.0, 10, &ClusterParams::default(), 0).is_err());
    }
}
