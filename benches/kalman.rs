//! Criterion benchmark of the batch Kalman filter + RTS smoother: 10,000 bearing samples,
//! 2-state Wiener velocity, irregular dt, two measurement noises (the bearing-fusion case).
use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use usvfast_core::kalman::{run_batch, BatchInput};
use usvfast_core::models::{Component, MotionModel};

fn sequence(n: usize) -> (Vec<f64>, Vec<f64>, Vec<usize>) {
    // Deterministic pseudo-random irregular sampling without extra dependencies.
    let mut state = 12345u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut t = 0.0;
    let (mut times, mut z, mut idx) = (vec![], vec![], vec![]);
    for i in 0..n {
        t += 0.05 + 0.2 * uniform();
        times.push(t);
        z.push(0.01 * t + uniform() - 0.5);
        idx.push(i % 2);
    }
    (times, z, idx)
}

fn bench_batch(c: &mut Criterion) {
    let model = MotionModel::new(vec![Component::ConstantVelocity { q: 1e-4 }]).unwrap();
    let (times, z, idx) = sequence(10_000);
    let noise = [0.49, 1.0];
    let input = BatchInput {
        times: &times,
        measurements: &z,
        measurement_dim: 1,
        measurement_matrix: &[1.0, 0.0],
        measurement_noise: &noise,
        noise_index: Some(&idx),
        prior_state: &[0.0, 0.0],
        prior_covariance: &[100.0, 0.0, 0.0, 1.0],
        prior_time: times[0],
    };
    c.bench_function("kf_rts_10k_2state", |b| {
        b.iter(|| run_batch(black_box(&model), black_box(&input), true).unwrap())
    });
    c.bench_function("kf_only_10k_2state", |b| {
        b.iter(|| run_batch(black_box(&model), black_box(&input), false).unwrap())
    });
}

criterion_group!(benches, bench_batch);
criterion_main!(benches);
