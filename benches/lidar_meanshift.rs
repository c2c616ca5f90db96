//! Criterion benchmark of the flat-kernel mean shift: 500 buffered 2-D points (8 floating
//! objects + 10 % clutter), bandwidth 2 m, cluster_all = false, with and without bin seeding.
use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use usvfast_core::mean_shift::{mean_shift, MeanShiftParams};

#[path = "lidar_scene.rs"]
#[allow(dead_code)]
mod lidar_scene;

fn bench_mean_shift(c: &mut Criterion) {
    let x = lidar_scene::buffered_detections(500, 8);
    let mut g = c.benchmark_group("mean_shift_500");
    for bin_seeding in [false, true] {
        let params = MeanShiftParams {
            bandwidth: 2.0,
            cluster_all: false,
            bin_seeding,
            ..Default::default()
        };
        let name = if bin_seeding {
            "bin_seeding"
        } else {
            "all_seeds"
        };
        g.bench_function(name, |b| {
            b.iter(|| mean_shift(black_box(&x), 2, None, &params).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench_mean_shift);
criterion_main!(benches);
