//! Linear-Gaussian Kalman filtering: predict, Joseph-form update, batch filtering of a whole
//! sequence and the Rauch–Tung–Striebel smoother.
//!
//! The routines are generic over nalgebra dimensions, so the same code runs on stack-allocated
//! fixed-size matrices (2-, 4- and 6-state fast paths, chosen by [`run_batch`]) and on
//! heap-allocated dynamic ones for any other size.

use crate::error::{check_finite, Error, Result};
use nalgebra::allocator::Allocator;
use nalgebra::{Cholesky, DefaultAllocator, Dim, OMatrix, OVector};

mod batch;
pub use batch::*;

/// `ln(2π)`.
const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// Prediction `x⁻ = F x`, `P⁻ = F P Fᵀ + Q` (symmetrised).
pub fn predict<N: Dim>(
    x: &OVector<f64, N>,
    p: &OMatrix<f64, N, N>,
    f: &OMatrix<f64, N, N>,
    q: &OMatrix<f64, N, N>,
) -> (OVector<f64, N>, OMatrix<f64, N, N>)
where
    DefaultAllocator: Allocator<N, N> + Allocator<N>,
{
    let mut pp = f * p * f.transpose() + q;
    symmetrise(&mut pp);
    (f * x, pp)
}

/// The result of one measurement update.
#[derive(Debug, Clone)]
pub struct Update<N: Dim, M: Dim>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N> + Allocator<M, M> + Allocator<M>,
{
    /// Posterior state.
    pub x: OVector<f64, N>,
    /// Posterior covariance (Joseph form, symmetrised).
    pub p: OMatrix<f64, N, N>,
    /// Innovation `y = z − H x⁻`.
    pub innovation: OVector<f64, M>,
    /// Innovation covariance `S = H P⁻ Hᵀ + R`.
    pub s: OMatrix<f64, M, M>,
    /// Normalised innovation squared `yᵀ S⁻¹ y`.
    pub nis: f64,
    /// Gaussian log-likelihood of the measurement, `ln N(z; H x⁻, S)`.
    pub log_likelihood: f64,
}

/// The gain part of a Kalman step: `S = H P⁻ Hᵀ + R`, its Cholesky factor, `ln det S` and the
/// gain `K = P⁻ Hᵀ S⁻¹`, from `hph = H P⁻ Hᵀ` and `pht = P⁻ Hᵀ` (linearised or sigma-point
/// versions for non-linear sensors). `None` when `S` has no Cholesky factor. This and
/// [`posterior_covariance`] are the one Kalman step of the crate: the filter ([`update`]) and
/// the tracker's updaters (`tracking::hypothesise`) both use them.
pub fn gain<N: Dim, M: Dim>(
    hph: &OMatrix<f64, M, M>,
    pht: &OMatrix<f64, N, M>,
    r: &OMatrix<f64, M, M>,
) -> Option<Gain<N, M>>
where
    DefaultAllocator: Allocator<N, M> + Allocator<M, N> + Allocator<M, M> + Allocator<M>,
{
    let s = hph + r;
    let chol = Cholesky::new(s.clone())?;
    let ln_det = chol.l_dirty().diagonal().iter().map(|d| 2.0 * d.ln()).sum();
    // K = P⁻ Hᵀ S⁻¹, computed as (S⁻¹ H P⁻)ᵀ since S and P⁻ are symmetric.
    let k = chol.solve(&pht.transpose()).transpose();
    Some(Gain { s, chol, ln_det, k })
}

/// See [`gain`].
#[derive(Debug, Clone)]
pub struct Gain<N: Dim, M: Dim>
where
    DefaultAllocator: Allocator<N, M> + Allocator<M, M>,
{
    /// Innovation covariance `S`.
    pub s: OMatrix<f64, M, M>,
    pub chol: Cholesky<f64, M>,
    /// `ln det S`.
    pub ln_det: f64,
    /// Kalman gain `K`, `(n, m)`.
    pub k: OMatrix<f64, N, M>,
}

/// The posterior covariance of a Kalman step with gain `k`: Joseph form
/// `(I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ` (`joseph`) or `P⁻ − K S Kᵀ`; then `(P + Pᵀ) / 2` when
/// `symmetric`.
pub fn posterior_covariance<N: Dim, M: Dim>(
    p: &OMatrix<f64, N, N>,
    k: &OMatrix<f64, N, M>,
    s: &OMatrix<f64, M, M>,
    h: &OMatrix<f64, M, N>,
    r: &OMatrix<f64, M, M>,
    joseph: bool,
    symmetric: bool,
) -> OMatrix<f64, N, N>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N, M> + Allocator<M, N> + Allocator<M, M>,
{
    let mut out = if joseph {
        let (n, _) = p.shape_generic();
        let ikh = OMatrix::<f64, N, N>::identity_generic(n, n) - k * h;
        &ikh * p * ikh.transpose() + k * r * k.transpose()
    } else {
        p - k * s * k.transpose()
    };
    if symmetric {
        symmetrise(&mut out);
    }
    out
}

/// Measurement update with the Joseph-form covariance
/// `P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ`, `K = P⁻ Hᵀ S⁻¹` (symmetrised): [`gain`] and
/// [`posterior_covariance`].
///
/// Fails with [`Error::NotPositiveDefinite`] when `S` has no Cholesky factor.
pub fn update<N: Dim, M: Dim>(
    x: &OVector<f64, N>,
    p: &OMatrix<f64, N, N>,
    z: &OVector<f64, M>,
    h: &OMatrix<f64, M, N>,
    r: &OMatrix<f64, M, M>,
) -> Result<Update<N, M>>
where
    DefaultAllocator: Allocator<N, N>
        + Allocator<N>
        + Allocator<M, M>
        + Allocator<M>
        + Allocator<M, N>
        + Allocator<N, M>,
{
    // y = z − H x⁻
    let innovation = z - h * x;
    let pht = p * h.transpose();
    let g = gain(&(h * &pht), &pht, r).ok_or_else(|| Error::NotPositiveDefinite {
        arg: "innovation covariance".into(),
        reason: "H P Hᵀ + R is not positive definite (check measurement_noise)".into(),
    })?;
    let s_inv_y = g.chol.solve(&innovation);
    let nis = innovation.dot(&s_inv_y);
    let m = innovation.len() as f64;
    let log_likelihood = -0.5 * (nis + g.ln_det + m * LN_2PI);
    let x_post = x + &g.k * &innovation;
    let p_post = posterior_covariance(p, &g.k, &g.s, h, r, true, true);
    Ok(Update {
        x: x_post,
        p: p_post,
        innovation,
        s: g.s,
        nis,
        log_likelihood,
    })
}

/// Replaces `p` by `(p + pᵀ) / 2`, removing rounding asymmetry.
pub fn symmetrise<N: Dim>(p: &mut OMatrix<f64, N, N>)
where
    DefaultAllocator: Allocator<N, N>,
{
    let n = p.nrows();
    for i in 0..n {
        for j in (i + 1)..n {
            let v = 0.5 * (p[(i, j)] + p[(j, i)]);
            p[(i, j)] = v;
            p[(j, i)] = v;
        }
    }
}

/// Fails unless the `n × n` row-major matrix `m` is symmetric (to a relative 1e-9) and
/// positive definite (`strict`) or positive semi-definite.
pub fn check_covariance(arg: &str, m: &[f64], n: usize, strict: bool) -> Result<()> {
    check_finite(arg, m)?;
    let scale = m
        .iter()
        .fold(0.0f64, |a, v| a.max(v.abs()))
        .max(f64::MIN_POSITIVE);
    for i in 0..n {
        for j in (i + 1)..n {
            if (m[i * n + j] - m[j * n + i]).abs() > 1e-9 * scale {
                return Err(Error::NotPositiveDefinite {
                    arg: arg.into(),
                    reason: format!("is not symmetric (entry ({i}, {j}) != ({j}, {i}))"),
                });
            }
        }
    }
    let mat = nalgebra::DMatrix::from_row_slice(n, n, m);
    let min_eig = mat.symmetric_eigenvalues().min();
    let ok = if strict {
        Cholesky::new(mat).is_some() && min_eig > 0.0
    } else {
        min_eig >= -1e-12 * scale
    };
    if ok {
        Ok(())
    } else {
        Err(Error::NotPositiveDefinite {
            arg: arg.into(),
            reason: format!(
                "must be positive {}definite (smallest eigenvalue {min_eig:e})",
                if strict { "" } else { "semi-" }
            ),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::batch::run_generic;
    use super::*;
    use crate::models::{Component, LinearModel, MotionModel};
    use nalgebra::{DMatrix, DVector, Dyn};

    fn input<'a>(
        times: &'a [f64],
        z: &'a [f64],
        h: &'a [f64],
        r: &'a [f64],
        x0: &'a [f64],
        p0: &'a [f64],
    ) -> BatchInput<'a> {
        BatchInput {
            times,
            measurements: z,
            measurement_dim: h.len() / x0.len(),
            measurement_matrix: h,
            measurement_noise: r,
            noise_index: None,
            prior_state: x0,
            prior_covariance: p0,
            prior_time: times[0],
        }
    }

    #[test]
    fn fixed_and_dynamic_paths_agree() {
        // A 2-state problem on the fast path versus the same maths on dynamic matrices.
        let model = MotionModel::new(vec![Component::ConstantVelocity { q: 0.3 }]).unwrap();
        let times = [0.0, 0.4, 1.1, 1.15, 2.0];
        let z = [0.1, 0.5, 1.2, 1.1, 2.3];
        let (h, r, x0, p0) = ([1.0, 0.0], [0.5], [0.0, 1.0], [1.0, 0.0, 0.0, 1.0]);
        let fast = run_batch(&model, &input(&times, &z, &h, &r, &x0, &p0), true).unwrap();
        let slow =
            run_generic::<Dyn, Dyn, _>(&model, &input(&times, &z, &h, &r, &x0, &p0), true).unwrap();
        for (a, b) in fast
            .smoothed_covariances
            .iter()
            .zip(&slow.smoothed_covariances)
        {
            assert!((a - b).abs() < 1e-12);
        }
        assert_eq!(fast.nis.len(), 5);
    }

    #[test]
    fn joseph_update_matches_textbook_form() {
        let x = DVector::from_vec(vec![1.0, 2.0]);
        let p = DMatrix::from_row_slice(2, 2, &[2.0, 0.3, 0.3, 1.0]);
        let h = DMatrix::from_row_slice(1, 2, &[1.0, 0.0]);
        let r = DMatrix::from_row_slice(1, 1, &[0.5]);
        let z = DVector::from_vec(vec![1.7]);
        let u = update(&x, &p, &z, &h, &r).unwrap();
        let s = 2.5;
        let k = DVector::from_vec(vec![2.0 / s, 0.3 / s]);
        let p_simple = &p - &k * s * k.transpose();
        assert!((&u.p - p_simple).abs().max() < 1e-14);
        assert!((u.nis - 0.49 / s).abs() < 1e-14);
    }

    #[test]
    fn linear_model_equals_motion_model() {
        // A fixed F, Q equal to the Wiener model at dt = 1 gives the same run on unit steps;
        // per-step matrices built at each dt give the same run on irregular steps.
        let motion = MotionModel::new(vec![Component::ConstantVelocity { q: 0.3 }]).unwrap();
        let (h, r, x0, p0) = ([1.0, 0.0], [0.5], [0.0, 1.0], [1.0, 0.0, 0.0, 1.0]);
        let times = [0.0, 1.0, 2.0, 3.0];
        let z = [0.1, 1.2, 1.9, 3.2];
        let (f, q) = motion.matrices(1.0);
        let row = |m: DMatrix<f64>| m.transpose().as_slice().to_vec();
        let fixed = LinearModel::new(2, row(f), row(q)).unwrap();
        // The fixed model also predicts before the first measurement: a prior one step before.
        let mut unit = input(&times, &z, &h, &r, &x0, &p0);
        unit.prior_time = -1.0;
        let a = run_batch(&motion, &unit, true).unwrap();
        let b = run_batch_linear(&fixed, &unit, true).unwrap();
        assert!(a
            .smoothed_states
            .iter()
            .zip(&b.smoothed_states)
            .all(|(u, v)| (u - v).abs() < 1e-12));
        let times = [0.0, 0.4, 1.1, 2.0];
        let (mut fs, mut qs) = (Vec::new(), Vec::new());
        let mut prev = times[0];
        for &t in &times {
            let (f, q) = motion.matrices(t - prev);
            fs.extend(row(f));
            qs.extend(row(q));
            prev = t;
        }
        let per_step = LinearModel::new(2, fs, qs).unwrap();
        let a = run_batch(&motion, &input(&times, &z, &h, &r, &x0, &p0), true).unwrap();
        let b = run_batch_linear(&per_step, &input(&times, &z, &h, &r, &x0, &p0), true).unwrap();
        assert!(a
            .smoothed_covariances
            .iter()
            .zip(&b.smoothed_covariances)
            .all(|(u, v)| (u - v).abs() < 1e-12));
        let wrong = LinearModel::new(2, [1.0, 0.0, 0.0, 1.0].repeat(2), vec![0.0; 8]).unwrap();
        assert!(run_batch_linear(&wrong, &input(&times, &z, &h, &r, &x0, &p0), false).is_err());
    }

    #[test]
    fn many_equals_one_by_one() {
        let f = [1.0, 1.0, 0.0, 1.0];
        let q = [0.1, 0.0, 0.0, 0.1];
        let xs = [0.0, 1.0, 5.0, -1.0];
        let ps = [1.0, 0.2, 0.2, 2.0, 3.0, 0.0, 0.0, 1.0];
        let (xp, pp) = predict_many(&xs, &ps, 2, &f, &q).unwrap();
        let (h, r, z) = ([1.0, 0.0], [0.5], [1.2, 3.9]);
        let (xu, pu, nis) = update_many(&xp, &pp, 2, &z, &h, &r).unwrap();
        let fm = DMatrix::from_row_slice(2, 2, &f);
        let qm = DMatrix::from_row_slice(2, 2, &q);
        for i in 0..2 {
            let x = DVector::from_row_slice(&xs[2 * i..2 * i + 2]);
            let p = DMatrix::from_row_slice(2, 2, &ps[4 * i..4 * i + 4]);
            let (x1, p1) = predict(&x, &p, &fm, &qm);
            let u = update(
                &x1,
                &p1,
                &DVector::from_row_slice(&z[i..i + 1]),
                &DMatrix::from_row_slice(1, 2, &h),
                &DMatrix::from_row_slice(1, 1, &r),
            )
            .unwrap();
            assert!(
                (u.x[0] - xu[2 * i]).abs() < 1e-14 && (u.p[(1, 1)] - pu[4 * i + 3]).abs() < 1e-14
            );
            assert!((u.nis - nis[i]).abs() < 1e-14);
        }
        assert!(predict_many(&xs, &ps[..4], 2, &f, &q).is_err());
        assert!(update_many(&xs, &ps, 2, &z[..1], &h, &r).is_err());
        assert!(update_many(&xs, &ps, 2, &z, &h, &[-1.0]).is_err());
    }

    #[test]
    fn rejects_bad_inputs() {
        let model = MotionModel::new(vec![Component::ConstantVelocity { q: 0.3 }]).unwrap();
        let (h, x0, p0) = ([1.0, 0.0], [0.0, 1.0], [1.0, 0.0, 0.0, 1.0]);
        let t = [0.0, 1.0];
        let bad_r = run_batch(
            &model,
            &input(&t, &[0.0, 1.0], &h, &[-1.0], &x0, &p0),
            false,
        );
        assert!(matches!(bad_r, Err(Error::NotPositiveDefinite { .. })));
        let back = run_batch(
            &model,
            &input(&[1.0, 0.0], &[0.0, 1.0], &h, &[1.0], &x0, &p0),
            false,
        );
        assert!(matches!(back, Err(Error::Order { .. })));
        let nan = run_batch(
            &model,
            &input(&t, &[f64::NAN, 1.0], &h, &[1.0], &x0, &p0),
            false,
        );
        assert!(matches!(nan, Err(Error::NonFinite { .. })));
        let shape = run_batch(&model, &input(&t, &[0.0], &h, &[1.0], &x0, &p0), false);
        assert!(matches!(shape, Err(Error::Dimension { .. })));
    }
}
