//! Joint existence: JIPDA (Mušicki and Evans, "Joint integrated probabilistic data
//! association: JIPDA", IEEE Trans. AES 40(3), 2004) with the visibility of the VIMMJIPDA
//! (Brekke and co-workers): the JPDA association of a cluster weights each track by its
//! predicted probability of existing and being visible, and the posterior existence,
//! visibility and state follow from the joint marginals.
//!
//! **Model.** Per track `τ` a three-state Markov chain `ε_τ ∈ {∅, V, I}`: no target, a
//! target that exists and is visible (detectable), one that exists unseen. Its prediction
//! ([`crate::tracking::config::Existence::predict`]) gives `P(V) = r⁻v⁻`, `P(I) = r⁻(1 − v⁻)`,
//! `P(∅) = 1 − r⁻`. A target in `V` is detected with `P_D`, inside its gate with `P_G`, with
//! likelihood `N(z; ẑ, S)`; clutter is Poisson with spatial density `λ`. A joint association
//! event `a` gives each track one gated detection `a(τ) = j ≥ 1` or none (`a(τ) = 0`), no
//! detection twice. As in the JPDA, the joint likelihood factorises over tracks (clutter
//! factors common to every event dropped):
//!
//! ```text
//! p(Z, a, ε) ∝ Π_τ P(ε_τ) g_τ(a(τ), ε_τ),   g(j ≥ 1, V) = P_D N(z_j; ẑ, S) / λ,
//!                                            g(j ≥ 1, ∅) = g(j ≥ 1, I) = 0,
//!                                            g(0, V) = 1 − P_D P_G,  g(0, ∅) = g(0, I) = 1.   (1)
//! ```
//!
//! **Association weights.** Summing (1) over each `ε_τ` leaves a JPDA whose single-track
//! weights are ([`JointPrior::ln_missed`], [`JointPrior::ln_detectable`])
//!
//! ```text
//! w_τ0 = (1 − r⁻) + r⁻(1 − v⁻) + r⁻v⁻(1 − P_D P_G) = 1 − P_D P_G r⁻v⁻,
//! w_τj = r⁻v⁻ · P_D N(z_j; ẑ_τ, S_τ) / λ,                                                     (2)
//! ```
//!
//! so the marginals `β_τj = P(a(τ) = j | Z)` come from the JPDA machinery
//! ([`crate::tracking::jpda`]: EHM, brute force, belief propagation) unchanged.
//!
//! **Posteriors** ([`JointPrior::posterior`]). Given `a`, the `ε_τ` are independent with
//! `P(ε_τ | a, Z) ∝ P(ε_τ) g_τ(a(τ), ε_τ)`: a detected track is in `V`; a missed one is in `∅`,
//! `V`, `I` with probabilities `(1 − r⁻, r⁻v⁻(1 − P_D P_G), r⁻(1 − v⁻)) / w_τ0`. Hence
//!
//! ```text
//! r⁺ = P(∃ | Z) = β_τ0 · r⁻(1 − P_D P_G v⁻) / (1 − P_D P_G r⁻v⁻) + Σ_{j≥1} β_τj,             (3)
//! P(V | Z)      = β_τ0 · r⁻v⁻(1 − P_D P_G) / (1 − P_D P_G r⁻v⁻) + Σ_{j≥1} β_τj,   v⁺ = P(V | Z) / r⁺,   (4)
//! ```
//!
//! and the state given that the target exists is the mixture of the prediction and the Kalman
//! updates with the association probabilities conditioned on existence (Mušicki and Evans's
//! `β` given `χ`; the VIMMJIPDA's `p_j r_j / r⁺`):
//!
//! ```text
//! β̃_τ0 = β_τ0 · r⁻(1 − P_D P_G v⁻) / ((1 − P_D P_G r⁻v⁻) r⁺),   β̃_τj = β_τj / r⁺,   Σ β̃ = 1.   (5)
//! ```
//!
//! **One track** (a cluster of one): `β_0 ∝ 1 − P_D P_G r⁻v⁻`, `β_j ∝ r⁻v⁻ c_j` with
//! `c_j = P_D N_j / λ`, and with `L = 1 − P_D P_G + Σ c_j` (3) and (4) reduce to the IPDA closed
//! form `r⁺ = r⁻(v⁻L + 1 − v⁻) / (r⁻(v⁻L + 1 − v⁻) + 1 − r⁻)`, `v⁺ = v⁻L / (v⁻L + 1 − v⁻)`
//! ([`crate::tracking::config::Existence::update`]). The state weights (5) become
//! `β̃_0 ∝ 1 − P_D P_G v⁻`, `β̃_j ∝ v⁻ c_j`: the PDA update when `v⁻ = 1`; with `v⁻ < 1` the
//! missed hypothesis also covers "exists but unseen" (the VIMMJIPDA), where the per-track IPDA
//! (`Existence(joint = false)`) keeps the PDA update.

/// A track's predicted existence `r⁻` and visibility `v⁻` with the scan's `P_D P_G`: its
/// single-track JIPDA weights (2) and posteriors (3)–(5) (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointPrior {
    /// `r⁻`, the predicted probability that the target exists, in [0, 1].
    pub existence: f64,
    /// `v⁻`, the predicted probability that it is visible given it exists, in [0, 1].
    pub visibility: f64,
    /// `P_D P_G`, in (0, 1).
    pub pd_pg: f64,
}

/// A track's JIPDA posterior: [`JointPrior::posterior`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointPosterior {
    /// `r⁺`, eq. (3), in [0, 1].
    pub existence: f64,
    /// `v⁺`, eq. (4), in [0, 1].
    pub visibility: f64,
    /// `β̃_0`, eq. (5): the missed hypothesis's weight in the state given existence.
    pub missed: f64,
    /// `1 / r⁺`: multiplies each `β_j` into `β̃_j`, eq. (5).
    pub detection_scale: f64,
}

impl JointPrior {
    /// `ln w_0 = ln(1 − P_D P_G r⁻v⁻)`, eq. (2): the log weight of "no detection of this track".
    pub fn ln_missed(&self) -> f64 {
        (-self.pd_pg * self.existence * self.visibility).ln_1p()
    }

    /// `ln(r⁻v⁻)`, eq. (2): added to each detection's PDA log weight `ln(P_D N(z; ẑ, S)/λ)`
    /// (`−∞` when the track cannot be detected).
    pub fn ln_detectable(&self) -> f64 {
        (self.existence * self.visibility).ln()
    }

    /// Posterior existence, visibility and existence-conditioned state weights, eqs. (3)–(5),
    /// from the normalised joint marginals of the track: `missed` `= β_0` and `detected`
    /// `= Σ_{j≥1} β_j`. `None` when `r⁺` is not positive (a track that cannot exist, `r⁻ = 0`:
    /// its state given existence is undefined).
    pub fn posterior(&self, missed: f64, detected: f64) -> Option<JointPosterior> {
        let (r, v, g) = (self.existence, self.visibility, self.pd_pg);
        // 1 − P_D P_G r⁻v⁻ (> 0 as P_D P_G < 1).
        let w0 = 1.0 - g * r * v;
        // (3): P(∃, a(τ) = 0 | Z) = β_0 r⁻(1 − P_D P_G v⁻) / w_0.
        let exists_missed = missed * (r * (1.0 - g * v) / w0);
        let r1 = exists_missed + detected;
        if !(r1 > 0.0 && r1.is_finite()) {
            return None;
        }
        // (4): P(V | Z) = β_0 r⁻v⁻(1 − P_D P_G) / w_0 + Σ β_j.
        let visible = missed * (r * v * (1.0 - g) / w0) + detected;
        Some(JointPosterior {
            existence: r1.clamp(0.0, 1.0),
            visibility: (visible / r1).clamp(0.0, 1.0),
            missed: exists_missed / r1,
            detection_scale: 1.0 / r1,
        })
    }

    /// Eqs. (3)–(5) in place for one track of a scan: `missed` and `detections` hold the
    /// track's joint marginals `β` (any common scale) on entry and its association
    /// probabilities given existence `β̃` on return (summing to 1); returns `(r⁺, v⁺)`.
    /// `ln_pda` are the detections' PDA log weights `ln(P_D N(z; ẑ, S)/λ)` in the order of
    /// `detections`, used only when `r⁺ = 0` (`r⁻ = 0`, where the state given existence is
    /// undefined): then the track takes a lone track's weights `1 − P_D P_G v⁻ : v⁻ P_D N/λ`,
    /// the limit `r⁻ → 0` when no other track of its cluster can exist either (e.g.
    /// `survival = 0`), else an approximation that leaves out their competition, and
    /// `(0, v)` with `v` the lone track's `v⁺` (eq. (4) in the limit).
    pub fn condition(
        &self,
        missed: &mut f64,
        detections: &mut [f64],
        ln_pda: impl Iterator<Item = f64> + Clone,
    ) -> (f64, f64) {
        let det: f64 = detections.iter().sum();
        let tot = *missed + det;
        if let Some(p) = self.posterior(*missed / tot, det / tot) {
            *missed = p.missed;
            detections
                .iter_mut()
                .for_each(|b| *b = *b / tot * p.detection_scale);
            return (p.existence, p.visibility);
        }
        let (g, v) = (self.pd_pg, self.visibility);
        let (lm, lv) = ((-g * v).ln_1p(), v.ln());
        let mx = ln_pda.clone().map(|w| w + lv).fold(lm, f64::max);
        let w0 = (lm - mx).exp();
        let tot = w0 + ln_pda.clone().map(|w| (w + lv - mx).exp()).sum::<f64>();
        for (b, w) in detections.iter_mut().zip(ln_pda) {
            *b = (w + lv - mx).exp() / tot;
        }
        *missed = w0 / tot;
        // Eq. (4) of a lone track: β̃_0 v⁻(1 − P_D P_G)/(1 − P_D P_G v⁻) + Σ β̃_j.
        let vis = 1.0 - *missed + *missed * v * (1.0 - g) / (1.0 - g * v);
        (0.0, vis.clamp(0.0, 1.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::config::{Association, Existence, TrackerConfig};
    use crate::tracking::jpda::{marginals_brute_force, marginals_ehm, TrackHypotheses};
    use crate::tracking::track::Deleter;
    use crate::tracking::tracker::Tracker;
    use rand::{Rng, SeedableRng};

    fn existence(survival: f64, vis_stay: f64, invis_stay: f64) -> Existence {
        Existence {
            survival,
            initial: 0.9,
            delete: 0.0,
            vis_stay,
            invis_stay,
            confirm: None,
            birth: 0.5,
            joint: true,
        }
    }

    /// One track: the JIPDA posterior of eqs. (3)–(4) is the IPDA closed form of
    /// `Existence::update`, and the state weights (5) are `1 − P_D P_G v⁻ : v⁻ c_j`.
    #[test]
    fn one_track_is_ipda() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for _ in 0..2000 {
            let ex = existence(
                rng.random_range(0.5..1.0),
                rng.random_range(0.0..=1.0),
                rng.random_range(0.0..=1.0),
            );
            let rv = (rng.random_range(0.01..=1.0), rng.random_range(0.0..=1.0));
            let pd_pg = rng.random_range(0.05..0.99);
            let c: Vec<f64> = (0..rng.random_range(0..5))
                .map(|_| rng.random_range(0.0..3.0f64).powi(3))
                .collect();
            let (r0, v0) = ex.predict(rv);
            let p = JointPrior {
                existence: r0,
                visibility: v0,
                pd_pg,
            };
            // Eq. (2), normalised: a cluster of one.
            let w0 = p.ln_missed().exp();
            let wd: Vec<f64> = c.iter().map(|cj| (p.ln_detectable()).exp() * cj).collect();
            let tot = w0 + wd.iter().sum::<f64>();
            let post = p.posterior(w0 / tot, wd.iter().sum::<f64>() / tot).unwrap();
            let ln_l = (1.0 - pd_pg + c.iter().sum::<f64>()).ln();
            let (r1, v1) = ex.update(rv, ln_l);
            assert!((post.existence - r1).abs() < 1e-12, "{post:?} {r1}");
            assert!((post.visibility - v1).abs() < 1e-12, "{post:?} {v1}");
            // (5) against 1 − P_D P_G v⁻ : v⁻ c_j.
            let z = 1.0 - pd_pg * v0 + v0 * c.iter().sum::<f64>();
            assert!((post.missed - (1.0 - pd_pg * v0) / z).abs() < 1e-12);
            for (w, cj) in wd.iter().zip(&c) {
                assert!((w / tot * post.detection_scale - v0 * cj / z).abs() < 1e-12);
            }
        }
    }

    /// `r⁻ = 0`: `r⁺ = 0`, the lone-track weights and the lone track's `v⁺`.
    #[test]
    fn a_track_that_cannot_exist_takes_a_lone_tracks_weights() {
        let p = JointPrior {
            existence: 0.0,
            visibility: 0.6,
            pd_pg: 0.8,
        };
        let c = [2.0f64, 0.5];
        let (mut missed, mut det) = (1.0, [0.0, 0.0]);
        let (r, v) = p.condition(&mut missed, &mut det, c.iter().map(|c| c.ln()));
        let z = 1.0 - 0.8 * 0.6 + 0.6 * 2.5;
        assert_eq!(r, 0.0);
        assert!((missed - (1.0 - 0.48) / z).abs() < 1e-15);
        assert!((det[0] - 1.2 / z).abs() < 1e-15 && (det[1] - 0.3 / z).abs() < 1e-15);
        // v⁺ = v⁻L / (v⁻L + 1 − v⁻), L = 1 − P_D P_G + Σ c.
        let l = 1.0 - 0.8 + 2.5;
        assert!((v - 0.6 * l / (0.6 * l + 0.4)).abs() < 1e-15);
    }

    /// Code 5.7 with existence (`joint` as given), λ = 0.01, P_D = 0.9, P_G = 0.99.
    fn tracker(joint: bool, vis_stay: f64) -> Tracker {
        let mut c = TrackerConfig::code_5_7();
        if let Association::Jpda(j) = &mut c.association {
            j.clutter_density = Some(0.01);
            j.prob_detect = 0.9;
            j.prob_gate = 0.99;
        }
        c.deleter = Deleter::StepsSinceUpdate(1000);
        c.existence = Some(Existence {
            vis_stay,
            invis_stay: 0.5,
            ..existence(1.0, 1.0, 0.0)
        });
        c.existence.as_mut().unwrap().joint = joint;
        Tracker::new(c).unwrap()
    }

    /// A lone track (clutter 30 m away) that stays visible: the same states and existence
    /// with and without `joint` over a run.
    #[test]
    fn a_lone_visible_track_runs_as_under_ipda() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let (mut a, mut b) = (tracker(false, 1.0), tracker(true, 1.0));
        let p0 = [
            0.3, 0.0, 0.0, 0.0, 0.0, 0.05, 0.0, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.05,
        ];
        for tr in [&mut a, &mut b] {
            tr.add_track_with(&[0.0, 0.2, 0.0, 0.0], &p0, 0.0, Some((0.6, 1.0)))
                .unwrap();
        }
        for k in 1..40 {
            let t = k as f64;
            let mut z = vec![];
            if rng.random_bool(0.8) {
                z.extend([
                    0.2 * t + rng.random_range(-0.3..0.3),
                    rng.random_range(-0.3..0.3),
                ]);
            }
            for _ in 0..rng.random_range(0..3) {
                z.extend([
                    rng.random_range(-5.0..5.0),
                    30.0 + rng.random_range(0.0..5.0),
                ]);
            }
            let ids = vec![0; z.len() / 2];
            a.step(t, &z, &ids).unwrap();
            b.step(t, &z, &ids).unwrap();
            let (ta, tb) = (&a.tracks[0], &b.tracks[0]);
            assert_eq!((ta.id, tb.id), (0, 0));
            for (x, y) in ta.x.iter().zip(tb.x.iter()) {
                assert!((x - y).abs() < 1e-12, "scan {k}: {} {}", ta.x, tb.x);
            }
            let (ea, eb) = (ta.existence.unwrap(), tb.existence.unwrap());
            assert!((ea.0 - eb.0).abs() < 1e-12 && ea.1 == 1.0 && eb.1 == 1.0);
        }
    }

    /// Tracks A (r 0.95) and B (r 0.1) 1 m apart and one detection between them: under JIPDA
    /// A takes it and B's existence falls; under IPDA both count it in full.
    #[test]
    fn a_doubtful_track_yields_its_detection_to_a_sure_one() {
        let p0 = [
            0.5, 0.0, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.1,
        ];
        let run = |joint: bool| {
            let mut tr = tracker(joint, 1.0);
            tr.add_track_with(&[-1.0, 1.0, 0.0, 0.0], &p0, 0.0, Some((0.95, 1.0)))
                .unwrap();
            tr.add_track_with(&[0.0, 1.0, 0.0, 0.0], &p0, 0.0, Some((0.1, 1.0)))
                .unwrap();
            tr.step(1.0, &[0.6, 0.0], &[0]).unwrap();
            let r: Vec<f64> = tr.tracks.iter().map(|t| t.existence.unwrap().0).collect();
            let missed_a = tr.tracks[0].history.missed_probability.last().copied();
            (r, missed_a.unwrap())
        };
        let ((ri, ma_i), (rj, ma_j)) = (run(false), run(true));
        assert!(ma_j < ma_i - 0.1, "A's missed probability {ma_j} vs {ma_i}");
        assert!(
            rj[1] < 0.1 && ri[1] > 0.5,
            "B's existence {} vs {}",
            rj[1],
            ri[1]
        );
        assert!(rj[0] > 0.98);
    }

    /// Eqs. (2)–(5) against an enumeration of every joint event `(a, ε)` of model (1): the
    /// association `a` and each track's state `∅ / V / I`, weighted by its prior and `g`.
    #[test]
    fn clusters_equal_the_enumeration_of_existence_and_association() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        for _ in 0..300 {
            let nt = rng.random_range(1..5);
            let nd = rng.random_range(0..5);
            let pd_pg = rng.random_range(0.05..0.99);
            let pri: Vec<JointPrior> = (0..nt)
                .map(|_| JointPrior {
                    existence: rng.random_range(0.0..=1.0),
                    visibility: rng.random_range(0.0..=1.0),
                    pd_pg,
                })
                .collect();
            // c[t][j] = P_D N / λ of gated pairs (None: outside the gate).
            let c: Vec<Vec<Option<f64>>> = (0..nt)
                .map(|_| {
                    (0..nd)
                        .map(|_| rng.random_bool(0.7).then(|| rng.random_range(0.0..4.0)))
                        .collect()
                })
                .collect();
            // Enumeration: per track a(τ) ∈ {0} ∪ gated j (distinct), ε ∈ {∅, V, I}.
            let mut total = 0.0;
            let mut p_exists = vec![0.0; nt];
            let mut p_visible = vec![0.0; nt];
            // P(∃, a(τ) = j | Z) per track, j = 0 missed.
            let mut p_assoc = vec![vec![0.0; nd + 1]; nt];
            let choices: usize = (nd + 1).pow(nt as u32) * 3usize.pow(nt as u32);
            for code in 0..choices {
                let mut k = code;
                let mut a = vec![0usize; nt];
                let mut eps = vec![0usize; nt]; // 0 ∅, 1 V, 2 I
                for t in 0..nt {
                    a[t] = k % (nd + 1);
                    k /= nd + 1;
                    eps[t] = k % 3;
                    k /= 3;
                }
                let mut used = vec![false; nd];
                let mut w = 1.0;
                for t in 0..nt {
                    let p = &pri[t];
                    let prior = [
                        1.0 - p.existence,
                        p.existence * p.visibility,
                        p.existence * (1.0 - p.visibility),
                    ][eps[t]];
                    let g = match (a[t], eps[t]) {
                        (0, 1) => 1.0 - pd_pg,
                        (0, _) => 1.0,
                        (j, 1) => {
                            if used[j - 1] {
                                0.0
                            } else {
                                used[j - 1] = true;
                                c[t][j - 1].unwrap_or(0.0)
                            }
                        }
                        _ => 0.0,
                    };
                    w *= prior * g;
                }
                if w == 0.0 {
                    continue;
                }
                total += w;
                for t in 0..nt {
                    if eps[t] != 0 {
                        p_exists[t] += w;
                        p_assoc[t][a[t]] += w;
                    }
                    if eps[t] == 1 {
                        p_visible[t] += w;
                    }
                }
            }
            // Ours: eq. (2) weights, exact marginals, eqs. (3)–(5).
            let th: Vec<TrackHypotheses> = (0..nt)
                .map(|t| TrackHypotheses {
                    missed: pri[t].ln_missed().exp(),
                    detections: (0..nd)
                        .filter_map(|j| c[t][j].map(|cj| (j, pri[t].ln_detectable().exp() * cj)))
                        .collect(),
                })
                .collect();
            for m in [
                marginals_brute_force(&th).unwrap(),
                marginals_ehm(&th).unwrap(),
            ] {
                for t in 0..nt {
                    let det: f64 = m[t].detections.iter().sum();
                    let want_r = p_exists[t] / total;
                    match pri[t].posterior(m[t].missed, det) {
                        None => assert!(want_r < 1e-15, "{want_r}"),
                        Some(post) => {
                            assert!((post.existence - want_r).abs() < 1e-12);
                            let want_v = p_visible[t] / p_exists[t];
                            assert!((post.visibility - want_v).abs() < 1e-12);
                            let want_0 = p_assoc[t][0] / p_exists[t];
                            assert!((post.missed - want_0).abs() < 1e-12);
                            for (&(j, _), b) in th[t].detections.iter().zip(&m[t].detections) {
                                let want = p_assoc[t][j + 1] / p_exists[t];
                                assert!((b * post.detection_scale - want).abs() < 1e-12);
                            }
                        }
                    }
                }
            }
        }
    }
}
