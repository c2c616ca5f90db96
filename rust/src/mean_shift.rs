//! Flat-kernel mean shift, step for step as scikit-learn's `sklearn.cluster.MeanShift`
//! (version 1.x `_mean_shift.py`), with grid neighbourhood queries instead of a KD-tree.
//!
//! Points are `n` rows of `dim` coordinates (any unit; the LiDAR pipeline uses metres in the
//! NED world frame). What is reproduced from scikit-learn:
//! - seeds: the points themselves, given seeds, or bin seeding (`round(x / bandwidth)` with
//!   ties to even, bins kept when holding `>= min_bin_freq` points, in first-seen order,
//!   scaled back in `f32` as scikit-learn does; when every point has its own bin the points
//!   are used and [`MeanShiftResult::bin_seeding_fell_back`] is set);
//! - hill climbing: the mean of the points within `bandwidth` (inclusive, squared distance
//!   `<= bandwidth²`), until the shift is `<= 1e-3 · bandwidth` or `max_iter` iterations;
//!   seeds with no point within `bandwidth` are dropped; the intensity of a centre is the
//!   number of points in its last window;
//! - equal centres merge (the last seed's intensity wins), centres are sorted by
//!   (intensity, coordinates) descending, and a centre within `bandwidth` of a kept centre
//!   earlier in that order is dropped;
//! - labels: the nearest kept centre (lowest index on ties); with `cluster_all == false`
//!   points farther than `bandwidth` from every centre get `-1`.
//!
//! Window sums are taken in point-index order (scikit-learn sums in KD-tree order), so centres can
//! differ from scikit-learn's in the last bits; and a point at exactly the same distance from
//! two centres gets the lower index here, while scikit-learn breaks such exact ties in its
//! KD-tree traversal order (only exactly representable inputs, e.g. grids, hit this).
//! Trajectories are memoised on (mean, iteration): seeds that meet on the same mean after
//! the same number of steps share the rest of the climb, which is exact.

use crate::error::{check_finite, Error, Result};
use std::cmp::Ordering;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Parameters of [`mean_shift`] (scikit-learn's names and defaults).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanShiftParams {
    /// Flat kernel radius, same unit as the points; finite and > 0.
    pub bandwidth: f64,
    /// Seed from a grid of bins of size `bandwidth` instead of every point.
    pub bin_seeding: bool,
    /// Minimum number of points in a bin for it to become a seed (>= 1).
    pub min_bin_freq: usize,
    /// Give orphans (farther than `bandwidth` from every centre) the nearest label anyway.
    pub cluster_all: bool,
    /// Maximum number of iterations per seed.
    pub max_iter: usize,
}

impl Default for MeanShiftParams {
    fn default() -> Self {
        MeanShiftParams {
            bandwidth: 2.0,
            bin_seeding: false,
            min_bin_freq: 1,
            cluster_all: true,
            max_iter: 300,
        }
    }
}

/// Result of [`mean_shift`].
#[derive(Debug, Clone, PartialEq)]
pub struct MeanShiftResult {
    /// Cluster centres, `k` rows of `dim` values, row-major, in scikit-learn's order.
    pub centers: Vec<f64>,
    /// Label of each point: the index of its centre, or -1 for an orphan.
    pub labels: Vec<i64>,
    /// Largest number of completed iterations of any seed (scikit-learn's `n_iter_`).
    pub n_iter: usize,
    /// Bin seeding produced one bin per point, so the points were used as seeds
    /// (scikit-learn warns in this case).
    pub bin_seeding_fell_back: bool,
}

/// Mean shift clustering of `points` (`n × dim`, row-major) from `seeds` (`k × dim`,
/// row-major) or from the points / bins (see the module docs).
///
/// An empty `points` gives no centres and no labels. Fails on shapes that do not divide by
/// `dim`, non-finite values, a bandwidth that is not finite and positive, `min_bin_freq == 0`,
/// or when no seed has any point within `bandwidth` (scikit-learn raises then too).
pub fn mean_shift(
    points: &[f64],
    dim: usize,
    seeds: Option<&[f64]>,
    params: &MeanShiftParams,
) -> Result<MeanShiftResult> {
    check_params(points, dim, seeds, params)?;
    let n = points.len() / dim;
    let empty = MeanShiftResult {
        centers: Vec::new(),
        labels: Vec::new(),
        n_iter: 0,
        bin_seeding_fell_back: false,
    };
    if n == 0 {
        return Ok(empty);
    }
    let bw = params.bandwidth;
    let (seed_values, fell_back) = match seeds {
        Some(s) => (s.to_vec(), false),
        None if params.bin_seeding => bin_seeds(points, dim, bw, params.min_bin_freq),
        None => (points.to_vec(), false),
    };
    let grid = Grid::new(points, dim, bw);
    let mut climber = Climber::new(points, dim, &grid, bw, params.max_iter);
    // Final centre -> intensity, keeping first-insertion keys (a Python dict of tuples).
    let mut index: FastMap<Vec<u64>, usize> = HashMap::default();
    let mut found: Vec<(Vec<f64>, usize)> = Vec::new();
    let mut outcome_slot: FastMap<u32, usize> = HashMap::default();
    let mut n_iter = 0;
    for seed in seed_values.chunks_exact(dim) {
        let o = climber.climb(seed);
        n_iter = n_iter.max(climber.outcome_iters[o as usize]);
        let intensity = climber.outcome_sizes[o as usize];
        if intensity == 0 {
            continue;
        }
        if let Some(&slot) = outcome_slot.get(&o) {
            found[slot].1 = intensity;
            continue;
        }
        let center = climber.outcome_mean(o);
        let slot = *index.entry(key_bits(center)).or_insert_with(|| {
            found.push((center.to_vec(), intensity));
            found.len() - 1
        });
        found[slot].1 = intensity;
        outcome_slot.insert(o, slot);
    }
    if found.is_empty() {
        return Err(Error::param(
            "seeds",
            format!(
                "no point was within bandwidth={bw} of any seed; try a different seeding \
                 strategy or a larger bandwidth"
            ),
        ));
    }
    // Sort by (intensity, coordinates) descending, as sorted(..., reverse=True) does.
    found.sort_by(|a, b| {
        b.1.cmp(&a.1).then_with(|| {
            for (x, y) in b.0.iter().zip(&a.0) {
                match x.partial_cmp(y) {
                    Some(Ordering::Equal) | None => {}
                    Some(o) => return o,
                }
            }
            Ordering::Equal
        })
    });
    let sorted: Vec<f64> = found.iter().flat_map(|c| c.0.iter().copied()).collect();
    let kept = suppress_duplicates(&sorted, dim, bw);
    let centers: Vec<f64> = kept
        .iter()
        .flat_map(|&i| sorted[i * dim..(i + 1) * dim].iter().copied())
        .collect();
    let labels = assign_labels(points, dim, &centers, bw, params.cluster_all);
    Ok(MeanShiftResult {
        centers,
        labels,
        n_iter,
        bin_seeding_fell_back: fell_back,
    })
}

fn check_params(
    points: &[f64],
    dim: usize,
    seeds: Option<&[f64]>,
    params: &MeanShiftParams,
) -> Result<()> {
    if dim == 0 {
        return Err(Error::dim("points", "at least one column", "0 columns"));
    }
    if points.len() % dim != 0 {
        return Err(Error::dim(
            "points",
            format!("rows of {dim} values"),
            format!("{} values", points.len()),
        ));
    }
    check_finite("points", points)?;
    if let Some(s) = seeds {
        if s.len() % dim != 0 {
            return Err(Error::dim(
                "seeds",
                format!("rows of {dim} values (the points' dimension)"),
                format!("{} values", s.len()),
            ));
        }
        check_finite("seeds", s)?;
    }
    if !(params.bandwidth.is_finite() && params.bandwidth > 0.0) {
        return Err(Error::param(
            "bandwidth",
            format!("must be finite and positive, got {}", params.bandwidth),
        ));
    }
    if params.min_bin_freq == 0 {
        return Err(Error::param("min_bin_freq", "must be at least 1, got 0"));
    }
    Ok(())
}

/// scikit-learn's `get_bin_seeds`: returns the seeds and whether it fell back to the points.
fn bin_seeds(points: &[f64], dim: usize, bin_size: f64, min_bin_freq: usize) -> (Vec<f64>, bool) {
    let mut order: Vec<Vec<f64>> = Vec::new();
    let mut counts: FastMap<Vec<u64>, usize> = HashMap::default();
    let mut freq: Vec<usize> = Vec::new();
    for p in points.chunks_exact(dim) {
        let binned: Vec<f64> = p.iter().map(|v| (v / bin_size).round_ties_even()).collect();
        let slot = *counts.entry(key_bits(&binned)).or_insert_with(|| {
            order.push(binned.clone());
            freq.push(0);
            freq.len() - 1
        });
        freq[slot] += 1;
    }
    let kept: Vec<&Vec<f64>> = order
        .iter()
        .zip(&freq)
        .filter(|(_, &f)| f >= min_bin_freq)
        .map(|(b, _)| b)
        .collect();
    if kept.len() == points.len() / dim {
        return (points.to_vec(), true);
    }
    // np.array(..., dtype=float32) * bin_size: a float32 product.
    let size32 = bin_size as f32;
    let seeds = kept
        .iter()
        .flat_map(|b| b.iter().map(move |&v| f64::from((v as f32) * size32)))
        .collect();
    (seeds, false)
}

/// Hash key of a coordinate tuple with Python's float equality (-0.0 == 0.0).
fn key_bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|&x| (x + 0.0).to_bits()).collect()
}

// ---------------------------------------------------------------------------------------
// Neighbourhood queries: a hash grid of cells of size `bandwidth` (dims <= 3), else a scan.

/// FxHash-style multiplicative hasher: grid keys are small integer tuples.
#[derive(Default)]
struct FxHasher(u64);

impl Hasher for FxHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut buf = [0u8; 8];
            buf[..chunk.len()].copy_from_slice(chunk);
            self.write_u64(u64::from_le_bytes(buf));
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

type FastMap<K, V> = HashMap<K, V, BuildHasherDefault<FxHasher>>;

struct Grid {
    dim: usize,
    inv_cell: f64,
    /// Cell -> range in `members`; `None` means "scan everything" (dim > 3).
    cells: Option<FastMap<[i64; 3], (u32, u32)>>,
    members: Vec<u32>,
}

impl Grid {
    /// Grid whose 3^dim block around a query holds every point within `radius` of it (cells
    /// are slightly larger than `radius` so that rounding cannot break this).
    fn new(points: &[f64], dim: usize, radius: f64) -> Self {
        let n = points.len() / dim;
        let inv_cell = 1.0 / (radius * (1.0 + 1e-9));
        if dim > 3 {
            return Grid {
                dim,
                inv_cell,
                cells: None,
                members: (0..n as u32).collect(),
            };
        }
        let mut keyed: Vec<([i64; 3], u32)> = points
            .chunks_exact(dim)
            .enumerate()
            .map(|(i, p)| (cell_of(p, inv_cell), i as u32))
            .collect();
        keyed.sort_unstable();
        let mut cells: FastMap<[i64; 3], (u32, u32)> = HashMap::default();
        let mut start = 0;
        for i in 1..=keyed.len() {
            if i == keyed.len() || keyed[i].0 != keyed[start].0 {
                cells.insert(keyed[start].0, (start as u32, i as u32));
                start = i;
            }
        }
        Grid {
            dim,
            inv_cell,
            cells: Some(cells),
            members: keyed.into_iter().map(|k| k.1).collect(),
        }
    }

    /// Calls `f(i)` for every point index in the cells around `q` (a superset of the ball
    /// of radius `cell` around `q`).
    fn for_candidates(&self, q: &[f64], mut f: impl FnMut(u32)) {
        let Some(cells) = &self.cells else {
            self.members.iter().for_each(|&i| f(i));
            return;
        };
        let c = cell_of(q, self.inv_cell);
        let span = |axis: usize| if axis < self.dim { -1..=1 } else { 0..=0 };
        for dx in span(0) {
            for dy in span(1) {
                for dz in span(2) {
                    let key = [c[0] + dx, c[1] + dy, c[2] + dz];
                    if let Some(&(a, b)) = cells.get(&key) {
                        self.members[a as usize..b as usize]
                            .iter()
                            .for_each(|&i| f(i));
                    }
                }
            }
        }
    }
}

fn cell_of(p: &[f64], inv_cell: f64) -> [i64; 3] {
    let mut c = [0i64; 3];
    for (k, v) in p.iter().enumerate() {
        // Saturating float -> int cast; far-away coordinates still land in a valid cell.
        c[k] = (v * inv_cell).floor() as i64;
    }
    c
}

#[inline]
fn dist2(a: &[f64], b: &[f64]) -> f64 {
    let mut s = 0.0;
    for (x, y) in a.iter().zip(b) {
        let t = x - y;
        s += t * t;
    }
    s
}

/// Hill climbing of seeds with a memo of visited states (mean, completed iterations):
/// the rest of a climb depends only on that state, so meeting a known state reuses its
/// outcome. States and outcomes live in flat arenas (no allocation per step).
struct Climber<'a> {
    points: &'a [f64],
    dim: usize,
    grid: &'a Grid,
    bw2: f64,
    stop: f64,
    max_iter: usize,
    /// (hash of mean bits, completed) -> first state with that key (chained via `next`).
    memo: FastMap<(u64, usize), u32>,
    state_means: Vec<f64>,
    state_next: Vec<u32>,
    state_outcome: Vec<u32>,
    /// Outcomes: final mean (`dim` values each), window size, completed iterations.
    outcome_means: Vec<f64>,
    outcome_sizes: Vec<usize>,
    outcome_iters: Vec<usize>,
    window: Vec<u32>,
    visited: Vec<u32>,
    mean: Vec<f64>,
    sum: Vec<f64>,
}

const NONE: u32 = u32::MAX;

impl<'a> Climber<'a> {
    fn new(points: &'a [f64], dim: usize, grid: &'a Grid, bw: f64, max_iter: usize) -> Self {
        Climber {
            points,
            dim,
            grid,
            bw2: bw * bw,
            stop: 1e-3 * bw,
            max_iter,
            memo: HashMap::default(),
            state_means: Vec::new(),
            state_next: Vec::new(),
            state_outcome: Vec::new(),
            outcome_means: Vec::new(),
            outcome_sizes: Vec::new(),
            outcome_iters: Vec::new(),
            window: Vec::new(),
            visited: Vec::new(),
            mean: vec![0.0; dim],
            sum: vec![0.0; dim],
        }
    }

    fn outcome_mean(&self, o: u32) -> &[f64] {
        &self.outcome_means[o as usize * self.dim..(o as usize + 1) * self.dim]
    }

    /// Known state equal (bit for bit) to the current mean after `completed` steps, or
    /// registers it; returns (state, was it known).
    fn state(&mut self, completed: usize) -> (u32, bool) {
        let mut h = FxHasher::default();
        self.mean.iter().for_each(|v| h.write_u64(v.to_bits()));
        let key = (h.finish(), completed);
        let dim = self.dim;
        let head = self.memo.get(&key).copied().unwrap_or(NONE);
        let mut s = head;
        while s != NONE {
            let m = &self.state_means[s as usize * dim..(s as usize + 1) * dim];
            if m.iter()
                .zip(&self.mean)
                .all(|(a, b)| a.to_bits() == b.to_bits())
            {
                return (s, true);
            }
            s = self.state_next[s as usize];
        }
        let new = self.state_next.len() as u32;
        self.state_means.extend_from_slice(&self.mean);
        self.state_next.push(head);
        self.state_outcome.push(NONE);
        self.memo.insert(key, new);
        (new, false)
    }

    /// scikit-learn's `_mean_shift_single_seed`; returns the outcome index.
    fn climb(&mut self, seed: &[f64]) -> u32 {
        let dim = self.dim;
        self.mean.copy_from_slice(seed);
        self.visited.clear();
        let mut completed = 0usize;
        let outcome = loop {
            let (state, known) = self.state(completed);
            if known {
                break self.state_outcome[state as usize];
            }
            self.visited.push(state);
            self.window.clear();
            let (pts, bw2, mean, window) = (self.points, self.bw2, &self.mean, &mut self.window);
            self.grid.for_candidates(mean, |i| {
                let p = &pts[i as usize * dim..(i as usize + 1) * dim];
                if dist2(p, mean) <= bw2 {
                    window.push(i);
                }
            });
            if self.window.is_empty() {
                break self.push_outcome(0, completed);
            }
            self.window.sort_unstable(); // sum in point-index order
            self.sum.iter_mut().for_each(|v| *v = 0.0);
            for &i in &self.window {
                let p = &pts[i as usize * dim..(i as usize + 1) * dim];
                for (s, v) in self.sum.iter_mut().zip(p) {
                    *s += v;
                }
            }
            let count = self.window.len();
            // np.mean: the sum divided by the count; then the shift from the old mean.
            let mut shift2 = 0.0;
            for (m, s) in self.mean.iter_mut().zip(&self.sum) {
                let new = s / count as f64;
                let t = new - *m;
                shift2 += t * t;
                *m = new;
            }
            if shift2.sqrt() <= self.stop || completed == self.max_iter {
                break self.push_outcome(count, completed);
            }
            completed += 1;
        };
        for &s in &self.visited {
            self.state_outcome[s as usize] = outcome;
        }
        outcome
    }

    fn push_outcome(&mut self, size: usize, completed: usize) -> u32 {
        self.outcome_means.extend_from_slice(&self.mean);
        self.outcome_sizes.push(size);
        self.outcome_iters.push(completed);
        (self.outcome_sizes.len() - 1) as u32
    }
}

/// Greedy duplicate suppression over centres sorted by decreasing intensity: indices kept.
fn suppress_duplicates(sorted: &[f64], dim: usize, bw: f64) -> Vec<usize> {
    let k = sorted.len() / dim;
    let grid = Grid::new(sorted, dim, bw);
    let bw2 = bw * bw;
    let mut unique = vec![true; k];
    for i in 0..k {
        if !unique[i] {
            continue;
        }
        let c = &sorted[i * dim..(i + 1) * dim];
        grid.for_candidates(c, |j| {
            let j = j as usize;
            if dist2(&sorted[j * dim..(j + 1) * dim], c) <= bw2 {
                unique[j] = false;
            }
        });
        unique[i] = true;
    }
    (0..k).filter(|&i| unique[i]).collect()
}

/// Nearest centre of each point (lowest index on ties); -1 beyond `bw` unless `cluster_all`.
fn assign_labels(
    points: &[f64],
    dim: usize,
    centers: &[f64],
    bw: f64,
    cluster_all: bool,
) -> Vec<i64> {
    let grid = Grid::new(centers, dim, bw);
    let k = centers.len() / dim;
    let center = |j: usize| &centers[j * dim..(j + 1) * dim];
    points
        .chunks_exact(dim)
        .map(|p| {
            let mut best = (f64::INFINITY, usize::MAX);
            grid.for_candidates(p, |j| {
                let d = dist2(center(j as usize), p);
                if d < best.0 || (d == best.0 && (j as usize) < best.1) {
                    best = (d, j as usize);
                }
            });
            // Centres outside the neighbouring cells are farther than `bw`.
            if cluster_all && best.0.sqrt() > bw {
                for j in 0..k {
                    let d = dist2(center(j), p);
                    if d < best.0 || (d == best.0 && j < best.1) {
                        best = (d, j);
                    }
                }
            }
            if cluster_all || best.0.sqrt() <= bw {
                best.1 as i64
            } else {
                -1
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    #[test]
    fn sklearn_docstring_example() {
        // sklearn.cluster.mean_shift docstring: centres [[3.33, 6], [1.33, 0.66]], labels
        // [1, 1, 1, 0, 0, 0].
        let x = [1.0, 1.0, 2.0, 1.0, 1.0, 0.0, 4.0, 7.0, 3.0, 5.0, 3.0, 6.0];
        let params = MeanShiftParams {
            bandwidth: 2.0,
            ..Default::default()
        };
        let r = mean_shift(&x, 2, None, &params).unwrap();
        assert_eq!(r.labels, vec![1, 1, 1, 0, 0, 0]);
        let expect = [10.0 / 3.0, 6.0, 4.0 / 3.0, 2.0 / 3.0];
        for (a, b) in r.centers.iter().zip(expect) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn orphans_get_minus_one_without_cluster_all() {
        let mut x = vec![];
        for i in 0..10 {
            x.extend([0.1 * i as f64, 0.0]);
        }
        x.extend([50.0, 50.0]);
        let params = MeanShiftParams {
            bandwidth: 2.0,
            cluster_all: false,
            bin_seeding: true,
            min_bin_freq: 3,
            ..Default::default()
        };
        let r = mean_shift(&x, 2, None, &params).unwrap();
        assert_eq!(r.centers.len(), 2);
        assert_eq!(r.labels[10], -1);
        assert!(r.labels[..10].iter().all(|&l| l == 0));
    }

    #[test]
    fn grid_equals_scan_in_high_dimension_path() {
        // 3-D through the grid vs the same points padded to 4-D (scan path).
        let mut rng = StdRng::seed_from_u64(1);
        let x3: Vec<f64> = (0..600).map(|_| rng.random_range(-6.0..6.0)).collect();
        let x4: Vec<f64> = x3.chunks(3).flat_map(|c| [c[0], c[1], c[2], 0.0]).collect();
        let params = MeanShiftParams {
            bandwidth: 1.5,
            cluster_all: false,
            ..Default::default()
        };
        let a = mean_shift(&x3, 3, None, &params).unwrap();
        let b = mean_shift(&x4, 4, None, &params).unwrap();
        assert_eq!(a.labels, b.labels);
        let b3: Vec<f64> = b.centers.chunks(4).flat_map(|c| c[..3].to_vec()).collect();
        assert_eq!(a.centers, b3);
    }

    #[test]
    fn bad_input_names_the_argument() {
        let p = MeanShiftParams::default();
        let bad = |r: Result<MeanShiftResult>| r.unwrap_err().to_string();
        assert!(bad(mean_shift(&[1.0, 2.0, 3.0], 2, None, &p)).starts_with("points"));
        assert!(bad(mean_shift(&[1.0, f64::NAN], 2, None, &p)).starts_with("points"));
        assert!(bad(mean_shift(&[1.0, 2.0], 2, Some(&[1.0]), &p)).starts_with("seeds"));
        let q = MeanShiftParams {
            bandwidth: 0.0,
            ..p
        };
        assert!(bad(mean_shift(&[1.0, 2.0], 2, None, &q)).starts_with("bandwidth"));
        let q = MeanShiftParams {
            min_bin_freq: 0,
            ..p
        };
        assert!(bad(mean_shift(&[1.0, 2.0], 2, None, &q)).starts_with("min_bin_freq"));
        // No point near any seed.
        assert!(bad(mean_shift(&[1.0, 2.0], 2, Some(&[50.0, 50.0]), &p)).starts_with("seeds"));
    }
}
