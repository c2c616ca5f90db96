//! Criterion benchmark of one tracker scan in steady state (Code 5.7 configuration: CV
//! q = 0.001, position sensor σ = 0.25 m, JPDA P_D 0.85, P_G 0.95, λ = 0.125, EHM):
//! separated targets (5, 20, and 10 … 10,000 for scaling — time must grow about linearly) and
//! targets moving in parallel 0.3 m apart, inside each other's gates (8 and 20); and the small
//! scans of the Stone Soup drop-in (2 and 4 targets seen by two sensors, σ = 0.25 m and
//! 0.35 m, plus one clutter detection a scan), where the fixed cost per scan dominates.
use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use std::hint::black_box;
use usvfast_core::tracking::tracker::{Tracker, TrackerConfig};

struct Lcg(u64);
impl Lcg {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The thesis's Code 5.7 tracker (one sensor, σ = 0.25 m).
fn config() -> TrackerConfig {
    TrackerConfig::code_5_7()
}

/// Targets (on a grid `spacing` metres apart, or in a row when `spacing` < 1 m) moving at
/// (0, 0.2) m/s, and a tracker holding one confirmed track per target.
#[derive(Clone)]
struct Scene {
    tracker: Tracker,
    pos: Vec<(f64, f64)>,
    noise: Vec<f64>,
    t: f64,
    k: usize,
    z: Vec<f64>,
    s: Vec<usize>,
    /// Two sensors and one clutter detection a scan (the drop-in's small scans).
    two_sensors: bool,
}

const NOISE_SCANS: usize = 64;
const VEL: (f64, f64) = (0.0, 0.2);

impl Scene {
    fn new(n: usize, spacing: f64, two_sensors: bool) -> Self {
        let mut rng = Lcg(42);
        let side = (n as f64).sqrt().ceil() as usize;
        let pos: Vec<(f64, f64)> = (0..n)
            .map(|i| {
                if spacing < 1.0 {
                    (i as f64 * spacing, 0.0)
                } else {
                    ((i % side) as f64 * spacing, (i / side) as f64 * spacing)
                }
            })
            .collect();
        let mut cfg = config();
        if two_sensors {
            let mut second = cfg.sensors[0].clone();
            second.r *= 2.0;
            second.init.1 *= 2.0;
            cfg.sensors.push(second);
        }
        let mut tracker = Tracker::new(cfg).unwrap();
        let p0 = [
            0.05, 0.0, 0.0, 0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.0, 0.05, 0.0, 0.0, 0.0, 0.0, 0.01,
        ];
        for &(x, y) in &pos {
            tracker.add_track(&[x, VEL.0, y, VEL.1], &p0, 0.0).unwrap();
        }
        let noise = (0..NOISE_SCANS * (2 * n + 1) * 2)
            .map(|_| 0.25 * rng.normal())
            .collect();
        let mut scene = Scene {
            tracker,
            pos,
            noise,
            t: 0.0,
            k: 0,
            z: Vec::with_capacity(4 * n + 2),
            s: Vec::with_capacity(2 * n + 1),
            two_sensors,
        };
        for _ in 0..5 {
            scene.step();
        }
        scene
    }

    /// The next scan: one detection per target, 1 s later.
    fn step(&mut self) {
        self.t += 1.0;
        let n = self.pos.len();
        let per_scan = 2 * n + 1;
        let off = (self.k % NOISE_SCANS) * per_scan * 2;
        let nz = &self.noise[off..off + 2 * per_scan];
        self.k += 1;
        self.z.clear();
        self.s.clear();
        let sensors = if self.two_sensors { 2 } else { 1 };
        for s in 0..sensors {
            for (i, &(x, y)) in self.pos.iter().enumerate() {
                let j = 2 * (s * n + i);
                self.z.push(x + VEL.0 * self.t + nz[j]);
                self.z.push(y + VEL.1 * self.t + nz[j + 1]);
                self.s.push(s);
            }
        }
        if self.two_sensors {
            // Clutter far from every target (starts, then loses, tentative tracks).
            self.z.push(-50.0 + 40.0 * nz[4 * n]);
            self.z.push(-50.0 + 40.0 * nz[4 * n + 1]);
            self.s.push(1);
        }
        self.tracker
            .step(self.t, black_box(&self.z), &self.s)
            .unwrap();
    }
}

fn bench_scan(c: &mut Criterion) {
    let mut g = c.benchmark_group("tracker_scan");
    g.sample_size(10);
    let cases: Vec<(&str, usize, f64, bool)> = vec![
        ("small_two_sensor_2", 2, 100.0, true),
        ("small_two_sensor_4", 4, 100.0, true),
        ("separated_5", 5, 100.0, false),
        ("separated_20", 20, 100.0, false),
        ("parallel_0.3m_8", 8, 0.3, false),
        ("parallel_0.3m_20", 20, 0.3, false),
        ("scaling_10", 10, 100.0, false),
        ("scaling_100", 100, 100.0, false),
        ("scaling_1000", 1000, 100.0, false),
        ("scaling_10000", 10_000, 100.0, false),
    ];
    for (name, n, spacing, two) in cases {
        // Five scans from tracks started at the truth, then time the sixth scan on a fresh
        // copy each iteration (steady state without the slow coalescence of tracks that stay
        // inside each other's gates for hundreds of scans).
        let scene = Scene::new(n, spacing, two);
        if two {
            // Small scans run on one tracker (its reused buffers warm, as in a real run),
            // restarted from the fresh scene every 1,000 scans to bound the histories.
            g.bench_function(name, |b| {
                let mut s = scene.clone();
                let mut scans = 0usize;
                b.iter(|| {
                    scans += 1;
                    if scans % 1000 == 0 {
                        s = scene.clone();
                    }
                    s.step();
                })
            });
            continue;
        }
        g.bench_function(name, |b| {
            b.iter_batched(
                || {
                    let mut s = Scene {
                        tracker: scene.tracker.clone(),
                        pos: scene.pos.clone(),
                        noise: scene.noise.clone(),
                        t: scene.t,
                        k: scene.k,
                        z: scene.z.clone(),
                        s: scene.s.clone(),
                        two_sensors: scene.two_sensors,
                    };
                    s.tracker.reserve_history(8);
                    s
                },
                |mut s| {
                    s.step();
                    s
                },
                BatchSize::LargeInput,
            )
        });
    }
    g.finish();
}

criterion_group!(benches, bench_scan);
criterion_main!(benches);
