//! Range–bearing (polar) measurements: `z = (φ, ρ)` of a target at state positions
//! `(x, y) = (x[i], x[j])` seen from a sensor at `(x₀, y₀)` (Stone Soup's
//! `CartesianToBearingRange` without rotation):
//!
//! `φ = atan2(y − y₀, x − x₀)`, `ρ = sqrt((x − x₀)² + (y − y₀)²)`, noise `R` on `(φ, ρ)`.
//!
//! With the state `[n, v_n, e, v_e]` and mapping `(0, 2)` (`x` = north, `y` = east), `φ` is the
//! compass bearing (clockwise from north), in radians. Bearings and bearing residuals are
//! wrapped to `[−π, π)` like Stone Soup's `Bearing`.
//!
//! The innovation is formed either by linearisation at the prediction (extended Kalman:
//! Jacobian `J`, `S = J P Jᵀ + R`, `P_xz = P Jᵀ`) or by the unscented transform (sigma points
//! of Julier and Uhlmann with Stone Soup's `gauss2sigma` parameters `α`, `β`, `κ`; circular
//! weighted mean of the bearings).

use crate::error::{Error, Result};
use crate::tracking::hypothesise::{finish, Alloc, Innovation};
use crate::tracking::unscented::SigmaWeights;
use nalgebra::{Cholesky, DefaultAllocator, Dim, OMatrix, OVector, U1};
use std::f64::consts::PI;

/// How a polar measurement is turned into an innovation.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum PolarUpdate {
    /// Extended Kalman (Stone Soup `ExtendedKalmanUpdater`, analytic Jacobian).
    Extended,
    /// Unscented Kalman (Stone Soup `UnscentedKalmanUpdater`): sigma-point spread `alpha`,
    /// `beta` (2 for Gaussian priors), `kappa` (`None`: `3 − n`).
    Unscented {
        alpha: f64,
        beta: f64,
        kappa: Option<f64>,
    },
}

/// A range–bearing sensor model: the state indices of the Cartesian `(x, y)` it observes and
/// the update.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Polar {
    pub mapping: [usize; 2],
    pub update: PolarUpdate,
}

/// Wraps an angle to `[−π, π)` (Stone Soup's `mod_bearing`).
pub fn wrap(a: f64) -> f64 {
    (a + PI).rem_euclid(2.0 * PI) - PI
}

impl Polar {
    /// `(φ, ρ)` of the state `x` from `origin`.
    pub fn function(&self, x: &[f64], origin: [f64; 2]) -> [f64; 2] {
        let dx = x[self.mapping[0]] - origin[0];
        let dy = x[self.mapping[1]] - origin[1];
        [wrap(dy.atan2(dx)), (dx * dx + dy * dy).sqrt()]
    }

    /// The Jacobian's non-zero block `∂(φ, ρ)/∂(x, y)` at `x` (row-major 2×2), or an error at
    /// zero range.
    fn jacobian_block(&self, x: &[f64], origin: [f64; 2]) -> Result<[f64; 4]> {
        let dx = x[self.mapping[0]] - origin[0];
        let dy = x[self.mapping[1]] - origin[1];
        let r2 = dx * dx + dy * dy;
        if r2.is_nan() || r2 <= 0.0 || r2.is_infinite() {
            return Err(Error::param(
                "origins",
                "a track is at the polar sensor's position (zero range: the bearing is undefined)",
            ));
        }
        let r = r2.sqrt();
        Ok([-dy / r2, dx / r2, dx / r, dy / r])
    }

    /// The innovation of the prediction `(x, p)` for a detection with noise `r` seen from
    /// `origin`.
    pub(crate) fn innovation<N: Dim, M: Dim>(
        &self,
        x: &OVector<f64, N>,
        p: &OMatrix<f64, N, N>,
        r: &OMatrix<f64, M, M>,
        origin: [f64; 2],
    ) -> Result<Innovation<N, M>>
    where
        DefaultAllocator: Alloc<N, M>,
    {
        let (n, _) = p.shape_generic();
        let (m, _) = r.shape_generic();
        match self.update {
            PolarUpdate::Extended => {
                let jb = self.jacobian_block(x.as_slice(), origin)?;
                let mut h = OMatrix::<f64, M, N>::zeros_generic(m, n);
                for (row, k) in [(0, 0), (1, 2)] {
                    h[(row, self.mapping[0])] = jb[k];
                    h[(row, self.mapping[1])] = jb[k + 1];
                }
                let f = self.function(x.as_slice(), origin);
                let zhat = OVector::<f64, M>::from_column_slice_generic(m, U1, &f);
                let pht = p * h.transpose();
                let hph = &h * &pht;
                finish(zhat, hph, pht, r, Some(r.clone()), Some(h), true)
            }
            PolarUpdate::Unscented { alpha, beta, kappa } => {
                let nd = n.value();
                let SigmaWeights {
                    spread: sc,
                    mean: wm,
                    covariance: wc,
                } = SigmaWeights::new(nd, alpha, beta, kappa);
                let l = Cholesky::new(p.clone())
                    .ok_or_else(|| Error::NotPositiveDefinite {
                        arg: "track covariance".into(),
                        reason: "the predicted covariance of a track is not positive definite \
                                 (the unscented update needs its Cholesky factor)"
                            .into(),
                    })?
                    .unpack();
                let np = 2 * nd + 1;
                // Sigma points and their measurements.
                let mut pts: Vec<OVector<f64, N>> = Vec::with_capacity(np);
                pts.push(x.clone());
                for i in 0..nd {
                    pts.push(x + l.column(i) * sc);
                }
                for i in 0..nd {
                    pts.push(x - l.column(i) * sc);
                }
                let zs: Vec<[f64; 2]> = pts
                    .iter()
                    .map(|s| self.function(s.as_slice(), origin))
                    .collect();
                let wsum: f64 = wm.iter().sum();
                let (mut ss, mut cs, mut rs) = (0.0, 0.0, 0.0);
                for (z, w) in zs.iter().zip(&wm) {
                    ss += z[0].sin() * w;
                    cs += z[0].cos() * w;
                    rs += z[1] * w;
                }
                let mean = [wrap((ss / wsum).atan2(cs / wsum)), rs / wsum];
                let mut hph = OMatrix::<f64, M, M>::zeros_generic(m, m);
                let mut pht = OMatrix::<f64, N, M>::zeros_generic(n, m);
                for ((z, pt), w) in zs.iter().zip(&pts).zip(&wc) {
                    let d = [wrap(z[0] - mean[0]), z[1] - mean[1]];
                    for a in 0..2 {
                        for b in 0..2 {
                            hph[(a, b)] += d[a] * w * d[b];
                        }
                    }
                    let dx = pt - &pts[0];
                    for a in 0..nd {
                        for b in 0..2 {
                            pht[(a, b)] += dx[a] * w * d[b];
                        }
                    }
                }
                let zhat = OVector::<f64, M>::from_column_slice_generic(m, U1, &mean);
                finish(zhat, hph, pht, r, Some(r.clone()), None, true)
            }
        }
    }

    /// The state positions of a detection `z = (φ, ρ)` seen from `origin`, and the mapped block
    /// of the initiation covariance `J⁺ R J⁺ᵀ` (`J` the Jacobian at that position; Stone
    /// Soup's `SimpleMeasurementInitiator` with a reversible model), row-major 2×2.
    pub fn inverse(&self, z: &[f64], r: &[f64], origin: [f64; 2]) -> Result<([f64; 2], [f64; 4])> {
        let (phi, rho) = (z[0], z[1]);
        let pos = [origin[0] + rho * phi.cos(), origin[1] + rho * phi.sin()];
        let mut state = vec![0.0; self.mapping[0].max(self.mapping[1]) + 1];
        state[self.mapping[0]] = pos[0];
        state[self.mapping[1]] = pos[1];
        let j = self.jacobian_block(&state, origin)?;
        let ji = nalgebra::Matrix2::new(j[0], j[1], j[2], j[3])
            .try_inverse()
            .ok_or_else(|| {
                Error::param(
                    "measurements",
                    "a polar detection at zero range cannot start a track",
                )
            })?;
        let rm = nalgebra::Matrix2::new(r[0], r[1], r[2], r[3]);
        let c = ji * rm * ji.transpose();
        Ok((pos, [c[(0, 0)], c[(0, 1)], c[(1, 0)], c[(1, 1)]]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Matrix4, Vector4, U2, U4};

    #[test]
    fn wrap_matches_mod_bearing() {
        assert_eq!(wrap(PI), -PI);
        assert!((wrap(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-15);
        assert!((wrap(-0.1) + 0.1).abs() < 1e-15);
    }

    #[test]
    fn ekf_jacobian_matches_finite_differences() {
        let pol = Polar {
            mapping: [0, 2],
            update: PolarUpdate::Extended,
        };
        let x = Vector4::new(30.0, 1.0, -40.0, 0.5);
        let p = Matrix4::identity();
        let r = Matrix2::identity() * 0.01;
        let inn: Innovation<U4, U2> = pol.innovation(&x, &p, &r, [1.0, 2.0]).unwrap();
        let h = inn.h.unwrap();
        for c in 0..4 {
            let mut xp = x;
            xp[c] += 1e-6;
            let (a, b) = (
                pol.function(xp.as_slice(), [1.0, 2.0]),
                pol.function(x.as_slice(), [1.0, 2.0]),
            );
            for row in 0..2 {
                let fd = (a[row] - b[row]) / 1e-6;
                assert!((fd - h[(row, c)]).abs() < 1e-6, "{row} {c}");
            }
        }
        // The inverse maps the prediction back onto its positions.
        let z = pol.function(x.as_slice(), [1.0, 2.0]);
        let (pos, _) = pol.inverse(&z, &[0.01, 0.0, 0.0, 1.0], [1.0, 2.0]).unwrap();
        assert!((pos[0] - 30.0).abs() < 1e-12 && (pos[1] + 40.0).abs() < 1e-12);
    }
}
