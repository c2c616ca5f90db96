//! The coordinated turn with the turn rate in the state (Stone Soup's
//! `stonesoup.models.transition.nonlinear.ConstantTurn`): state `[x, ẋ, y, ẏ, ω]` (m, m/s,
//! rad/s; `ω > 0` turns from x towards y — to starboard with `x` = north, `y` = east).
//!
//! Exact discretisation of a constant turn over `T` seconds (the coordinated-turn model with an
//! unknown turn rate of Li and Jilkov, "Survey of maneuvering target tracking, Part I: dynamic
//! models", IEEE Trans. AES 39(4), 2003), with `A(ω) = sin(ωT)/ω` and `B(ω) = (1 − cos ωT)/ω`:
//!
//! `x' = x + A ẋ − B ẏ`, `ẋ' = cos(ωT) ẋ − sin(ωT) ẏ`, `y' = y + B ẋ + A ẏ`,
//! `ẏ' = sin(ωT) ẋ + cos(ωT) ẏ`, `ω' = ω`.
//!
//! `A` and `B` are evaluated without cancellation (`B = 2 sin²(ωT/2)/ω`) and by their Taylor
//! series for `|ωT| < 0.01`, so `ω → 0` is the constant-velocity limit (`A → T`, `B → 0`)
//! without a division by zero (Stone Soup replaces `ω = 0` by machine epsilon instead).
//!
//! Process noise (Stone Soup's `covar`): `block_diag(q_x Q, q_y Q, q_ω |T|)` with
//! `Q = [[|T|³/3, |T|²/2], [|T|²/2, |T|]]`.
//!
//! Prediction is extended Kalman (analytic Jacobian; Stone Soup's `ExtendedKalmanPredictor`,
//! which differentiates numerically) or unscented (Stone Soup's `UnscentedKalmanPredictor`:
//! `gauss2sigma` sigma points, `unscented_transform` with the additive noise `Q`).

use crate::error::{Error, Result};
use crate::tracking::unscented::SigmaWeights;
use nalgebra::{DMatrix, DVector};

/// Below this `|ωT|` the turn functions use their Taylor series.
const SERIES: f64 = 1e-2;

/// How a [`ConstantTurn`] mode predicts a Gaussian.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum TurnPredictor {
    /// Extended Kalman: `x⁻ = f(x)`, `P⁻ = J P Jᵀ + Q` with the analytic Jacobian `J` at `x`.
    Extended,
    /// Unscented Kalman: sigma-point spread `alpha`, `beta` (2 for Gaussian priors), `kappa`
    /// (`None`: `3 − 5`); Stone Soup's defaults are 0.5, 2, `None`.
    Unscented {
        alpha: f64,
        beta: f64,
        kappa: Option<f64>,
    },
}

/// The constant-turn model on `[x, ẋ, y, ẏ, ω]`: Wiener-velocity noise `q = [q_x, q_y]`
/// (m² s⁻³) and turn-rate noise `q_turn` (rad² s⁻³), predicted by `predictor`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ConstantTurn {
    pub q: [f64; 2],
    pub q_turn: f64,
    pub predictor: TurnPredictor,
}

/// `(A, B, dA/dω, dB/dω)` at turn rate `w` over `t` seconds.
fn turn_terms(w: f64, t: f64) -> (f64, f64, f64, f64) {
    let a = w * t;
    if a.abs() < SERIES {
        let a2 = a * a;
        // A = T (1 − a²/6 + a⁴/120 − a⁶/5040), B = T (a/2 − a³/24 + a⁵/720 − a⁷/40320)
        let sa = t * (1.0 - a2 / 6.0 * (1.0 - a2 / 20.0 * (1.0 - a2 / 42.0)));
        let sb = t * a * (0.5 - a2 / 24.0 * (1.0 - a2 / 30.0 * (1.0 - a2 / 56.0)));
        // dA/dω = T² (−a/3 + a³/30 − a⁵/840), dB/dω = T² (1/2 − a²/8 + a⁴/144 − a⁶/5760)
        let t2 = t * t;
        let da = t2 * a * (-1.0 / 3.0 + a2 / 30.0 - a2 * a2 / 840.0);
        let db = t2 * (0.5 - a2 / 8.0 + a2 * a2 / 144.0 - a2 * a2 * a2 / 5760.0);
        return (sa, sb, da, db);
    }
    let (s, c) = a.sin_cos();
    let h = (0.5 * a).sin();
    let sa = s / w;
    let sb = 2.0 * h * h / w;
    // dA/dω = (T cos ωT − A)/ω, dB/dω = (T sin ωT − B)/ω
    let da = (t * c - sa) / w;
    let db = (t * s - sb) / w;
    (sa, sb, da, db)
}

impl ConstantTurn {
    /// State dimension (5).
    pub const NDIM: usize = 5;

    /// Checks the noise coefficients and the unscented parameters; `arg` names the mode.
    pub fn validate(&self, arg: &str) -> Result<()> {
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        if !(self.q.iter().all(|v| ok(*v)) && ok(self.q_turn)) {
            return Err(Error::param(
                arg,
                format!(
                    "noise coefficients must be finite and >= 0, got q={:?}, q_turn={}",
                    self.q, self.q_turn
                ),
            ));
        }
        if let TurnPredictor::Unscented { alpha, beta, kappa } = self.predictor {
            let n = Self::NDIM as f64;
            if !(alpha > 0.0 && alpha.is_finite() && beta.is_finite())
                || kappa.is_some_and(|k| !k.is_finite() || n + k <= 0.0)
            {
                return Err(Error::param(
                    arg,
                    format!(
                        "unscented parameters need alpha > 0, finite beta and 5 + kappa > 0, \
                         got alpha={alpha}, beta={beta}, kappa={kappa:?}"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// `f(x)` over `dt` seconds (`x` has 5 entries).
    pub fn function(x: &[f64], dt: f64) -> [f64; 5] {
        let w = x[4];
        let (sa, sb, _, _) = turn_terms(w, dt);
        let (s, c) = (w * dt).sin_cos();
        [
            x[0] + sa * x[1] - sb * x[3],
            c * x[1] - s * x[3],
            x[2] + sb * x[1] + sa * x[3],
            s * x[1] + c * x[3],
            w,
        ]
    }

    /// The Jacobian `∂f/∂x` at `x` over `dt` seconds, row-major 5×5.
    pub fn jacobian(x: &[f64], dt: f64) -> [[f64; 5]; 5] {
        let w = x[4];
        let (sa, sb, da, db) = turn_terms(w, dt);
        let (s, c) = (w * dt).sin_cos();
        let (vx, vy) = (x[1], x[3]);
        [
            [1.0, sa, 0.0, -sb, da * vx - db * vy],
            [0.0, c, 0.0, -s, -dt * (s * vx + c * vy)],
            [0.0, sb, 1.0, sa, db * vx + da * vy],
            [0.0, s, 0.0, c, dt * (c * vx - s * vy)],
            [0.0, 0.0, 0.0, 0.0, 1.0],
        ]
    }

    /// The process noise `Q(dt)` (5×5).
    pub fn covar(&self, dt: f64) -> DMatrix<f64> {
        let t = dt.abs();
        let mut q = DMatrix::zeros(5, 5);
        for (k, &qq) in self.q.iter().enumerate() {
            let o = 2 * k;
            q[(o, o)] = qq * t * t * t / 3.0;
            q[(o, o + 1)] = qq * t * t / 2.0;
            q[(o + 1, o)] = qq * t * t / 2.0;
            q[(o + 1, o + 1)] = qq * t;
        }
        q[(4, 4)] = self.q_turn * t;
        q
    }

    /// Predicts the Gaussian `(x, p)` (5, 5×5) over `dt` seconds with this mode's predictor.
    pub fn predict(
        &self,
        x: &DVector<f64>,
        p: &DMatrix<f64>,
        dt: f64,
    ) -> (DVector<f64>, DMatrix<f64>) {
        match self.predictor {
            TurnPredictor::Extended => {
                let j = Self::jacobian(x.as_slice(), dt);
                let jm = DMatrix::from_fn(5, 5, |r, c| j[r][c]);
                let xp = DVector::from_row_slice(&Self::function(x.as_slice(), dt));
                let pp = &jm * p * jm.transpose() + self.covar(dt);
                (xp, pp)
            }
            TurnPredictor::Unscented { alpha, beta, kappa } => {
                let n = Self::NDIM;
                let SigmaWeights {
                    spread: sc,
                    mean: wm,
                    covariance: wc,
                } = SigmaWeights::new(n, alpha, beta, kappa);
                let l = lower_factor(p);
                let np = 2 * n + 1;
                let mut ys: Vec<[f64; 5]> = Vec::with_capacity(np);
                ys.push(Self::function(x.as_slice(), dt));
                let mut pt = [0.0; 5];
                for sign in [1.0, -1.0] {
                    for i in 0..n {
                        for (r, v) in pt.iter_mut().enumerate() {
                            *v = x[r] + sign * l[(r, i)] * sc;
                        }
                        ys.push(Self::function(&pt, dt));
                    }
                }
                // np.average: Σ w y / Σ w.
                let wsum: f64 = wm.iter().sum();
                let mut mean = [0.0; 5];
                for (y, w) in ys.iter().zip(&wm) {
                    for r in 0..n {
                        mean[r] += y[r] * w;
                    }
                }
                mean.iter_mut().for_each(|m| *m /= wsum);
                let mut pp = self.covar(dt);
                for (y, w) in ys.iter().zip(&wc) {
                    for r in 0..n {
                        let dr = y[r] - mean[r];
                        for k in 0..n {
                            pp[(r, k)] += dr * w * (y[k] - mean[k]);
                        }
                    }
                }
                (DVector::from_row_slice(&mean), pp)
            }
        }
    }
}

/// The lower Cholesky factor of `p`; for a matrix that is not numerically positive definite,
/// the factor with every pivot below `spacing(max diag)` floored at its square root (Stone
/// Soup's `cholesky_eps`, whose lower factor this is: its `gauss2sigma` takes the upper one
/// there, which is not a square root of `p`).
fn lower_factor(p: &DMatrix<f64>) -> DMatrix<f64> {
    if let Some(c) = nalgebra::Cholesky::new(p.clone()) {
        return c.unpack();
    }
    let n = p.nrows();
    let mx = (0..n).map(|i| p[(i, i)]).fold(f64::NEG_INFINITY, f64::max);
    // np.spacing(mx): the gap to the next float away from zero.
    let eps = if mx.is_finite() {
        let a = mx.abs();
        f64::from_bits(a.to_bits() + 1) - a
    } else {
        f64::EPSILON
    };
    let mut l = DMatrix::<f64>::zeros(n, n);
    for i in 0..n {
        for j in 0..i {
            let dot: f64 = (0..n).map(|k| l[(i, k)] * l[(j, k)]).sum();
            l[(i, j)] = (p[(i, j)] - dot) / l[(j, j)];
        }
        let dot: f64 = (0..n).map(|k| l[(i, k)] * l[(i, k)]).sum();
        let v = p[(i, i)] - dot;
        l[(i, i)] = if v > eps { v.sqrt() } else { eps.sqrt() };
    }
    l
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fd_jacobian(x: &[f64], dt: f64) -> [[f64; 5]; 5] {
        // Central differences with step h: error O(h²).
        let mut j = [[0.0; 5]; 5];
        for c in 0..5 {
            let h = 1e-6 * x[c].abs().max(1e-2);
            let (mut xp, mut xm) = ([0.0; 5], [0.0; 5]);
            xp.copy_from_slice(x);
            xm.copy_from_slice(x);
            xp[c] += h;
            xm[c] -= h;
            let (fp, fm) = (
                ConstantTurn::function(&xp, dt),
                ConstantTurn::function(&xm, dt),
            );
            for r in 0..5 {
                j[r][c] = (fp[r] - fm[r]) / (2.0 * h);
            }
        }
        j
    }

    #[test]
    fn jacobian_matches_finite_differences_on_both_branches() {
        for &(w, dt) in &[
            (0.12, 2.5),
            (-0.3, 1.0),
            (1e-4, 3.0),
            (0.0, 2.0),
            (2e-3, 4.0),
        ] {
            let x = [100.0, 7.0, -50.0, -3.0, w];
            let (a, n) = (ConstantTurn::jacobian(&x, dt), fd_jacobian(&x, dt));
            for r in 0..5 {
                for c in 0..5 {
                    assert!(
                        (a[r][c] - n[r][c]).abs() < 1e-6,
                        "({r},{c}) w={w}: {a:?} {n:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn series_and_closed_form_agree_at_the_switch() {
        let t = 2.0;
        let below = turn_terms(SERIES / t * (1.0 - 1e-12), t);
        let above = turn_terms(SERIES / t * (1.0 + 1e-12), t);
        for (a, b) in [
            (below.0, above.0),
            (below.1, above.1),
            (below.2, above.2),
            (below.3, above.3),
        ] {
            assert!((a - b).abs() < 1e-12 * t * t, "{a} {b}");
        }
    }

    #[test]
    fn zero_rate_is_constant_velocity_and_quarter_turn_turns() {
        let f = ConstantTurn::function(&[1.0, 2.0, 3.0, 4.0, 0.0], 0.5);
        assert_eq!(f, [2.0, 2.0, 5.0, 4.0, 0.0]);
        let w = 0.1;
        let f = ConstantTurn::function(&[0.0, 1.0, 0.0, 0.0, w], std::f64::consts::PI / (2.0 * w));
        assert!(f[1].abs() < 1e-12 && (f[3] - 1.0).abs() < 1e-12);
        assert!((f[0] - 10.0).abs() < 1e-9 && (f[2] - 10.0).abs() < 1e-9);
    }

    #[test]
    fn unscented_of_a_linear_turn_is_the_kalman_prediction() {
        // With no uncertainty on ω the transition is linear in the rest: the unscented
        // prediction equals the extended one.
        let x = DVector::from_vec(vec![10.0, 3.0, -4.0, 1.0, 0.2]);
        let mut p = DMatrix::from_diagonal(&DVector::from_vec(vec![4.0, 1.0, 9.0, 2.0, 1e-30]));
        p[(0, 1)] = 0.5;
        p[(1, 0)] = 0.5;
        let mk = |predictor| ConstantTurn {
            q: [0.3, 0.5],
            q_turn: 0.01,
            predictor,
        };
        let (xe, pe) = mk(TurnPredictor::Extended).predict(&x, &p, 1.5);
        let u = TurnPredictor::Unscented {
            alpha: 0.5,
            beta: 2.0,
            kappa: None,
        };
        let (xu, pu) = mk(u).predict(&x, &p, 1.5);
        assert!((xe - xu).amax() < 1e-9);
        assert!((pe - pu).amax() < 1e-9);
    }

    #[test]
    fn validation_names_the_mode() {
        let bad = ConstantTurn {
            q: [1.0, -1.0],
            q_turn: 0.1,
            predictor: TurnPredictor::Extended,
        };
        assert!(
            matches!(bad.validate("imm.modes[1]"), Err(Error::InvalidParameter { arg, .. }) if arg == "imm.modes[1]")
        );
        let bad = ConstantTurn {
            q: [1.0, 1.0],
            q_turn: 0.1,
            predictor: TurnPredictor::Unscented {
                alpha: 0.0,
                beta: 2.0,
                kappa: None,
            },
        };
        assert!(bad.validate("m").is_err());
    }

    #[test]
    fn lower_factor_of_a_singular_matrix_is_finite() {
        let p = DMatrix::from_diagonal(&DVector::from_vec(vec![0.0, 1.0, 0.0, 1.0, 0.0]));
        let l = lower_factor(&p);
        assert!(l.iter().all(|v| v.is_finite()));
        assert!((&l * l.transpose() - &p).amax() < 1e-7);
    }
}
