//! The initiator (Stone Soup `MultiMeasurementInitiator` with `SimpleMeasurementInitiator`
//! starts): tentative tracks, their GNN association and updates, confirmation (min points,
//! M of N, existence), their deleter, new tentative tracks from free detections (with the
//! per-scan cap), and the native duplicate suppression.

use super::hypothesise::{
    gate_pairs, gnn_step, sensors_t, Alloc, CovForm, Dets, Innovations, Pred, SensorT,
};
use super::tracker::Tracker;
use crate::error::{Error, Result};
use crate::tracking::config::{Association, Confirmation, GnnParams, InitiatorConfig, Measure};
use crate::tracking::gating::chi2_quantile;
use crate::tracking::track::Deleter;
use crate::tracking::track::{Entry, History, Track};
use nalgebra::{DMatrix, DVector, DefaultAllocator, Dim, Dyn};

/// An initiator configuration that allocates nothing, held in the tracker's configuration
/// while [`Tracker::initiate`] uses the real one.
fn placeholder() -> InitiatorConfig {
    InitiatorConfig {
        prior_state: DVector::zeros(0),
        prior_covariance: DMatrix::zeros(0, 0),
        diag_load: 0.0,
        confirmation: Confirmation::MOfN { m: 0, n: 0 },
        deleter: Deleter::StepsSinceUpdate(0),
        gnn: GnnParams {
            measure: Measure::Mahalanobis,
            missed_distance: 0.0,
            include_all: false,
        },
        motion_model: None,
        use_joseph_cov: false,
        symmetric_covariance: false,
        max_new_tentative: None,
        imm: false,
    }
}

/// A sensor's initiation model: its `H`, `R` and what the initiator derives from them.
#[derive(Debug, Clone)]
pub(crate) struct InitModel {
    h: DMatrix<f64>,
    r: DMatrix<f64>,
    /// `H⁺`.
    pinv: DMatrix<f64>,
    /// `H⁺ R H⁺ᵀ`.
    cov: DMatrix<f64>,
    /// State axes that `H` maps.
    mapped: Vec<bool>,
}

/// Work of the tracker's scans kept between scans.
#[derive(Debug, Clone, Default)]
pub(crate) struct Scratch {
    /// Initiation model per sensor (`None` until a detection of it starts a track).
    init_models: Vec<Option<InitModel>>,
    /// Histories of dropped tentative tracks, emptied and reused by new ones (at most
    /// [`SPARE_HISTORIES`]).
    spare_histories: Vec<History>,
    /// An empty buffer for the next scan's surviving tentative tracks.
    spare_tentative: Vec<Track>,
}

/// Most histories of dropped tentative tracks kept for reuse.
const SPARE_HISTORIES: usize = 64;

impl Scratch {
    /// Keeps `tr`'s history buffers for a later tentative track.
    fn recycle(&mut self, tr: Track) {
        if self.spare_histories.len() < SPARE_HISTORIES {
            self.spare_histories.push(tr.history);
        }
    }
}

impl Tracker {
    /// The initiator's scan (Stone Soup `MultiMeasurementInitiator`): GNN-associates the
    /// tentative tracks with the `free` detections, updates them, confirms or drops them,
    /// and starts a tentative track on every detection still left.
    pub(super) fn initiate<N: Dim, M: Dim>(
        &mut self,
        t: f64,
        dets: &Dets<'_, M>,
        free: &[usize],
        sensors: &[SensorT<N, M>],
        dims: (N, M),
    ) -> Result<()>
    where
        DefaultAllocator: Alloc<N, M>,
    {
        // The initiator's configuration is moved out for the scan (instead of cloned) and put
        // back on every path; nothing below reads `self.cfg.initiator`.
        let init = std::mem::replace(&mut self.cfg.initiator, placeholder());
        let out = self.initiate_with(&init, t, dets, free, sensors, dims);
        self.cfg.initiator = init;
        out
    }

    /// [`Tracker::initiate`] with the initiator's configuration `init` (moved out of
    /// `self.cfg`).
    fn initiate_with<N: Dim, M: Dim>(
        &mut self,
        init: &InitiatorConfig,
        t: f64,
        dets: &Dets<'_, M>,
        free: &[usize],
        sensors: &[SensorT<N, M>],
        dims: (N, M),
    ) -> Result<()>
    where
        DefaultAllocator: Alloc<N, M>,
    {
        let model = init.motion_model.as_ref().unwrap_or(&self.cfg.motion_model);
        // The IMM bank on tentative tracks (their IMM states start lazily at their initiation
        // Gaussians, `hypothesise::imm_predict_all`, and stay with them once confirmed).
        let imm = if init.imm {
            self.cfg.imm.as_ref()
        } else {
            None
        };
        let m = self.m;
        let det_sensor = dets.sensor;
        let covs = dets.covs;
        let mut used = vec![false; det_sensor.len()];
        if !self.tentative.is_empty() {
            let mut ln_pdf = Vec::new();
            let assoc = gnn_step(
                &mut self.tentative,
                model,
                sensors,
                &init.gnn,
                CovForm {
                    joseph: init.use_joseph_cov,
                    symmetric: init.symmetric_covariance,
                },
                t,
                dets,
                dims,
                free,
                self.scan,
                imm,
                Some(&mut ln_pdf),
            )?;
            // Existence of tentative tracks: L = 1 − P_D P_G (+ P_D N(z)/λ with a detection).
            let ex_conf = match (&self.cfg.existence, &self.cfg.association) {
                (Some(e), Association::Jpda(j)) if e.confirm.is_some() => Some((*e, *j)),
                _ => None,
            };
            if let Some((e, j)) = ex_conf {
                let lam = j.clutter_density.unwrap_or(1.0);
                let ln_missed = (1.0 - j.prob_detect * j.prob_gate).ln();
                for (tr, lp) in self.tentative.iter_mut().zip(&ln_pdf) {
                    let lw = j.prob_detect.ln() - lam.ln() + lp;
                    let mx = lw.max(ln_missed);
                    let ln_l = mx + ((ln_missed - mx).exp() + (lw - mx).exp()).ln();
                    let rv = tr.existence.unwrap_or((e.birth, 1.0));
                    tr.existence = Some(e.update(rv, ln_l));
                }
            }
            for d in assoc.into_iter().flatten() {
                used[d] = true;
            }
            // The surviving tracks go to the spare buffer, which then holds the tentative
            // tracks (the old buffer becomes the spare: no allocation per scan).
            let mut old = std::mem::take(&mut self.tentative);
            let mut keep = std::mem::take(&mut self.scratch.spare_tentative);
            keep.clear();
            let mut confirmed = Vec::new();
            for tr in old.drain(..) {
                let (confirm, drop) = match init.confirmation {
                    Confirmation::MinPoints {
                        min_points,
                        updates_only,
                    } => {
                        let count = if updates_only {
                            tr.n_updates()
                        } else {
                            tr.history.len()
                        };
                        (count >= min_points, false)
                    }
                    Confirmation::MOfN { m: mm, n } => {
                        let ups = tr.history.is_update.iter().take(n).filter(|u| **u).count();
                        (ups >= mm, tr.history.len() >= n)
                    }
                };
                let (confirm, drop) = match (ex_conf, tr.existence) {
                    (Some((e, _)), Some((r, _))) => (
                        confirm && r >= e.confirm.unwrap_or(0.0),
                        drop || r < e.delete,
                    ),
                    _ => (confirm, drop),
                };
                if confirm {
                    confirmed.push(tr);
                } else {
                    // Under min points the initiator's deleter ends unconfirmed tracks.
                    let deleted = matches!(init.confirmation, Confirmation::MinPoints { .. })
                        && init.deleter.check(&tr);
                    if drop || deleted {
                        self.scratch.recycle(tr);
                    } else {
                        keep.push(tr);
                    }
                }
            }
            if !self.cfg.initiate_in_gates {
                confirmed = self.without_duplicates(confirmed)?;
            }
            for mut tr in confirmed {
                tr.id = self.next_id;
                self.next_id += 1;
                tr.confirmed_time = t;
                self.tracks.push(tr);
            }
            self.tentative = keep;
            self.scratch.spare_tentative = old;
        }
        // New tentative tracks from every detection left whose sensor starts tracks. Per sensor (computed once, kept
        // across scans while the sensor's initiation model is the same): H⁺, H⁺ R H⁺ᵀ and the
        // mapped state axes; H⁺ R_d H⁺ᵀ per detection with its own covariance R_d (unless the
        // sensor has its own initiation noise).
        let ns = self.cfg.sensors.len();
        self.scratch.init_models.resize_with(ns, || None);
        let mut started = 0usize;
        for &d in free {
            if used[d] || !self.cfg.sensors[det_sensor[d]].starts_tracks {
                continue;
            }
            if init.max_new_tentative.is_some_and(|cap| started >= cap) {
                self.capped_detections += 1;
                continue;
            }
            started += 1;
            let s = det_sensor[d];
            if let Some(pol) = self.cfg.sensors[s].polar {
                // Stone Soup's SimpleMeasurementInitiator with a reversible model: positions
                // from the inverse function, J⁺ R J⁺ᵀ on them, the prior elsewhere.
                let sensor = &self.cfg.sensors[s];
                let r: Vec<f64> = match covs {
                    Some(c) if !sensor.init_noise_given => {
                        c[d].transpose().iter().copied().collect()
                    }
                    _ => sensor.init.1.transpose().iter().copied().collect(),
                };
                let (pos, c) = pol.inverse(dets.row(d, m), &r, dets.origin(d))?;
                let mut x = init.prior_state.clone();
                let mut p = init.prior_covariance.clone();
                let n = x.len();
                for &c in &pol.mapping {
                    x[c] = 0.0;
                    for r in 0..n {
                        p[(c, r)] = 0.0;
                        p[(r, c)] = 0.0;
                    }
                }
                let [i, j] = pol.mapping;
                x[i] += pos[0];
                x[j] += pos[1];
                p[(i, i)] += c[0];
                p[(i, j)] += c[1];
                p[(j, i)] += c[2];
                p[(j, j)] += c[3];
                for i in 0..n {
                    p[(i, i)] += init.diag_load;
                }
                self.push_tentative(t, x, p, s, d);
                continue;
            }
            let (hi, ri) = &self.cfg.sensors[s].init;
            let cached = &mut self.scratch.init_models[s];
            if !cached.as_ref().is_some_and(|c| c.h == *hi && c.r == *ri) {
                let pinv = hi
                    .clone()
                    .pseudo_inverse(1e-15)
                    .map_err(|e| Error::param("initiation_measurement_matrix", e))?;
                let cov = &pinv * ri * pinv.transpose();
                let mapped = (0..hi.ncols())
                    .map(|c| (0..hi.nrows()).any(|r| hi[(r, c)] != 0.0))
                    .collect();
                *cached = Some(InitModel {
                    h: hi.clone(),
                    r: ri.clone(),
                    pinv,
                    cov,
                    mapped,
                });
            }
            let Some(InitModel {
                pinv,
                cov: pcov,
                mapped,
                ..
            }) = cached.as_ref()
            else {
                return Err(Error::param(
                    "tracker",
                    "internal error: no initiation model",
                ));
            };
            let zd = DVector::from_column_slice(dets.row(d, m));
            let mut x = init.prior_state.clone();
            let mut p = init.prior_covariance.clone();
            let n = x.len();
            for c in 0..n {
                if mapped[c] {
                    x[c] = 0.0;
                    for r in 0..n {
                        p[(c, r)] = 0.0;
                        p[(r, c)] = 0.0;
                    }
                }
            }
            x += pinv * zd;
            match covs {
                Some(c) if !self.cfg.sensors[s].init_noise_given => {
                    let rd = DMatrix::from_iterator(m, m, c[d].iter().copied());
                    p += pinv * rd * pinv.transpose();
                }
                _ => p += pcov,
            }
            for i in 0..n {
                p[(i, i)] += init.diag_load;
            }
            self.push_tentative(t, x, p, s, d);
        }
        Ok(())
    }

    /// Starts a tentative track `(x, p)` from detection `d` of sensor `s` at time `t`.
    fn push_tentative(&mut self, t: f64, x: DVector<f64>, p: DMatrix<f64>, s: usize, d: usize) {
        let id = self.next_tentative_id;
        self.next_tentative_id += 1;
        let history = self.scratch.spare_histories.pop().unwrap_or_default();
        self.tentative.push(Track::new_in(
            id,
            x,
            p,
            Entry {
                time: t,
                is_update: true,
                scan: self.scan,
                sensor: s as i64,
                detection: d as i64,
                nis: f64::NAN,
                missed_probability: f64::NAN,
                assoc: vec![(d as i64, 1.0)],
            },
            history,
        ));
    }

    /// Drops tentative tracks about to be confirmed whose position falls inside the gate of a
    /// confirmed track or of a candidate accepted before them (native duplicate suppression;
    /// the gate is the association gate widened to at least χ²_m(0.9999)).
    fn without_duplicates(&self, cands: Vec<Track>) -> Result<Vec<Track>> {
        if cands.is_empty() {
            return Ok(cands);
        }
        let m = self.m;
        let gate = match &self.cfg.association {
            Association::Jpda(_) => self.gate,
            Association::Gnn(g) => match g.measure {
                Measure::Mahalanobis => g.missed_distance * g.missed_distance,
                Measure::SquaredMahalanobis => g.missed_distance,
            },
        };
        // A generous gate: a candidate is a duplicate unless clearly outside (P = 0.9999).
        let wide = chi2_quantile(0.9999, m)?;
        let gate = if gate.is_finite() {
            gate.max(wide)
        } else {
            wide
        };
        // Each candidate as a pseudo-detection H x from the sensor of its last update.
        let sens: Vec<usize> = cands
            .iter()
            .map(|c| {
                let s = *c.history.sensor.last().unwrap_or(&0);
                if s >= 0 {
                    s as usize
                } else {
                    0
                }
            })
            .collect();
        let z: Vec<f64> = cands
            .iter()
            .zip(&sens)
            .flat_map(|(c, &s)| {
                (&self.cfg.sensors[s].h * &c.x)
                    .iter()
                    .copied()
                    .collect::<Vec<_>>()
            })
            .collect();
        let all: Vec<usize> = (0..cands.len()).collect();
        let ns = self.cfg.sensors.len();
        let (nd, md) = (Dyn(self.cfg.motion_model.ndim()), Dyn(m));
        let sensors = sensors_t(&self.cfg.sensors, nd, md);
        let existing: Vec<Pred<Dyn>> = self
            .tracks
            .iter()
            .map(|t| (t.x.clone(), t.p.clone()))
            .collect();
        let mut innov = Innovations::new(existing.len(), ns);
        let mut reject = vec![false; cands.len()];
        let dets = Dets {
            z: &z,
            sensor: &sens,
            covs: None,
            origins: None,
        };
        for p in gate_pairs(&existing, &sensors, md, &dets, &all, gate, &mut innov)? {
            reject[p.d] = true;
        }
        let own: Vec<Pred<Dyn>> = cands.iter().map(|t| (t.x.clone(), t.p.clone())).collect();
        let mut innov = Innovations::new(own.len(), ns);
        let mut gated_by: Vec<Vec<usize>> = vec![Vec::new(); cands.len()];
        for p in gate_pairs(&own, &sensors, md, &dets, &all, gate, &mut innov)? {
            if p.t != p.d {
                gated_by[p.d].push(p.t);
            }
        }
        let mut accepted = vec![false; cands.len()];
        for c in 0..cands.len() {
            if !reject[c] && !gated_by[c].iter().any(|&i| accepted[i]) {
                accepted[c] = true;
            }
        }
        Ok(cands
            .into_iter()
            .zip(accepted)
            .filter_map(|(c, a)| a.then_some(c))
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use crate::models::MotionModel;
    use crate::tracking::config::{Association, GnnParams, Measure, TrackerConfig};
    use crate::tracking::imm::{ImmConfig, Mode};
    use crate::tracking::tracker::Tracker;
    use nalgebra::{DMatrix, DVector};

    /// A GNN tracker of position plots (σ = 1 m) whose tentative tracks need 4 updates, with
    /// the IMM bank `modes` (uniform switching) on confirmed tracks and, with `imm_init`, on
    /// tentative ones.
    fn tracker(modes: Vec<Mode>, imm_init: bool) -> Tracker {
        tracker_confirming_at(modes, imm_init, 4)
    }

    /// [`tracker`] whose tentative tracks need `min_points` updates.
    fn tracker_confirming_at(modes: Vec<Mode>, imm_init: bool, min_points: usize) -> Tracker {
        let mut c = TrackerConfig::code_5_7();
        c.motion_model = MotionModel::constant_velocity_2d(0.05).unwrap();
        c.sensors[0].r = DMatrix::identity(2, 2);
        c.sensors[0].init.1 = DMatrix::identity(2, 2);
        c.deleter = crate::tracking::track::Deleter::StepsSinceUpdate(3);
        c.association = Association::Gnn(GnnParams {
            measure: Measure::Mahalanobis,
            missed_distance: 5.0,
            include_all: false,
        });
        c.initiator.prior_covariance =
            DMatrix::from_diagonal(&DVector::from_vec(vec![0.0, 25.0, 0.0, 25.0]));
        c.initiator.gnn.missed_distance = 4.0;
        c.initiator.confirmation = crate::tracking::config::Confirmation::MinPoints {
            min_points,
            updates_only: true,
        };
        c.initiator.imm = imm_init;
        let r = modes.len();
        let stay = if r == 1 { 1.0 } else { 0.9 };
        let off = if r == 1 { 0.0 } else { 0.1 / (r - 1) as f64 };
        c.imm = Some(ImmConfig {
            modes,
            transition: DMatrix::from_fn(r, r, |i, j| if i == j { stay } else { off }),
            initial: vec![1.0 / r as f64; r],
        });
        Tracker::new(c).unwrap()
    }

    /// A boat at `v` m/s turning at `w` rad/s, one plot a second at `k` s (noise-free).
    fn plot(k: f64, w: f64, v: f64) -> [f64; 2] {
        [v / w * (w * k).sin(), v / w * (1.0 - (w * k).cos())]
    }

    #[test]
    fn one_mode_bank_is_the_plain_initiator() {
        let cv = || {
            vec![Mode::Linear(
                MotionModel::constant_velocity_2d(0.05).unwrap(),
            )]
        };
        let (mut a, mut b) = (tracker(cv(), false), tracker(cv(), true));
        for k in 0..8 {
            let t = k as f64;
            a.step(t, &plot(t, 0.05, 5.0), &[0]).unwrap();
            b.step(t, &plot(t, 0.05, 5.0), &[0]).unwrap();
            for (x, y) in [(&a.tentative, &b.tentative), (&a.tracks, &b.tracks)] {
                assert_eq!(x.len(), y.len());
                for (p, q) in x.iter().zip(y) {
                    assert!((&p.x - &q.x).amax() < 1e-12 && (&p.p - &q.p).amax() < 1e-12);
                }
            }
        }
        assert_eq!(b.tracks.len(), 1);
    }

    #[test]
    fn a_confirmed_track_keeps_its_tentative_modes() {
        let modes = || {
            vec![
                Mode::Linear(MotionModel::constant_velocity_2d(0.05).unwrap()),
                Mode::KnownTurnRate {
                    q: [0.05, 0.05],
                    omega: 0.3,
                },
            ]
        };
        let (mut on, mut off) = (tracker(modes(), true), tracker(modes(), false));
        // The same bank, its tentative tracks confirmed later: at scan 3 still tentative.
        let mut later = tracker_confirming_at(modes(), true, 10);
        for k in 0..4 {
            let t = k as f64;
            for tr in [&mut on, &mut off, &mut later] {
                tr.step(t, &plot(t, 0.3, 10.0), &[0]).unwrap();
            }
            if k == 2 {
                assert!(off.tentative[0].imm.is_none());
            }
        }
        // Confirmed at scan 3 (its 4th update) with that scan's IMM cycle of its tentative
        // state, exactly as the track still tentative under the later confirmation; the
        // turn mode leads. Without the option the confirmed track has no IMM state until its
        // first scan as a confirmed track (every mode then starts at its state).
        let st = on.tracks[0].imm.as_ref().unwrap();
        assert_eq!(Some(st), later.tentative[0].imm.as_ref());
        assert!(st.mu[1] > 0.6, "{:?}", st.mu);
        assert!(off.tracks[0].imm.is_none());
        let x = crate::tracking::imm::combine(&st.mu, &st.x, &st.p).0;
        assert!((&x - &on.tracks[0].x).amax() < 1e-9);
    }

    #[test]
    fn a_non_starting_sensor_updates_tentative_tracks_but_starts_none() {
        let cv = || {
            vec![Mode::Linear(
                MotionModel::constant_velocity_2d(0.05).unwrap(),
            )]
        };
        let mut tr = tracker(cv(), false);
        let mut quiet = tr.cfg.sensors[0].clone();
        quiet.starts_tracks = false;
        tr.cfg.sensors.push(quiet);
        // Sensor 1 alone: nothing starts.
        for k in 0..3 {
            let t = k as f64;
            tr.step(t, &plot(t, 0.05, 5.0), &[1]).unwrap();
            assert!(tr.tentative.is_empty() && tr.tracks.is_empty());
        }
        // One plot of sensor 0 starts a track; sensor 1's plots then update and confirm it.
        for k in 3..8 {
            let t = k as f64;
            tr.step(t, &plot(t, 0.05, 5.0), &[usize::from(k > 3)])
                .unwrap();
        }
        assert_eq!((tr.tentative.len(), tr.tracks.len()), (0, 1));
        let h = &tr.tracks[0].history;
        assert_eq!(h.sensor[0], 0);
        assert!(h.sensor[1..].iter().all(|&s| s == 1));
    }
}
