//! The sampling steps of the local tier (Bloisi et al. Fig. 9): propagate particles by the
//! constant-velocity transition, draw proposal particles around the observations, weight by
//! the observations' likelihood and re-sample by the SIR principle (systematic resampling).
//!
//! Particles are flat `[u, v, du, dv]` rows (px, px/frame); random numbers are drawn in row
//! order from a [`Stream`] so that the numbers are reproducible from the seed.

use super::rng::Stream;
use super::DIM;

/// Constant-velocity transition over `dt` frames with a random acceleration per particle
/// and axis, `a ~ N(0, accel_std²)` (px/frame²): `u += du·dt + a·dt²/2`, `du += a·dt`.
/// Draws two normals per particle (u axis, then v axis).
pub fn propagate(particles: &mut [f64], dt: f64, accel_std: f64, rng: &mut Stream) {
    for p in particles.chunks_exact_mut(DIM) {
        let au = accel_std * rng.normal();
        let av = accel_std * rng.normal();
        p[0] += p[2] * dt + 0.5 * au * dt * dt;
        p[1] += p[3] * dt + 0.5 * av * dt * dt;
        p[2] += au * dt;
        p[3] += av * dt;
    }
}

/// Proposal particles around one observation: `count` rows with position
/// `N(centre, pos_std²)` per axis and velocity `N(velocity, vel_std²)` per axis; draws four
/// normals per particle in the order u, v, du, dv. Appended to `out`.
pub fn sample_around(
    out: &mut Vec<f64>,
    count: usize,
    centre: [f64; 2],
    pos_std: [f64; 2],
    velocity: [f64; 2],
    vel_std: f64,
    rng: &mut Stream,
) {
    out.reserve(count * DIM);
    for _ in 0..count {
        let u = centre[0] + pos_std[0] * rng.normal();
        let v = centre[1] + pos_std[1] * rng.normal();
        let du = velocity[0] + vel_std * rng.normal();
        let dv = velocity[1] + vel_std * rng.normal();
        out.extend_from_slice(&[u, v, du, dv]);
    }
}

/// Unnormalised weights of the particles under the observations: a mixture of axis-aligned
/// Gaussians, `Σ_k exp(−½ ((u − z_u,k)²/σ_u,k² + (v − z_v,k)²/σ_v,k²)) / (2π σ_u,k σ_v,k)`
/// plus the floor `clutter` (a density per px² that keeps every weight positive).
/// `obs` rows are `[z_u, z_v, σ_u, σ_v]` (px).
pub fn weights(particles: &[f64], obs: &[[f64; 4]], clutter: f64) -> Vec<f64> {
    particles
        .chunks_exact(DIM)
        .map(|p| {
            let mut w = clutter;
            for z in obs {
                let du = (p[0] - z[0]) / z[2];
                let dv = (p[1] - z[1]) / z[3];
                w += (-0.5 * (du * du + dv * dv)).exp() / (std::f64::consts::TAU * z[2] * z[3]);
            }
            w
        })
        .collect()
}

/// Systematic resampling: `n` indices into `weights` (non-negative, positive sum), the j-th
/// being the first `i` with `W_i > (u₀ + j)/n · W_total` where `W` is the running sum and
/// `u₀` one uniform draw. Each particle is drawn `⌊n wᵢ⌋` or `⌈n wᵢ⌉` times (wᵢ normalised),
/// so the count is unbiased: its expectation is `n wᵢ`.
pub fn systematic_resample(weights: &[f64], n: usize, rng: &mut Stream) -> Vec<usize> {
    let mut cum = Vec::with_capacity(weights.len());
    let mut s = 0.0;
    for w in weights {
        s += w;
        cum.push(s);
    }
    let u0 = rng.uniform();
    let mut out = Vec::with_capacity(n);
    if weights.is_empty() || s <= 0.0 {
        return out;
    }
    let mut i = 0;
    let last = weights.len() - 1;
    for j in 0..n {
        let pos = (u0 + j as f64) / n as f64 * s;
        while i < last && cum[i] <= pos {
            i += 1;
        }
        out.push(i);
    }
    out
}

/// The rows `idx` of `particles` (a resampled set).
pub fn gather(particles: &[f64], idx: &[usize]) -> Vec<f64> {
    let mut out = Vec::with_capacity(idx.len() * DIM);
    for &i in idx {
        out.extend_from_slice(&particles[i * DIM..(i + 1) * DIM]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resample_counts_within_one_of_expectation() {
        let w = [0.1, 0.0, 0.55, 0.05, 0.3];
        for seed in 0..50 {
            let idx = systematic_resample(&w, 40, &mut Stream::new(seed));
            for (i, wi) in w.iter().enumerate() {
                let c = idx.iter().filter(|&&k| k == i).count() as f64;
                assert!((c - 40.0 * wi).abs() < 1.0 + 1e-9, "{seed} {i} {c}");
            }
        }
    }

    #[test]
    fn propagate_moves_by_velocity_without_noise() {
        let mut p = vec![10.0, 20.0, 1.5, -2.0];
        propagate(&mut p, 4.0, 0.0, &mut Stream::new(1));
        assert_eq!(p, vec![16.0, 12.0, 1.5, -2.0]);
    }
}
