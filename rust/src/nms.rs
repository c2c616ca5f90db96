//! Non-maximum suppression (NMS) of axis-aligned detection boxes, per class or class-agnostic.
//!
//! Semantics follow `torchvision.ops.nms` / `batched_nms`: boxes are `[x1, y1, x2, y2]` in
//! pixels (`x2 >= x1`, `y2 >= y1`), candidates are visited in descending score order, and a
//! candidate is dropped when its intersection-over-union (IoU) with an already kept box of the
//! same class is strictly greater than the threshold. Area is `(x2 - x1) * (y2 - y1)` (no `+1`).
//! Equal scores are visited in ascending index order (a stable sort), so results are
//! deterministic. The kept indices are returned in descending score order.

use crate::error::{check_finite, Error, Result};

/// Boxes after sorting, stored as structure-of-arrays for a cache-friendly inner loop.
struct Sorted {
    x1: Vec<f64>,
    y1: Vec<f64>,
    x2: Vec<f64>,
    y2: Vec<f64>,
    area: Vec<f64>,
    /// Original index of each sorted box.
    index: Vec<usize>,
}

impl Sorted {
    fn new(boxes: &[f64], order: &[usize]) -> Self {
        let n = order.len();
        let mut s = Sorted {
            x1: Vec::with_capacity(n),
            y1: Vec::with_capacity(n),
            x2: Vec::with_capacity(n),
            y2: Vec::with_capacity(n),
            area: Vec::with_capacity(n),
            index: order.to_vec(),
        };
        for &i in order {
            let b = &boxes[4 * i..4 * i + 4];
            s.x1.push(b[0]);
            s.y1.push(b[1]);
            s.x2.push(b[2]);
            s.y2.push(b[3]);
            s.area.push((b[2] - b[0]) * (b[3] - b[1]));
        }
        s
    }

    /// IoU of sorted boxes `i` and `j`; 0 when the union is empty (two zero-area boxes).
    #[inline]
    fn iou(&self, i: usize, j: usize) -> f64 {
        let w = (self.x2[i].min(self.x2[j]) - self.x1[i].max(self.x1[j])).max(0.0);
        let h = (self.y2[i].min(self.y2[j]) - self.y1[i].max(self.y1[j])).max(0.0);
        let inter = w * h;
        let union = self.area[i] + self.area[j] - inter;
        if union > 0.0 {
            inter / union
        } else {
            0.0
        }
    }

    /// Greedy suppression over the sorted range `lo..hi`; appends kept sorted positions.
    ///
    /// Small ranges use the plain O(m²) loop. Larger ranges bin the boxes by top-left corner
    /// in a uniform grid whose cells are at least the largest box width/height, so the boxes
    /// that can overlap box `i` (IoU > 0) lie in the cells covering
    /// `[x1_i - max_w, x2_i] × [y1_i - max_h, y2_i]`. Only those are tested, in the same greedy
    /// order, which gives exactly the plain loop's result (a box with IoU 0 is never suppressed
    /// since the threshold is >= 0).
    fn suppress(&self, lo: usize, hi: usize, iou_threshold: f64, kept: &mut Vec<usize>) {
        let m = hi - lo;
        let mut removed = vec![false; m];
        if m <= 64 {
            for i in lo..hi {
                if removed[i - lo] {
                    continue;
                }
                kept.push(i);
                for j in i + 1..hi {
                    if !removed[j - lo] && self.iou(i, j) > iou_threshold {
                        removed[j - lo] = true;
                    }
                }
            }
            return;
        }
        let (mut min_x, mut min_y, mut max_x, mut max_y) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        let (mut max_w, mut max_h) = (0.0f64, 0.0f64);
        for k in lo..hi {
            min_x = min_x.min(self.x1[k]);
            min_y = min_y.min(self.y1[k]);
            max_x = max_x.max(self.x1[k]);
            max_y = max_y.max(self.y1[k]);
            max_w = max_w.max(self.x2[k] - self.x1[k]);
            max_h = max_h.max(self.y2[k] - self.y1[k]);
        }
        // Grid side per axis: cells no smaller than the largest box, at most ~2·sqrt(m) cells.
        let cap = (2.0 * (m as f64).sqrt()).ceil().max(1.0);
        let cells = |range: f64, size: f64| -> (usize, f64) {
            let n = if size > 0.0 {
                (range / size).floor().clamp(1.0, cap)
            } else {
                cap
            };
            let n = n as usize;
            (n, if range > 0.0 { range / n as f64 } else { 1.0 })
        };
        let (nx, cw) = cells(max_x - min_x, max_w);
        let (ny, ch) = cells(max_y - min_y, max_h);
        let cell_of = |x: f64, y: f64| -> (usize, usize) {
            let cx = (((x - min_x) / cw).floor().max(0.0) as usize).min(nx - 1);
            let cy = (((y - min_y) / ch).floor().max(0.0) as usize).min(ny - 1);
            (cx, cy)
        };
        // CSR buckets of sorted positions, each bucket in ascending (= score) order.
        let mut start = vec![0usize; nx * ny + 1];
        let cell: Vec<usize> = (lo..hi)
            .map(|k| {
                let (cx, cy) = cell_of(self.x1[k], self.y1[k]);
                cy * nx + cx
            })
            .collect();
        for &c in &cell {
            start[c + 1] += 1;
        }
        for c in 0..nx * ny {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut members = vec![0usize; m];
        for (off, &c) in cell.iter().enumerate() {
            members[fill[c]] = lo + off;
            fill[c] += 1;
        }
        for i in lo..hi {
            if removed[i - lo] {
                continue;
            }
            kept.push(i);
            let (cx0, cy0) = cell_of(self.x1[i] - max_w, self.y1[i] - max_h);
            let (cx1, cy1) = cell_of(self.x2[i], self.y2[i]);
            for cy in cy0..=cy1 {
                for cx in cx0..=cx1 {
                    let c = cy * nx + cx;
                    for &j in &members[start[c]..start[c + 1]] {
                        if j > i && !removed[j - lo] && self.iou(i, j) > iou_threshold {
                            removed[j - lo] = true;
                        }
                    }
                }
            }
        }
    }
}

fn check_inputs(boxes: &[f64], scores: &[f64], iou_threshold: f64) -> Result<usize> {
    if boxes.len() % 4 != 0 {
        return Err(Error::dim(
            "boxes",
            "shape (n, 4)",
            format!("{} values", boxes.len()),
        ));
    }
    let n = boxes.len() / 4;
    if scores.len() != n {
        return Err(Error::dim("scores", format!("length {n}"), scores.len()));
    }
    check_finite("boxes", boxes)?;
    check_finite("scores", scores)?;
    if !(iou_threshold.is_finite() && (0.0..=1.0).contains(&iou_threshold)) {
        return Err(Error::param(
            "iou_threshold",
            format!("must be in [0, 1], got {iou_threshold}"),
        ));
    }
    if let Some(i) =
        (0..n).find(|&i| boxes[4 * i + 2] < boxes[4 * i] || boxes[4 * i + 3] < boxes[4 * i + 1])
    {
        return Err(Error::param(
            "boxes",
            format!(
                "row {i} is not [x1, y1, x2, y2] with x2 >= x1 and y2 >= y1: {:?}",
                &boxes[4 * i..4 * i + 4]
            ),
        ));
    }
    Ok(n)
}

/// Indices `0..n` sorted by descending score, ties by ascending index.
fn by_score(scores: &[f64]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..scores.len()).collect();
    order.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]));
    order
}

/// Class-agnostic NMS.
///
/// `boxes`: row-major `(n, 4)` `[x1, y1, x2, y2]` pixels; `scores`: `(n,)`;
/// `iou_threshold` in `[0, 1]`. Returns the kept indices in descending score order.
/// Fails on shape mismatch, non-finite values, inverted boxes or a threshold outside `[0, 1]`.
pub fn nms(boxes: &[f64], scores: &[f64], iou_threshold: f64) -> Result<Vec<usize>> {
    let n = check_inputs(boxes, scores, iou_threshold)?;
    let sorted = Sorted::new(boxes, &by_score(scores));
    let mut kept = Vec::new();
    sorted.suppress(0, n, iou_threshold, &mut kept);
    Ok(kept.into_iter().map(|k| sorted.index[k]).collect())
}

/// Per-class NMS: boxes of different classes never suppress each other
/// (`torchvision.ops.batched_nms`).
///
/// Same arguments as [`nms`] plus `classes`: `(n,)` integer class ids. Returns the kept indices
/// in descending score order (ties by ascending index) across all classes.
pub fn batched_nms(
    boxes: &[f64],
    scores: &[f64],
    classes: &[i64],
    iou_threshold: f64,
) -> Result<Vec<usize>> {
    let n = check_inputs(boxes, scores, iou_threshold)?;
    if classes.len() != n {
        return Err(Error::dim("classes", format!("length {n}"), classes.len()));
    }
    // Group by class, descending score inside each group.
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| {
        classes[a]
            .cmp(&classes[b])
            .then(scores[b].total_cmp(&scores[a]))
    });
    let sorted = Sorted::new(boxes, &order);
    let mut kept = Vec::new();
    let mut lo = 0;
    while lo < n {
        let c = classes[order[lo]];
        let mut hi = lo + 1;
        while hi < n && classes[order[hi]] == c {
            hi += 1;
        }
        sorted.suppress(lo, hi, iou_threshold, &mut kept);
        lo = hi;
    }
    let mut out: Vec<usize> = kept.into_iter().map(|k| sorted.index[k]).collect();
    out.sort_by(|&a, &b| scores[b].total_cmp(&scores[a]).then(a.cmp(&b)));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The textbook O(n^2) reference: repeatedly take the best remaining box.
    fn reference(boxes: &[[f64; 4]], scores: &[f64], classes: &[i64], thr: f64) -> Vec<usize> {
        let iou = |a: &[f64; 4], b: &[f64; 4]| {
            let w = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
            let h = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
            let i = w * h;
            let u = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - i;
            if u > 0.0 {
                i / u
            } else {
                0.0
            }
        };
        let mut alive: Vec<usize> = (0..boxes.len()).collect();
        let mut kept = Vec::new();
        while !alive.is_empty() {
            let best = *alive
                .iter()
                .max_by(|&&a, &&b| scores[a].total_cmp(&scores[b]).then(b.cmp(&a)))
                .unwrap();
            kept.push(best);
            alive.retain(|&j| {
                j != best && !(classes[j] == classes[best] && iou(&boxes[best], &boxes[j]) > thr)
            });
        }
        kept
    }

    #[test]
    fn suppresses_overlap_and_keeps_disjoint() {
        let boxes = [0., 0., 10., 10., 1., 1., 11., 11., 20., 20., 30., 30.];
        let scores = [0.9, 0.8, 0.7];
        assert_eq!(nms(&boxes, &scores, 0.5).unwrap(), vec![0, 2]);
        assert_eq!(
            batched_nms(&boxes, &scores, &[0, 1, 0], 0.5).unwrap(),
            vec![0, 1, 2]
        );
    }

    #[test]
    fn rejects_bad_input() {
        assert!(nms(&[0., 0., 1.], &[1.0], 0.5).is_err());
        assert!(nms(&[0., 0., 1., 1.], &[1.0, 2.0], 0.5).is_err());
        assert!(nms(&[2., 0., 1., 1.], &[1.0], 0.5).is_err());
        assert!(nms(&[0., 0., 1., 1.], &[f64::NAN], 0.5).is_err());
        assert!(nms(&[0., 0., 1., 1.], &[1.0], 1.5).is_err());
        assert!(batched_nms(&[0., 0., 1., 1.], &[1.0], &[], 0.5).is_err());
        assert!(nms(&[], &[], 0.5).unwrap().is_empty());
    }

    proptest! {
        #[test]
        fn equals_reference(
            raw in prop::collection::vec((0.0..50.0f64, 0.0..50.0f64, 0.0..20.0f64, 0.0..20.0f64, 0u8..4, 0i64..3), 0..200),
            thr in 0.0..1.0f64,
        ) {
            let boxes: Vec<[f64; 4]> = raw.iter().map(|r| [r.0, r.1, r.0 + r.2, r.1 + r.3]).collect();
            // Coarse scores so ties happen.
            let scores: Vec<f64> = raw.iter().map(|r| f64::from(r.4) / 4.0).collect();
            let classes: Vec<i64> = raw.iter().map(|r| r.5).collect();
            let flat: Vec<f64> = boxes.iter().flatten().copied().collect();
            let zeros = vec![0i64; boxes.len()];
            prop_assert_eq!(nms(&flat, &scores, thr).unwrap(), reference(&boxes, &scores, &zeros, thr));
            prop_assert_eq!(
                batched_nms(&flat, &scores, &classes, thr).unwrap(),
                reference(&boxes, &scores, &classes, thr)
            );
        }
    }
}
