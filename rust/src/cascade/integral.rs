//! Integral images of an 8-bit grey image: rectangle sums and squared sums in O(1).

use crate::error::{Error, Result};

/// Summed-area tables `(w + 1) × (h + 1)` of an image and of its squares (row-major,
/// entry `(y, x)` = sum of pixels above and left of `(x, y)`).
#[derive(Debug, Clone)]
pub struct IntegralImage {
    width: usize,
    height: usize,
    sum: Vec<f64>,
    sqsum: Vec<f64>,
}

impl IntegralImage {
    /// Builds the tables of a row-major `width × height` image. Fails when the sizes
    /// disagree or the image is empty.
    pub fn new(pixels: &[u8], width: usize, height: usize) -> Result<Self> {
        if width == 0 || height == 0 || pixels.len() != width * height {
            return Err(Error::dim(
                "image",
                format!("{height} x {width} pixels (non-empty)"),
                pixels.len(),
            ));
        }
        let stride = width + 1;
        let mut sum = vec![0.0; stride * (height + 1)];
        let mut sqsum = vec![0.0; stride * (height + 1)];
        for y in 0..height {
            let (mut row, mut row_sq) = (0.0, 0.0);
            for x in 0..width {
                let v = f64::from(pixels[y * width + x]);
                row += v;
                row_sq += v * v;
                sum[(y + 1) * stride + x + 1] = sum[y * stride + x + 1] + row;
                sqsum[(y + 1) * stride + x + 1] = sqsum[y * stride + x + 1] + row_sq;
            }
        }
        Ok(Self {
            width,
            height,
            sum,
            sqsum,
        })
    }

    /// Image width in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Image height in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    #[inline]
    fn table(t: &[f64], stride: usize, x: usize, y: usize, w: usize, h: usize) -> f64 {
        t[(y + h) * stride + x + w] - t[y * stride + x + w] - t[(y + h) * stride + x]
            + t[y * stride + x]
    }

    /// Sum of the pixels of the rectangle `(x, y, w, h)` (must lie inside the image).
    #[inline]
    pub fn rect_sum(&self, x: usize, y: usize, w: usize, h: usize) -> f64 {
        Self::table(&self.sum, self.width + 1, x, y, w, h)
    }

    /// Sum of the squared pixels of the rectangle `(x, y, w, h)`.
    #[inline]
    pub fn rect_sqsum(&self, x: usize, y: usize, w: usize, h: usize) -> f64 {
        Self::table(&self.sqsum, self.width + 1, x, y, w, h)
    }

    /// OpenCV's variance normalisation of a `w × h` window at `(x, y)`: over the window
    /// shrunk by one pixel on each side, `sqrt(area · Σv² − (Σv)²)`, or 1 when that is not
    /// positive. Feature values are divided by it.
    #[inline]
    pub fn norm_factor(&self, x: usize, y: usize, w: usize, h: usize) -> f64 {
        let (iw, ih) = (w - 2, h - 2);
        let area = (iw * ih) as f64;
        let s = self.rect_sum(x + 1, y + 1, iw, ih);
        let sq = self.rect_sqsum(x + 1, y + 1, iw, ih);
        let nf = area * sq - s * s;
        if nf > 0.0 {
            nf.sqrt()
        } else {
            1.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_equal_brute_force() {
        let (w, h) = (7, 5);
        let px: Vec<u8> = (0..w * h).map(|i| ((i * 37) % 251) as u8).collect();
        let ii = IntegralImage::new(&px, w, h).unwrap();
        let brute = |x: usize, y: usize, rw: usize, rh: usize, sq: bool| -> f64 {
            let mut s = 0.0;
            for yy in y..y + rh {
                for xx in x..x + rw {
                    let v = f64::from(px[yy * w + xx]);
                    s += if sq { v * v } else { v };
                }
            }
            s
        };
        assert_eq!(ii.rect_sum(1, 2, 4, 3), brute(1, 2, 4, 3, false));
        assert_eq!(ii.rect_sqsum(0, 0, 7, 5), brute(0, 0, 7, 5, true));
        assert!(IntegralImage::new(&px, w, h + 1).is_err());
    }
}
