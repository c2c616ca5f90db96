//! Shared synthetic inputs of the LiDAR benches (deterministic, no extra dependencies).

/// Tiny LCG so the benches need no RNG crate.
pub struct Lcg(u64);

impl Lcg {
    pub fn new(seed: u64) -> Self {
        Lcg(seed)
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((self.0 >> 11) as f64 / (1u64 << 53) as f64)
    }
    /// Approximately normal (sum of 4 uniforms), mean 0, standard deviation `sigma`.
    pub fn normal(&mut self, sigma: f64) -> f64 {
        let s: f64 = (0..4).map(|_| self.uniform(-0.5, 0.5)).sum();
        s * sigma * 3f64.sqrt()
    }
}

/// A harbour-like frame: `n` points uniform in a 20 m square around the sensor and `m`
/// segments cut from four wall polylines (quays and piers), flat arrays.
pub fn los_scene(n: usize, m: usize) -> (Vec<f64>, Vec<f64>) {
    let mut rng = Lcg::new(42);
    let points: Vec<f64> = (0..2 * n).map(|_| rng.uniform(-10.0, 10.0)).collect();
    let walls = [
        ([-9.0, 6.0], [9.0, 7.0]),
        ([-7.0, -9.0], [-6.0, 5.0]),
        ([3.0, -8.0], [8.0, -3.0]),
        ([9.0, -9.0], [9.5, 5.0]),
    ];
    let per_wall = m.div_ceil(walls.len());
    let mut segments = Vec::with_capacity(4 * m);
    'outer: for (a, b) in walls {
        for k in 0..per_wall {
            if segments.len() == 4 * m {
                break 'outer;
            }
            let (t0, t1) = (
                k as f64 / per_wall as f64,
                (k as f64 + 0.9) / per_wall as f64,
            );
            for t in [t0, t1] {
                segments.push(a[0] + t * (b[0] - a[0]) + rng.normal(0.03));
                segments.push(a[1] + t * (b[1] - a[1]) + rng.normal(0.03));
            }
        }
    }
    (points, segments)
}

/// `k` floating objects seen over several frames plus surface clutter: `n` 2-D points.
pub fn buffered_detections(n: usize, k: usize) -> Vec<f64> {
    let mut rng = Lcg::new(7);
    let centres: Vec<[f64; 2]> = (0..k)
        .map(|_| [rng.uniform(-9.0, 9.0), rng.uniform(-9.0, 9.0)])
        .collect();
    let clutter = n / 10;
    let mut out = Vec::with_capacity(2 * n);
    for i in 0..n - clutter {
        let c = centres[i % k];
        out.push(c[0] + rng.normal(0.15));
        out.push(c[1] + rng.normal(0.15));
    }
    for _ in 0..clutter {
        out.push(rng.uniform(-10.0, 10.0));
        out.push(rng.uniform(-10.0, 10.0));
    }
    out
}
