//! Branch-free elementary functions that the compiler can vectorise, and a block driver that
//! runs a per-point kernel over arrays with AVX2 when the CPU has it.
//!
//! `std`'s `sin_cos` and `atan2` are calls into libm, which keeps loops scalar; these versions
//! are straight-line arithmetic (polynomials with the Taylor coefficients, Cody–Waite range
//! reduction, selects instead of branches), accurate to a few ulp on the ranges documented on
//! each function (tested against `std` below), so an 8-point block compiles to SIMD.

/// Points per block: the kernels see `[f64; LANES]` arrays.
pub const LANES: usize = 8;
/// One block of one coordinate.
pub type Block = [f64; LANES];

/// `1 / n!` for n = 0..=20, computed at compile time.
const INV_FACT: [f64; 21] = {
    let mut t = [1.0; 21];
    let mut i = 1;
    while i < 21 {
        t[i] = t[i - 1] / i as f64;
        i += 1;
    }
    t
};

/// π/2 split in three parts: `P1` keeps 33 significant bits so `k·P1` is exact for
/// |k| < 2^20, `P2` is the rest of the double nearest π/2, `P3` the double's error.
const P1: f64 = f64::from_bits(std::f64::consts::FRAC_PI_2.to_bits() & !0xF_FFFF);
const P2: f64 = std::f64::consts::FRAC_PI_2 - P1;
const P3: f64 = 6.123_233_995_736_766e-17;
/// 1.5·2^52: adding and subtracting it rounds a double of magnitude < 2^51 to an integer.
const ROUND_MAGIC: f64 = 6_755_399_441_055_744.0;

/// `(sin x, cos x)` for |x| < 1.6e6 (radians); within ~2 ulp of `std` there. Larger |x| loses
/// accuracy gradually (callers reject such angles).
#[inline(always)]
#[must_use]
pub fn sin_cos(x: f64) -> (f64, f64) {
    // k = round(x / (π/2)), and k mod 4 from the low mantissa bits of the magic sum.
    let shifted = x * std::f64::consts::FRAC_2_PI + ROUND_MAGIC;
    let quadrant = shifted.to_bits() & 3;
    let k = shifted - ROUND_MAGIC;
    // r = x − k·π/2 in [−π/4, π/4], Cody–Waite.
    let r = ((x - k * P1) - k * P2) - k * P3;
    let r2 = r * r;
    // sin r = r Σ (−1)^j r^{2j} / (2j+1)!, j ≤ 7 (next term < 5e-17 on |r| ≤ π/4).
    let mut s = -INV_FACT[15];
    s = s * r2 + INV_FACT[13];
    s = s * r2 - INV_FACT[11];
    s = s * r2 + INV_FACT[9];
    s = s * r2 - INV_FACT[7];
    s = s * r2 + INV_FACT[5];
    s = s * r2 - INV_FACT[3];
    let s = r + r * r2 * s;
    // cos r = Σ (−1)^j r^{2j} / (2j)!, j ≤ 8 (next term < 3e-18).
    let mut c = INV_FACT[16];
    c = c * r2 - INV_FACT[14];
    c = c * r2 + INV_FACT[12];
    c = c * r2 - INV_FACT[10];
    c = c * r2 + INV_FACT[8];
    c = c * r2 - INV_FACT[6];
    c = c * r2 + INV_FACT[4];
    c = c * r2 - INV_FACT[2];
    let c = 1.0 + r2 * c;
    // Quadrant: (s, c), (c, −s), (−s, −c), (−c, s).
    let swap = quadrant & 1 == 1;
    let (ss, cc) = if swap { (c, s) } else { (s, c) };
    let sin_neg = quadrant & 2 == 2;
    let cos_neg = (quadrant + 1) & 2 == 2;
    (
        if sin_neg { -ss } else { ss },
        if cos_neg { -cc } else { cc },
    )
}

/// `atan2(y, x)` in (−π, π] for finite inputs; within a few ulp of `std`. `atan2(0, 0) = 0`.
#[inline(always)]
#[must_use]
pub fn atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let (ax, ay) = (x.abs(), y.abs());
    let (mx, mn) = if ay > ax { (ay, ax) } else { (ax, ay) };
    // t = mn/mx in [0, 1]; atan t = π/4 + atan((t − 1)/(t + 1)) for t > tan(π/8), i.e.
    // u = (mn − mx)/(mn + mx); then one half-angle step:
    // atan u = 2 atan(u / (1 + sqrt(1 + u²))), leaving |v| ≤ tan(π/16) ≈ 0.199.
    let big = mn > (std::f64::consts::SQRT_2 - 1.0) * mx;
    let (num, den) = if big { (mn - mx, mn + mx) } else { (mn, mx) };
    let u = if den > 0.0 { num / den } else { 0.0 };
    let v = u / (1.0 + (1.0 + u * u).sqrt());
    let v2 = v * v;
    // atan v = Σ (−1)^j v^{2j+1} / (2j+1), j ≤ 10 (next term < 4e-18).
    let mut p = -1.0 / 21.0;
    p = p * v2 + 1.0 / 19.0;
    p = p * v2 - 1.0 / 17.0;
    p = p * v2 + 1.0 / 15.0;
    p = p * v2 - 1.0 / 13.0;
    p = p * v2 + 1.0 / 11.0;
    p = p * v2 - 1.0 / 9.0;
    p = p * v2 + 1.0 / 7.0;
    p = p * v2 - 1.0 / 5.0;
    p = p * v2 + 1.0 / 3.0;
    let atan_v = v - v * v2 * p;
    let mut r = 2.0 * atan_v + if big { FRAC_PI_4 } else { 0.0 };
    r = if ay > ax { FRAC_PI_2 - r } else { r };
    r = if x < 0.0 { PI - r } else { r };
    r.copysign(y)
}

/// Runs `kernel` over `n` points in blocks of [`LANES`]: `cols` are coordinate columns of
/// length `n` or 1 (broadcast); the three outputs have length `n`. Uses AVX2 code when the CPU
/// supports it (detected at run time), portable SIMD otherwise; large inputs are split over the
/// available cores (results do not depend on the split: every point is computed alone).
pub fn map_blocks<const NI: usize, K>(n: usize, cols: [&[f64]; NI], kernel: K) -> [Vec<f64>; 3]
where
    K: Fn(&[Block; NI]) -> [Block; 3] + Sync,
{
    const MIN_POINTS_PER_THREAD: usize = 1 << 16;
    let threads = std::thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(n / MIN_POINTS_PER_THREAD)
        .max(1);
    if threads == 1 {
        return map_blocks_serial(n, cols, &kernel);
    }
    let chunk = n.div_ceil(threads).next_multiple_of(LANES);
    let kernel = &kernel;
    let parts: Vec<[Vec<f64>; 3]> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..n)
            .step_by(chunk)
            .map(|start| {
                let end = (start + chunk).min(n);
                let sub: [&[f64]; NI] = std::array::from_fn(|j| {
                    let c = cols[j];
                    if c.len() == 1 {
                        c
                    } else {
                        &c[start..end]
                    }
                });
                scope.spawn(move || map_blocks_serial(end - start, sub, kernel))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    let mut out = [
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    ];
    for part in parts {
        for (o, p) in out.iter_mut().zip(part) {
            o.extend_from_slice(&p);
        }
    }
    out
}

fn map_blocks_serial<const NI: usize, K>(n: usize, cols: [&[f64]; NI], kernel: &K) -> [Vec<f64>; 3]
where
    K: Fn(&[Block; NI]) -> [Block; 3],
{
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { map_blocks_avx2(n, cols, kernel) };
        }
    }
    map_blocks_generic(n, cols, kernel)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn map_blocks_avx2<const NI: usize, K>(
    n: usize,
    cols: [&[f64]; NI],
    kernel: &K,
) -> [Vec<f64>; 3]
where
    K: Fn(&[Block; NI]) -> [Block; 3],
{
    map_blocks_generic(n, cols, kernel)
}

#[inline(always)]
fn load(c: &[f64], start: usize, n: usize) -> Block {
    if c.len() == 1 {
        return [c[0]; LANES];
    }
    let end = (start + LANES).min(n);
    // Past the end, repeat the last valid value so the padding lanes stay finite.
    let mut out = [c[end - 1]; LANES];
    out[..end - start].copy_from_slice(&c[start..end]);
    out
}

#[inline(always)]
fn map_blocks_generic<const NI: usize, K>(n: usize, cols: [&[f64]; NI], kernel: &K) -> [Vec<f64>; 3]
where
    K: Fn(&[Block; NI]) -> [Block; 3],
{
    let mut out = [
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    ];
    let full = n / LANES * LANES;
    let mut start = 0;
    while start < full {
        // Fixed-size loads and stores: no per-block memcpy calls.
        let block: [Block; NI] = std::array::from_fn(|j| {
            let c = cols[j];
            if c.len() == 1 {
                [c[0]; LANES]
            } else {
                let mut b = [0.0; LANES];
                b.copy_from_slice(&c[start..start + LANES]);
                b
            }
        });
        let r = kernel(&block);
        for (o, ri) in out.iter_mut().zip(r.iter()) {
            o.extend_from_slice(ri);
        }
        start += LANES;
    }
    if full < n {
        let block: [Block; NI] = std::array::from_fn(|j| load(cols[j], full, n));
        let r = kernel(&block);
        for (o, ri) in out.iter_mut().zip(r.iter()) {
            o.extend_from_slice(&ri[..n - full]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn split_over_threads_equals_serial() {
        let n = 300_001; // several threads' worth, not a multiple of LANES
        let a: Vec<f64> = (0..n).map(|i| i as f64 * 1e-3).collect();
        let b = [0.5];
        let kernel = |blk: &[Block; 2]| {
            let mut o = [[0.0; LANES]; 3];
            for l in 0..LANES {
                o[0][l] = blk[0][l].sin() + blk[1][l];
                o[1][l] = blk[0][l] * 2.0;
                o[2][l] = -blk[0][l];
            }
            o
        };
        let par = map_blocks(n, [&a, &b], kernel);
        let ser = map_blocks_serial(n, [&a, &b], &kernel);
        assert_eq!(par, ser);
        assert_eq!(par[0].len(), n);
    }

    fn ulps(a: f64, b: f64) -> f64 {
        // Error in units of the spacing near 1 (absolute for small values).
        (a - b).abs() / f64::EPSILON / b.abs().max(1.0)
    }

    proptest! {
        #[test]
        fn sin_cos_matches_std(x in -1.0e4..1.0e4f64) {
            let (s, c) = sin_cos(x);
            prop_assert!(ulps(s, x.sin()) < 4.0, "sin {x}: {s} vs {}", x.sin());
            prop_assert!(ulps(c, x.cos()) < 4.0, "cos {x}: {c} vs {}", x.cos());
        }

        #[test]
        fn sin_cos_small_angles(x in -1.0..1.0f64, e in -300i32..0) {
            let x = x * 10f64.powi(e / 10);
            let (s, c) = sin_cos(x);
            prop_assert!((s - x.sin()).abs() <= 2.0 * f64::EPSILON * x.abs().max(f64::MIN_POSITIVE));
            prop_assert!(ulps(c, x.cos()) < 2.0);
        }

        #[test]
        fn atan2_matches_std(y in -1.0e7..1.0e7f64, x in -1.0e7..1.0e7f64) {
            let a = atan2(y, x);
            prop_assert!((a - y.atan2(x)).abs() < 4.0 * f64::EPSILON * y.atan2(x).abs().max(1e-300)
                || ulps(a, y.atan2(x)) < 4.0, "{y} {x}: {a} vs {}", y.atan2(x));
        }
    }

    #[test]
    fn special_values() {
        use std::f64::consts::{FRAC_PI_2, PI};
        assert_eq!(sin_cos(0.0), (0.0, 1.0));
        assert!((sin_cos(FRAC_PI_2).0 - 1.0).abs() < 1e-16);
        assert!(sin_cos(PI).0.abs() < 2e-16);
        assert_eq!(atan2(0.0, 0.0), 0.0);
        assert_eq!(atan2(0.0, -1.0), PI);
        assert_eq!(atan2(1.0, 0.0), FRAC_PI_2);
        assert_eq!(atan2(-1.0, 0.0), -FRAC_PI_2);
        assert!((atan2(1.0, 1.0) - PI / 4.0).abs() < 2e-16);
        assert!((atan2(-3.0, -3.0) + 3.0 * PI / 4.0).abs() < 4e-16);
        assert!((atan2(1e-300, 1.0) - 1e-300).abs() < 1e-315);
    }

    #[test]
    fn simd_and_portable_drivers_agree_bit_for_bit() {
        // The AVX2 build of the driver must compute exactly what the portable one does (no
        // fused multiply-adds are introduced, so results are identical).
        let x: Vec<f64> = (0..1001).map(|i| -400.0 + 0.7993 * f64::from(i)).collect();
        let y: Vec<f64> = x.iter().map(|v| 3.0 - v * 0.37).collect();
        let kernel = |b: &[Block; 2]| {
            let mut o = [[0.0; LANES]; 3];
            for l in 0..LANES {
                let (s, c) = sin_cos(b[0][l]);
                o[0][l] = s;
                o[1][l] = c;
                o[2][l] = atan2(b[1][l], b[0][l]);
            }
            o
        };
        let fast = map_blocks(x.len(), [&x, &y], kernel);
        let portable = map_blocks_generic(x.len(), [&x, &y], &kernel);
        assert_eq!(fast, portable);
    }

    #[test]
    fn blocks_cover_every_point_and_broadcast() {
        let a: Vec<f64> = (0..19).map(f64::from).collect();
        let [x, y, z] = map_blocks(19, [&a, &[10.0]], |b| {
            let mut o = [[0.0; LANES]; 3];
            for l in 0..LANES {
                o[0][l] = b[0][l] + b[1][l];
                o[1][l] = b[0][l];
                o[2][l] = 1.0;
            }
            o
        });
        assert_eq!(x, a.iter().map(|v| v + 10.0).collect::<Vec<_>>());
        assert_eq!(y, a);
        assert_eq!(z, vec![1.0; 19]);
        assert!(map_blocks(0, [&[] as &[f64]], |_| [[0.0; LANES]; 3])[0].is_empty());
    }
}
