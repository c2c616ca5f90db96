//! One scan's JPDA of the confirmed tracks (step 2 of [`super`]): per-cluster marginals —
//! exact EHM within the cluster budget, approximated above it, joint existence with JIPDA —
//! and each track's moment-matched mixture or IMM update.

use super::*;
use crate::tracking::gating::validation_volume;
use crate::tracking::hypothesise::{
    axis_orders, gate_pairs, order_cluster, posterior_cov, predict_all, Innovations, SensorT,
    NO_OWN,
};
use crate::tracking::jipda::JointPrior;
use crate::tracking::jpda::{ehm_size_estimate, marginals_within, Exactness, TrackHypotheses};
use nalgebra::OVector;

impl Tracker {
    /// JPDA over the confirmed tracks for detections `which` of `dets` at scan time `t`: each
    /// track's new state and history entry; returns which detections are associated (a
    /// marginal above the track's missed one, or inside a gate without
    /// `initiate_in_gates`) and the scan's cluster counts. Checks `interrupt` between
    /// clusters.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn step_jpda<N: Dim, M: Dim>(
        &mut self,
        t: f64,
        dets: &Dets<'_, M>,
        which: &[usize],
        j: &JpdaParams,
        sensors: &[SensorT<N, M>],
        (n, md): (N, M),
        interrupt: &mut dyn FnMut() -> bool,
    ) -> Result<(Vec<bool>, ClusterStats)>
    where
        DefaultAllocator: Alloc<N, M>,
    {
        let m = self.m;
        let k = dets.len();
        let det_sensor = dets.sensor;
        let ns = sensors.len();
        let (imm_preds, preds) = match &self.cfg.imm {
            Some(c) => {
                let (a, b) = crate::tracking::imm_scan::imm_predict_all(c, &mut self.tracks, t, n);
                (Some(a), b)
            }
            None => (
                None,
                predict_all(&self.cfg.motion_model, &self.tracks, t, n),
            ),
        };
        let mut innov = Innovations::new(preds.len(), ns);
        let gate = if j.include_all {
            f64::INFINITY
        } else {
            self.gate
        };
        let pairs = gate_pairs(&preds, sensors, md, dets, which, gate, &mut innov)?;
        // Log weights per track: missed, then gated detections.
        let ln_missed = (1.0 - j.prob_detect * j.prob_gate).ln();
        // (det, ln w, d2, index into pairs), flat in the order of the pairs (sorted by track):
        // track `t`'s hypotheses are `hyps[offs[t]..offs[t + 1]]`.
        let mut hyps: Vec<(usize, f64, f64, usize)> = Vec::with_capacity(pairs.len());
        let mut offs = vec![0usize; preds.len() + 1];
        for (pi, p) in pairs.iter().enumerate() {
            let inn = innov.of(p, det_sensor[p.d])?;
            let logpdf = -0.5 * (p.d2 + inn.ln_det + m as f64 * LN_2PI);
            let mut lw = logpdf + j.prob_detect.ln();
            if let Some(l) = j.clutter_density {
                lw -= l.ln();
            }
            hyps.push((p.d, lw, p.d2, pi));
            offs[p.t + 1] += 1;
        }
        for t in 0..preds.len() {
            offs[t + 1] += offs[t];
        }
        let range = |t: usize| offs[t]..offs[t + 1];
        if j.clutter_density.is_none() {
            for t in 0..preds.len() {
                let h = &mut hyps[range(t)];
                let n_valid = h.iter().filter(|x| x.2 <= self.gate).count() as f64;
                for e in h.iter_mut() {
                    let p = &pairs[e.3];
                    let inn = innov.of(p, det_sensor[p.d])?;
                    let vol = validation_volume(m, self.gate, inn.ln_det.exp());
                    e.1 += vol.ln() - n_valid.ln();
                }
            }
        }
        // JIPDA: each track's predicted existence and visibility weight its hypotheses
        // (`jipda`, eq. (2)): missed 1 − P_D P_G r⁻v⁻, detections × r⁻v⁻.
        let pd_pg = j.prob_detect * j.prob_gate;
        let joint: Option<Vec<JointPrior>> = match &self.cfg.existence {
            Some(ex) if ex.joint => Some(
                self.tracks
                    .iter()
                    .map(|tr| {
                        let (r, v) = ex.predict(tr.existence.unwrap_or((ex.initial, 1.0)));
                        JointPrior {
                            existence: r,
                            visibility: v,
                            pd_pg,
                        }
                    })
                    .collect(),
            ),
            _ => None,
        };
        let th: Vec<TrackHypotheses> = (0..preds.len())
            .map(|t| {
                let h = &hyps[range(t)];
                let Some(pri) = &joint else {
                    let mx = h.iter().map(|e| e.1).fold(ln_missed, f64::max);
                    return TrackHypotheses {
                        missed: (ln_missed - mx).exp(),
                        detections: h.iter().map(|e| (e.0, (e.1 - mx).exp())).collect(),
                    };
                };
                let (lm, lq) = (pri[t].ln_missed(), pri[t].ln_detectable());
                let mx = h.iter().map(|e| e.1 + lq).fold(lm, f64::max);
                TrackHypotheses {
                    missed: (lm - mx).exp(),
                    detections: h.iter().map(|e| (e.0, (e.1 + lq - mx).exp())).collect(),
                }
            })
            .collect();
        // Marginals: missed per track, detections flat as `hyps`.
        let mut marg_missed = vec![0.0; th.len()];
        let mut marg_det = vec![0.0; hyps.len()];
        let mut stats = ClusterStats::default();
        for c in clusters(&th, k) {
            stats.clusters += 1;
            stats.largest = stats.largest.max(c.len());
            if interrupt() {
                return Err(Error::Interrupted);
            }
            if c.len() == 1 {
                let h = &th[c[0]];
                let tot = h.missed + h.detections.iter().map(|d| d.1).sum::<f64>();
                marg_missed[c[0]] = h.missed / tot;
                for (dst, d) in marg_det[range(c[0])].iter_mut().zip(&h.detections) {
                    *dst = d.1 / tot;
                }
                continue;
            }
            let mut ordered = order_cluster(&c, &preds);
            // EHM's net depends on the order (the marginals do not): of the orders along each
            // state axis, both ways, take the one with the smallest estimated net.
            if matches!(j.method, Method::Ehm) && c.len() > 2 {
                let mut best = ehm_size_estimate(&th, &ordered, k);
                for o in axis_orders(&c, &preds) {
                    let e = ehm_size_estimate(&th, &o, k);
                    if e < best {
                        best = e;
                        ordered = o;
                    }
                }
            }
            let sub: Vec<TrackHypotheses> = ordered.iter().map(|&i| th[i].clone()).collect();
            let (r, how) = marginals_within(&sub, j.method, j.max_hypotheses)?;
            if how != Exactness::Exact {
                stats.approximated += 1;
            }
            for (i, mm) in ordered.into_iter().zip(r) {
                marg_missed[i] = mm.missed;
                for (dst, &b) in marg_det[range(i)].iter_mut().zip(&mm.detections) {
                    *dst = b;
                }
            }
        }
        // JIPDA: posterior existence and visibility (`jipda`, eqs. (3)–(4)); the marginals
        // become the association probabilities given existence (eq. (5)), which the state
        // mixture, the IMM and the track's association record use below.
        let posts = joint.as_ref().map(|pri| {
            (0..pri.len())
                .map(|ti| {
                    let ln_pda = hyps[range(ti)].iter().map(|e| e.1);
                    let mg = &mut marg_det[range(ti)];
                    pri[ti].condition(&mut marg_missed[ti], mg, ln_pda)
                })
                .collect::<Vec<_>>()
        });
        let mut associated = vec![false; k];
        let mut in_gate = vec![false; k];
        let form = CovForm {
            joseph: self.cfg.use_joseph_cov,
            symmetric: self.cfg.symmetric_covariance,
        };
        let mut entry = Entry {
            time: t,
            is_update: false,
            scan: self.scan,
            sensor: -1,
            detection: -1,
            nis: f64::NAN,
            missed_probability: f64::NAN,
            assoc: Vec::new(),
        };
        // Scratch reused across tracks: mixture components (weight, state, pair), posterior
        // covariance per sensor (detections without their own covariance).
        let mut comps: Vec<(f64, OVector<f64, N>, usize)> = Vec::new();
        let mut post_by_sensor: Vec<Option<OMatrix<f64, N, N>>> = (0..ns).map(|_| None).collect();
        for (ti, ((xp, pp), tr)) in preds.into_iter().zip(self.tracks.iter_mut()).enumerate() {
            let h = &hyps[range(ti)];
            let mg = &marg_det[range(ti)];
            let b0 = marg_missed[ti];
            let tot: f64 = b0 + mg.iter().sum::<f64>();
            // Components: prediction, then one Kalman update per gated detection.
            let mut mean = &xp * (b0 / tot);
            comps.clear();
            for (e, &b) in h.iter().zip(mg) {
                let inn = innov.of(&pairs[e.3], det_sensor[e.0])?;
                let y = inn.residual(dets.row(e.0, m));
                let xu = &xp + &inn.k * y;
                mean += &xu * (b / tot);
                comps.push((b / tot, xu, e.3));
                in_gate[e.0] = true;
            }
            let dx = &xp - &mean;
            let mut cov = &pp * (b0 / tot) + (&dx * dx.transpose()) * (b0 / tot);
            post_by_sensor.iter_mut().for_each(|p| *p = None);
            for (w, xu, pi) in &comps {
                let p = &pairs[*pi];
                let s = det_sensor[p.d];
                let inn = innov.of(p, s)?;
                let own;
                let pu = if p.own == NO_OWN {
                    &*post_by_sensor[s]
                        .get_or_insert_with(|| posterior_cov(&pp, inn, &sensors[s], form))
                } else {
                    own = posterior_cov(&pp, inn, &sensors[s], form);
                    &own
                };
                let dx = xu - &mean;
                cov += pu * *w + (&dx * dx.transpose()) * *w;
            }
            if let Some(ps) = &posts {
                tr.existence = Some(ps[ti]);
            } else if let Some(ex) = &self.cfg.existence {
                // ln L = logsumexp(ln(1 − P_D P_G), ln w_i) over the track's gated detections.
                let mx = h.iter().map(|e| e.1).fold(ln_missed, f64::max);
                let ln_l = mx
                    + ((ln_missed - mx).exp() + h.iter().map(|e| (e.1 - mx).exp()).sum::<f64>())
                        .ln();
                let rv = tr.existence.unwrap_or((ex.initial, 1.0));
                tr.existence = Some(ex.update(rv, ln_l));
            }
            let mut best: Option<usize> = None;
            for (i, &b) in mg.iter().enumerate() {
                if b > b0 {
                    associated[h[i].0] = true;
                    if best.is_none_or(|bi| b > mg[bi]) {
                        best = Some(i);
                    }
                }
            }
            entry.is_update = best.is_some();
            entry.sensor = best.map_or(-1, |i| det_sensor[h[i].0] as i64);
            entry.detection = best.map_or(-1, |i| h[i].0 as i64);
            entry.nis = best.map_or(f64::NAN, |i| h[i].2);
            entry.missed_probability = b0 / tot;
            entry.assoc.clear();
            entry
                .assoc
                .extend(h.iter().zip(mg).map(|(e, &b)| (e.0 as i64, b / tot)));
            if let Some(ip) = &imm_preds {
                // Mode-conditioned PDA with the track's association weights; the clutter term
                // ln(P_D/λ) of each detection is the one of its combined weight. Under JIPDA
                // the mode likelihoods are those of the track given existence (`jipda`, eq.
                // (5)): missed 1 − P_D P_G v⁻, detections × v⁻.
                let (imm_missed, ln_vis) = match &joint {
                    Some(pri) => {
                        let v = pri[ti].visibility;
                        ((-pd_pg * v).ln_1p(), Some(v.ln()))
                    }
                    None => (ln_missed, None),
                };
                let hy: Vec<(usize, f64, f64)> = h
                    .iter()
                    .zip(mg)
                    .map(|(e, &b)| {
                        let p = &pairs[e.3];
                        let inn = innov.of(p, det_sensor[p.d])?;
                        let logpdf = -0.5 * (p.d2 + inn.ln_det + m as f64 * LN_2PI);
                        let ln_c = e.1 - logpdf;
                        Ok((e.0, b / tot, ln_vis.map_or(ln_c, |lv| ln_c + lv)))
                    })
                    .collect::<Result<_>>()?;
                let (st, (xu, pu)) = crate::tracking::imm_scan::imm_update(
                    &ip[ti],
                    n,
                    sensors,
                    dets,
                    form,
                    b0 / tot,
                    &hy,
                    imm_missed,
                )?;
                tr.imm = Some(st);
                tr.append_slices(xu.as_slice(), pu.as_slice(), &entry);
                continue;
            }
            tr.append_slices(mean.as_slice(), cov.as_slice(), &entry);
        }
        if !self.cfg.initiate_in_gates {
            for d in 0..k {
                associated[d] |= in_gate[d];
            }
        }
        Ok((associated, stats))
    }
}
