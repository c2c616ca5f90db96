//! Per-scan kernels of the tracker: prediction of all tracks, innovations, gating of
//! (track, detection) pairs through the spatial grid, GNN association with Kalman updates, and
//! the spatial ordering of JPDA clusters for EHM.

use crate::assign::gnn_assign;
use crate::error::{Error, Result};
use crate::gating::CandidateGrid;
use crate::models::MotionModel;
use crate::track::{Entry, Track};
use crate::tracker_config::{GnnParams, Measure, Sensor};
use nalgebra::{Cholesky, DMatrix, DVector, Dyn};

/// Per (track, sensor) quantities of a prediction.
pub(crate) struct Innovation {
    pub zhat: DVector<f64>,
    pub s: DMatrix<f64>,
    pub chol: Cholesky<f64, Dyn>,
    pub ln_det: f64,
    /// Kalman gain `P⁻ Hᵀ S⁻¹`.
    pub k: DMatrix<f64>,
}

pub(crate) fn innovation(
    x: &DVector<f64>,
    p: &DMatrix<f64>,
    sensor: &Sensor,
) -> Result<Innovation> {
    let h = &sensor.h;
    let pht = p * h.transpose();
    let s = h * &pht + &sensor.r;
    let chol = Cholesky::new(s.clone()).ok_or_else(|| Error::NotPositiveDefinite {
        arg: "innovation covariance".into(),
        reason: "H P Hᵀ + R is not positive definite".into(),
    })?;
    let ln_det = chol.l_dirty().diagonal().iter().map(|d| 2.0 * d.ln()).sum();
    let k = chol.solve(&pht.transpose()).transpose();
    Ok(Innovation {
        zhat: h * x,
        s,
        chol,
        ln_det,
        k,
    })
}

/// Posterior covariance of a Kalman update (same for every detection of a sensor).
pub(crate) fn posterior_cov(
    p: &DMatrix<f64>,
    inn: &Innovation,
    sensor: &Sensor,
    joseph: bool,
) -> DMatrix<f64> {
    if joseph {
        let n = p.nrows();
        let ikh = DMatrix::identity(n, n) - &inn.k * &sensor.h;
        &ikh * p * ikh.transpose() + &inn.k * &sensor.r * inn.k.transpose()
    } else {
        p - &inn.k * &inn.s * inn.k.transpose()
    }
}

/// Predicts every track to `t` (`x⁻ = F x`, `P⁻ = F P Fᵀ + Q`), computing `F`, `Q` once per
/// distinct time step.
pub(crate) fn predict_all(
    model: &MotionModel,
    tracks: &[Track],
    t: f64,
) -> Vec<(DVector<f64>, DMatrix<f64>)> {
    // (dt bits, F, Fᵀ, Q)
    type Step = (u64, DMatrix<f64>, DMatrix<f64>, DMatrix<f64>);
    let mut cache: Vec<Step> = Vec::new();
    tracks
        .iter()
        .map(|tr| {
            let dt = t - tr.t;
            let key = dt.to_bits();
            let k = match cache.iter().position(|c| c.0 == key) {
                Some(k) => k,
                None if cache.len() >= 8 => {
                    // Many distinct steps (tracks at scattered times): no caching.
                    let (f, q) = model.matrices(dt);
                    return (&f * &tr.x, &f * &tr.p * f.transpose() + q);
                }
                None => {
                    let (f, q) = model.matrices(dt);
                    let ft = f.transpose();
                    cache.push((key, f, ft, q));
                    cache.len() - 1
                }
            };
            let (_, f, ft, q) = &cache[k];
            (f * &tr.x, f * &tr.p * ft + q)
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
/// Candidate `(track, detection, squared Mahalanobis)` pairs within `gate` (squared), for
/// predictions `preds[t] = (x⁻, P⁻)`; `innov[t][s]` is filled lazily per sensor.
pub(crate) fn gate_pairs(
    preds: &[(DVector<f64>, DMatrix<f64>)],
    sensors: &[Sensor],
    z: &[f64],
    m: usize,
    det_sensor: &[usize],
    dets: &[usize],
    gate: f64,
    innov: &mut [Vec<Option<Innovation>>],
) -> Result<Vec<(usize, usize, f64)>> {
    let mut pairs = Vec::new();
    if preds.is_empty() || dets.is_empty() {
        return Ok(pairs);
    }
    for (s, sensor) in sensors.iter().enumerate() {
        let ids: Vec<usize> = dets
            .iter()
            .copied()
            .filter(|&d| det_sensor[d] == s)
            .collect();
        if ids.is_empty() {
            continue;
        }
        for (t, (x, p)) in preds.iter().enumerate() {
            if innov[t][s].is_none() {
                innov[t][s] = Some(innovation(x, p, sensor)?);
            }
        }
        let pts: Vec<f64> = ids
            .iter()
            .flat_map(|&d| z[d * m..(d + 1) * m].iter().copied())
            .collect();
        // Cell side: median gate box width over tracks.
        let mut widths: Vec<f64> = innov
            .iter()
            .map(|v| {
                let inn = v[s].as_ref().expect("filled above");
                let w = (0..m.min(2)).map(|i| inn.s[(i, i)]).fold(0.0, f64::max);
                2.0 * (gate * w).sqrt()
            })
            .collect();
        let cell = if gate.is_finite() {
            let mid = widths.len() / 2;
            *widths.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
        } else {
            f64::INFINITY
        };
        let local: Vec<usize> = (0..ids.len()).collect();
        let grid = CandidateGrid::new(&pts, m, &local, cell);
        let mut half = vec![0.0; m];
        for (t, v) in innov.iter().enumerate() {
            let inn = v[s].as_ref().expect("filled above");
            for (i, h) in half.iter_mut().enumerate() {
                *h = (gate * inn.s[(i, i)]).sqrt();
                if h.is_nan() {
                    *h = f64::INFINITY;
                }
            }
            grid.query(inn.zhat.as_slice(), &half, |k| {
                let d = ids[k];
                let y = DVector::from_column_slice(&z[d * m..(d + 1) * m]) - &inn.zhat;
                let d2 = y.dot(&inn.chol.solve(&y));
                if d2 <= gate {
                    pairs.push((t, d, d2));
                }
            });
        }
    }
    pairs.sort_unstable_by_key(|&(t, d, _)| (t, d));
    Ok(pairs)
}

/// Orders a cluster's tracks along the axis of largest spread of their predicted states, so
/// that EHM's sets of pending detections stay small.
pub(crate) fn order_cluster(c: &[usize], preds: &[(DVector<f64>, DMatrix<f64>)]) -> Vec<usize> {
    let mut out = c.to_vec();
    let n = preds[c[0]].0.len();
    let spread = |i: usize| {
        let v: Vec<f64> = c.iter().map(|&t| preds[t].0[i]).collect();
        let lo = v.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        hi - lo
    };
    let axis = (0..n)
        .max_by(|&a, &b| spread(a).total_cmp(&spread(b)))
        .unwrap_or(0);
    out.sort_by(|&a, &b| preds[a].0[axis].total_cmp(&preds[b].0[axis]));
    out
}

/// Distance hypotheses + GNN + update/predict on `tracks` (confirmed or tentative). Returns
/// the detection assigned to each track.
#[allow(clippy::too_many_arguments)]
pub(crate) fn gnn_step(
    tracks: &mut [Track],
    model: &MotionModel,
    sensors: &[Sensor],
    g: &GnnParams,
    joseph: bool,
    t: f64,
    z: &[f64],
    m: usize,
    det_sensor: &[usize],
    dets: &[usize],
    scan: i64,
) -> Result<Vec<Option<usize>>> {
    let preds = predict_all(model, tracks, t);
    let mut innov: Vec<Vec<Option<Innovation>>> = (0..preds.len())
        .map(|_| (0..sensors.len()).map(|_| None).collect())
        .collect();
    let gate = if g.include_all {
        f64::INFINITY
    } else {
        match g.measure {
            Measure::Mahalanobis => g.missed_distance * g.missed_distance,
            Measure::SquaredMahalanobis => g.missed_distance,
        }
    };
    let pairs = gate_pairs(&preds, sensors, z, m, det_sensor, dets, gate, &mut innov)?;
    let mut hyps: Vec<Vec<(usize, f64)>> = vec![Vec::new(); tracks.len()];
    let mut d2s: Vec<Vec<f64>> = vec![Vec::new(); tracks.len()];
    for (ti, d, d2) in pairs {
        let dist = match g.measure {
            Measure::Mahalanobis => d2.sqrt(),
            Measure::SquaredMahalanobis => d2,
        };
        if g.include_all || dist < g.missed_distance {
            hyps[ti].push((d, dist));
            d2s[ti].push(d2);
        }
    }
    let assign = gnn_assign(&hyps, det_sensor.len(), g.missed_distance)?;
    for (ti, ((xp, pp), tr)) in preds.into_iter().zip(tracks.iter_mut()).enumerate() {
        let assoc: Vec<(i64, f64)> = hyps[ti]
            .iter()
            .map(|&(d, _)| (d as i64, if assign[ti] == Some(d) { 1.0 } else { 0.0 }))
            .collect();
        match assign[ti] {
            Some(d) => {
                let s = det_sensor[d];
                let inn = innov[ti][s].as_ref().expect("gated");
                let y = DVector::from_column_slice(&z[d * m..(d + 1) * m]) - &inn.zhat;
                let nis = d2s[ti][hyps[ti].iter().position(|h| h.0 == d).expect("hyp")];
                let xu = &xp + &inn.k * y;
                let pu = posterior_cov(&pp, inn, &sensors[s], joseph);
                tr.append(
                    xu,
                    pu,
                    Entry {
                        time: t,
                        is_update: true,
                        scan,
                        sensor: s as i64,
                        detection: d as i64,
                        nis,
                        missed_probability: 0.0,
                        assoc,
                    },
                );
            }
            None => tr.append(
                xp,
                pp,
                Entry {
                    time: t,
                    is_update: false,
                    scan,
                    sensor: -1,
                    detection: -1,
                    nis: f64::NAN,
                    missed_probability: 1.0,
                    assoc,
                },
            ),
        }
    }
    Ok(assign)
}
