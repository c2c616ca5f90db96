//! Sharpness of a point map under trial heading corrections: the hot loop of the heading
//! calibration (`usvfast.nav.heading_offset`). Each point, given in the body frame of its
//! LiDAR frame, is placed in NED with its frame's pose and the heading plus the candidate
//! offset, counted on a grid of `cell` metres (twice, the second grid shifted by half a
//! cell; cells aligned on the NED origin), and the score is Σ n² / (Σ n)² over the cells,
//! the mean of the two grids.

use crate::error::{check_finite, Error, Result};

/// Score of every candidate offset (rad) for points `xy` (n × 2, body FRD x forward,
/// y starboard, m) whose frames' poses are `north`, `east` (m) and `heading` (rad clockwise),
/// one per point. `cell` > 0 m. Errors name the argument on mismatched lengths, non-finite
/// values or a grid larger than 2^28 cells.
pub fn map_sharpness(
    xy: &[f64],
    north: &[f64],
    east: &[f64],
    heading: &[f64],
    offsets: &[f64],
    cell: f64,
) -> Result<Vec<f64>> {
    let n = north.len();
    if xy.len() != 2 * n || east.len() != n || heading.len() != n {
        return Err(Error::dim(
            "xy/north/east/heading",
            "(n, 2), (n,), (n,), (n,)",
            format!(
                "{}, {}, {}, {} values",
                xy.len(),
                n,
                east.len(),
                heading.len()
            ),
        ));
    }
    for (name, v) in [
        ("xy", xy),
        ("north", north),
        ("east", east),
        ("heading", heading),
        ("offsets", offsets),
    ] {
        check_finite(name, v)?;
    }
    if !(cell > 0.0 && cell.is_finite()) {
        return Err(Error::param("cell", format!("must be > 0, got {cell}")));
    }
    if n == 0 {
        return Err(Error::param("xy", "no point"));
    }
    // Every placement lies within the poses' box grown by the largest body range.
    let reach = xy
        .chunks_exact(2)
        .map(|p| p[0].hypot(p[1]))
        .fold(0.0_f64, f64::max);
    let bounds = |v: &[f64]| {
        let (lo, hi) = v
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
        (lo - reach - cell, hi + reach + cell)
    };
    // Cells are aligned on the NED origin: cell (i, j) holds i <= north / cell + shift < i + 1.
    let (n0, n1) = bounds(north);
    let (e0, e1) = bounds(east);
    let (i0, j0) = ((n0 / cell).floor() - 1.0, (e0 / cell).floor() - 1.0);
    let rows = ((n1 - n0) / cell).ceil() as usize + 4;
    let cols = ((e1 - e0) / cell).ceil() as usize + 4;
    if rows.saturating_mul(cols) > 1 << 28 {
        return Err(Error::param(
            "cell",
            format!("the map's grid would hold {rows} x {cols} cells; use a larger cell"),
        ));
    }
    let mut counts = vec![0u32; rows * cols];
    let mut touched: Vec<usize> = Vec::with_capacity(n);
    let total = (n as f64) * (n as f64);
    let mut out = Vec::with_capacity(offsets.len());
    let trig: Vec<(f64, f64)> = heading.iter().map(|h| h.sin_cos()).collect();
    for &offset in offsets {
        let (so, co) = offset.sin_cos();
        let mut score = 0.0;
        for shift in [0.0, 0.5] {
            touched.clear();
            for k in 0..n {
                // sin and cos of heading + offset by the angle-sum formulas
                let (sh, ch) = trig[k];
                let (s, c) = (sh * co + ch * so, ch * co - sh * so);
                let (x, y) = (xy[2 * k], xy[2 * k + 1]);
                let i = ((north[k] + c * x - s * y) / cell + shift).floor() - i0;
                let j = ((east[k] + s * x + c * y) / cell + shift).floor() - j0;
                let idx = (i as usize) * cols + j as usize;
                if counts[idx] == 0 {
                    touched.push(idx);
                }
                counts[idx] += 1;
            }
            let mut sum = 0.0;
            for &idx in &touched {
                let c = f64::from(counts[idx]);
                sum += c * c;
                counts[idx] = 0;
            }
            score += sum / total;
        }
        out.push(score / 2.0);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coincident_points_score_highest() {
        let xy = [1.0, 0.0, 1.0, 0.0, 5.0, 5.0];
        let zero = [0.0; 3];
        let s = map_sharpness(&xy, &zero, &zero, &zero, &[0.0], 0.1).unwrap();
        assert!((s[0] - 5.0 / 9.0).abs() < 1e-12);
    }

    #[test]
    fn a_rotated_map_is_sharpest_at_the_correction() {
        // one wall point seen from two positions with the heading 0.02 rad too large
        let bias: f64 = 0.02;
        let wall = (10.0, 5.0);
        let mut xy = Vec::new();
        let (mut north, mut east, mut heading) = (Vec::new(), Vec::new(), Vec::new());
        for (sn, se) in [(0.0, 0.0), (8.0, 1.0)] {
            let (dn, de): (f64, f64) = (wall.0 - sn, wall.1 - se);
            xy.extend([dn, de]); // body = NED offsets at true heading 0
            north.push(sn);
            east.push(se);
            heading.push(bias);
        }
        let s = map_sharpness(&xy, &north, &east, &heading, &[0.0, -bias], 0.05).unwrap();
        assert!(s[1] > s[0], "{s:?}");
    }

    #[test]
    fn bad_input_names_the_argument() {
        let e = map_sharpness(&[1.0], &[0.0], &[0.0], &[0.0], &[0.0], 0.1).unwrap_err();
        assert!(e.to_string().contains("xy"));
        let e = map_sharpness(&[1.0, 0.0], &[0.0], &[0.0], &[0.0], &[0.0], 0.0).unwrap_err();
        assert!(e.to_string().contains("cell"));
        let nan = f64::NAN;
        let e = map_sharpness(&[1.0, 0.0], &[nan], &[0.0], &[0.0], &[0.0], 0.1).unwrap_err();
        assert!(e.to_string().contains("north"));
        let e = map_sharpness(&[], &[], &[], &[], &[0.0], 0.1).unwrap_err();
        assert!(e.to_string().contains("xy"));
    }
}
