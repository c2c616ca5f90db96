//! Haar-like features of a detection window (Viola–Jones; the edge, line and
//! centre-surround kinds of Bloisi et al.'s Fig. 3a), in OpenCV's weighted-rectangle form: a
//! feature is up to three rectangles with weights, its value `Σ weightᵢ · sumᵢ`.

use super::integral::IntegralImage;

/// One weighted rectangle `(x, y, w, h)` in window pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WeightedRect {
    pub x: usize,
    pub y: usize,
    pub w: usize,
    pub h: usize,
    pub weight: f64,
}

/// A Haar-like feature: 2 or 3 weighted rectangles (the first spans the whole feature
/// with weight −1, as OpenCV writes them).
#[derive(Debug, Clone, PartialEq)]
pub struct HaarFeature {
    pub rects: Vec<WeightedRect>,
}

impl HaarFeature {
    /// Raw value on the window whose top-left corner is `(x0, y0)` in `ii` (not normalised).
    #[inline]
    pub fn value(&self, ii: &IntegralImage, x0: usize, y0: usize) -> f64 {
        self.rects
            .iter()
            .map(|r| r.weight * ii.rect_sum(x0 + r.x, y0 + r.y, r.w, r.h))
            .sum()
    }
}

fn rect(x: usize, y: usize, w: usize, h: usize, weight: f64) -> WeightedRect {
    WeightedRect { x, y, w, h, weight }
}

/// The feature pool of a `width × height` window: edge (two halves, horizontal and
/// vertical), line (three thirds, both directions), four-square and centre-surround
/// features, with cell sizes and positions on a grid of `step` pixels.
pub fn feature_pool(width: usize, height: usize, step: usize) -> Vec<HaarFeature> {
    let step = step.max(1);
    let mut out = Vec::new();
    // (cells across, cells down, builder from the cell size and origin)
    type Build = fn(usize, usize, usize, usize) -> Vec<WeightedRect>;
    let kinds: [(usize, usize, Build); 6] = [
        (2, 1, |x, y, dx, dy| {
            vec![rect(x, y, 2 * dx, dy, -1.0), rect(x + dx, y, dx, dy, 2.0)]
        }),
        (1, 2, |x, y, dx, dy| {
            vec![rect(x, y, dx, 2 * dy, -1.0), rect(x, y + dy, dx, dy, 2.0)]
        }),
        (3, 1, |x, y, dx, dy| {
            vec![rect(x, y, 3 * dx, dy, -1.0), rect(x + dx, y, dx, dy, 3.0)]
        }),
        (1, 3, |x, y, dx, dy| {
            vec![rect(x, y, dx, 3 * dy, -1.0), rect(x, y + dy, dx, dy, 3.0)]
        }),
        (2, 2, |x, y, dx, dy| {
            vec![
                rect(x, y, 2 * dx, 2 * dy, -1.0),
                rect(x, y, dx, dy, 2.0),
                rect(x + dx, y + dy, dx, dy, 2.0),
            ]
        }),
        (3, 3, |x, y, dx, dy| {
            vec![
                rect(x, y, 3 * dx, 3 * dy, -1.0),
                rect(x + dx, y + dy, dx, dy, 9.0),
            ]
        }),
    ];
    for (cx, cy, build) in kinds {
        let mut dx = step;
        while cx * dx <= width {
            let mut dy = step;
            while cy * dy <= height {
                let mut y = 0;
                while y + cy * dy <= height {
                    let mut x = 0;
                    while x + cx * dx <= width {
                        out.push(HaarFeature {
                            rects: build(x, y, dx, dy),
                        });
                        x += step;
                    }
                    y += step;
                }
                dy += step;
            }
            dx += step;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edge_feature_responds_to_an_edge() {
        // left half dark, right half bright: the horizontal edge feature is positive
        let (w, h) = (8, 4);
        let px: Vec<u8> = (0..w * h)
            .map(|i| if i % w < 4 { 10 } else { 200 })
            .collect();
        let ii = IntegralImage::new(&px, w, h).unwrap();
        let f = HaarFeature {
            rects: vec![rect(0, 0, 8, 4, -1.0), rect(4, 0, 4, 4, 2.0)],
        };
        assert_eq!(
            f.value(&ii, 0, 0),
            -(16.0 * 10.0 + 16.0 * 200.0) + 2.0 * 16.0 * 200.0
        );
        let pool = feature_pool(60, 30, 6);
        assert!(pool.len() > 500);
        assert!(pool.iter().all(|f| f
            .rects
            .iter()
            .all(|r| r.x + r.w <= 60 && r.y + r.h <= 30 && r.w > 0 && r.h > 0)));
    }
}
