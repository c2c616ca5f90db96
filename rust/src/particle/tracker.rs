//! The local tier of the two-tier particle filter as a multi-target image tracker (Bloisi et
//! al. §V, Figs. 9–12): per frame, sample (propagate every track's particles and draw proposal
//! particles around each detection), weight by the detections, SIR-resample, KClusterize, and
//! associate the clusters with the tracks by proximity, direction and speed (module of the
//! velocity). Tracks whose boxes close in on each other form an occlusion group: their colour
//! histograms are frozen and used to give the identities back when the boats separate.
//!
//! Image frame: pixels, origin top-left, u right, v down; boxes are `[x, y, w, h]` (top-left
//! corner and size). Velocities are px per frame; `dt` is the number of frames since the last
//! step. Confirmation is M-of-N (`confirm_hits` updates in the last `confirm_window` steps);
//! a confirmed track is deleted after `max_age` consecutive misses (twice that in a group).

use super::kcluster::{kclusterize, Cluster};
use super::params::TrackerParams;
use super::rng::Stream;
use super::sir::{gather, propagate, sample_around, systematic_resample, weights};
use super::DIM;
use crate::error::{Error, Result};
use crate::tracking::assign::linear_sum_assignment;

/// One image track.
#[derive(Debug, Clone)]
pub struct Track {
    /// Identity (from 1).
    pub id: u64,
    /// Particles, flat `[u, v, du, dv]` rows.
    pub particles: Vec<f64>,
    /// Mean `[u, v, du, dv]` of the particles.
    pub mean: [f64; DIM],
    /// Standard deviation of `[u, v, du, dv]`.
    pub std: [f64; DIM],
    /// Smoothed box size `[w, h]` (px).
    pub size: [f64; 2],
    /// Colour histogram (running mean of the matched detections'; empty when none).
    pub hist: Vec<f64>,
    /// The histogram frozen when the track joined its occlusion group.
    pub group_hist: Vec<f64>,
    /// Occlusion group (`None`: alone).
    pub group: Option<u64>,
    /// Bit i set: updated i steps ago (bit 0 is this step).
    pub hit_bits: u32,
    /// Whether M-of-N confirmation has been reached.
    pub confirmed: bool,
    /// Consecutive steps without an update.
    pub misses: u32,
    /// Steps since the track was started.
    pub age: u32,
    /// Score of the last matched detection.
    pub score: f64,
    /// λ: weight of the track's cluster in this step's mixture (0 when missed).
    pub weight: f64,
}

impl Track {
    /// Box `[x, y, w, h]` of the mean position and the smoothed size.
    pub fn bbox(&self) -> [f64; 4] {
        [
            self.mean[0] - self.size[0] / 2.0,
            self.mean[1] - self.size[1] / 2.0,
            self.size[0],
            self.size[1],
        ]
    }

    fn diag(&self) -> f64 {
        self.size[0].hypot(self.size[1])
    }
}

/// The detections of one frame: boxes `[x, y, w, h]`, scores and optional colour histograms
/// (`hist_len` values per box, empty slice for none).
#[derive(Debug, Clone, Copy)]
pub struct Frame<'a> {
    /// Flat `[x, y, w, h]` rows (px).
    pub boxes: &'a [f64],
    /// One score per box.
    pub scores: &'a [f64],
    /// Flat histograms (`hist_len` per box) or empty.
    pub hists: &'a [f64],
    /// Values per histogram (0 when none).
    pub hist_len: usize,
}

/// Bhattacharyya distance of two histograms as OpenCV's `HISTCMP_BHATTACHARYYA`:
/// `sqrt(1 − Σ sqrt(aᵢ bᵢ) / sqrt(Σa Σb))`, 1 when either is empty or all zero.
pub fn bhattacharyya(a: &[f64], b: &[f64]) -> f64 {
    if a.is_empty() || a.len() != b.len() {
        return 1.0;
    }
    let (sa, sb): (f64, f64) = (a.iter().sum(), b.iter().sum());
    if sa <= 0.0 || sb <= 0.0 {
        return 1.0;
    }
    let bc: f64 = a.iter().zip(b).map(|(x, y)| (x * y).sqrt()).sum();
    (1.0 - bc / (sa * sb).sqrt()).max(0.0).sqrt()
}

/// IoU of two `[x, y, w, h]` boxes (0 when the union is empty).
pub fn box_iou(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    let iw = ((a[0] + a[2]).min(b[0] + b[2]) - a[0].max(b[0])).max(0.0);
    let ih = ((a[1] + a[3]).min(b[1] + b[3]) - a[1].max(b[1])).max(0.0);
    let inter = iw * ih;
    let union = a[2] * a[3] + b[2] * b[3] - inter;
    if union > 0.0 {
        inter / union
    } else {
        0.0
    }
}

/// Optimal pairs of an `nr × nc` cost matrix (+inf: forbidden), each row either paired or
/// left out at the price `miss` (so some assignment always exists).
fn assign(cost: &[f64], nr: usize, nc: usize, miss: f64) -> Vec<(usize, usize)> {
    if nr == 0 || nc == 0 {
        return Vec::new();
    }
    let w = nc + nr;
    let mut padded = vec![f64::INFINITY; nr * w];
    for i in 0..nr {
        padded[i * w..i * w + nc].copy_from_slice(&cost[i * nc..(i + 1) * nc]);
        padded[i * w + nc + i] = miss;
    }
    match linear_sum_assignment(&padded, nr, w) {
        Ok(cols) => cols
            .into_iter()
            .enumerate()
            .filter(|&(i, j)| j < nc && cost[i * nc + j] < miss)
            .collect(),
        Err(_) => Vec::new(),
    }
}

fn mean_std(particles: &[f64]) -> ([f64; DIM], [f64; DIM]) {
    let n = (particles.len() / DIM).max(1) as f64;
    let mut m = [0.0; DIM];
    for p in particles.chunks_exact(DIM) {
        for d in 0..DIM {
            m[d] += p[d];
        }
    }
    m.iter_mut().for_each(|v| *v /= n);
    let mut s = [0.0; DIM];
    for p in particles.chunks_exact(DIM) {
        for d in 0..DIM {
            s[d] += (p[d] - m[d]).powi(2);
        }
    }
    (m, s.map(|v| (v / n).sqrt()))
}

/// The local tier of Bloisi et al.'s tracker for one camera (module doc).
#[derive(Debug, Clone)]
pub struct ParticleTracker {
    /// Parameters.
    pub params: TrackerParams,
    /// Live tracks (confirmed and tentative).
    pub tracks: Vec<Track>,
    /// The last step's clusters (the local Gaussian mixture).
    pub mixture: Vec<Cluster>,
    rng: Stream,
    next_id: u64,
    next_group: u64,
    /// Steps run.
    pub steps: u64,
}

/// A cluster paired with the detection it explains.
struct Candidate {
    cluster: usize,
    det: usize,
}

impl ParticleTracker {
    /// A tracker with no tracks; all random numbers from `seed`.
    pub fn new(params: TrackerParams, seed: u64) -> Result<Self> {
        params.validate()?;
        Ok(Self {
            params,
            tracks: Vec::new(),
            mixture: Vec::new(),
            rng: Stream::new(seed),
            next_id: 1,
            next_group: 1,
            steps: 0,
        })
    }

    fn check(frame: &Frame<'_>, dt: f64) -> Result<usize> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(Error::param(
                "dt",
                format!("must be finite and > 0, got {dt}"),
            ));
        }
        if frame.boxes.len() % 4 != 0 {
            return Err(Error::dim("boxes", "(k, 4)", frame.boxes.len()));
        }
        let k = frame.boxes.len() / 4;
        if frame.scores.len() != k {
            return Err(Error::dim("scores", format!("({k},)"), frame.scores.len()));
        }
        if frame.hist_len > 0 && frame.hists.len() != k * frame.hist_len {
            return Err(Error::dim(
                "hists",
                format!("({k}, {})", frame.hist_len),
                frame.hists.len(),
            ));
        }
        crate::error::check_finite("boxes", frame.boxes)?;
        crate::error::check_finite("scores", frame.scores)?;
        crate::error::check_finite("hists", frame.hists)?;
        if frame
            .boxes
            .chunks_exact(4)
            .any(|b| b[2] <= 0.0 || b[3] <= 0.0)
        {
            return Err(Error::param("boxes", "widths and heights must be > 0"));
        }
        if frame.hists.iter().any(|v| *v < 0.0) {
            return Err(Error::param("hists", "must be ≥ 0"));
        }
        Ok(k)
    }

    fn hist<'a>(frame: &Frame<'a>, j: usize) -> &'a [f64] {
        if frame.hist_len == 0 {
            &[]
        } else {
            &frame.hists[j * frame.hist_len..(j + 1) * frame.hist_len]
        }
    }

    /// Occlusion groups: confirmed tracks whose predicted boxes overlap by more than
    /// `group_iou` join one group (histograms frozen on joining); a track overlapping no
    /// member of its group leaves it.
    fn update_groups(&mut self) {
        let n = self.tracks.len();
        let boxes: Vec<[f64; 4]> = self.tracks.iter().map(Track::bbox).collect();
        let mut touching = vec![false; n];
        for i in 0..n {
            for j in i + 1..n {
                let live = |t: &Track| t.confirmed && t.misses == 0;
                if !(live(&self.tracks[i]) && live(&self.tracks[j])) {
                    continue;
                }
                if box_iou(&boxes[i], &boxes[j]) <= self.params.group_iou {
                    continue;
                }
                touching[i] = true;
                touching[j] = true;
                let g = match (self.tracks[i].group, self.tracks[j].group) {
                    (Some(a), _) => a,
                    (None, Some(b)) => b,
                    (None, None) => {
                        self.next_group += 1;
                        self.next_group - 1
                    }
                };
                for t in [i, j] {
                    let tr = &mut self.tracks[t];
                    if tr.group.is_none() {
                        tr.group_hist = tr.hist.clone();
                    }
                    tr.group = Some(g);
                }
            }
        }
        for (t, tr) in self.tracks.iter_mut().enumerate() {
            if !touching[t] && tr.group.is_some() && tr.misses == 0 {
                tr.group = None;
            }
        }
    }

    /// The proximity gate of a track: `gate` predicted-box diagonals plus 3σ of its particles'
    /// position spread, the spread's part capped at half a diagonal (px).
    fn reach(&self, t: &Track) -> f64 {
        let d = t.diag();
        self.params.gate * d + (3.0 * t.std[0].hypot(t.std[1])).min(0.5 * d)
    }

    /// Whether a cluster may continue a track: close, same direction, same speed module.
    fn compatible(&self, t: &Track, c: &Cluster) -> Option<f64> {
        let p = &self.params;
        let dist = (c.mean[0] - t.mean[0]).hypot(c.mean[1] - t.mean[1]);
        if dist > self.reach(t) {
            return None;
        }
        let (st, sc) = (t.mean[2].hypot(t.mean[3]), c.mean[2].hypot(c.mean[3]));
        // the velocity tests apply once the speeds stand out of their spread (2σ)
        let (vt, vc) = (t.std[2].hypot(t.std[3]), c.std[2].hypot(c.std[3]));
        if st >= p.min_speed.max(2.0 * vt) && sc >= p.min_speed.max(2.0 * vc) {
            let cos = (t.mean[2] * c.mean[2] + t.mean[3] * c.mean[3]) / (st * sc);
            if cos.clamp(-1.0, 1.0).acos().to_degrees() > p.max_angle_deg {
                return None;
            }
        }
        if (st - sc).abs() > p.speed_abs + p.speed_rel * st.max(sc) + 2.0 * (vt + vc) {
            return None;
        }
        Some(dist / t.diag().max(1.0))
    }

    /// Advance `dt` frames and take this frame's detections; returns the indices (into
    /// `tracks`) of the confirmed tracks updated in this step.
    pub fn step(&mut self, frame: &Frame<'_>, dt: f64) -> Result<Vec<usize>> {
        let k = Self::check(frame, dt)?;
        let p = self.params;
        self.steps += 1;
        // 1. sample: propagate every track's particles
        for t in &mut self.tracks {
            propagate(&mut t.particles, dt, p.accel_std, &mut self.rng);
            let (m, s) = mean_std(&t.particles);
            t.mean = m;
            t.std = s;
            t.age += 1;
            t.hit_bits <<= 1;
            t.weight = 0.0;
        }
        self.update_groups();
        // proposal particles around each detection, moving like the nearest track
        let mut set: Vec<f64> = Vec::new();
        for t in &self.tracks {
            set.extend_from_slice(&t.particles);
        }
        let mut obs = Vec::with_capacity(k);
        for j in 0..k {
            let b = &frame.boxes[4 * j..4 * j + 4];
            let c = [b[0] + b[2] / 2.0, b[1] + b[3] / 2.0];
            let cap = p.cluster.delta / 4.0;
            let sd = [
                (p.meas_scale * b[2]).clamp(0.5, cap.max(0.5)),
                (p.meas_scale * b[3]).clamp(0.5, cap.max(0.5)),
            ];
            obs.push([c[0], c[1], sd[0], sd[1]]);
            let near = self
                .tracks
                .iter()
                .map(|t| ((t.mean[0] - c[0]).hypot(t.mean[1] - c[1]), t))
                .filter(|(d, t)| *d <= self.reach(t))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let (vel, vsd) = match near {
                Some((_, t)) => (
                    [
                        t.mean[2] + p.vel_gain * (c[0] - t.mean[0]) / dt,
                        t.mean[3] + p.vel_gain * (c[1] - t.mean[1]) / dt,
                    ],
                    p.track_vel_std,
                ),
                None => ([0.0, 0.0], p.birth_vel_std),
            };
            sample_around(&mut set, p.particles, c, sd, vel, vsd, &mut self.rng);
        }
        // 2. weight and SIR-resample, 3. KClusterize
        self.mixture.clear();
        let mut cands: Vec<Candidate> = Vec::new();
        let mut resampled = Vec::new();
        if k > 0 {
            let w = weights(&set, &obs, p.clutter);
            let idx = systematic_resample(&w, p.particles * k, &mut self.rng);
            resampled = gather(&set, &idx);
            let ones = vec![1.0; idx.len()];
            self.mixture = kclusterize(&resampled, &ones, &p.cluster);
            // each detection keeps the heaviest cluster whose mean lies within its reach
            let mut best: Vec<Option<usize>> = vec![None; k];
            for (ci, c) in self.mixture.iter().enumerate() {
                let mut near: Option<(f64, usize)> = None;
                for (j, z) in obs.iter().enumerate() {
                    let b = &frame.boxes[4 * j..4 * j + 4];
                    let d = (c.mean[0] - z[0]).hypot(c.mean[1] - z[1]);
                    let reach = (0.5 * b[2].hypot(b[3])).max(p.cluster.delta);
                    if d <= reach && near.is_none_or(|(bd, _)| d < bd) {
                        near = Some((d, j));
                    }
                }
                if let Some((_, j)) = near {
                    if best[j].is_none_or(|b| self.mixture[b].weight < c.weight) {
                        best[j] = Some(ci);
                    }
                }
            }
            cands = best
                .iter()
                .enumerate()
                .filter_map(|(det, c)| c.map(|cluster| Candidate { cluster, det }))
                .collect();
        }
        // 4. data association: proximity, direction, speed (+ appearance)
        let (nt, nc) = (self.tracks.len(), cands.len());
        const MISS: f64 = 1e6;
        let mut cost = vec![f64::INFINITY; nt * nc];
        for (ti, t) in self.tracks.iter().enumerate() {
            for (ci, cand) in cands.iter().enumerate() {
                if let Some(d) = self.compatible(t, &self.mixture[cand.cluster]) {
                    let app = bhattacharyya(&t.hist, Self::hist(frame, cand.det));
                    let a = if t.hist.is_empty() { 0.0 } else { app };
                    cost[ti * nc + ci] = (1.0 - p.appearance_weight) * d + p.appearance_weight * a;
                }
            }
        }
        let mut pairs = assign(&cost, nt, nc, MISS);
        // occlusion groups: the members matched in this step share their clusters by the
        // histograms frozen when the group formed (re-identification after the occlusion)
        let mut groups: Vec<u64> = self.tracks.iter().filter_map(|t| t.group).collect();
        groups.sort_unstable();
        groups.dedup();
        for g in groups {
            let members: Vec<usize> = (0..pairs.len())
                .filter(|&q| self.tracks[pairs[q].0].group == Some(g))
                .collect();
            if members.len() < 2 {
                continue;
            }
            let m = members.len();
            let mut hc = vec![0.0; m * m];
            for (a, &qa) in members.iter().enumerate() {
                let t = &self.tracks[pairs[qa].0];
                for (b, &qb) in members.iter().enumerate() {
                    let det = cands[pairs[qb].1].det;
                    hc[a * m + b] = bhattacharyya(&t.group_hist, Self::hist(frame, det));
                }
            }
            if let Ok(cols) = linear_sum_assignment(&hc, m, m) {
                let old: Vec<usize> = members.iter().map(|&q| pairs[q].1).collect();
                for (a, &q) in members.iter().enumerate() {
                    pairs[q].1 = old[cols[a]];
                }
            }
        }
        let mut used_t = vec![false; nt];
        let mut used_c = vec![false; nc];
        for &(ti, ci) in &pairs {
            used_t[ti] = true;
            used_c[ci] = true;
        }
        // re-identification of the leftovers by colour, near a lost track
        let lost: Vec<usize> = (0..nt)
            .filter(|&t| !used_t[t] && self.tracks[t].confirmed && !self.tracks[t].hist.is_empty())
            .collect();
        let left: Vec<usize> = (0..nc).filter(|&c| !used_c[c]).collect();
        if !lost.is_empty() && !left.is_empty() && frame.hist_len > 0 {
            let mut rc = vec![f64::INFINITY; lost.len() * left.len()];
            for (a, &ti) in lost.iter().enumerate() {
                let t = &self.tracks[ti];
                for (b, &ci) in left.iter().enumerate() {
                    let c = &self.mixture[cands[ci].cluster];
                    let dist = (c.mean[0] - t.mean[0]).hypot(c.mean[1] - t.mean[1]);
                    let h = bhattacharyya(&t.hist, Self::hist(frame, cands[ci].det));
                    if h <= p.reid_distance && dist <= p.reid_radius * t.diag() {
                        rc[a * left.len() + b] = h;
                    }
                }
            }
            for (a, b) in assign(&rc, lost.len(), left.len(), MISS) {
                pairs.push((lost[a], left[b]));
                used_t[lost[a]] = true;
                used_c[left[b]] = true;
            }
        }
        // 5. update the matched tracks from their clusters
        for &(ti, ci) in &pairs {
            let cl = &self.mixture[cands[ci].cluster];
            let det = cands[ci].det;
            let b = &frame.boxes[4 * det..4 * det + 4];
            let t = &mut self.tracks[ti];
            t.particles = keep_members(&resampled, &cl.members, p.particles);
            t.mean = cl.mean;
            t.std = cl.std;
            t.weight = cl.weight;
            let g = p.size_gain;
            t.size = [
                g * b[2] + (1.0 - g) * t.size[0],
                g * b[3] + (1.0 - g) * t.size[1],
            ];
            t.score = frame.scores[det];
            let h = Self::hist(frame, det);
            if !h.is_empty() {
                if t.hist.len() == h.len() {
                    for (x, y) in t.hist.iter_mut().zip(h) {
                        *x = 0.7 * *x + 0.3 * y;
                    }
                } else {
                    t.hist = h.to_vec();
                }
            }
            t.hit_bits |= 1;
            t.misses = 0;
        }
        for (ti, t) in self.tracks.iter_mut().enumerate() {
            if !used_t[ti] {
                t.misses += 1;
            }
            let window = if p.confirm_window == 32 {
                u32::MAX
            } else {
                (1u32 << p.confirm_window) - 1
            };
            if (t.hit_bits & window).count_ones() >= p.confirm_hits {
                t.confirmed = true;
            }
        }
        // 6. start tracks on the clusters no track took
        for ci in (0..nc).filter(|&c| !used_c[c]) {
            let cl = &self.mixture[cands[ci].cluster];
            let det = cands[ci].det;
            let b = &frame.boxes[4 * det..4 * det + 4];
            self.tracks.push(Track {
                id: self.next_id,
                particles: keep_members(&resampled, &cl.members, p.particles),
                mean: cl.mean,
                std: cl.std,
                size: [b[2], b[3]],
                hist: Self::hist(frame, det).to_vec(),
                group_hist: Vec::new(),
                group: None,
                hit_bits: 1,
                confirmed: p.confirm_hits == 1,
                misses: 0,
                age: 0,
                score: frame.scores[det],
                weight: cl.weight,
            });
            self.next_id += 1;
        }
        // 7. deletion: tentative tracks that can no longer reach M of N, old confirmed misses
        let (m_hits, n_win, age) = (p.confirm_hits, p.confirm_window, p.max_age);
        self.tracks.retain(|t| {
            if t.confirmed {
                let limit = if t.group.is_some() { 2 * age } else { age };
                t.misses <= limit
            } else {
                let left = n_win.saturating_sub(t.age + 1);
                let have = t.hit_bits.count_ones();
                have + left >= m_hits && t.misses <= n_win - m_hits
            }
        });
        Ok((0..self.tracks.len())
            .filter(|&i| self.tracks[i].confirmed && self.tracks[i].misses == 0)
            .collect())
    }
}

/// At most `n` of the cluster's member particles (evenly spaced), as a flat particle set.
fn keep_members(particles: &[f64], members: &[usize], n: usize) -> Vec<f64> {
    if members.len() <= n {
        return gather(particles, members);
    }
    let idx: Vec<usize> = (0..n).map(|i| members[i * members.len() / n]).collect();
    gather(particles, &idx)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(boxes: &[f64]) -> (Vec<f64>, Vec<f64>) {
        (boxes.to_vec(), vec![1.0; boxes.len() / 4])
    }

    #[test]
    fn two_boats_keep_their_ids() {
        let mut tr = ParticleTracker::new(TrackerParams::default(), 4).unwrap();
        let mut ids_seen = Vec::new();
        for f in 0..20 {
            let x = f as f64 * 3.0;
            let (b, s) = frame(&[20.0 + x, 50.0, 40.0, 20.0, 200.0 - x, 120.0, 30.0, 15.0]);
            let out = tr
                .step(
                    &Frame {
                        boxes: &b,
                        scores: &s,
                        hists: &[],
                        hist_len: 0,
                    },
                    1.0,
                )
                .unwrap();
            if f >= 2 {
                assert_eq!(out.len(), 2, "frame {f}");
                let mut ids: Vec<u64> = out.iter().map(|&i| tr.tracks[i].id).collect();
                ids.sort_unstable();
                ids_seen.push(ids);
            }
        }
        assert!(ids_seen.iter().all(|v| v == &ids_seen[0]));
        let t = tr.tracks.iter().find(|t| t.id == ids_seen[0][0]).unwrap();
        assert!((t.mean[2] - 3.0).abs() < 0.5, "velocity {:?}", t.mean);
    }

    #[test]
    fn bad_boxes_are_errors() {
        let mut tr = ParticleTracker::new(TrackerParams::default(), 0).unwrap();
        let f = Frame {
            boxes: &[0.0, 0.0, -1.0, 2.0],
            scores: &[1.0],
            hists: &[],
            hist_len: 0,
        };
        assert!(tr.step(&f, 1.0).is_err());
        let f = Frame {
            boxes: &[0.0, 0.0, 1.0, 2.0],
            scores: &[1.0],
            hists: &[],
            hist_len: 0,
        };
        assert!(tr.step(&f, 0.0).is_err());
    }
}
