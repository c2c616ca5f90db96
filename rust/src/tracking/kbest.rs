//! Approximate JPDA marginals from the `k` most likely joint hypotheses, enumerated by Murty's
//! ranking of assignments (K. G. Murty, "An algorithm for ranking all the assignments in order
//! of increasing cost", Operations Research 16(3), 1968), as in the k-best JPDA of Cox & Miller
//! (1995).
//!
//! A joint hypothesis is an assignment of the cluster's tracks (rows) to columns
//! `[detections | one missed column per track]` with cost `-ln w` (`+inf` where a track has no
//! such hypothesis); detections left over are clutter (weight 1). Murty's partition visits the
//! assignments in increasing cost without repeats, each child problem solved by the shortest
//! augmenting path solver of [`crate::tracking::assign`]. The marginals are the weights of the
//! visited assignments, summed per (track, hypothesis) and normalised. They only miss the mass
//! of the joint hypotheses not visited: when the enumeration ends before `k` (every joint
//! hypothesis was visited) they are exact.

use super::assign::linear_sum_assignment;
use super::jpda::{Marginals, TrackHypotheses};
use crate::error::{Error, Result};
use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

/// The k-best marginals of one cluster.
#[derive(Debug, Clone, PartialEq)]
pub struct KBest {
    /// Per track, as [`crate::tracking::jpda::marginals`] gives them.
    pub marginals: Vec<Marginals>,
    /// Joint hypotheses summed (`<= k`).
    pub assignments: usize,
    /// Every joint hypothesis of non-zero weight was summed (fewer than `k` exist): the
    /// marginals are exact.
    pub exhaustive: bool,
}

/// A Murty subproblem: its best assignment, and the constraints that define it — the rows
/// below `fixed` keep their columns of `solution`, and the `(row, column)` pairs of `banned`
/// are forbidden.
struct Node {
    cost: f64,
    solution: Vec<usize>,
    fixed: usize,
    banned: Vec<(usize, usize)>,
}

impl PartialEq for Node {
    fn eq(&self, other: &Self) -> bool {
        self.cost.total_cmp(&other.cost) == Ordering::Equal
    }
}
impl Eq for Node {}
impl PartialOrd for Node {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Node {
    /// Reversed, so that `BinaryHeap` pops the cheapest node first.
    fn cmp(&self, other: &Self) -> Ordering {
        other.cost.total_cmp(&self.cost)
    }
}

/// The optimal assignment of `cost` (`nr × nc`), or `None` when none of finite cost exists.
fn solve(cost: &[f64], nr: usize, nc: usize) -> Option<(f64, Vec<usize>)> {
    let sol = linear_sum_assignment(cost, nr, nc).ok()?;
    let total: f64 = sol.iter().enumerate().map(|(i, &j)| cost[i * nc + j]).sum();
    total.is_finite().then_some((total, sol))
}

/// Keep `row` on column `col` only: forbid its other columns and `col` for every other row.
fn force(cost: &mut [f64], nr: usize, nc: usize, row: usize, col: usize) {
    for j in (0..nc).filter(|&j| j != col) {
        cost[row * nc + j] = f64::INFINITY;
    }
    for i in (0..nr).filter(|&i| i != row) {
        cost[i * nc + col] = f64::INFINITY;
    }
}

/// Visits the finite-cost assignments of `base` (`nr × nc`, `nr <= nc`, `+inf` forbidden) in
/// increasing cost, at most `k` of them, calling `visit(cost, col_of_row)`. Returns whether
/// the enumeration ran out before `k`, i.e. every assignment was visited.
pub fn ranked_assignments(
    base: &[f64],
    nr: usize,
    nc: usize,
    k: usize,
    mut visit: impl FnMut(f64, &[usize]),
) -> bool {
    let mut heap = BinaryHeap::new();
    if let Some((cost, solution)) = solve(base, nr, nc) {
        heap.push(Node {
            cost,
            solution,
            fixed: 0,
            banned: Vec::new(),
        });
    }
    let mut visited = 0;
    let mut work = vec![0.0; nr * nc];
    while visited < k {
        let Some(node) = heap.pop() else { break };
        visited += 1;
        visit(node.cost, &node.solution);
        if visited == k {
            break;
        }
        // Children: for each free row t, row t leaves its column and rows before it keep theirs.
        work.copy_from_slice(base);
        for &(r, c) in &node.banned {
            work[r * nc + c] = f64::INFINITY;
        }
        for r in 0..node.fixed {
            force(&mut work, nr, nc, r, node.solution[r]);
        }
        for t in node.fixed..nr {
            let col = node.solution[t];
            let kept = work[t * nc + col];
            work[t * nc + col] = f64::INFINITY;
            if let Some((_, solution)) = solve(&work, nr, nc) {
                let cost = solution
                    .iter()
                    .enumerate()
                    .map(|(i, &j)| base[i * nc + j])
                    .sum();
                let mut banned = node.banned.clone();
                banned.push((t, col));
                heap.push(Node {
                    cost,
                    solution,
                    fixed: t,
                    banned,
                });
            }
            work[t * nc + col] = kept;
            force(&mut work, nr, nc, t, col);
        }
    }
    visited < k
}

/// The assignment problem of a cluster: costs `-ln w` of `[detections | missed per track]`
/// (row-major, `nr × (nd + nr)`) and, per cell, the position of that hypothesis in the
/// track's marginals (0 = missed; `usize::MAX` where forbidden).
fn problem(cluster: &[TrackHypotheses]) -> (Vec<f64>, Vec<usize>, usize) {
    let mut local: HashMap<usize, usize> = HashMap::new();
    for h in cluster {
        for &(d, _) in &h.detections {
            let l = local.len();
            local.entry(d).or_insert(l);
        }
    }
    let nr = cluster.len();
    let nc = local.len() + nr;
    let neg_ln = |w: f64| if w > 0.0 { -w.ln() } else { f64::INFINITY };
    let mut cost = vec![f64::INFINITY; nr * nc];
    let mut entry = vec![usize::MAX; nr * nc];
    for (i, h) in cluster.iter().enumerate() {
        let missed = i * nc + local.len() + i;
        cost[missed] = neg_ln(h.missed);
        entry[missed] = 0;
        for (e, &(d, w)) in h.detections.iter().enumerate() {
            cost[i * nc + local[&d]] = neg_ln(w);
            entry[i * nc + local[&d]] = e + 1;
        }
    }
    (cost, entry, nc)
}

/// Marginals of a cluster from its `k >= 1` most likely joint hypotheses (see the module
/// documentation). Weights must be finite and `>= 0`; fails when no joint hypothesis has a
/// non-zero weight. Each marginal is within the unvisited share of the total weight of the
/// exact one.
pub fn marginals_kbest(cluster: &[TrackHypotheses], k: usize) -> Result<KBest> {
    if k == 0 {
        return Err(Error::param("k_best", "must be >= 1"));
    }
    let ok = |w: f64| w.is_finite() && w >= 0.0;
    for (t, h) in cluster.iter().enumerate() {
        if !ok(h.missed) || h.detections.iter().any(|&(_, w)| !ok(w)) {
            return Err(Error::param(
                "likelihoods",
                format!("weights of track {t} must be finite and >= 0"),
            ));
        }
    }
    let (cost, entry, nc) = problem(cluster);
    let nr = cluster.len();
    let mut sums: Vec<Vec<f64>> = cluster
        .iter()
        .map(|h| vec![0.0; 1 + h.detections.len()])
        .collect();
    let mut best = None;
    let mut assignments = 0;
    let exhaustive = ranked_assignments(&cost, nr, nc, k, |c, sol| {
        // Weights relative to the best assignment's, so that none underflows.
        let w = (*best.get_or_insert(c) - c).exp();
        for (i, &j) in sol.iter().enumerate() {
            sums[i][entry[i * nc + j]] += w;
        }
        assignments += 1;
    });
    if assignments == 0 {
        return Err(Error::param(
            "likelihoods",
            "every joint hypothesis has zero weight (no track can be missed or detected)",
        ));
    }
    let marginals = sums
        .into_iter()
        .map(|s| {
            let tot: f64 = s.iter().sum();
            Marginals {
                missed: s[0] / tot,
                detections: s[1..].iter().map(|p| p / tot).collect(),
            }
        })
        .collect();
    Ok(KBest {
        marginals,
        assignments,
        exhaustive,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracking::jpda::marginals_ehm;
    use rand::{Rng, SeedableRng};

    /// Up to 6 tracks and 6 detections, each pair gated with probability ½.
    fn random_cluster(rng: &mut rand::rngs::StdRng) -> Vec<TrackHypotheses> {
        let (n, nd) = (rng.random_range(1..7), rng.random_range(0..7));
        crate::tracking::jpda::tests::random_cluster(rng, n, nd, 0.5)
    }

    #[test]
    fn exhaustive_enumeration_equals_ehm() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        for _ in 0..300 {
            let c = random_cluster(&mut rng);
            let r = marginals_kbest(&c, usize::MAX).unwrap();
            assert!(r.exhaustive);
            for (a, b) in r.marginals.iter().zip(marginals_ehm(&c).unwrap()) {
                assert!((a.missed - b.missed).abs() < 1e-12);
                for (x, y) in a.detections.iter().zip(&b.detections) {
                    assert!((x - y).abs() < 1e-12, "{x} vs {y}");
                }
            }
        }
    }

    /// Every joint hypothesis's cost, by enumeration.
    fn all_costs(c: &[TrackHypotheses]) -> Vec<f64> {
        let (cost, _, nc) = problem(c);
        let mut out = Vec::new();
        fn rec(
            cost: &[f64],
            nr: usize,
            nc: usize,
            i: usize,
            used: &mut [bool],
            acc: f64,
            out: &mut Vec<f64>,
        ) {
            if i == nr {
                if acc.is_finite() {
                    out.push(acc);
                }
                return;
            }
            for j in 0..nc {
                if !used[j] && cost[i * nc + j].is_finite() {
                    used[j] = true;
                    rec(cost, nr, nc, i + 1, used, acc + cost[i * nc + j], out);
                    used[j] = false;
                }
            }
        }
        rec(&cost, c.len(), nc, 0, &mut vec![false; nc], 0.0, &mut out);
        out.sort_by(f64::total_cmp);
        out
    }

    #[test]
    fn assignments_come_in_order_without_repeats() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        for _ in 0..200 {
            let c = random_cluster(&mut rng);
            let (cost, _, nc) = problem(&c);
            let mut seen = Vec::new();
            let mut costs = Vec::new();
            let done = ranked_assignments(&cost, c.len(), nc, usize::MAX, |k, sol| {
                costs.push(k);
                seen.push(sol.to_vec());
            });
            assert!(done);
            let all = all_costs(&c);
            assert_eq!(costs.len(), all.len());
            for (a, b) in costs.iter().zip(&all) {
                assert!((a - b).abs() < 1e-9, "{a} vs {b}");
            }
            seen.sort();
            seen.dedup();
            assert_eq!(seen.len(), all.len());
        }
    }

    #[test]
    fn error_is_within_the_unvisited_mass() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        for _ in 0..200 {
            let c = random_cluster(&mut rng);
            let exact = marginals_ehm(&c).unwrap();
            let all = all_costs(&c);
            let total: f64 = all.iter().map(|x| (all[0] - x).exp()).sum();
            for k in [1, 2, 3, 5, 8] {
                let r = marginals_kbest(&c, k).unwrap();
                let seen: f64 = all.iter().take(k).map(|x| (all[0] - x).exp()).sum();
                let bound = 1.0 - seen / total + 1e-12;
                for (a, b) in r.marginals.iter().zip(&exact) {
                    assert!((a.missed - b.missed).abs() <= bound);
                    for (x, y) in a.detections.iter().zip(&b.detections) {
                        assert!((x - y).abs() <= bound, "k {k}: |{x} - {y}| > {bound}");
                    }
                }
                assert_eq!(r.exhaustive, k > all.len());
            }
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let c = vec![TrackHypotheses {
            missed: f64::NAN,
            detections: vec![],
        }];
        assert!(marginals_kbest(&c, 10).is_err());
        let ok = vec![TrackHypotheses {
            missed: 1.0,
            detections: vec![(0, 2.0)],
        }];
        assert!(marginals_kbest(&ok, 0).is_err());
        let zero = vec![TrackHypotheses {
            missed: 0.0,
            detections: vec![],
        }];
        assert!(marginals_kbest(&zero, 3).is_err());
    }
}
