//! The IMM's per-scan kernels on the tracker's tracks: every track's mode predictions and
//! their combination for gating, and the mode-conditioned update with one scan's association
//! weights (the bank itself, mixing and combination: [`super::imm`]).

use super::hypothesise::*;
use crate::error::Result;
use crate::tracking::track::Track;
use nalgebra::allocator::Allocator;
use nalgebra::{DefaultAllocator, Dim, OMatrix, OVector, U1};

/// IMM predictions of `tracks` to `t` (a track without an IMM state starts every mode at its
/// state with `imm.initial`), and the combined predictions `Σ c̄_j N(x_j⁻, P_j⁻)` used for
/// gating and association.
pub(crate) fn imm_predict_all<N: Dim>(
    imm: &crate::tracking::imm::ImmConfig,
    tracks: &mut [Track],
    t: f64,
    n: N,
) -> (Vec<crate::tracking::imm::ImmPrediction>, Vec<Pred<N>>)
where
    DefaultAllocator: Allocator<N, N> + Allocator<N>,
{
    let mut out = Vec::with_capacity(tracks.len());
    let mut preds = Vec::with_capacity(tracks.len());
    for tr in tracks.iter_mut() {
        let st = tr
            .imm
            .get_or_insert_with(|| crate::tracking::imm::ImmState::new(&tr.x, &tr.p, &imm.initial));
        let pr = crate::tracking::imm::predict(imm, st, t - tr.t);
        let (x, p) = crate::tracking::imm::combine(&pr.cbar, &pr.x, &pr.p);
        preds.push((
            OVector::<f64, N>::from_column_slice_generic(n, U1, x.as_slice()),
            OMatrix::<f64, N, N>::from_column_slice_generic(n, n, p.as_slice()),
        ));
        out.push(pr);
    }
    (out, preds)
}

/// The IMM update of one track: every mode gets the PDA mixture of its prediction (weight
/// `b0`) and its Kalman updates with the detections `hyps[i] = (detection, β_i, ln(P_D/λ))`
/// (the association weights `β` are the track's, shared by the modes; Blom and Bloem's
/// IMM-JPDA with a common association), mode likelihoods
/// `Λ_j = e^{ln_missed} + Σ_i e^{ln(P_D/λ)} N(z_i; ẑ_j, S_j)`, `μ_j ∝ c̄_j Λ_j`. Returns the new
/// IMM state and its combined Gaussian (column-major slices of the output state).
#[allow(clippy::too_many_arguments)]
pub(crate) fn imm_update<N: Dim, M: Dim>(
    pred: &crate::tracking::imm::ImmPrediction,
    n: N,
    sensors: &[SensorT<N, M>],
    dets: &Dets<'_, M>,
    form: CovForm,
    b0: f64,
    hyps: &[(usize, f64, f64)],
    ln_missed: f64,
) -> Result<(crate::tracking::imm::ImmState, Pred<N>)>
where
    DefaultAllocator: Alloc<N, M>,
{
    const LN_2PI: f64 = 1.837_877_066_409_345_5;
    let r = pred.x.len();
    let mut xs = Vec::with_capacity(r);
    let mut ps = Vec::with_capacity(r);
    let mut ln_lik = Vec::with_capacity(r);
    for j in 0..r {
        let xp = OVector::<f64, N>::from_column_slice_generic(n, U1, pred.x[j].as_slice());
        let pp = OMatrix::<f64, N, N>::from_column_slice_generic(n, n, pred.p[j].as_slice());
        let mut terms = vec![ln_missed];
        let mut comps: Vec<(f64, Pred<N>)> = Vec::new();
        if b0 > 0.0 {
            comps.push((b0, (xp.clone(), pp.clone())));
        }
        for &(d, beta, ln_c) in hyps {
            let s = dets.sensor[d];
            let inn = pair_innovation(&xp, &pp, &sensors[s], dets, d)?;
            let y = inn.residual(dets.row(d, inn.zhat.len()));
            let d2 = y.dot(&inn.chol.solve(&y));
            terms.push(ln_c - 0.5 * (d2 + inn.ln_det + y.len() as f64 * LN_2PI));
            if beta > 0.0 {
                let xu = &xp + &inn.k * y;
                let pu = posterior_cov(&pp, &inn, &sensors[s], form);
                comps.push((beta, (xu, pu)));
            }
        }
        let mx = terms.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        ln_lik.push(if mx.is_finite() {
            mx + terms.iter().map(|v| (v - mx).exp()).sum::<f64>().ln()
        } else {
            f64::NEG_INFINITY
        });
        let wsum: f64 = comps.iter().map(|c| c.0).sum();
        let mut mean = OVector::<f64, N>::zeros_generic(n, U1);
        for (w, (x, _)) in &comps {
            mean += x * (*w / wsum);
        }
        let mut cov = OMatrix::<f64, N, N>::zeros_generic(n, n);
        for (w, (x, p)) in &comps {
            let dx = x - &mean;
            cov += (p + &dx * dx.transpose()) * (*w / wsum);
        }
        if form.symmetric {
            let t = cov.transpose();
            cov = (cov + t) / 2.0;
        }
        xs.push(nalgebra::DVector::from_column_slice(mean.as_slice()));
        ps.push(nalgebra::DMatrix::from_column_slice(
            n.value(),
            n.value(),
            cov.as_slice(),
        ));
    }
    let mu = crate::tracking::imm::mode_probabilities(&pred.cbar, &ln_lik);
    let (x, p) = crate::tracking::imm::combine(&mu, &xs, &ps);
    let st = crate::tracking::imm::ImmState { mu, x: xs, p: ps };
    Ok((
        st,
        (
            OVector::<f64, N>::from_column_slice_generic(n, U1, x.as_slice()),
            OMatrix::<f64, N, N>::from_column_slice_generic(n, n, p.as_slice()),
        ),
    ))
}
