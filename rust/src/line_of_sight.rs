//! Line-of-sight filter for 2-D LiDAR points behind line segments (thesis section 3.3.4,
//! Algorithm 1), as a fast bearing sweep plus a naive O(n·m) reference.
//!
//! Frame: the sensor's horizontal plane, metres; `sensor` is the sight-line origin. A point
//! `p` is dropped (its keep flag is `false`) when, for some segment `s = [a, b]`:
//! - **wall return**: the distance from `p` to the closed segment `s` is `<= tolerance`
//!   ([`within_tolerance`]), or
//! - **hidden**: `s` intersects the half-open sight segment `(sensor, p]` ([`blocks`]).
//!
//! Degenerate cases (both implementations share the predicates, evaluated in `f64` exactly as
//! written in [`blocks`] and [`within_tolerance`], so they agree bit for bit):
//! - a point exactly at the sensor is never hidden (its sight segment is empty); it is
//!   still dropped if within `tolerance` of a segment;
//! - a segment collinear with the sight line hides the point when the two overlap anywhere
//!   in `(sensor, p]`; a segment touching the sight line only at the sensor does not hide;
//! - a segment endpoint exactly on the sight line hides (closed segments);
//! - a zero-length segment is a point obstacle: it hides the points exactly behind it on
//!   its ray and drops the points within `tolerance` of it.
//!
//! The fast filter ([`line_of_sight_filter`]) answers "is any segment nearer than `p` along
//! its bearing?" from the *lower envelope* of the segments in polar coordinates: for every
//! bearing, the first element of the active set of segments ordered by range. The envelope
//! is built by divide and conquer, each merge being an angular sweep over two envelopes
//! (two segments cross at most once, so it has O(m α(m)) pieces and costs O(m log m)); each
//! point then finds its envelope piece through a bearing bucket table (O(1) typical, O(log m)
//! at worst). Bearings are diamond pseudo-angles ([`pseudo_angle`]), monotone in the true
//! bearing and cheaper than `atan2`. Wall returns come from a uniform grid over the
//! segments widened by `tolerance`. Every decision is finally taken by
//! the shared predicates on the candidates found, so the result equals the naive one:
//! candidates are the envelope segment at the point's bearing (envelope intervals are
//! shrunk by [`BEARING_MARGIN`] so that the predicates are robust on them), every segment
//! with an endpoint within [`BEARING_MARGIN`] of the point's bearing (grazing cases), and
//! segments whose line passes through the sensor (tested against every point).
//! Cost: O((n + m) log(n + m)) plus the number of such grazing pairs, which is zero on
//! generic data. The equality argument needs `tolerance` above ~1e-7 of the scene extent.

use crate::error::{check_finite, Error, Result};

/// Half a turn in pseudo-angle units (see [`pseudo_angle`]).
const PI: f64 = 2.0;

/// Margin (pseudo-angle units, see [`pseudo_angle`]; at least as many radians) below which a
/// point's bearing counts as grazing a segment endpoint; such pairs are decided by the
/// predicates directly.
pub const BEARING_MARGIN: f64 = 1e-7;

/// Bearing of `(x, y)` as a "diamond angle" in (-2, 2]: 0 along +x, 1 along +y, 2 along -x,
/// -1 along -y; increasing with the true bearing `atan2(y, x)`, with slope between 1/2 and 1
/// per radian, and much cheaper than `atan2`. `(0, 0)` maps to 0.
#[must_use]
#[inline]
pub fn pseudo_angle(x: f64, y: f64) -> f64 {
    let s = x.abs() + y.abs();
    if s == 0.0 {
        return 0.0;
    }
    let t = y / s;
    if x >= 0.0 {
        t
    } else if y >= 0.0 {
        2.0 - t
    } else {
        -2.0 - t
    }
}

/// A direction (on the diamond |x| + |y| = 1) with the given pseudo-angle.
#[inline]
fn pseudo_direction(t: f64) -> [f64; 2] {
    if t > 1.0 {
        let y = 2.0 - t;
        [y - 1.0, y]
    } else if t < -1.0 {
        let y = -2.0 - t;
        [-1.0 - y, y]
    } else {
        [1.0 - t.abs(), t]
    }
}

/// `true` when segment `seg = [x1, y1, x2, y2]` intersects the half-open sight segment
/// `(sensor, point]` (all in metres, same frame). See the module docs for the degenerate
/// cases. Evaluated in `f64` exactly in this order (the numpy peer copies it).
#[must_use]
#[inline]
pub fn blocks(sensor: [f64; 2], point: [f64; 2], seg: &[f64; 4]) -> bool {
    let (dx, dy) = (point[0] - sensor[0], point[1] - sensor[1]);
    if dx == 0.0 && dy == 0.0 {
        return false;
    }
    let (ax, ay) = (seg[0] - sensor[0], seg[1] - sensor[1]);
    let (bx, by) = (seg[2] - sensor[0], seg[3] - sensor[1]);
    // Sides of a and b with respect to the sight line.
    let oa = dx * ay - dy * ax;
    let ob = dx * by - dy * bx;
    if (oa > 0.0 && ob > 0.0) || (oa < 0.0 && ob < 0.0) {
        return false;
    }
    if oa == 0.0 && ob == 0.0 {
        // Collinear: does [a, b] projected on the sight line overlap (0, |d|²]?
        let ta = dx * ax + dy * ay;
        let tb = dx * bx + dy * by;
        let dd = dx * dx + dy * dy;
        return ta.max(tb) > 0.0 && ta.min(tb) <= dd;
    }
    // One crossing point X of the two lines; X lies on [a, b]. Is it on (sensor, point]?
    let (ex, ey) = (bx - ax, by - ay);
    let so = ey * ax - ex * ay;
    if so == 0.0 {
        return false; // X is the sensor itself
    }
    let sp = ex * (dy - ay) - ey * (dx - ax);
    sp == 0.0 || (sp > 0.0) != (so > 0.0)
}

/// `true` when `point` is within `tolerance_sq` (squared metres) of the closed segment `seg`.
/// Evaluated in `f64` exactly in this order (the numpy peer copies it).
#[must_use]
#[inline]
pub fn within_tolerance(point: [f64; 2], seg: &[f64; 4], tolerance_sq: f64) -> bool {
    let (vx, vy) = (seg[2] - seg[0], seg[3] - seg[1]);
    let (wx, wy) = (point[0] - seg[0], point[1] - seg[1]);
    let c2 = vx * vx + vy * vy;
    let t = if c2 > 0.0 {
        ((wx * vx + wy * vy) / c2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (qx, qy) = (seg[0] + t * vx, seg[1] + t * vy);
    let (ex, ey) = (point[0] - qx, point[1] - qy);
    ex * ex + ey * ey <= tolerance_sq
}

fn check_inputs(points: &[f64], segments: &[f64], sensor: [f64; 2], tolerance: f64) -> Result<()> {
    if points.len() % 2 != 0 {
        return Err(Error::dim(
            "points",
            "shape (n, 2)",
            format!("{} values", points.len()),
        ));
    }
    if segments.len() % 4 != 0 {
        return Err(Error::dim(
            "segments",
            "shape (m, 4)",
            format!("{} values", segments.len()),
        ));
    }
    check_finite("points", points)?;
    check_finite("segments", segments)?;
    check_finite("sensor", &sensor)?;
    if !(tolerance.is_finite() && tolerance > 0.0) {
        return Err(Error::param(
            "tolerance",
            format!("must be a finite positive distance in metres, got {tolerance}"),
        ));
    }
    Ok(())
}

fn as_points(points: &[f64]) -> impl Iterator<Item = [f64; 2]> + '_ {
    points.chunks_exact(2).map(|c| [c[0], c[1]])
}

fn as_segments(segments: &[f64]) -> Vec<[f64; 4]> {
    segments
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect()
}

/// Naive O(n·m) reference: keep-mask over `points` (flat `[x0, y0, x1, y1, ...]`, metres)
/// given `segments` (flat rows `[x1, y1, x2, y2]`). Fails on odd shapes, non-finite
/// values, or a `tolerance` that is not finite and positive.
pub fn line_of_sight_filter_naive(
    points: &[f64],
    segments: &[f64],
    sensor: [f64; 2],
    tolerance: f64,
) -> Result<Vec<bool>> {
    check_inputs(points, segments, sensor, tolerance)?;
    let segs = as_segments(segments);
    let tol2 = tolerance * tolerance;
    Ok(as_points(points)
        .map(|p| {
            !segs
                .iter()
                .any(|s| within_tolerance(p, s, tol2) || blocks(sensor, p, s))
        })
        .collect())
}

/// Fast sweep filter with the same contract and result as [`line_of_sight_filter_naive`].
pub fn line_of_sight_filter(
    points: &[f64],
    segments: &[f64],
    sensor: [f64; 2],
    tolerance: f64,
) -> Result<Vec<bool>> {
    check_inputs(points, segments, sensor, tolerance)?;
    let segs = as_segments(segments);
    if segs.is_empty() {
        return Ok(vec![true; points.len() / 2]);
    }
    let tol2 = tolerance * tolerance;
    let grid = TolGrid::new(&segs, tolerance, points.len() / 2);
    let sweep = Sweep::new(&segs, sensor);
    Ok(as_points(points)
        .map(|p| !(grid.near(p, &segs, tol2) || sweep.hidden(p, &segs)))
        .collect())
}

// ---------------------------------------------------------------------------------------
// Wall returns: a uniform grid over the segments widened by the tolerance.

struct TolGrid {
    x0: f64,
    y0: f64,
    inv_cell: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl TolGrid {
    fn new(segs: &[[f64; 4]], tolerance: f64, n_points: usize) -> Self {
        let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for s in segs {
            x0 = x0.min(s[0]).min(s[2]);
            x1 = x1.max(s[0]).max(s[2]);
            y0 = y0.min(s[1]).min(s[3]);
            y1 = y1.max(s[1]).max(s[3]);
        }
        let scale = x0.abs().max(x1.abs()).max(y0.abs()).max(y1.abs());
        // Widening radius: tolerance plus a margin far above the predicate's rounding.
        let r = tolerance * (1.0 + 1e-6) + 1e-9 * scale;
        let (x0, y0, x1, y1) = (x0 - r, y0 - r, x1 + r, y1 + r);
        let (w, h) = (x1 - x0, y1 - y0);
        let target = (n_points.max(segs.len() * 16)).clamp(64, 1 << 20) as f64;
        let cell = (w * h / target)
            .sqrt()
            .max(tolerance)
            .max(w.max(h) / 2048.0);
        let cell = if cell > 0.0 { cell } else { 1.0 };
        // At most 2049 cells a side (cell >= extent / 2048) and about `target` in all.
        let nx = (w / cell) as usize + 1;
        let ny = (h / cell) as usize + 1;
        let inv_cell = 1.0 / cell;
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        for (k, s) in segs.iter().enumerate() {
            let (lo_y, hi_y) = (s[1].min(s[3]) - r, s[1].max(s[3]) + r);
            let j0 = (((lo_y - y0) * inv_cell).floor().max(0.0) as usize).min(ny - 1);
            let j1 = (((hi_y - y0) * inv_cell).floor().max(0.0) as usize).min(ny - 1);
            for j in j0..=j1 {
                // Part of the segment within the row band widened by r, then its x-range ± r.
                let band_lo = y0 + j as f64 * cell - r;
                let band_hi = y0 + (j + 1) as f64 * cell + r;
                let Some((xa, xb)) = clip_x_range(s, band_lo, band_hi) else {
                    continue;
                };
                let i0 = (((xa - r - x0) * inv_cell).floor().max(0.0) as usize).min(nx - 1);
                let i1 = (((xb + r - x0) * inv_cell).floor().max(0.0) as usize).min(nx - 1);
                for i in i0..=i1 {
                    pairs.push(((j * nx + i) as u32, k as u32));
                }
            }
        }
        pairs.sort_unstable();
        let mut start = vec![0u32; nx * ny + 1];
        for &(c, _) in &pairs {
            start[c as usize + 1] += 1;
        }
        for c in 0..nx * ny {
            start[c + 1] += start[c];
        }
        let items = pairs.into_iter().map(|(_, k)| k).collect();
        TolGrid {
            x0,
            y0,
            inv_cell,
            nx,
            ny,
            start,
            items,
        }
    }

    #[inline]
    fn near(&self, p: [f64; 2], segs: &[[f64; 4]], tol2: f64) -> bool {
        let fx = (p[0] - self.x0) * self.inv_cell;
        let fy = (p[1] - self.y0) * self.inv_cell;
        if !(fx >= 0.0 && fy >= 0.0) {
            return false;
        }
        let (i, j) = (fx as usize, fy as usize);
        if i >= self.nx || j >= self.ny {
            return false; // outside the widened segment bounds
        }
        let c = j * self.nx + i;
        let (a, b) = (self.start[c] as usize, self.start[c + 1] as usize);
        self.items[a..b]
            .iter()
            .any(|&k| within_tolerance(p, &segs[k as usize], tol2))
    }
}

/// x-range of the part of segment `s` with y in `[lo, hi]`, or `None` when there is none.
fn clip_x_range(s: &[f64; 4], lo: f64, hi: f64) -> Option<(f64, f64)> {
    let (ax, ay, bx, by) = (s[0], s[1], s[2], s[3]);
    let dy = by - ay;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    if dy == 0.0 {
        if ay < lo || ay > hi {
            return None;
        }
    } else {
        let (ta, tb) = ((lo - ay) / dy, (hi - ay) / dy);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
        if t0 > t1 {
            return None;
        }
    }
    let (xa, xb) = (ax + t0 * (bx - ax), ax + t1 * (bx - ax));
    // Widen by the rounding of the interpolation (conservative).
    let slack = 1e-12 * (ax.abs() + bx.abs() + 1.0);
    Some((xa.min(xb) - slack, xa.max(xb) + slack))
}

// ---------------------------------------------------------------------------------------
// Hidden points: the lower envelope of the segments over bearing.

/// One piece of the envelope: on bearings `[lo, hi]` (pseudo-angles in [-2, 2]) segment `seg` is
/// the nearest of the envelope segments.
#[derive(Clone, Copy, Debug)]
struct Piece {
    lo: f64,
    hi: f64,
    seg: u32,
}

struct Sweep {
    sensor: [f64; 2],
    /// Envelope pieces sorted by bearing, disjoint.
    envelope: Vec<Piece>,
    /// Endpoint bearings with their segment, sorted by bearing.
    endpoints: Vec<(f64, u32)>,
    /// Segments whose line passes through (or within rounding of) the sensor.
    through_sensor: Vec<u32>,
    /// Bearing buckets over [-π, π]: bucket `b` starts at `-π + b / bucket_scale`.
    bucket_scale: f64,
    /// First envelope piece with `hi >= ` the bucket's start, per bucket.
    envelope_from: Vec<u32>,
    /// First endpoint with bearing `>=` the bucket's start, per bucket.
    endpoints_from: Vec<u32>,
}

impl Sweep {
    fn new(segs: &[[f64; 4]], sensor: [f64; 2]) -> Self {
        let mut dual = vec![[0.0; 2]; segs.len()];
        let mut endpoints = Vec::with_capacity(2 * segs.len());
        let mut through_sensor = Vec::new();
        let mut leaves: Vec<Vec<Piece>> = Vec::new();
        for (k, s) in segs.iter().enumerate() {
            let (ax, ay) = (s[0] - sensor[0], s[1] - sensor[1]);
            let (bx, by) = (s[2] - sensor[0], s[3] - sensor[1]);
            let (ta, tb) = (pseudo_angle(ax, ay), pseudo_angle(bx, by));
            endpoints.push((ta, k as u32));
            endpoints.push((tb, k as u32));
            let cross = ax * by - ay * bx;
            let dot = ax * bx + ay * by;
            let (na, nb) = (ax.hypot(ay), bx.hypot(by));
            if cross.abs() <= 1e-9 * na * nb {
                // Collinear with the sensor (or zero-length, or an endpoint at the sensor).
                if dot < 0.0 {
                    through_sensor.push(k as u32);
                }
                // Otherwise it can only hide points at its endpoint bearings.
                continue;
            }
            let (start, end) = if cross > 0.0 { (ta, tb) } else { (tb, ta) };
            let width = if end < start {
                end + 2.0 * PI - start
            } else {
                end - start
            };
            if width <= 2.0 * BEARING_MARGIN {
                continue;
            }
            // Line n·x = c with n = (-ey, ex), c = n·a; then 1/range along u is (n/c)·u.
            let (ex, ey) = (bx - ax, by - ay);
            let c = ex * ay - ey * ax;
            dual[k] = [-ey / c, ex / c];
            let mut lo = start + BEARING_MARGIN;
            let mut hi = start + width - BEARING_MARGIN;
            if lo > PI {
                lo -= 2.0 * PI;
                hi -= 2.0 * PI;
            }
            let leaf = if hi > PI {
                vec![
                    Piece {
                        lo: -PI,
                        hi: hi - 2.0 * PI,
                        seg: k as u32,
                    },
                    Piece {
                        lo,
                        hi: PI,
                        seg: k as u32,
                    },
                ]
            } else {
                vec![Piece {
                    lo,
                    hi,
                    seg: k as u32,
                }]
            };
            leaves.push(leaf);
        }
        endpoints.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let envelope = build_envelope(leaves, &dual);
        // Bucket tables turn the two bearing searches into a short forward scan.
        let buckets = (4 * (envelope.len() + endpoints.len())).clamp(64, 1 << 16);
        let bucket_scale = buckets as f64 / (2.0 * PI);
        let starts = (0..buckets).map(|b| -PI + b as f64 / bucket_scale);
        let envelope_from = starts
            .clone()
            .map(|lo| envelope.partition_point(|pc| pc.hi < lo) as u32)
            .collect();
        let endpoints_from = starts
            .map(|lo| endpoints.partition_point(|e| e.0 < lo) as u32)
            .collect();
        Sweep {
            sensor,
            envelope,
            endpoints,
            through_sensor,
            bucket_scale,
            envelope_from,
            endpoints_from,
        }
    }

    /// A bucket whose start is at or before `theta` (one bucket early against rounding).
    #[inline]
    fn bucket(&self, theta: f64) -> usize {
        // Truncation is floor here (non-negative); back off one bucket against rounding.
        let b = ((theta + PI).max(0.0) * self.bucket_scale) as usize;
        b.saturating_sub(1).min(self.envelope_from.len() - 1)
    }

    /// `true` when some segment hides `p` (the naive `any(blocks)` answer; see module docs).
    #[inline]
    fn hidden(&self, p: [f64; 2], segs: &[[f64; 4]]) -> bool {
        let (dx, dy) = (p[0] - self.sensor[0], p[1] - self.sensor[1]);
        if dx == 0.0 && dy == 0.0 {
            return false;
        }
        let test = |k: u32| blocks(self.sensor, p, &segs[k as usize]);
        let theta = pseudo_angle(dx, dy);
        // 1. The nearest envelope segment at this bearing (and neighbours at a boundary).
        let env = &self.envelope;
        let i = scan_from(env, self.envelope_from[self.bucket(theta)], |pc| {
            pc.hi < theta
        });
        if i < env.len() && env[i].lo <= theta {
            if test(env[i].seg) {
                return true;
            }
            if theta - env[i].lo <= 1e-12 && i > 0 && test(env[i - 1].seg) {
                return true;
            }
            if env[i].hi - theta <= 1e-12 && i + 1 < env.len() && test(env[i + 1].seg) {
                return true;
            }
        }
        // 2. Segments with an endpoint grazing this bearing (with wrap-around at ±π).
        if self.grazing(theta, &test) {
            return true;
        }
        // 3. Segments through the sensor.
        self.through_sensor.iter().any(|&k| test(k))
    }

    fn grazing(&self, theta: f64, test: &impl Fn(u32) -> bool) -> bool {
        let window = |lo: f64, hi: f64| {
            let e = &self.endpoints;
            let a = scan_from(e, self.endpoints_from[self.bucket(lo)], |x| x.0 < lo);
            e[a..].iter().take_while(|x| x.0 <= hi).any(|x| test(x.1))
        };
        let (lo, hi) = (theta - BEARING_MARGIN, theta + BEARING_MARGIN);
        window(lo, hi)
            || (lo < -PI && window(lo + 2.0 * PI, PI))
            || (hi > PI && window(-PI, hi - 2.0 * PI))
    }

    #[cfg(test)]
    fn envelope_len(&self) -> usize {
        self.envelope.len()
    }
}

/// First index at or after `start` where `before` turns false (`before` is true on a prefix):
/// a few linear steps (the bucket tables make this O(1) on typical data), then binary search,
/// so that a crowded bucket costs O(log n) at worst.
#[inline]
fn scan_from<T>(items: &[T], start: u32, before: impl Fn(&T) -> bool) -> usize {
    let mut i = start as usize;
    for _ in 0..8 {
        if i >= items.len() || !before(&items[i]) {
            return i;
        }
        i += 1;
    }
    i + items[i..].partition_point(before)
}

/// Divide-and-conquer lower envelope (in range; upper in `dual · u`) of the leaf pieces.
fn build_envelope(mut leaves: Vec<Vec<Piece>>, dual: &[[f64; 2]]) -> Vec<Piece> {
    if leaves.is_empty() {
        return Vec::new();
    }
    while leaves.len() > 1 {
        let mut next = Vec::with_capacity(leaves.len().div_ceil(2));
        let mut it = leaves.into_iter();
        while let Some(a) = it.next() {
            match it.next() {
                Some(b) => next.push(merge(&a, &b, dual)),
                None => next.push(a),
            }
        }
        leaves = next;
    }
    leaves.pop().unwrap_or_default()
}

#[inline]
fn inv_range(dual: &[[f64; 2]], seg: u32, theta: f64) -> f64 {
    let w = dual[seg as usize];
    let u = pseudo_direction(theta);
    w[0] * u[0] + w[1] * u[1]
}

fn push_piece(out: &mut Vec<Piece>, lo: f64, hi: f64, seg: u32) {
    if let Some(last) = out.last_mut() {
        if last.seg == seg && last.hi >= lo {
            last.hi = last.hi.max(hi);
            return;
        }
    }
    out.push(Piece { lo, hi, seg });
}

/// Merges two envelopes by sweeping their joint breakpoints in bearing order.
fn merge(a: &[Piece], b: &[Piece], dual: &[[f64; 2]]) -> Vec<Piece> {
    let mut cuts: Vec<f64> = Vec::with_capacity(2 * (a.len() + b.len()));
    for p in a.iter().chain(b) {
        cuts.push(p.lo);
        cuts.push(p.hi);
    }
    cuts.sort_unstable_by(f64::total_cmp);
    cuts.dedup();
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut ia, mut ib) = (0usize, 0usize);
    for w in cuts.windows(2) {
        let (x, y) = (w[0], w[1]);
        while ia < a.len() && a[ia].hi <= x {
            ia += 1;
        }
        while ib < b.len() && b[ib].hi <= x {
            ib += 1;
        }
        let pa = (ia < a.len() && a[ia].lo <= x).then(|| a[ia].seg);
        let pb = (ib < b.len() && b[ib].lo <= x).then(|| b[ib].seg);
        match (pa, pb) {
            (None, None) => {}
            (Some(s), None) | (None, Some(s)) => push_piece(&mut out, x, y, s),
            (Some(s1), Some(s2)) => {
                let f = |t: f64| inv_range(dual, s1, t) - inv_range(dual, s2, t);
                let (fx, fy) = (f(x), f(y));
                if fx >= 0.0 && fy >= 0.0 {
                    push_piece(&mut out, x, y, s1);
                } else if fx <= 0.0 && fy <= 0.0 {
                    push_piece(&mut out, x, y, s2);
                } else {
                    // f(θ) = Δ·u(θ) vanishes where u ⟂ Δ: one zero inside (x, y) (width < half a turn).
                    let d1 = dual[s1 as usize];
                    let d2 = dual[s2 as usize];
                    let (gx, gy) = (d1[0] - d2[0], d1[1] - d2[1]);
                    let mut tc = x;
                    for cand in [pseudo_angle(-gy, gx), pseudo_angle(gy, -gx)] {
                        if cand >= x && cand <= y {
                            tc = cand;
                            break;
                        }
                    }
                    let (first, second) = if fx > 0.0 { (s1, s2) } else { (s2, s1) };
                    push_piece(&mut out, x, tc, first);
                    push_piece(&mut out, tc, y, second);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn both(points: &[f64], segs: &[f64], sensor: [f64; 2], tol: f64) -> Vec<bool> {
        let fast = line_of_sight_filter(points, segs, sensor, tol).unwrap();
        let naive = line_of_sight_filter_naive(points, segs, sensor, tol).unwrap();
        assert_eq!(fast, naive);
        fast
    }

    #[test]
    fn wall_hides_points_behind_and_drops_its_returns() {
        // Wall x = 5 from y = -2 to 2; sensor at origin.
        let segs = [5.0, -2.0, 5.0, 2.0];
        let points = [
            3.0, 0.0, // in front: kept
            8.0, 0.0, // behind: hidden
            5.05, 1.0, // on the wall (within 0.1): dropped
            8.0, 8.0, // beside the wall's shadow: kept
            10.0, 4.0, // exactly on the shadow edge through (5, 2): hidden (closed)
            -6.0, 0.0, // behind the sensor: kept
        ];
        let keep = both(&points, &segs, [0.0, 0.0], 0.1);
        assert_eq!(keep, vec![true, false, false, true, false, true]);
    }

    #[test]
    fn degenerate_cases() {
        let sensor = [1.0, 1.0];
        // Zero-length segment at (3, 1): hides (5, 1) exactly behind it only.
        let segs = [3.0, 1.0, 3.0, 1.0];
        let keep = both(&[5.0, 1.0, 5.0, 1.5, 1.0, 1.0], &segs, sensor, 0.1);
        assert_eq!(keep, vec![false, true, true]);
        // Segment through the sensor: hides only points along it.
        let segs = [0.0, 0.0, 2.0, 2.0];
        let keep = both(
            &[4.0, 4.0, 4.0, 3.0, -3.0, -3.0, 1.0, 3.0],
            &segs,
            sensor,
            0.1,
        );
        assert_eq!(keep, vec![false, true, false, true]);
        // Segment collinear with a sight line, beyond the point: nothing hidden.
        let segs = [6.0, 1.0, 9.0, 1.0];
        let keep = both(&[4.0, 1.0, 10.0, 1.0], &segs, sensor, 0.1);
        assert_eq!(keep, vec![true, false]);
        // Point at the sensor, far from segments: kept; segment ending at the sensor.
        let segs = [1.0, 1.0, 1.0, 4.0];
        let keep = both(&[1.0, 1.0, 1.0, 6.0, 2.0, 6.0], &segs, sensor, 0.1);
        assert_eq!(keep, vec![false, false, true]);
    }

    const ROUNDS: usize = 300;

    #[test]
    fn random_scenes_match_naive() {
        let mut rng = StdRng::seed_from_u64(7);
        for round in 0..ROUNDS {
            let n = rng.random_range(0..300);
            let m = rng.random_range(0..40);
            let grid = round % 3 == 0; // small integer coordinates: many exact degeneracies
            let coord = |rng: &mut StdRng| {
                if grid {
                    rng.random_range(-4i32..=4) as f64
                } else {
                    rng.random_range(-10.0..10.0)
                }
            };
            let points: Vec<f64> = (0..2 * n).map(|_| coord(&mut rng)).collect();
            let segs: Vec<f64> = (0..4 * m).map(|_| coord(&mut rng)).collect();
            let sensor = if grid {
                [0.0, 0.0]
            } else {
                [coord(&mut rng), coord(&mut rng)]
            };
            let tol = if grid {
                0.25
            } else {
                rng.random_range(0.01..0.5)
            };
            both(&points, &segs, sensor, tol);
        }
    }

    #[test]
    fn pseudo_angle_is_monotone_and_invertible() {
        let mut last = f64::NEG_INFINITY;
        for k in 0..=20_000 {
            let a = -std::f64::consts::PI + k as f64 * 2.0 * std::f64::consts::PI / 20_000.0;
            let (x, y) = (3.0 * a.cos(), 3.0 * a.sin());
            let t = pseudo_angle(x, y);
            assert!(t >= last && (-2.0..=2.0).contains(&t));
            last = t;
            let u = pseudo_direction(t);
            assert!((u[0] * y - u[1] * x).abs() < 1e-12 && u[0] * x + u[1] * y > 0.0);
        }
    }

    #[test]
    fn envelope_is_small() {
        let mut rng = StdRng::seed_from_u64(3);
        let segs: Vec<[f64; 4]> = (0..200)
            .map(|_| {
                let (x, y) = (rng.random_range(-20.0..20.0), rng.random_range(-20.0..20.0));
                [
                    x,
                    y,
                    x + rng.random_range(-3.0..3.0),
                    y + rng.random_range(-3.0..3.0),
                ]
            })
            .collect();
        let sweep = Sweep::new(&segs, [0.0, 0.0]);
        assert!(sweep.envelope_len() < 2000);
    }

    #[test]
    fn bad_input_names_the_argument() {
        let e = line_of_sight_filter(&[0.0, 1.0, 2.0], &[], [0.0, 0.0], 0.1).unwrap_err();
        assert!(e.to_string().starts_with("points"));
        let e = line_of_sight_filter(&[], &[0.0; 3], [0.0, 0.0], 0.1).unwrap_err();
        assert!(e.to_string().starts_with("segments"));
        let e = line_of_sight_filter(&[f64::NAN, 0.0], &[], [0.0, 0.0], 0.1).unwrap_err();
        assert!(e.to_string().starts_with("points"));
        let e = line_of_sight_filter(&[], &[], [0.0, 0.0], 0.0).unwrap_err();
        assert!(e.to_string().starts_with("tolerance"));
        let e = line_of_sight_filter_naive(&[], &[], [f64::INFINITY, 0.0], 0.1).unwrap_err();
        assert!(e.to_string().starts_with("sensor"));
    }
}
