//! Criterion benchmark of the batch WGS84 conversions on 100,000 points spread over the globe
//! (heights -1 km .. 100 km) and, for the local frames, within ~50 km of one origin.
use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use usvfast_core::geodesy::{self, Ellipsoid, LocalFrame};

fn points(n: usize) -> [Vec<f64>; 3] {
    let mut state = 7u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = [vec![], vec![], vec![]];
    for _ in 0..n {
        out[0].push((2.0 * uniform() - 1.0).asin().to_degrees());
        out[1].push(360.0 * uniform() - 180.0);
        out[2].push(101_000.0 * uniform() - 1000.0);
    }
    out
}

fn bench(c: &mut Criterion) {
    let w = Ellipsoid::WGS84;
    let n = 100_000;
    let [lat, lon, h] = points(n);
    let [x, y, z] = geodesy::geodetic2ecef(&w, &lat, &lon, &h, true).unwrap();
    let near_lat: Vec<f64> = lat.iter().map(|v| 59.9 + v / 200.0).collect();
    let near_lon: Vec<f64> = lon.iter().map(|v| 10.7 + v / 200.0).collect();
    let origin = [
        ("lat0", &[59.9][..]),
        ("lon0", &[10.7][..]),
        ("h0", &[20.0][..]),
    ];
    let pts = [
        ("lat", &near_lat[..]),
        ("lon", &near_lon[..]),
        ("h", &h[..]),
    ];
    let [nn, ee, dd] = geodesy::geodetic2local(&w, LocalFrame::Ned, pts, origin, true).unwrap();
    let ned = [("n", &nn[..]), ("e", &ee[..]), ("d", &dd[..])];

    let mut g = c.benchmark_group("geodesy_100k");
    g.bench_function("geodetic2ecef", |b| {
        b.iter(|| geodesy::geodetic2ecef(&w, black_box(&lat), &lon, &h, true).unwrap())
    });
    g.bench_function("ecef2geodetic", |b| {
        b.iter(|| geodesy::ecef2geodetic(&w, black_box(&x), &y, &z, true).unwrap())
    });
    g.bench_function("geodetic2ned", |b| {
        b.iter(|| geodesy::geodetic2local(&w, LocalFrame::Ned, black_box(pts), origin, true))
    });
    g.bench_function("ned2geodetic", |b| {
        b.iter(|| geodesy::local2geodetic(&w, LocalFrame::Ned, black_box(ned), origin, true))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
