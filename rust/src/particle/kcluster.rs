//! KClusterize (Bloisi et al. Fig. 10): group particles into clusters without knowing their
//! number, keep the clusters that look Gaussian and split the others with a smaller radius.
//!
//! 1. Centroids: a particle becomes a centroid when it is farther than δ (image distance of
//!    `u, v`, px) from every centroid so far (one pass, in order).
//! 2. Each particle joins its nearest centroid (every particle lies within δ of one).
//! 3. A cluster is Gaussian when it has at least `min_size` members and the kurtosis of its
//!    members along each image axis is at least `min_kurtosis` (a normal's is 3; two
//!    separated blobs give values towards 1). Non-Gaussian clusters are re-clustered with
//!    δ/2, at most `max_depth` times, and only their Gaussian parts kept.
//!
//! Linear in the number of particles times the number of clusters.

use super::DIM;

/// KClusterize parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClusterParams {
    /// δ_model: the clustering radius (px).
    pub delta: f64,
    /// Least members of a kept cluster.
    pub min_size: usize,
    /// Least per-axis kurtosis of a Gaussian cluster (clusters under 8 members are not tested).
    pub min_kurtosis: f64,
    /// How many times a non-Gaussian cluster may be split with half the radius.
    pub max_depth: usize,
}

impl Default for ClusterParams {
    fn default() -> Self {
        Self {
            delta: 20.0,
            min_size: 8,
            min_kurtosis: 1.9,
            max_depth: 3,
        }
    }
}

/// One Gaussian component: weight λ (share of the input weight), mean and standard
/// deviation of `[u, v, du, dv]` (weighted by the particle weights), and the member indices.
#[derive(Debug, Clone, PartialEq)]
pub struct Cluster {
    /// λ: the members' share of the total weight.
    pub weight: f64,
    /// Mean `[u, v, du, dv]` (px, px/frame).
    pub mean: [f64; DIM],
    /// Standard deviation of each of `[u, v, du, dv]`.
    pub std: [f64; DIM],
    /// Indices of the member particles (ascending).
    pub members: Vec<usize>,
}

fn dist2(p: &[f64], q: &[f64]) -> f64 {
    (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)
}

fn moments(particles: &[f64], weights: &[f64], members: &[usize]) -> ([f64; DIM], [f64; DIM], f64) {
    let mut wsum = 0.0;
    let mut mean = [0.0; DIM];
    for &i in members {
        let w = weights[i];
        wsum += w;
        for d in 0..DIM {
            mean[d] += w * particles[i * DIM + d];
        }
    }
    let mut var = [0.0; DIM];
    if wsum > 0.0 {
        for m in &mut mean {
            *m /= wsum;
        }
        for &i in members {
            let w = weights[i];
            for d in 0..DIM {
                var[d] += w * (particles[i * DIM + d] - mean[d]).powi(2);
            }
        }
        for v in &mut var {
            *v /= wsum;
        }
    }
    (mean, var.map(f64::sqrt), wsum)
}

fn is_gaussian(
    particles: &[f64],
    members: &[usize],
    mean: &[f64; DIM],
    std: &[f64; DIM],
    p: &ClusterParams,
) -> bool {
    if members.len() < p.min_size {
        return false;
    }
    if members.len() < 8 {
        return true;
    }
    for d in 0..2 {
        if std[d] <= 1e-9 {
            continue; // a point mass is a degenerate Gaussian
        }
        let k = members
            .iter()
            .map(|&i| ((particles[i * DIM + d] - mean[d]) / std[d]).powi(4))
            .sum::<f64>()
            / members.len() as f64;
        if k < p.min_kurtosis {
            return false;
        }
    }
    true
}

fn leader(particles: &[f64], members: &[usize], delta: f64) -> Vec<Vec<usize>> {
    let d2 = delta * delta;
    let mut centroids: Vec<usize> = Vec::new();
    for &i in members {
        let p = &particles[i * DIM..i * DIM + DIM];
        if centroids
            .iter()
            .all(|&c| dist2(p, &particles[c * DIM..c * DIM + DIM]) > d2)
        {
            centroids.push(i);
        }
    }
    let mut groups = vec![Vec::new(); centroids.len()];
    for &i in members {
        let p = &particles[i * DIM..i * DIM + DIM];
        let mut best = (f64::INFINITY, 0);
        for (k, &c) in centroids.iter().enumerate() {
            let d = dist2(p, &particles[c * DIM..c * DIM + DIM]);
            if d < best.0 {
                best = (d, k);
            }
        }
        groups[best.1].push(i);
    }
    groups
}

#[allow(clippy::too_many_arguments)]
fn recurse(
    particles: &[f64],
    weights: &[f64],
    total: f64,
    members: &[usize],
    delta: f64,
    depth: usize,
    p: &ClusterParams,
    out: &mut Vec<Cluster>,
) {
    for group in leader(particles, members, delta) {
        let (mean, std, w) = moments(particles, weights, &group);
        if is_gaussian(particles, &group, &mean, &std, p) {
            out.push(Cluster {
                weight: w / total,
                mean,
                std,
                members: group,
            });
        } else if depth > 0 && group.len() >= p.min_size {
            recurse(
                particles,
                weights,
                total,
                &group,
                delta / 2.0,
                depth - 1,
                p,
                out,
            );
        }
    }
}

/// The Gaussian mixture of a particle set (`particles` flat `[u, v, du, dv]` rows, positive
/// `weights` one per row): clusters in order of their first centroid, each member of at most
/// one cluster. Returns an empty list when there are no particles.
pub fn kclusterize(particles: &[f64], weights: &[f64], p: &ClusterParams) -> Vec<Cluster> {
    let n = particles.len() / DIM;
    let total: f64 = weights.iter().sum();
    let mut out = Vec::new();
    if n == 0 || total <= 0.0 {
        return out;
    }
    let all: Vec<usize> = (0..n).collect();
    recurse(
        particles,
        weights,
        total,
        &all,
        p.delta,
        p.max_depth,
        p,
        &mut out,
    );
    for c in &mut out {
        c.members.sort_unstable();
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::particle::rng::Stream;

    fn blob(out: &mut Vec<f64>, n: usize, c: [f64; 2], s: f64, rng: &mut Stream) {
        for _ in 0..n {
            let u = c[0] + s * rng.normal();
            let v = c[1] + s * rng.normal();
            out.extend_from_slice(&[u, v, 0.0, 0.0]);
        }
    }

    #[test]
    fn two_separated_blobs_give_two_components() {
        let mut rng = Stream::new(3);
        let mut p = Vec::new();
        blob(&mut p, 100, [50.0, 50.0], 3.0, &mut rng);
        blob(&mut p, 60, [150.0, 60.0], 3.0, &mut rng);
        let w = vec![1.0; 160];
        let c = kclusterize(&p, &w, &ClusterParams::default());
        assert_eq!(c.len(), 2);
        assert!((c[0].weight - 100.0 / 160.0).abs() < 1e-12);
        assert!((c[0].mean[0] - 50.0).abs() < 1.5 && (c[1].mean[0] - 150.0).abs() < 1.5);
    }

    #[test]
    fn touching_blobs_are_split() {
        // two blobs 30 px apart, both within one δ = 40 px cluster at first
        let mut rng = Stream::new(5);
        let mut p = Vec::new();
        blob(&mut p, 100, [50.0, 50.0], 2.0, &mut rng);
        blob(&mut p, 100, [80.0, 50.0], 2.0, &mut rng);
        let w = vec![1.0; 200];
        let params = ClusterParams {
            delta: 60.0,
            ..ClusterParams::default()
        };
        let c = kclusterize(&p, &w, &params);
        assert_eq!(c.len(), 2, "{c:?}");
    }
}
