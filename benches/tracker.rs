//! Criterion benchmark of one tracker scan in steady state (Code 5.7 configuration: CV
//! q = 0.001, position sensor σ = 0.25 m, JPDA P_D 0.85, P_G 0.95, λ = 0.125, EHM):
//! separated targets (5, 20, and 10 … 10,000 for scaling — time must grow about linearly) and
//! targets moving in parallel 0.3 m apart, inside each other's gates (8 and 20); and the small
//! scans of the Stone Soup drop-in (2 and 4 targets seen by two sensors, σ = 0.25 m and
//! 0.35 m, plus one clutter detection a scan), where the fixed cost per scan dominates.
//! `imm_scan`: one scan of IMM trackers (1 and 20 separated targets): the 4-D bank of the
//! `joyride` preset (CV, CV-high, known-rate turns at ±0.09 and ±0.16 rad/s) against the
//! 5-D bank with the turn rate in the state (CV5, CV5-high and a `ConstantTurn`, EKF or UKF).
//! `existence_scan`: one scan of a cluster (the parallel scenes, 8 and 20 tracks) with
//! existence and visibility per track (IPDA) and joint (JIPDA).
use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use nalgebra::{DMatrix, DVector};
use std::hint::black_box;
use usvfast_core::models::{Component, MotionModel};
use usvfast_core::tracking::config::Existence;
use usvfast_core::tracking::imm::{ConstantTurn, ImmConfig, Mode, TurnPredictor};
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
        Self::with_config(n, spacing, two_sensors, config())
    }

    fn with_config(n: usize, spacing: f64, two_sensors: bool, mut cfg: TrackerConfig) -> Self {
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

/// One scan of the 0.3 m parallel scenes (one cluster of 8 or 20 tracks) with existence and
/// visibility per track (IPDA) and joint (JIPDA): survival 0.99, vis_stay 0.95, invis_stay 0.5.
fn bench_existence_scan(c: &mut Criterion) {
    let mut g = c.benchmark_group("existence_scan");
    g.sample_size(10);
    for n in [8, 20] {
        for joint in [false, true] {
            let mut cfg = config();
            cfg.existence = Some(Existence {
                survival: 0.99,
                initial: 0.9,
                delete: 0.0,
                vis_stay: 0.95,
                invis_stay: 0.5,
                confirm: None,
                birth: 0.5,
                joint,
            });
            let scene = Scene::with_config(n, 0.3, false, cfg);
            let name = format!("parallel_0.3m_{n}_{}", if joint { "jipda" } else { "ipda" });
            g.bench_function(name, |b| {
                b.iter_batched(
                    || {
                        let mut s = scene.clone();
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
    }
    g.finish();
}

/// The IMM banks of `bench_imm_scan`: Code 5.7 with σ = 2 m, JPDA λ = 1e-5, and the bank.
fn imm_config(bank: &str) -> TrackerConfig {
    let mut cfg = config();
    cfg.association = usvfast_core::tracking::tracker::Association::Jpda(
        usvfast_core::tracking::tracker::JpdaParams {
            prob_detect: 0.9,
            prob_gate: 0.999,
            clutter_density: Some(1e-5),
            include_all: false,
            method: usvfast_core::tracking::jpda::Method::Ehm,
            max_hypotheses: None,
        },
    );
    cfg.deleter = usvfast_core::tracking::track::Deleter::StepsSinceUpdate(5);
    let cv = |q: f64| MotionModel::constant_velocity_2d(q).unwrap();
    let cv5 = |q: f64| {
        MotionModel::new(vec![
            Component::ConstantVelocity { q },
            Component::ConstantVelocity { q },
            Component::RandomWalk { q: 1e-5 },
        ])
        .unwrap()
    };
    let (modes, n) = if bank == "known_rate_4d" {
        let mut m = vec![Mode::Linear(cv(0.03)), Mode::Linear(cv(25.0))];
        for w in [0.09, -0.09, 0.16, -0.16] {
            m.push(Mode::KnownTurnRate {
                q: [4.0, 4.0],
                omega: w,
            });
        }
        (m, 4)
    } else {
        let predictor = if bank == "ct_ukf_5d" {
            TurnPredictor::Unscented {
                alpha: 0.5,
                beta: 2.0,
                kappa: None,
            }
        } else {
            TurnPredictor::Extended
        };
        let ct = ConstantTurn {
            q: [0.2, 0.2],
            q_turn: 1e-3,
            predictor,
        };
        (
            vec![
                Mode::Linear(cv5(0.03)),
                Mode::Linear(cv5(10.0)),
                Mode::ConstantTurn(ct),
            ],
            5,
        )
    };
    let r = modes.len();
    let stay = 0.97;
    let mut m = DMatrix::from_element(r, r, (1.0 - stay) / (r - 1) as f64);
    m.fill_diagonal(stay);
    cfg.imm = Some(ImmConfig {
        modes,
        transition: m,
        initial: vec![1.0 / r as f64; r],
    });
    let mut h = DMatrix::zeros(2, n);
    h[(0, 0)] = 1.0;
    h[(1, 2)] = 1.0;
    let sensor = &mut cfg.sensors[0];
    sensor.r = DMatrix::identity(2, 2) * 4.0;
    sensor.h = h.clone();
    sensor.init = (h, sensor.r.clone());
    cfg.motion_model = if n == 5 { cv5(0.03) } else { cv(0.03) };
    cfg.initiator.prior_state = DVector::zeros(n);
    cfg.initiator.prior_covariance = DMatrix::identity(n, n);
    cfg
}

fn bench_imm_scan(c: &mut Criterion) {
    let mut g = c.benchmark_group("imm_scan");
    g.sample_size(20);
    for bank in ["known_rate_4d", "ct_ekf_5d", "ct_ukf_5d"] {
        for n in [1usize, 20] {
            let mut tracker = Tracker::new(imm_config(bank)).unwrap();
            let nd = if bank == "known_rate_4d" { 4 } else { 5 };
            let mut p0 = vec![0.0; nd * nd];
            for i in 0..nd {
                p0[i * nd + i] = if i == 4 { 1e-3 } else { 1.0 };
            }
            for i in 0..n {
                let mut x = vec![100.0 * i as f64, 3.0, 0.0, 1.0];
                x.truncate(nd.min(4));
                if nd == 5 {
                    x.push(0.02);
                }
                tracker.add_track(&x, &p0, 0.0).unwrap();
            }
            let mut rng = Lcg(7);
            let mut t = 0.0;
            let mut scan = |tr: &mut Tracker, t: &mut f64| {
                *t += 1.0;
                let z: Vec<f64> = (0..n)
                    .flat_map(|i| {
                        [
                            100.0 * i as f64 + 3.0 * *t + 2.0 * rng.normal(),
                            *t + 2.0 * rng.normal(),
                        ]
                    })
                    .collect();
                tr.step(*t, black_box(&z), &vec![0; n]).unwrap();
            };
            for _ in 0..5 {
                scan(&mut tracker, &mut t);
            }
            g.bench_function(format!("{bank}_{n}"), |b| {
                b.iter_batched(
                    || {
                        let mut tr = tracker.clone();
                        tr.reserve_history(8);
                        tr
                    },
                    |mut tr| {
                        let mut tt = t;
                        scan(&mut tr, &mut tt);
                        tr
                    },
                    BatchSize::LargeInput,
                )
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench_scan, bench_imm_scan, bench_existence_scan);
criterion_main!(benches);
