//! Global nearest neighbour: distance hypotheses (Stone Soup `DistanceHypothesiser`), the
//! optimal assignment (`GNNWith2DAssignment`) and the Kalman update or prediction of each track.

use super::hypothesise::*;
use super::imm_scan::{imm_predict_all, imm_update};
use crate::error::Result;
use crate::models::MotionModel;
use crate::tracking::assign::gnn_assign;
use crate::tracking::config::{GnnParams, Measure};
use crate::tracking::track::{Entry, Track};
use nalgebra::{DefaultAllocator, Dim};

/// Distance hypotheses + GNN + update/predict on `tracks` (confirmed or tentative) with the
/// detections `which` of `dets`; `ln_pdf` receives per track `ln N(z; ẑ, S)` of its assigned
/// detection (−∞ when missed). Returns the detection assigned to each
/// track.
#[allow(clippy::too_many_arguments)]
pub(crate) fn gnn_step<N: Dim, M: Dim>(
    tracks: &mut [Track],
    model: &MotionModel,
    sensors: &[SensorT<N, M>],
    g: &GnnParams,
    form: CovForm,
    t: f64,
    dets: &Dets<'_, M>,
    (n, m): (N, M),
    which: &[usize],
    scan: i64,
    imm: Option<&crate::tracking::imm::ImmConfig>,
    mut ln_pdf: Option<&mut Vec<f64>>,
) -> Result<Vec<Option<usize>>>
where
    DefaultAllocator: Alloc<N, M>,
{
    let (imm_preds, preds) = match imm {
        Some(c) => {
            let (a, b) = imm_predict_all(c, tracks, t, n);
            (Some(a), b)
        }
        None => (None, predict_all(model, tracks, t, n)),
    };
    let ns = sensors.len();
    let mut innov = Innovations::new(preds.len(), ns);
    let gate = if g.include_all {
        f64::INFINITY
    } else {
        match g.measure {
            Measure::Mahalanobis => g.missed_distance * g.missed_distance,
            Measure::SquaredMahalanobis => g.missed_distance,
        }
    };
    let pairs = gate_pairs(&preds, sensors, m, dets, which, gate, &mut innov)?;
    let mut hyps: Vec<Vec<(usize, f64)>> = vec![Vec::new(); tracks.len()];
    let mut kept: Vec<Vec<Pair>> = vec![Vec::new(); tracks.len()];
    for p in pairs {
        let dist = match g.measure {
            Measure::Mahalanobis => p.d2.sqrt(),
            Measure::SquaredMahalanobis => p.d2,
        };
        if g.include_all || dist < g.missed_distance {
            hyps[p.t].push((p.d, dist));
            kept[p.t].push(p);
        }
    }
    let assign = gnn_assign(&hyps, dets.len(), g.missed_distance)?;
    let md = m.value();
    let mut entry = Entry {
        time: t,
        is_update: false,
        scan,
        sensor: -1,
        detection: -1,
        nis: f64::NAN,
        missed_probability: 1.0,
        assoc: Vec::new(),
    };
    for (ti, ((xp, pp), tr)) in preds.into_iter().zip(tracks.iter_mut()).enumerate() {
        entry.assoc.clear();
        entry.assoc.extend(
            hyps[ti]
                .iter()
                .map(|&(d, _)| (d as i64, if assign[ti] == Some(d) { 1.0 } else { 0.0 })),
        );
        let pair = assign[ti].and_then(|d| kept[ti].iter().find(|p| p.d == d));
        match pair {
            Some(p) => {
                let d = p.d;
                let s = dets.sensor[d];
                let inn = innov.of(p, s)?;
                if let Some(out) = ln_pdf.as_deref_mut() {
                    const LN_2PI: f64 = 1.837_877_066_409_345_5;
                    out.push(-0.5 * (p.d2 + inn.ln_det + md as f64 * LN_2PI));
                }
                let (xu, pu) = match &imm_preds {
                    Some(ip) => {
                        let hy = [(d, 1.0, 0.0)];
                        let (st, (xu, pu)) = imm_update(
                            &ip[ti],
                            n,
                            sensors,
                            dets,
                            form,
                            0.0,
                            &hy,
                            f64::NEG_INFINITY,
                        )?;
                        tr.imm = Some(st);
                        (xu, pu)
                    }
                    None => {
                        let y = inn.residual(dets.row(d, md));
                        (&xp + &inn.k * y, posterior_cov(&pp, inn, &sensors[s], form))
                    }
                };
                entry.is_update = true;
                entry.sensor = s as i64;
                entry.detection = d as i64;
                entry.nis = p.d2;
                entry.missed_probability = 0.0;
                tr.append_slices(xu.as_slice(), pu.as_slice(), &entry);
            }
            None => {
                if let Some(out) = ln_pdf.as_deref_mut() {
                    out.push(f64::NEG_INFINITY);
                }
                entry.is_update = false;
                entry.sensor = -1;
                entry.detection = -1;
                entry.nis = f64::NAN;
                entry.missed_probability = 1.0;
                if let Some(ip) = &imm_preds {
                    let (st, (xu, pu)) =
                        imm_update(&ip[ti], n, sensors, dets, form, 1.0, &[], 0.0)?;
                    tr.imm = Some(st);
                    tr.append_slices(xu.as_slice(), pu.as_slice(), &entry);
                } else {
                    tr.append_slices(xp.as_slice(), pp.as_slice(), &entry);
                }
            }
        }
    }
    Ok(assign)
}
