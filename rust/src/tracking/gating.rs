//! Gating: chi-square gate thresholds, validation-region volumes and a spatial grid that finds
//! the candidate (track, detection) pairs of a scan without testing every pair.
//!
//! A track's gate in measurement space is the ellipsoid `yᵀ S⁻¹ y ≤ g` around its predicted
//! measurement `ẑ = H x⁻` (`S = H P⁻ Hᵀ + R`). Its projection on axis `i` is the interval
//! `|y_i| ≤ sqrt(g · S_ii)`, so the axis-aligned box with those half-widths contains the gate
//! exactly; [`CandidateGrid`] returns the detections inside each box (a superset of the gated
//! ones) in time linear in tracks + detections + candidates when gates are small.

use crate::error::{Error, Result};
use crate::tracking::jpda::FastMap;

/// `ln Γ(x)` for `x > 0` (Lanczos approximation, relative error < 1e-14).
fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x) Γ(1 − x) = π / sin(πx).
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// Regularised lower incomplete gamma `P(a, x)` (series for `x < a + 1`, Lentz continued
/// fraction otherwise).
fn gamma_p(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let ln_pre = a * x.ln() - x - ln_gamma(a);
    if x < a + 1.0 {
        let (mut term, mut sum, mut n) = (1.0 / a, 1.0 / a, a);
        for _ in 0..1000 {
            n += 1.0;
            term *= x / n;
            sum += term;
            if term.abs() < sum.abs() * 1e-17 {
                break;
            }
        }
        (sum.ln() + ln_pre).exp()
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-17 {
                break;
            }
        }
        1.0 - (ln_pre.exp() * h)
    }
}

/// The chi-square quantile `F⁻¹(p; k)` (scipy's `chi2.ppf(p, k)`): the squared-Mahalanobis gate
/// that holds a true measurement with probability `p`. `p` in (0, 1]; `p = 1` gives infinity.
pub fn chi2_quantile(p: f64, dof: usize) -> Result<f64> {
    if !(p > 0.0 && p <= 1.0) || dof == 0 {
        return Err(Error::param(
            "prob_gate",
            format!("must be in (0, 1] with at least one degree of freedom, got {p}"),
        ));
    }
    if p == 1.0 {
        return Ok(f64::INFINITY);
    }
    if dof == 2 {
        // Closed form: F(x; 2) = 1 − exp(−x/2).
        return Ok(-2.0 * (-p).ln_1p());
    }
    let a = dof as f64 / 2.0;
    // Bracket, then bisect on P(a, x/2) = p and polish with Newton steps.
    let (mut lo, mut hi) = (0.0f64, (dof as f64).max(1.0));
    while gamma_p(a, hi / 2.0) < p {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if gamma_p(a, mid / 2.0) < p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-15 * hi {
            break;
        }
    }
    let mut x = 0.5 * (lo + hi);
    for _ in 0..3 {
        let f = gamma_p(a, x / 2.0) - p;
        // Density of chi2(k) at x.
        let pdf = ((a - 1.0) * (x / 2.0).ln() - x / 2.0 - ln_gamma(a)).exp() / 2.0;
        if pdf > 0.0 && pdf.is_finite() {
            let step = f / pdf;
            if step.abs() < 0.5 * x {
                x -= step;
            }
        }
    }
    Ok(x)
}

/// Volume of the unit ball in `n` dimensions, `π^(n/2) / Γ(n/2 + 1)`.
pub fn unit_ball_volume(n: usize) -> f64 {
    let h = n as f64 / 2.0;
    (h * std::f64::consts::PI.ln() - ln_gamma(h + 1.0)).exp()
}

/// Volume of the validation region `{y : yᵀ S⁻¹ y ≤ g}`: `c_n g^(n/2) sqrt(det S)`.
pub fn validation_volume(n: usize, gate: f64, det_s: f64) -> f64 {
    unit_ball_volume(n) * gate.powf(n as f64 / 2.0) * det_s.sqrt()
}

/// Detections of one sensor bucketed on a uniform grid over their first one or two
/// measurement coordinates; answers "which detections lie in this box".
#[derive(Debug)]
pub struct CandidateGrid<'a> {
    /// Detections `(k, m)` row-major.
    points: &'a [f64],
    m: usize,
    /// Indices into the caller's detection list, parallel to the rows of `points`.
    ids: &'a [usize],
    cell: f64,
    dims: usize,
    /// Rows sorted by cell; `cells[key] = (start, end)` into `order`.
    order: Vec<u32>,
    cells: FastMap<(i64, i64), (u32, u32)>,
}

impl<'a> CandidateGrid<'a> {
    /// Buckets `points` (`ids.len()` rows of `m` coordinates) into cells of side `cell`
    /// (metres, or the measurement unit). A non-finite or non-positive `cell` puts everything
    /// in one cell.
    pub fn new(points: &'a [f64], m: usize, ids: &'a [usize], cell: f64) -> Self {
        let dims = m.min(2);
        let cell = if cell.is_finite() && cell > 0.0 {
            cell
        } else {
            f64::INFINITY
        };
        let mut keyed: Vec<((i64, i64), u32)> = (0..ids.len())
            .map(|k| {
                (
                    Self::key_of(&points[k * m..(k + 1) * m], dims, cell),
                    k as u32,
                )
            })
            .collect();
        keyed.sort_unstable();
        let mut cells: FastMap<(i64, i64), (u32, u32)> = FastMap::default();
        cells.reserve(keyed.len());
        let mut start = 0;
        while start < keyed.len() {
            let key = keyed[start].0;
            let mut end = start + 1;
            while end < keyed.len() && keyed[end].0 == key {
                end += 1;
            }
            cells.insert(key, (start as u32, end as u32));
            start = end;
        }
        Self {
            points,
            m,
            ids,
            cell,
            dims,
            order: keyed.into_iter().map(|(_, k)| k).collect(),
            cells,
        }
    }

    fn coord(v: f64, cell: f64) -> i64 {
        if cell.is_infinite() {
            0
        } else {
            (v / cell).floor().clamp(-4e18, 4e18) as i64
        }
    }

    fn key_of(p: &[f64], dims: usize, cell: f64) -> (i64, i64) {
        let a = Self::coord(p[0], cell);
        let b = if dims > 1 { Self::coord(p[1], cell) } else { 0 };
        (a, b)
    }

    /// Calls `f(id)` for every detection with `|z_i − center_i| ≤ half_width_i` on all axes.
    pub fn query(&self, center: &[f64], half_width: &[f64], mut f: impl FnMut(usize)) {
        let inside = |k: usize| {
            let z = &self.points[k * self.m..(k + 1) * self.m];
            (0..self.m).all(|i| (z[i] - center[i]).abs() <= half_width[i])
        };
        let (mut lo, mut hi) = ([0i64; 2], [0i64; 2]);
        for i in 0..self.dims {
            lo[i] = Self::coord(center[i] - half_width[i], self.cell);
            hi[i] = Self::coord(center[i] + half_width[i], self.cell);
        }
        let span = |i: usize| (hi[i] - lo[i]).saturating_add(1).max(1) as u128;
        let n_cells = (0..self.dims).map(span).product::<u128>();
        if n_cells > self.cells.len() as u128 {
            // A big gate: cheaper to test every occupied cell's points.
            for k in 0..self.ids.len() {
                if inside(k) {
                    f(self.ids[k]);
                }
            }
            return;
        }
        let (b_lo, b_hi) = if self.dims > 1 {
            (lo[1], hi[1])
        } else {
            (0, 0)
        };
        for a in lo[0]..=hi[0] {
            for b in b_lo..=b_hi {
                if let Some(&(s, e)) = self.cells.get(&(a, b)) {
                    for &k in &self.order[s as usize..e as usize] {
                        if inside(k as usize) {
                            f(self.ids[k as usize]);
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_quantiles_match_tables() {
        // scipy.stats.chi2.ppf values.
        assert!((chi2_quantile(0.95, 1).unwrap() - 3.841_458_820_694_124).abs() < 1e-9);
        assert!((chi2_quantile(0.95, 2).unwrap() - 5.991_464_547_107_979).abs() < 1e-12);
        assert!((chi2_quantile(0.99, 3).unwrap() - 11.344_866_730_144_373).abs() < 1e-9);
        assert!((chi2_quantile(0.5, 4).unwrap() - 3.356_693_980_033_322).abs() < 1e-9);
        assert!(chi2_quantile(0.0, 2).is_err());
        assert!(chi2_quantile(1.0, 2).unwrap().is_infinite());
    }

    #[test]
    fn unit_ball() {
        assert!((unit_ball_volume(2) - std::f64::consts::PI).abs() < 1e-12);
        assert!((unit_ball_volume(3) - 4.0 / 3.0 * std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn grid_finds_exactly_the_points_in_the_box() {
        let pts: Vec<f64> = (0..200)
            .flat_map(|i| [(i % 20) as f64 * 1.3, (i / 20) as f64 * 0.7])
            .collect();
        let ids: Vec<usize> = (0..200).collect();
        let grid = CandidateGrid::new(&pts, 2, &ids, 1.0);
        for (c, w) in [([5.0, 3.0], [1.5, 0.8]), ([0.0, 0.0], [100.0, 100.0])] {
            let mut got = vec![];
            grid.query(&c, &w, |i| got.push(i));
            got.sort_unstable();
            let want: Vec<usize> = (0..200)
                .filter(|&k| {
                    (pts[2 * k] - c[0]).abs() <= w[0] && (pts[2 * k + 1] - c[1]).abs() <= w[1]
                })
                .collect();
            assert_eq!(got, want);
        }
    }
}
