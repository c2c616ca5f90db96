//! Criterion benches of the camera core: NMS on 10,000 candidate boxes and georeferencing
//! with covariance of 10,000 detections.

use criterion::{criterion_group, criterion_main, Criterion};
use rand::{Rng, SeedableRng};
use std::hint::black_box;
use usvfast_core::georef::{georeference, GeorefInput, GeorefNoise};
use usvfast_core::nms::{batched_nms, nms};

fn boxes(n: usize) -> (Vec<f64>, Vec<f64>, Vec<i64>) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    let mut b = Vec::with_capacity(4 * n);
    let mut s = Vec::with_capacity(n);
    let mut c = Vec::with_capacity(n);
    for _ in 0..n {
        let (x, y) = (rng.random_range(0.0..1920.0), rng.random_range(0.0..1080.0));
        let (w, h) = (rng.random_range(10.0..100.0), rng.random_range(10.0..100.0));
        b.extend_from_slice(&[x, y, x + w, y + h]);
        s.push(rng.random_range(0.0..1.0));
        c.push(rng.random_range(0..3));
    }
    (b, s, c)
}

fn bench(c: &mut Criterion) {
    let (b, s, cls) = boxes(10_000);
    c.bench_function("nms 10k agnostic", |bench| {
        bench.iter(|| nms(black_box(&b), black_box(&s), 0.45).unwrap())
    });
    c.bench_function("nms 10k per class", |bench| {
        bench.iter(|| batched_nms(black_box(&b), black_box(&s), black_box(&cls), 0.45).unwrap())
    });

    let n = 10_000;
    let mut rng = rand::rngs::StdRng::seed_from_u64(2);
    let normalized: Vec<f64> = (0..n)
        .flat_map(|_| [rng.random_range(-0.6..0.6), rng.random_range(0.02..0.4)])
        .collect();
    let jacobian: Vec<f64> = (0..n)
        .flat_map(|_| [1.0 / 900.0, 0.0, 0.0, 1.0 / 900.0])
        .collect();
    let roll: Vec<f64> = (0..n).map(|_| rng.random_range(-0.05..0.05)).collect();
    let pitch: Vec<f64> = (0..n).map(|_| rng.random_range(-0.05..0.05)).collect();
    let height = vec![2.5; n];
    let input = GeorefInput {
        normalized: &normalized,
        jacobian: &jacobian,
        roll: &roll,
        pitch: &pitch,
        height: &height,
        r_body_cam: [0., 0., 1., 1., 0., 0., 0., 1., 0.],
        cam_position: [1.0, 0.0, -2.0],
        heading: None,
        vessel_ne: None,
        min_depression: 0.0,
        noise: GeorefNoise {
            sigma_px: [1.0, 1.0],
            sigma_roll_pitch: [0.005, 0.005],
            sigma_height: 0.05,
            sigma_heading: 0.0,
        },
    };
    c.bench_function("georeference 10k + covariance", |bench| {
        bench.iter(|| georeference(black_box(&input)).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
