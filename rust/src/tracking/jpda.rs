//! Joint probabilistic data association: exact marginal association probabilities of a
//! cluster of tracks, by brute-force enumeration of the joint hypotheses or by Efficient
//! Hypothesis Management (Maskell, Briers & Wright, "Fast mutual exclusion", 2004), plus the
//! split of a scan into independent clusters (tracks connected by shared gated detections).
//!
//! A joint hypothesis assigns each track its missed detection or one of its gated detections,
//! no detection used twice; its weight is the product of the single-track weights. The
//! marginal of (track, hypothesis) is the normalised sum of the weights of the joint
//! hypotheses containing it — exactly what Stone Soup's `JPDA` and `JPDAwithEHM` compute.
//!
//! Bounded cost: [`marginals_within`] gives up an exact method once it has built more than a
//! budget of hypotheses and then approximates the marginals by loopy belief propagation on the
//! bipartite track–detection graph (Williams & Lau, "Approximate evaluation of marginal
//! association probabilities with belief propagation", IEEE Trans. AES 50(4), 2014, eqs.
//! 30–31), whose cost is linear in the number of gated pairs per iteration.

use crate::error::{Error, Result};
use std::collections::HashMap;

/// Single-track hypotheses of one track: the missed-detection weight and the weights of its
/// gated detections (linear scale, any common factor per track is irrelevant).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrackHypotheses {
    /// Weight of "no detection of this track".
    pub missed: f64,
    /// `(detection index, weight)` of each gated detection, detections distinct.
    pub detections: Vec<(usize, f64)>,
}

/// Marginal probabilities of one track: missed first, then one per entry of
/// [`TrackHypotheses::detections`] in the same order. They sum to 1.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Marginals {
    pub missed: f64,
    pub detections: Vec<f64>,
}

/// Which exact method computes the marginals of a cluster.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Method {
    /// Enumerate every joint hypothesis (exponential; reference implementation).
    BruteForce,
    /// Efficient Hypothesis Management (exact, polynomial when clusters are chain-like).
    Ehm,
    /// Loopy belief propagation (approximate, linear in the gated pairs per iteration).
    Lbp,
}

/// Sweeps of belief propagation at most, and the message change (absolute, messages in
/// (0, 1]) below which it has converged.
pub const LBP_MAX_ITERATIONS: usize = 1000;
/// See [`LBP_MAX_ITERATIONS`].
pub const LBP_TOLERANCE: f64 = 1e-13;

/// How the marginals of a cluster were obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exactness {
    /// By the exact method asked for.
    Exact,
    /// By belief propagation (asked for, or the exact method exceeded its budget); the sweeps
    /// it took.
    Approximate { iterations: usize },
}

pub use super::clustering::{clusters, group_by_shared_detections};

fn check(cluster: &[TrackHypotheses]) -> Result<()> {
    for (t, h) in cluster.iter().enumerate() {
        let ok = |w: f64| w.is_finite() && w >= 0.0;
        if !ok(h.missed) || h.detections.iter().any(|&(_, w)| !ok(w)) {
            return Err(Error::param(
                "likelihoods",
                format!("weights of track {t} must be finite and >= 0"),
            ));
        }
    }
    Ok(())
}

fn normalise(m: &mut [Marginals], total: f64) -> Result<()> {
    if !(total > 0.0 && total.is_finite()) {
        return Err(Error::param(
            "likelihoods",
            "every joint hypothesis has zero weight (no track can be missed or detected)",
        ));
    }
    for t in m.iter_mut() {
        t.missed /= total;
        t.detections.iter_mut().for_each(|p| *p /= total);
    }
    Ok(())
}

/// Exact marginals by enumerating all joint hypotheses of the cluster.
pub fn marginals_brute_force(cluster: &[TrackHypotheses]) -> Result<Vec<Marginals>> {
    brute_force_within(cluster, usize::MAX)?.ok_or_else(|| Error::param("likelihoods", "budget"))
}

/// [`marginals_brute_force`], or `None` once more than `budget` joint hypotheses are seen.
fn brute_force_within(
    cluster: &[TrackHypotheses],
    budget: usize,
) -> Result<Option<Vec<Marginals>>> {
    check(cluster)?;
    let mut out: Vec<Marginals> = cluster
        .iter()
        .map(|h| Marginals {
            missed: 0.0,
            detections: vec![0.0; h.detections.len()],
        })
        .collect();
    let mut choice = vec![usize::MAX; cluster.len()];
    let mut used: Vec<usize> = Vec::new();
    let mut total = 0.0;
    let mut left = budget;
    #[allow(clippy::too_many_arguments)]
    fn rec(
        c: &[TrackHypotheses],
        i: usize,
        w: f64,
        choice: &mut [usize],
        used: &mut Vec<usize>,
        out: &mut [Marginals],
        total: &mut f64,
        left: &mut usize,
    ) {
        if *left == 0 {
            return;
        }
        if i == c.len() {
            *left -= 1;
            *total += w;
            for (t, &k) in choice.iter().enumerate() {
                if k == usize::MAX {
                    out[t].missed += w;
                } else {
                    out[t].detections[k] += w;
                }
            }
            return;
        }
        choice[i] = usize::MAX;
        rec(c, i + 1, w * c[i].missed, choice, used, out, total, left);
        for (k, &(d, wd)) in c[i].detections.iter().enumerate() {
            if !used.contains(&d) {
                used.push(d);
                choice[i] = k;
                rec(c, i + 1, w * wd, choice, used, out, total, left);
                used.pop();
            }
        }
    }
    rec(
        cluster,
        0,
        1.0,
        &mut choice,
        &mut used,
        &mut out,
        &mut total,
        &mut left,
    );
    if left == 0 {
        return Ok(None);
    }
    normalise(&mut out, total)?;
    Ok(Some(out))
}

/// A set of local detection indices, as a bit set (inline for clusters of up to 128
/// detections, heap words beyond).
trait BitKey: Clone + Eq + std::hash::Hash {
    fn empty(n_bits: usize) -> Self;
    fn set(&mut self, b: usize);
    fn has(&self, b: usize) -> bool;
    fn and(&mut self, other: &Self);
}

impl BitKey for u64 {
    fn empty(_: usize) -> Self {
        0
    }
    fn set(&mut self, b: usize) {
        *self |= 1 << b;
    }
    fn has(&self, b: usize) -> bool {
        *self & (1 << b) != 0
    }
    fn and(&mut self, other: &Self) {
        *self &= other;
    }
}

impl BitKey for u128 {
    fn empty(_: usize) -> Self {
        0
    }
    fn set(&mut self, b: usize) {
        *self |= 1 << b;
    }
    fn has(&self, b: usize) -> bool {
        *self & (1 << b) != 0
    }
    fn and(&mut self, other: &Self) {
        *self &= other;
    }
}

impl BitKey for Vec<u64> {
    fn empty(n_bits: usize) -> Self {
        vec![0; n_bits.div_ceil(64).max(1)]
    }
    fn set(&mut self, b: usize) {
        self[b / 64] |= 1 << (b % 64);
    }
    fn has(&self, b: usize) -> bool {
        self[b / 64] & (1 << (b % 64)) != 0
    }
    fn and(&mut self, other: &Self) {
        for (w, o) in self.iter_mut().zip(other) {
            *w &= o;
        }
    }
}

/// A multiplicative hasher for the integer keys of EHM nodes (no DoS concern here).
#[derive(Default, Clone, Copy)]
pub(crate) struct FastHasher(u64);

impl std::hash::Hasher for FastHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_u128(&mut self, v: u128) {
        self.write_u64(v as u64);
        self.write_u64((v >> 64) as u64);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

pub(crate) type FastMap<K, V> = HashMap<K, V, std::hash::BuildHasherDefault<FastHasher>>;

/// Exact marginals by Efficient Hypothesis Management: tracks are processed in the order
/// given; a node of level `i` is the set of already-used detections that tracks `i..` could
/// still use, so equal histories merge. Cost is the number of distinct nodes, small when each
/// detection is shared by tracks close in the order (order tracks spatially).
pub fn marginals_ehm(cluster: &[TrackHypotheses]) -> Result<Vec<Marginals>> {
    ehm_within(cluster, usize::MAX)?.ok_or_else(|| Error::param("likelihoods", "budget"))
}

/// [`marginals_ehm`], or `None` once the net's size passes `budget`: its edges (single-track
/// hypotheses of its nodes, summed over the levels) times the 64-bit words of a node's key
/// (one per 64 detections of the cluster) — its memory and work.
fn ehm_within(cluster: &[TrackHypotheses], budget: usize) -> Result<Option<Vec<Marginals>>> {
    check(cluster)?;
    let mut local: HashMap<usize, usize> = HashMap::new();
    let hyps: Vec<Vec<(usize, f64)>> = cluster
        .iter()
        .map(|h| {
            h.detections
                .iter()
                .map(|&(d, w)| {
                    let l = local.len();
                    (*local.entry(d).or_insert(l), w)
                })
                .collect()
        })
        .collect();
    match local.len() {
        0..=64 => ehm::<u64>(cluster, &hyps, local.len(), budget),
        65..=128 => ehm::<u128>(cluster, &hyps, local.len(), budget),
        _ => ehm::<Vec<u64>>(cluster, &hyps, local.len(), budget),
    }
}

fn ehm<K: BitKey>(
    cluster: &[TrackHypotheses],
    hyps: &[Vec<(usize, f64)>],
    n_bits: usize,
    budget: usize,
) -> Result<Option<Vec<Marginals>>> {
    let n = cluster.len();
    // acc[i]: detections of tracks i.. (as a bit set); acc[n] = ∅.
    let mut acc: Vec<K> = vec![K::empty(n_bits); n + 1];
    for i in (0..n).rev() {
        let mut k = acc[i + 1].clone();
        for &(d, _) in &hyps[i] {
            k.set(d);
        }
        acc[i] = k;
    }
    // Forward pass: nodes of each level with forward weights, and the edges to the next level
    // stored flat: node `ni` of level `i` owns `edges[i][off[i][ni]..off[i][ni + 1]]`, each
    // (hypothesis index or MISSED, child node).
    const MISSED: u32 = u32::MAX;
    let mut fw: Vec<Vec<f64>> = vec![Vec::new(); n + 1];
    let mut off: Vec<Vec<u32>> = vec![Vec::new(); n];
    let mut edges: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n];
    let mut nodes: Vec<K> = vec![K::empty(n_bits)];
    fw[0].push(1.0);
    let mut index: FastMap<K, u32> = FastMap::default();
    let mut n_edges = 0usize;
    let words = n_bits.div_ceil(64).max(1);
    for i in 0..n {
        let level = nodes.len().saturating_mul(hyps[i].len() + 1);
        n_edges = n_edges.saturating_add(level.saturating_mul(words));
        if n_edges > budget {
            return Ok(None);
        }
        index.clear();
        let mut next_nodes: Vec<K> = Vec::with_capacity(nodes.len());
        let mut next_fw: Vec<f64> = Vec::with_capacity(nodes.len());
        let mut lo = Vec::with_capacity(nodes.len() + 1);
        let mut le: Vec<(u32, u32)> = Vec::with_capacity(nodes.len() * (hyps[i].len() + 1));
        lo.push(0u32);
        let missed = cluster[i].missed;
        for (ni, key) in nodes.iter().enumerate() {
            let f = fw[i][ni];
            let mut push = |mut child: K, h: u32, w: f64| {
                child.and(&acc[i + 1]);
                let c = match index.get(&child) {
                    Some(&c) => c,
                    None => {
                        let c = next_nodes.len() as u32;
                        index.insert(child.clone(), c);
                        next_nodes.push(child);
                        next_fw.push(0.0);
                        c
                    }
                };
                next_fw[c as usize] += f * w;
                le.push((h, c));
            };
            push(key.clone(), MISSED, missed);
            for (h, &(d, w)) in hyps[i].iter().enumerate() {
                if !key.has(d) {
                    let mut child = key.clone();
                    child.set(d);
                    push(child, h as u32, w);
                }
            }
            lo.push(le.len() as u32);
        }
        nodes = next_nodes;
        fw[i + 1] = next_fw;
        off[i] = lo;
        edges[i] = le;
    }
    let weight = |i: usize, h: u32| {
        if h == MISSED {
            cluster[i].missed
        } else {
            hyps[i][h as usize].1
        }
    };
    // Backward pass.
    let mut bw: Vec<Vec<f64>> = vec![Vec::new(); n + 1];
    bw[n] = vec![1.0; nodes.len()];
    for i in (0..n).rev() {
        let next = &bw[i + 1];
        bw[i] = off[i]
            .windows(2)
            .map(|r| {
                edges[i][r[0] as usize..r[1] as usize]
                    .iter()
                    .map(|&(h, c)| weight(i, h) * next[c as usize])
                    .sum()
            })
            .collect();
    }
    let total = bw[0][0];
    let mut out: Vec<Marginals> = Vec::with_capacity(n);
    for i in 0..n {
        let mut m = Marginals {
            missed: 0.0,
            detections: vec![0.0; hyps[i].len()],
        };
        for (ni, r) in off[i].windows(2).enumerate() {
            let f = fw[i][ni];
            for &(h, c) in &edges[i][r[0] as usize..r[1] as usize] {
                let v = f * weight(i, h) * bw[i + 1][c as usize];
                if h == MISSED {
                    m.missed += v;
                } else {
                    m.detections[h as usize] += v;
                }
            }
        }
        out.push(m);
    }
    normalise(&mut out, total)?;
    Ok(Some(out))
}

/// Approximate marginals by loopy belief propagation (Williams & Lau 2014, eqs. 30–31): with
/// track weights `w_i0` (missed) and `w_ij`, and weight 1 for a detection left to clutter,
/// messages `μ_ij = w_ij / (w_i0 + Σ_{j'≠j} w_ij' ν_j'i)` (track → detection) and
/// `ν_ji = 1 / (1 + Σ_{i'≠i} μ_i'j)` (detection → track) are iterated from `ν = 1` until no
/// `ν` moves by more than [`LBP_TOLERANCE`] (or [`LBP_MAX_ITERATIONS`] sweeps); then
/// `p_ij ∝ w_ij ν_ji`, `p_i0 ∝ w_i0`. Exact on trees (e.g. clusters where no two tracks share
/// two detections); the iteration converges on every graph (their Theorem 1). Returns the
/// marginals and the sweeps taken. Exclusive sums use prefix/suffix sums (no cancellation).
pub fn marginals_lbp(cluster: &[TrackHypotheses]) -> Result<(Vec<Marginals>, usize)> {
    check(cluster)?;
    // Edges grouped by track (as given) and, through `by_det`, by detection.
    let mut local: HashMap<usize, usize> = HashMap::new();
    let mut edge_det: Vec<usize> = Vec::new();
    let mut track_off = vec![0usize];
    for h in cluster {
        for &(d, _) in &h.detections {
            let l = local.len();
            edge_det.push(*local.entry(d).or_insert(l));
        }
        track_off.push(edge_det.len());
    }
    let ne = edge_det.len();
    let nd = local.len();
    let mut det_off = vec![0usize; nd + 1];
    for &d in &edge_det {
        det_off[d + 1] += 1;
    }
    for d in 0..nd {
        det_off[d + 1] += det_off[d];
    }
    let mut fill = det_off.clone();
    let mut by_det = vec![0usize; ne];
    for (e, &d) in edge_det.iter().enumerate() {
        by_det[fill[d]] = e;
        fill[d] += 1;
    }
    let w: Vec<f64> = cluster
        .iter()
        .flat_map(|h| h.detections.iter().map(|&(_, w)| w))
        .collect();
    let mut nu = vec![1.0f64; ne];
    let mut mu = vec![0.0f64; ne];
    let mut scratch: Vec<f64> = Vec::new();
    // Σ of `v` over a group except each member, by prefix and suffix sums, plus `base`.
    fn exclusive(v: &[f64], base: f64, out: &mut Vec<f64>) {
        out.clear();
        let mut acc = base;
        for &x in v {
            out.push(acc);
            acc += x;
        }
        let mut suf = 0.0;
        for (o, &x) in out.iter_mut().zip(v).rev() {
            *o += suf;
            suf += x;
        }
    }
    let mut vals: Vec<f64> = Vec::new();
    let mut iterations = 0;
    while iterations < LBP_MAX_ITERATIONS {
        iterations += 1;
        for (i, h) in cluster.iter().enumerate() {
            let r = track_off[i]..track_off[i + 1];
            vals.clear();
            vals.extend(r.clone().map(|e| w[e] * nu[e]));
            exclusive(&vals, h.missed, &mut scratch);
            for (e, &den) in r.zip(&scratch) {
                mu[e] = if den > 0.0 { w[e] / den } else { f64::INFINITY };
            }
        }
        let mut change = 0.0f64;
        for d in 0..nd {
            let es = &by_det[det_off[d]..det_off[d + 1]];
            vals.clear();
            vals.extend(es.iter().map(|&e| mu[e]));
            exclusive(&vals, 1.0, &mut scratch);
            for (&e, &den) in es.iter().zip(&scratch) {
                let v = 1.0 / den;
                change = change.max((v - nu[e]).abs());
                nu[e] = v;
            }
        }
        if change <= LBP_TOLERANCE {
            break;
        }
    }
    let mut out = Vec::with_capacity(cluster.len());
    for (i, h) in cluster.iter().enumerate() {
        let r = track_off[i]..track_off[i + 1];
        let mut m = Marginals {
            missed: h.missed,
            detections: r.map(|e| w[e] * nu[e]).collect(),
        };
        let tot = m.missed + m.detections.iter().sum::<f64>();
        if !(tot > 0.0 && tot.is_finite()) {
            return Err(Error::param(
                "likelihoods",
                format!("track {i} has zero weight for every hypothesis"),
            ));
        }
        m.missed /= tot;
        m.detections.iter_mut().for_each(|p| *p /= tot);
        out.push(m);
    }
    Ok((out, iterations))
}

/// Marginals by `method` within a `budget` of hypotheses (EHM: net edges times key words, see
/// `ehm_within`; brute force: joint hypotheses); past the budget, by belief propagation ([`marginals_lbp`]). `None`: no budget.
pub fn marginals_within(
    cluster: &[TrackHypotheses],
    method: Method,
    budget: Option<usize>,
) -> Result<(Vec<Marginals>, Exactness)> {
    let b = budget.unwrap_or(usize::MAX);
    let exact = match method {
        Method::BruteForce => brute_force_within(cluster, b)?,
        Method::Ehm => ehm_within(cluster, b)?,
        Method::Lbp => None,
    };
    match exact {
        Some(m) => Ok((m, Exactness::Exact)),
        None => {
            let (m, iterations) = marginals_lbp(cluster)?;
            Ok((m, Exactness::Approximate { iterations }))
        }
    }
}

/// A rough size of the EHM net for tracks taken in `order`: at each cut, the detections
/// shared by tracks on both sides (the frontier, `f`) can be used in at most
/// `Σ_{k ≤ min(i, f)} C(f, k)` ways by the first `i` tracks, and in at most `Π (1 + gated)` ways.
/// Capped at 1e18 per cut.
pub fn ehm_size_estimate(tracks: &[TrackHypotheses], order: &[usize], n_detections: usize) -> f64 {
    const CAP: f64 = 1e18;
    let mut total = vec![0u32; n_detections];
    for &t in order {
        for &(d, _) in &tracks[t].detections {
            total[d] += 1;
        }
    }
    let mut seen = vec![0u32; n_detections];
    let (mut frontier, mut prod, mut sum) = (0usize, 1.0f64, 0.0f64);
    for (i, &t) in order.iter().enumerate() {
        for &(d, _) in &tracks[t].detections {
            seen[d] += 1;
            if seen[d] == 1 && total[d] > 1 {
                frontier += 1;
            }
            if seen[d] == total[d] && total[d] > 1 {
                frontier -= 1;
            }
        }
        prod = (prod * (1.0 + tracks[t].detections.len() as f64)).min(CAP);
        let (mut c, mut reach) = (1.0f64, 1.0f64);
        for k in 1..=frontier.min(i + 1) {
            c = c * (frontier + 1 - k) as f64 / k as f64;
            reach += c;
            if reach >= CAP {
                break;
            }
        }
        sum += reach.min(prod);
    }
    sum
}

/// Marginals of a cluster by the chosen method.
pub fn marginals(cluster: &[TrackHypotheses], method: Method) -> Result<Vec<Marginals>> {
    match method {
        Method::BruteForce => marginals_brute_force(cluster),
        Method::Ehm => marginals_ehm(cluster),
        Method::Lbp => marginals_lbp(cluster).map(|r| r.0),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn ehm_equals_brute_force_on_random_clusters() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        for _ in 0..300 {
            let n = rng.random_range(1..7);
            let nd = rng.random_range(0..7);
            let c: Vec<TrackHypotheses> = (0..n)
                .map(|_| TrackHypotheses {
                    missed: rng.random_range(0.01..1.0),
                    detections: (0..nd)
                        .filter(|_| rng.random_bool(0.5))
                        .collect::<Vec<_>>()
                        .into_iter()
                        .map(|d| (d, rng.random_range(0.0..5.0)))
                        .collect(),
                })
                .collect();
            let a = marginals_brute_force(&c).unwrap();
            let b = marginals_ehm(&c).unwrap();
            for (x, y) in a.iter().zip(&b) {
                assert!((x.missed - y.missed).abs() < 1e-12);
                let s: f64 = x.missed + x.detections.iter().sum::<f64>();
                assert!((s - 1.0).abs() < 1e-12);
                for (p, q) in x.detections.iter().zip(&y.detections) {
                    assert!((p - q).abs() < 1e-12);
                }
            }
        }
    }

    /// Random clusters: `n` tracks, `nd` detections, each pair gated with probability `pg`.
    pub(crate) fn random_cluster(
        rng: &mut impl Rng,
        n: usize,
        nd: usize,
        pg: f64,
    ) -> Vec<TrackHypotheses> {
        (0..n)
            .map(|_| TrackHypotheses {
                missed: rng.random_range(0.05..1.0),
                detections: (0..nd)
                    .filter(|_| rng.random_bool(pg))
                    .collect::<Vec<_>>()
                    .into_iter()
                    .map(|d| (d, rng.random_range(0.0..5.0)))
                    .collect(),
            })
            .collect()
    }

    #[test]
    fn lbp_is_close_to_ehm_and_exact_on_trees() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut worst = 0.0f64;
        for _ in 0..300 {
            let n = rng.random_range(2..12);
            let nd = rng.random_range(1..12);
            let c = random_cluster(&mut rng, n, nd, 0.4);
            let a = marginals_ehm(&c).unwrap();
            let (b, it) = marginals_lbp(&c).unwrap();
            assert!(it < LBP_MAX_ITERATIONS);
            for (x, y) in a.iter().zip(&b) {
                let s: f64 = y.missed + y.detections.iter().sum::<f64>();
                assert!((s - 1.0).abs() < 1e-12);
                worst = worst.max((x.missed - y.missed).abs());
                for (p, q) in x.detections.iter().zip(&y.detections) {
                    worst = worst.max((p - q).abs());
                }
            }
        }
        // Williams & Lau report errors of a few hundredths on dense clusters.
        assert!(worst < 0.1, "{worst}");
        // A chain (a tree): belief propagation is exact.
        let chain: Vec<TrackHypotheses> = (0..30)
            .map(|i| TrackHypotheses {
                missed: 0.3,
                detections: vec![(i, 1.0 + (i % 3) as f64), (i + 1, 0.5)],
            })
            .collect();
        let a = marginals_ehm(&chain).unwrap();
        let (b, _) = marginals_lbp(&chain).unwrap();
        for (x, y) in a.iter().zip(&b) {
            assert!((x.missed - y.missed).abs() < 1e-12);
            for (p, q) in x.detections.iter().zip(&y.detections) {
                assert!((p - q).abs() < 1e-12, "{p} {q}");
            }
        }
    }

    #[test]
    fn a_budget_switches_to_belief_propagation() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let c = random_cluster(&mut rng, 10, 10, 0.5);
        let (exact, how) = marginals_within(&c, Method::Ehm, None).unwrap();
        assert_eq!(how, Exactness::Exact);
        let (approx, how) = marginals_within(&c, Method::Ehm, Some(10)).unwrap();
        assert!(matches!(how, Exactness::Approximate { .. }));
        assert_eq!(approx, marginals_lbp(&c).unwrap().0);
        assert_ne!(approx, exact);
        let (_, how) = marginals_within(&c, Method::BruteForce, Some(10)).unwrap();
        assert!(matches!(how, Exactness::Approximate { .. }));
        let (bf, how) = marginals_within(&c[..4], Method::BruteForce, Some(1 << 20)).unwrap();
        assert_eq!(how, Exactness::Exact);
        let e = marginals_ehm(&c[..4]).unwrap();
        for (x, y) in bf.iter().zip(&e) {
            assert!((x.missed - y.missed).abs() < 1e-12);
        }
        // A cluster far too large for EHM (200 tracks all gating 200 detections) finishes.
        let big = random_cluster(&mut rng, 200, 200, 1.0);
        let (m, how) = marginals_within(&big, Method::Ehm, Some(100_000)).unwrap();
        assert!(matches!(how, Exactness::Approximate { .. }));
        assert_eq!(m.len(), 200);
    }

    #[test]
    fn size_estimate_follows_the_frontier() {
        let t = |d: &[usize]| TrackHypotheses {
            missed: 1.0,
            detections: d.iter().map(|&i| (i, 1.0)).collect(),
        };
        // A chain (track i gates detections i, i + 1): frontier 1 at every cut.
        let chain: Vec<_> = (0..50).map(|i| t(&[i, i + 1])).collect();
        let order: Vec<usize> = (0..50).collect();
        let e = ehm_size_estimate(&chain, &order, 51);
        assert!(e <= 2.0 * 50.0, "{e}");
        // One track gating 10 detections and 10 tracks gating one each: with the wide track
        // first the net has ~11 nodes per level; with it last, the first i tracks leave 2^i
        // distinct sets of used detections for it.
        let mut star = vec![t(&(0..10).collect::<Vec<_>>())];
        star.extend((0..10).map(|i| t(&[i])));
        let wide_first: Vec<usize> = (0..11).collect();
        let wide_last: Vec<usize> = (1..11).chain([0]).collect();
        let (a, b) = (
            ehm_size_estimate(&star, &wide_first, 10),
            ehm_size_estimate(&star, &wide_last, 10),
        );
        assert!(a < 400.0 && b > 1000.0, "{a} {b}");
    }

    #[test]
    fn clusters_follow_shared_detections() {
        let t = |d: &[usize]| TrackHypotheses {
            missed: 1.0,
            detections: d.iter().map(|&i| (i, 1.0)).collect(),
        };
        let c = clusters(&[t(&[0]), t(&[2]), t(&[0, 1]), t(&[]), t(&[1])], 3);
        assert_eq!(c, vec![vec![0, 2, 4], vec![1], vec![3]]);
    }
}
