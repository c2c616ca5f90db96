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
    let points: Vec<Placed> = (0..n)
        .map(|k| {
            let (sin, cos) = heading[k].sin_cos();
            Placed {
                north: north[k],
                east: east[k],
                x: xy[2 * k],
                y: xy[2 * k + 1],
                sin,
                cos,
            }
        })
        .collect();
    let grid = Grid {
        points,
        cell,
        origin: (i0 as i64, j0 as i64),
        cols,
        cells: rows * cols,
    };
    // Trial corrections split over the cores, each thread with its own grid.
    const MIN_PLACEMENTS_PER_THREAD: usize = 1 << 20;
    let threads = std::thread::available_parallelism()
        .map_or(1, |t| t.get())
        .min(n * offsets.len() / MIN_PLACEMENTS_PER_THREAD)
        .clamp(1, offsets.len().max(1));
    if threads == 1 {
        return Ok(grid.scores(offsets));
    }
    let chunk = offsets.len().div_ceil(threads);
    let grid = &grid;
    let parts: Vec<Vec<f64>> = std::thread::scope(|scope| {
        let handles: Vec<_> = offsets
            .chunks(chunk)
            .map(|part| scope.spawn(move || grid.scores(part)))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect()
    });
    Ok(parts.concat())
}

/// `x.floor()` for |x| < 2^52 by truncation (the x86-64 baseline has no rounding instruction:
/// `f64::floor` is a library call there, the hot loop's largest cost).
#[inline]
fn floor(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t - 1
    } else {
        t
    }
}

/// A point in its frame's body coordinates with the frame's pose.
struct Placed {
    north: f64,
    east: f64,
    x: f64,
    y: f64,
    /// sin and cos of the frame's heading
    sin: f64,
    cos: f64,
}

/// The points and the grid of `map_sharpness`.
struct Grid {
    points: Vec<Placed>,
    cell: f64,
    /// cell indices of the grid's first row and column
    origin: (i64, i64),
    cols: usize,
    cells: usize,
}

impl Grid {
    /// The grid cell of `p` placed with its heading plus the offset whose cos and sin are
    /// `co`, `so`, the grid shifted by `shift` cells.
    fn index(&self, p: &Placed, co: f64, so: f64, shift: f64) -> usize {
        // sin and cos of heading + offset by the angle-sum formulas
        let (s, c) = (p.sin * co + p.cos * so, p.cos * co - p.sin * so);
        let i = floor((p.north + c * p.x - s * p.y) / self.cell + shift) - self.origin.0;
        let j = floor((p.east + s * p.x + c * p.y) / self.cell + shift) - self.origin.1;
        (i as usize) * self.cols + j as usize
    }

    /// The score of each of `offsets` (rad).
    fn scores(&self, offsets: &[f64]) -> Vec<f64> {
        let n = self.points.len();
        let total = (n as f64) * (n as f64);
        let mut counts = vec![0u32; self.cells];
        let mut touched: Vec<usize> = Vec::with_capacity(n);
        let mut out = Vec::with_capacity(offsets.len());
        for &offset in offsets {
            let (so, co) = offset.sin_cos();
            let mut score = 0.0;
            for shift in [0.0, 0.5] {
                touched.clear();
                for p in &self.points {
                    let idx = self.index(p, co, so, shift);
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
        out
    }
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
    fn the_cores_split_gives_the_one_thread_scores() {
        // 40,000 points x 64 trials: split over the cores; each trial alone: one thread
        let n = 40_000;
        let mut xy = Vec::with_capacity(2 * n);
        let (mut north, mut east, mut heading) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for k in 0..n {
            let f = k as f64 / n as f64;
            xy.extend([10.0 + 20.0 * f, 12.0 - (k % 7) as f64 * 0.3]);
            north[k] = (k / 1000) as f64 * 0.5;
            east[k] = ((k / 1000) % 3) as f64;
            heading[k] = 0.01 * (k / 1000) as f64;
        }
        let offsets: Vec<f64> = (0..64).map(|i| (i as f64 - 32.0) * 0.001).collect();
        let all = map_sharpness(&xy, &north, &east, &heading, &offsets, 0.1).unwrap();
        for (o, s) in offsets.iter().zip(&all) {
            let one = map_sharpness(&xy, &north, &east, &heading, &[*o], 0.1).unwrap();
            assert_eq!(one[0], *s);
        }
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
