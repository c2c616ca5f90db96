//! Optimal 2-D assignment (linear sum assignment) by shortest augmenting paths
//! (Jonker–Volgenant / Crouse), and the global-nearest-neighbour association of Stone Soup's
//! `GNNWith2DAssignment` + `DistanceHypothesiser` built on it.

use crate::error::{Error, Result};

/// Solves `min Σ cost[i, col(i)]` over injective row → column maps of an `nr × nc` row-major
/// cost matrix with `nr ≤ nc`. `+inf` marks a forbidden pair; NaN is not allowed.
///
/// Returns `col_of_row` (length `nr`). Fails with [`Error::InvalidParameter`] when no
/// assignment of finite cost exists, and with [`Error::Dimension`] when `nr > nc`.
pub fn linear_sum_assignment(cost: &[f64], nr: usize, nc: usize) -> Result<Vec<usize>> {
    if cost.len() != nr * nc {
        return Err(Error::dim(
            "cost",
            format!("{nr} x {nc} values"),
            cost.len(),
        ));
    }
    if nr > nc {
        return Err(Error::dim(
            "cost",
            "no more rows than columns",
            format!("{nr} x {nc}"),
        ));
    }
    if cost.iter().any(|c| c.is_nan() || *c == f64::NEG_INFINITY) {
        return Err(Error::param("cost", "contains NaN or -inf"));
    }
    const NONE: usize = usize::MAX;
    let mut u = vec![0.0f64; nr];
    let mut v = vec![0.0f64; nc];
    let mut col4row = vec![NONE; nr];
    let mut row4col = vec![NONE; nc];
    let mut shortest = vec![f64::INFINITY; nc];
    let mut path = vec![NONE; nc];
    let mut in_sr = vec![false; nr];
    let mut in_sc = vec![false; nc];
    let mut remaining: Vec<usize> = Vec::with_capacity(nc);
    for cur_row in 0..nr {
        shortest.iter_mut().for_each(|s| *s = f64::INFINITY);
        path.iter_mut().for_each(|p| *p = NONE);
        in_sr.iter_mut().for_each(|s| *s = false);
        in_sc.iter_mut().for_each(|s| *s = false);
        remaining.clear();
        remaining.extend((0..nc).rev());
        let mut n_rem = nc;
        let mut min_val = 0.0f64;
        let mut i = cur_row;
        let sink;
        loop {
            in_sr[i] = true;
            let mut lowest = f64::INFINITY;
            let mut index = NONE;
            for (it, &j) in remaining[..n_rem].iter().enumerate() {
                // Reduced cost of extending the path through (i, j).
                let r = min_val + cost[i * nc + j] - u[i] - v[j];
                if r < shortest[j] {
                    path[j] = i;
                    shortest[j] = r;
                }
                if shortest[j] < lowest || (shortest[j] == lowest && row4col[j] == NONE) {
                    lowest = shortest[j];
                    index = it;
                }
            }
            min_val = lowest;
            if index == NONE || !min_val.is_finite() {
                return Err(Error::param("cost", "no feasible assignment exists"));
            }
            let j = remaining[index];
            in_sc[j] = true;
            n_rem -= 1;
            remaining[index] = remaining[n_rem];
            if row4col[j] == NONE {
                sink = j;
                break;
            }
            i = row4col[j];
        }
        // Dual update.
        u[cur_row] += min_val;
        for r in 0..nr {
            if in_sr[r] && r != cur_row {
                u[r] += min_val - shortest[col4row[r]];
            }
        }
        for c in 0..nc {
            if in_sc[c] {
                v[c] -= min_val - shortest[c];
            }
        }
        // Augment along the path back to cur_row.
        let mut j = sink;
        loop {
            let i = path[j];
            row4col[j] = i;
            std::mem::swap(&mut col4row[i], &mut j);
            if i == cur_row {
                break;
            }
        }
    }
    Ok(col4row)
}

/// Global nearest neighbour with Stone Soup's missed-distance semantics.
///
/// `hyps[t]` lists `(detection, distance)` of the detections hypothesised for track `t`
/// (those with `distance < missed_distance`, or all of them with `include_all`). Tracks
/// without any detection hypothesis are missed. The others form the matrix
/// `[distances | diag(missed_distance)]` (absent pairs `+inf`) whose optimal assignment is
/// found per connected component (tracks sharing detections). Returns, per track, the
/// assigned detection or `None` (missed).
pub fn gnn_assign(
    hyps: &[Vec<(usize, f64)>],
    n_detections: usize,
    missed_distance: f64,
) -> Result<Vec<Option<usize>>> {
    let n = hyps.len();
    let mut out = vec![None; n];
    let groups = crate::tracking::jpda::group_by_shared_detections(n, n_detections, |t| {
        hyps[t].iter().map(|&(d, _)| d)
    });
    let mut local = vec![usize::MAX; n_detections];
    for tracks in groups.iter().filter(|g| !hyps[g[0]].is_empty()) {
        let mut dets: Vec<usize> = Vec::new();
        for &t in tracks {
            for &(d, _) in &hyps[t] {
                if local[d] == usize::MAX {
                    local[d] = dets.len();
                    dets.push(d);
                }
            }
        }
        let (nr, nd) = (tracks.len(), dets.len());
        let nc = nd + nr;
        let mut cost = vec![f64::INFINITY; nr * nc];
        for (i, &t) in tracks.iter().enumerate() {
            for &(d, dist) in &hyps[t] {
                cost[i * nc + local[d]] = dist;
            }
            cost[i * nc + nd + i] = missed_distance;
        }
        let sol = linear_sum_assignment(&cost, nr, nc).map_err(|_| {
            Error::param(
                "association",
                "GNN assignment is not feasible (missed_distance is infinite and there are \
                 more tracks than detections they can take)",
            )
        })?;
        for (i, &t) in tracks.iter().enumerate() {
            if sol[i] < nd {
                out[t] = Some(dets[sol[i]]);
            }
        }
        for &d in &dets {
            local[d] = usize::MAX;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(cost: &[f64], nr: usize, nc: usize) -> f64 {
        fn rec(cost: &[f64], nr: usize, nc: usize, i: usize, used: &mut Vec<bool>) -> f64 {
            if i == nr {
                return 0.0;
            }
            let mut best = f64::INFINITY;
            for j in 0..nc {
                if !used[j] {
                    used[j] = true;
                    best = best.min(cost[i * nc + j] + rec(cost, nr, nc, i + 1, used));
                    used[j] = false;
                }
            }
            best
        }
        rec(cost, nr, nc, 0, &mut vec![false; nc])
    }

    #[test]
    fn optimal_on_small_random_matrices() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for _ in 0..300 {
            let nr = rng.random_range(1..5);
            let nc = nr + rng.random_range(0..3);
            let cost: Vec<f64> = (0..nr * nc)
                .map(|_| {
                    if rng.random_bool(0.2) {
                        f64::INFINITY
                    } else {
                        rng.random_range(-5.0..5.0)
                    }
                })
                .collect();
            let best = brute(&cost, nr, nc);
            match linear_sum_assignment(&cost, nr, nc) {
                Ok(sol) => {
                    let total: f64 = sol.iter().enumerate().map(|(i, &j)| cost[i * nc + j]).sum();
                    assert!((total - best).abs() < 1e-9, "{total} vs {best}");
                }
                Err(_) => assert!(best.is_infinite()),
            }
        }
    }

    #[test]
    fn gnn_prefers_missing_over_expensive() {
        // Two tracks want detection 0; track 1 could also take detection 1 at a high cost.
        let hyps = vec![vec![(0, 0.1)], vec![(0, 0.2), (1, 0.9)]];
        let a = gnn_assign(&hyps, 2, 1.0).unwrap();
        assert_eq!(a, vec![Some(0), Some(1)]);
        let a = gnn_assign(&hyps, 2, 0.5).unwrap();
        assert_eq!(a, vec![Some(0), None]);
    }
}
