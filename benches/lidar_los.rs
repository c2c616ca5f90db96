//! Criterion benchmark of the line-of-sight filter: 30,000 points × 200 wall segments (one
//! VLP-16 frame with LSD lines), bearing sweep vs the naive O(n·m) loop.
use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use usvfast_core::line_of_sight::{line_of_sight_filter, line_of_sight_filter_naive};

#[path = "lidar_scene.rs"]
#[allow(dead_code)]
mod lidar_scene;

fn bench_los(c: &mut Criterion) {
    let (points, segments) = lidar_scene::los_scene(30_000, 200);
    let mut g = c.benchmark_group("line_of_sight_30000x200");
    g.bench_function("sweep", |b| {
        b.iter(|| line_of_sight_filter(black_box(&points), &segments, [0.0, 0.0], 0.1).unwrap())
    });
    g.bench_function("naive", |b| {
        b.iter(|| {
            line_of_sight_filter_naive(black_box(&points), &segments, [0.0, 0.0], 0.1).unwrap()
        })
    });
    g.finish();
}

criterion_group!(benches, bench_los);
criterion_main!(benches);
