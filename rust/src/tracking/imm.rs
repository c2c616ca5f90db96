//! Interacting multiple models (IMM; Blom and Bar-Shalom 1988) for the tracker's confirmed
//! tracks: a bank of linear motion models over one state, a Markov switching matrix, and per
//! track the mode probabilities and mode-conditioned Gaussians.
//!
//! One cycle (filterpy's `IMMEstimator` order): mixing probabilities
//! `ω_ij = M_ij μ_i / c̄_j`, `c̄_j = Σ_i M_ij μ_i`; mixed initial conditions per mode; each mode
//! predicted with its own `F_j`, `Q_j`; updated with the scan (mode likelihoods `Λ_j`); then
//! `μ_j ∝ c̄_j Λ_j` and the output is the moment-matched combination `Σ_j μ_j N(x_j, P_j)`.
//!
//! Modes: any [`MotionModel`] (constant velocity, acceleration, random walk per axis), the
//! known-turn-rate coordinated turn on `[x, ẋ, y, ẏ]` (Stone Soup's `KnownTurnRate`: exact
//! transition of a constant turn at rate `ω` rad/s, positive from x towards y — starboard with
//! `x` = north, `y` = east —, process noise of a Wiener velocity per axis), and the
//! coordinated turn with the turn rate in the state `[x, ẋ, y, ẏ, ω]` ([`ConstantTurn`], Stone
//! Soup's `ConstantTurn`, predicted by EKF or UKF; the other modes of its bank are then 5-D
//! too, e.g. `[CV(q), CV(q), RandomWalk(q_ω)]`).

use crate::error::{Error, Result};
use crate::models::MotionModel;
pub use crate::tracking::turn::{ConstantTurn, TurnPredictor};
use nalgebra::{DMatrix, DVector};

/// One mode of an IMM bank.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Mode {
    /// A block-diagonal linear model.
    Linear(MotionModel),
    /// Coordinated turn at the known rate `omega` (rad/s) on `[x, ẋ, y, ẏ]`, Wiener-velocity
    /// noise `q = [q_x, q_y]` (m² s⁻³).
    KnownTurnRate { q: [f64; 2], omega: f64 },
    /// Coordinated turn with the turn rate in the state `[x, ẋ, y, ẏ, ω]` (non-linear).
    ConstantTurn(ConstantTurn),
}

impl Mode {
    /// State dimension.
    pub fn ndim(&self) -> usize {
        match self {
            Mode::Linear(m) => m.ndim(),
            Mode::KnownTurnRate { .. } => 4,
            Mode::ConstantTurn(_) => ConstantTurn::NDIM,
        }
    }

    /// The prediction `(x⁻, P⁻)` of `(x, p)` over `dt` seconds: `F x`, `F P Fᵀ + Q` for the
    /// linear modes, the EKF or UKF prediction of a [`ConstantTurn`].
    pub fn predict(
        &self,
        x: &DVector<f64>,
        p: &DMatrix<f64>,
        dt: f64,
    ) -> (DVector<f64>, DMatrix<f64>) {
        if let Mode::ConstantTurn(ct) = self {
            return ct.predict(x, p, dt);
        }
        let (f, q) = self.matrices(dt);
        (&f * x, &f * p * f.transpose() + q)
    }

    /// `F(dt)` and `Q(dt)` of a linear mode (Stone Soup's `KnownTurnRate.matrix`/`covar`;
    /// `ω = 0` is the constant-velocity limit). For a [`ConstantTurn`]: its Jacobian at zero
    /// turn rate and zero velocity (the constant-velocity matrices) and its `Q`.
    pub fn matrices(&self, dt: f64) -> (DMatrix<f64>, DMatrix<f64>) {
        let n = self.ndim();
        let mut f = DMatrix::zeros(n, n);
        let mut q = DMatrix::zeros(n, n);
        match self {
            Mode::Linear(m) => m.fill(dt, &mut f, &mut q),
            Mode::ConstantTurn(ct) => {
                let j = ConstantTurn::jacobian(&[0.0; 5], dt);
                f = DMatrix::from_fn(5, 5, |r, c| j[r][c]);
                q = ct.covar(dt);
            }
            Mode::KnownTurnRate { q: qs, omega } => {
                let w = *omega;
                let rows = if w == 0.0 {
                    [
                        [1.0, dt, 0.0, 0.0],
                        [0.0, 1.0, 0.0, 0.0],
                        [0.0, 0.0, 1.0, dt],
                        [0.0, 0.0, 0.0, 1.0],
                    ]
                } else {
                    let (s, c) = (w * dt).sin_cos();
                    [
                        [1.0, s / w, 0.0, (c - 1.0) / w],
                        [0.0, c, 0.0, -s],
                        [0.0, (1.0 - c) / w, 1.0, s / w],
                        [0.0, s, 0.0, c],
                    ]
                };
                for (i, r) in rows.iter().enumerate() {
                    for (j, v) in r.iter().enumerate() {
                        f[(i, j)] = *v;
                    }
                }
                let t = dt.abs();
                for (k, &qq) in qs.iter().enumerate() {
                    let o = 2 * k;
                    q[(o, o)] = qq * t * t * t / 3.0;
                    q[(o, o + 1)] = qq * t * t / 2.0;
                    q[(o + 1, o)] = qq * t * t / 2.0;
                    q[(o + 1, o + 1)] = qq * t;
                }
            }
        }
        (f, q)
    }
}

/// An IMM bank: modes (same state dimension), switching matrix `M[i][j]` = P(mode j next |
/// mode i now) (rows sum to 1), and the mode probabilities of a newly confirmed track.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImmConfig {
    pub modes: Vec<Mode>,
    pub transition: DMatrix<f64>,
    pub initial: Vec<f64>,
}

impl ImmConfig {
    /// Checks the bank against an `ndim`-state tracker.
    pub fn validate(&self, ndim: usize) -> Result<()> {
        let r = self.modes.len();
        if r == 0 {
            return Err(Error::param("imm.modes", "needs at least one mode"));
        }
        for (i, m) in self.modes.iter().enumerate() {
            if m.ndim() != ndim {
                return Err(Error::dim(&format!("imm.modes[{i}]"), ndim, m.ndim()));
            }
            if let Mode::KnownTurnRate { q, omega } = m {
                if !(omega.is_finite() && q.iter().all(|v| v.is_finite() && *v >= 0.0)) {
                    return Err(Error::param(
                        &format!("imm.modes[{i}]"),
                        "turn rate must be finite and noise coefficients finite and >= 0",
                    ));
                }
            }
            if let Mode::ConstantTurn(ct) = m {
                ct.validate(&format!("imm.modes[{i}]"))?;
            }
        }
        if self.transition.shape() != (r, r) {
            return Err(Error::dim(
                "imm.transition",
                format!("({r}, {r})"),
                format!("{:?}", self.transition.shape()),
            ));
        }
        for i in 0..r {
            let row = self.transition.row(i);
            if row.iter().any(|v| !(v.is_finite() && *v >= 0.0)) || (row.sum() - 1.0).abs() > 1e-9 {
                return Err(Error::param(
                    "imm.transition",
                    format!("row {i} must hold probabilities summing to 1"),
                ));
            }
        }
        if self.initial.len() != r
            || self.initial.iter().any(|v| !(v.is_finite() && *v >= 0.0))
            || (self.initial.iter().sum::<f64>() - 1.0).abs() > 1e-9
        {
            return Err(Error::param(
                "imm.initial",
                format!("must be {r} probabilities summing to 1"),
            ));
        }
        Ok(())
    }
}

/// Per-track IMM state: mode probabilities `μ` and mode-conditioned Gaussians.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ImmState {
    pub mu: Vec<f64>,
    pub x: Vec<DVector<f64>>,
    pub p: Vec<DMatrix<f64>>,
}

impl ImmState {
    /// Every mode at `(x, p)` with probabilities `mu`.
    pub fn new(x: &DVector<f64>, p: &DMatrix<f64>, mu: &[f64]) -> Self {
        Self {
            mu: mu.to_vec(),
            x: vec![x.clone(); mu.len()],
            p: vec![p.clone(); mu.len()],
        }
    }
}

/// A predicted IMM state: predicted mode probabilities `c̄` and mode predictions.
#[derive(Debug, Clone)]
pub struct ImmPrediction {
    pub cbar: Vec<f64>,
    pub x: Vec<DVector<f64>>,
    pub p: Vec<DMatrix<f64>>,
}

/// Mixing and mode predictions over `dt` seconds.
pub fn predict(cfg: &ImmConfig, st: &ImmState, dt: f64) -> ImmPrediction {
    let r = cfg.modes.len();
    let m = &cfg.transition;
    let cbar: Vec<f64> = (0..r)
        .map(|j| (0..r).map(|i| m[(i, j)] * st.mu[i]).sum())
        .collect();
    let mut xs = Vec::with_capacity(r);
    let mut ps = Vec::with_capacity(r);
    for j in 0..r {
        let w: Vec<f64> = (0..r)
            .map(|i| {
                if cbar[j] > 0.0 {
                    m[(i, j)] * st.mu[i] / cbar[j]
                } else {
                    0.0
                }
            })
            .collect();
        let mut x = DVector::zeros(st.x[0].len());
        for (xi, wi) in st.x.iter().zip(&w) {
            x += xi * *wi;
        }
        let mut p = DMatrix::zeros(x.len(), x.len());
        for ((xi, pi), wi) in st.x.iter().zip(&st.p).zip(&w) {
            let y = xi - &x;
            p += (&y * y.transpose() + pi) * *wi;
        }
        let (xj, pj) = cfg.modes[j].predict(&x, &p, dt);
        xs.push(xj);
        ps.push(pj);
    }
    ImmPrediction { cbar, x: xs, p: ps }
}

/// The moment-matched Gaussian `Σ w_j N(x_j, P_j)` (weights summing to 1).
pub fn combine(
    w: &[f64],
    xs: &[DVector<f64>],
    ps: &[DMatrix<f64>],
) -> (DVector<f64>, DMatrix<f64>) {
    let mut x = DVector::zeros(xs[0].len());
    for (xi, wi) in xs.iter().zip(w) {
        x += xi * *wi;
    }
    let mut p = DMatrix::zeros(x.len(), x.len());
    for ((xi, pi), wi) in xs.iter().zip(ps).zip(w) {
        let y = xi - &x;
        p += (&y * y.transpose() + pi) * *wi;
    }
    (x, p)
}

/// Posterior mode probabilities `μ_j ∝ c̄_j Λ_j` from log-likelihoods `ln Λ_j` (normalised in
/// the log domain; a scan every mode finds impossible keeps `c̄`).
pub fn mode_probabilities(cbar: &[f64], ln_lik: &[f64]) -> Vec<f64> {
    let lw: Vec<f64> = cbar.iter().zip(ln_lik).map(|(c, l)| c.ln() + l).collect();
    let mx = lw.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if !mx.is_finite() {
        return cbar.to_vec();
    }
    let e: Vec<f64> = lw.iter().map(|v| (v - mx).exp()).collect();
    let s: f64 = e.iter().sum();
    e.iter().map(|v| v / s).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turn_of_zero_rate_is_constant_velocity() {
        let ct = Mode::KnownTurnRate {
            q: [0.1, 0.1],
            omega: 0.0,
        };
        let cv = Mode::Linear(MotionModel::constant_velocity_2d(0.1).unwrap());
        let (f1, q1) = ct.matrices(2.0);
        let (f2, q2) = cv.matrices(2.0);
        assert_eq!(f1, f2);
        assert_eq!(q1, q2);
        // A quarter turn at 0.1 rad/s takes a northbound unit velocity to eastbound.
        let t = Mode::KnownTurnRate {
            q: [0.0, 0.0],
            omega: 0.1,
        };
        let (f, _) = t.matrices(std::f64::consts::PI / 0.2);
        let v = f * DVector::from_vec(vec![0.0, 1.0, 0.0, 0.0]);
        assert!(v[1].abs() < 1e-12 && (v[3] - 1.0).abs() < 1e-12);
    }

    /// A 5-D tracker (CV5 + CT) on a boat turning to starboard at 0.08 rad/s, plots every
    /// second without noise: one track, ω of the turn's sign, μ summing to 1, and a saved copy
    /// that continues bit-exactly.
    #[test]
    fn five_state_tracker_follows_a_turn() {
        use crate::models::Component;
        use crate::tracking::tracker::{Tracker, TrackerConfig};
        let cv5 = MotionModel::new(vec![
            Component::ConstantVelocity { q: 0.05 },
            Component::ConstantVelocity { q: 0.05 },
            Component::RandomWalk { q: 1e-6 },
        ])
        .unwrap();
        for predictor in [
            TurnPredictor::Extended,
            TurnPredictor::Unscented {
                alpha: 0.5,
                beta: 2.0,
                kappa: None,
            },
        ] {
            let mut c = TrackerConfig::code_5_7();
            c.motion_model = cv5.clone();
            let mut h = DMatrix::zeros(2, 5);
            h[(0, 0)] = 1.0;
            h[(1, 2)] = 1.0;
            c.sensors[0].h = h.clone();
            c.sensors[0].r = DMatrix::identity(2, 2);
            c.sensors[0].init = (h, DMatrix::identity(2, 2));
            c.deleter = crate::tracking::track::Deleter::StepsSinceUpdate(5);
            if let crate::tracking::config::Association::Jpda(j) = &mut c.association {
                j.prob_gate = 0.999;
                j.clutter_density = Some(1e-5);
            }
            c.initiate_in_gates = false;
            c.initiator.prior_state = DVector::zeros(5);
            c.initiator.prior_covariance =
                DMatrix::from_diagonal(&DVector::from_vec(vec![0.0, 50.0, 0.0, 50.0, 0.01]));
            c.initiator.gnn.missed_distance = 5.0;
            let ct = ConstantTurn {
                q: [0.2, 0.2],
                q_turn: 1e-4,
                predictor,
            };
            c.imm = Some(ImmConfig {
                modes: vec![Mode::Linear(cv5.clone()), Mode::ConstantTurn(ct)],
                transition: DMatrix::from_row_slice(2, 2, &[0.95, 0.05, 0.1, 0.9]),
                initial: vec![0.5, 0.5],
            });
            let mut tr = Tracker::new(c).unwrap();
            let (w, v) = (0.08, 6.0);
            let plot = |k: f64| [v / w * (w * k).sin(), v / w * (1.0 - (w * k).cos())];
            for k in 0..40 {
                tr.step(k as f64, &plot(k as f64), &[0]).unwrap();
            }
            assert_eq!(tr.tracks.len(), 1);
            let t = &tr.tracks[0];
            assert!(t.x[4] > 0.04 && t.x[4] < 0.24, "omega {}", t.x[4]);
            let mu = &t.imm.as_ref().unwrap().mu;
            assert!((mu.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let mut copy = Tracker::from_bytes(&tr.to_bytes().unwrap()).unwrap();
            tr.step(40.0, &plot(40.0), &[0]).unwrap();
            copy.step(40.0, &plot(40.0), &[0]).unwrap();
            assert_eq!(tr.tracks[0].x, copy.tracks[0].x);
            assert_eq!(tr.tracks[0].p, copy.tracks[0].p);
        }
    }

    #[test]
    fn mode_probabilities_sum_to_one() {
        let mu = mode_probabilities(&[0.7, 0.2, 0.1], &[-800.0, -801.0, -1e6]);
        assert!((mu.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(mu[0] > mu[1] && mu[2] == 0.0);
    }
}
