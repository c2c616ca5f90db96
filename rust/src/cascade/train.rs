//! Cascade training: stage after stage, each on the positives the cascade still passes and
//! on negatives bootstrapped from a pool (windows the cascade so far wrongly accepts), until
//! the cascade's false-alarm rate on fresh pool windows reaches the target.

use super::boost::{train_stage, StageFit, StageTargets};
use super::haar::{feature_pool, HaarFeature};
use super::integral::IntegralImage;
use super::Cascade;
use crate::error::{Error, Result};

/// Training parameters (OpenCV `opencv_traincascade` names in brackets).
#[derive(Debug, Clone, Copy)]
pub struct TrainParams {
    /// Per-stage hit rate [minHitRate], e.g. 0.995.
    pub min_hit_rate: f64,
    /// Per-stage false-alarm rate [maxFalseAlarmRate], e.g. 0.5.
    pub max_false_alarm: f64,
    /// Most stumps per stage [maxWeakCount].
    pub max_weak: usize,
    /// Most stages [numStages].
    pub max_stages: usize,
    /// Negatives per stage [numNeg].
    pub negatives_per_stage: usize,
    /// Grid of the feature pool, pixels (1 = every position and size).
    pub feature_step: usize,
    /// Training stops when the cascade accepts at most this share of fresh pool windows.
    pub target_false_alarm: f64,
}

impl TrainParams {
    fn check(&self) -> Result<()> {
        let unit = |name: &str, v: f64| {
            if v > 0.0 && v <= 1.0 {
                Ok(())
            } else {
                Err(Error::param(name, format!("must be in (0, 1], got {v}")))
            }
        };
        unit("min_hit_rate", self.min_hit_rate)?;
        unit("max_false_alarm", self.max_false_alarm)?;
        unit("target_false_alarm", self.target_false_alarm)?;
        for (name, v) in [
            ("max_weak", self.max_weak),
            ("max_stages", self.max_stages),
            ("negatives_per_stage", self.negatives_per_stage),
            ("feature_step", self.feature_step),
        ] {
            if v == 0 {
                return Err(Error::param(name, "must be at least 1"));
            }
        }
        Ok(())
    }
}

/// What one stage did: stumps, rates on its training samples, samples used, and the share
/// of fresh pool windows the cascade accepted before it (the cascade's false-alarm rate).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageReport {
    pub weak: usize,
    pub fit: StageFit,
    pub positives: usize,
    pub negatives: usize,
    pub acceptance_before: f64,
}

/// Windows of `width × height` pixels stacked in one row-major buffer.
#[derive(Debug, Clone, Copy)]
pub struct Windows<'a> {
    pub pixels: &'a [u8],
    pub width: usize,
    pub height: usize,
}

impl Windows<'_> {
    fn check(&self, arg: &str) -> Result<usize> {
        let size = self.width * self.height;
        if self.width < 3 || self.height < 3 || self.pixels.len() % size != 0 {
            return Err(Error::dim(
                arg,
                format!(
                    "(n, {}, {}) windows of at least 3 x 3",
                    self.height, self.width
                ),
                self.pixels.len(),
            ));
        }
        Ok(self.pixels.len() / size)
    }

    fn integral(&self, i: usize) -> IntegralImage {
        let size = self.width * self.height;
        IntegralImage::new(
            &self.pixels[i * size..(i + 1) * size],
            self.width,
            self.height,
        )
        .expect("window sizes checked")
    }
}

/// Normalised feature values `[f * n + i]` of the windows `idx` of each source.
fn feature_values(pool: &[HaarFeature], samples: &[(&Windows, usize)]) -> Vec<f32> {
    let n = samples.len();
    let mut values = vec![0.0f32; pool.len() * n];
    for (i, (src, k)) in samples.iter().enumerate() {
        let ii = src.integral(*k);
        let nf = ii.norm_factor(0, 0, src.width, src.height);
        for (f, feat) in pool.iter().enumerate() {
            values[f * n + i] = (feat.value(&ii, 0, 0) / nf) as f32;
        }
    }
    values
}

/// Trains one stage of `cascade` on `positives` and `negatives` (all of them, no
/// bootstrapping) and appends it; for a final stage on chosen negatives (e.g. wakes).
pub fn add_stage(
    cascade: &mut Cascade,
    positives: &Windows,
    negatives: &Windows,
    params: &TrainParams,
) -> Result<StageReport> {
    params.check()?;
    let n_pos = positives.check("positives")?;
    let n_neg = negatives.check("negatives")?;
    if (positives.width, positives.height) != (cascade.width, cascade.height)
        || (negatives.width, negatives.height) != (cascade.width, cascade.height)
    {
        return Err(Error::param(
            "negatives",
            format!(
                "windows must be {} x {} pixels",
                cascade.width, cascade.height
            ),
        ));
    }
    if n_pos == 0 || n_neg == 0 {
        return Err(Error::param(
            "positives",
            "need at least one positive and one negative",
        ));
    }
    let pool = feature_pool(cascade.width, cascade.height, params.feature_step);
    let samples: Vec<(&Windows, usize)> = (0..n_pos)
        .map(|i| (positives, i))
        .chain((0..n_neg).map(|i| (negatives, i)))
        .collect();
    let values = feature_values(&pool, &samples);
    let targets = StageTargets {
        min_hit_rate: params.min_hit_rate,
        max_false_alarm: params.max_false_alarm,
        max_weak: params.max_weak,
    };
    let (stage, fit) = train_stage(&values, pool.len(), n_pos, n_neg, targets);
    let weak = stage.weak.len();
    cascade.push_stage(stage, &pool);
    Ok(StageReport {
        weak,
        fit,
        positives: n_pos,
        negatives: n_neg,
        acceptance_before: f64::NAN,
    })
}

/// Trains a cascade of `positives` against negatives bootstrapped from `negative_pool` (read
/// in order; shuffle it beforehand). Stops at `max_stages`, when the cascade accepts at most
/// `target_false_alarm` of fresh pool windows, or when the pool runs out of accepted windows.
pub fn train_cascade(
    positives: &Windows,
    negative_pool: &Windows,
    params: &TrainParams,
) -> Result<(Cascade, Vec<StageReport>)> {
    params.check()?;
    let n_pos = positives.check("positives")?;
    let n_pool = negative_pool.check("negative_pool")?;
    if (positives.width, positives.height) != (negative_pool.width, negative_pool.height) {
        return Err(Error::param(
            "negative_pool",
            "windows must have the positives' size",
        ));
    }
    if n_pos == 0 || n_pool == 0 {
        return Err(Error::param(
            "positives",
            "need positives and a non-empty negative pool",
        ));
    }
    let (w, h) = (positives.width, positives.height);
    let pool = feature_pool(w, h, params.feature_step);
    let mut cascade = Cascade::new(w, h);
    let mut reports = Vec::new();
    let mut cursor = 0;
    let mut kept_neg: Vec<usize> = Vec::new();
    let targets = StageTargets {
        min_hit_rate: params.min_hit_rate,
        max_false_alarm: params.max_false_alarm,
        max_weak: params.max_weak,
    };
    for _ in 0..params.max_stages {
        let pos: Vec<usize> = (0..n_pos)
            .filter(|&i| cascade.accepts(&positives.integral(i), 0, 0))
            .collect();
        let mut neg: Vec<usize> = kept_neg
            .iter()
            .copied()
            .filter(|&i| cascade.accepts(&negative_pool.integral(i), 0, 0))
            .collect();
        let (mut scanned, mut accepted) = (0usize, 0usize);
        while neg.len() < params.negatives_per_stage && cursor < n_pool {
            scanned += 1;
            if cascade.accepts(&negative_pool.integral(cursor), 0, 0) {
                accepted += 1;
                neg.push(cursor);
            }
            cursor += 1;
        }
        let acceptance = if scanned > 0 {
            accepted as f64 / scanned as f64
        } else {
            0.0
        };
        if pos.is_empty()
            || neg.len() < 10
            || (scanned > 0 && acceptance <= params.target_false_alarm)
        {
            break;
        }
        let samples: Vec<(&Windows, usize)> = pos
            .iter()
            .map(|&i| (positives, i))
            .chain(neg.iter().map(|&i| (negative_pool, i)))
            .collect();
        let values = feature_values(&pool, &samples);
        let (stage, fit) = train_stage(&values, pool.len(), pos.len(), neg.len(), targets);
        reports.push(StageReport {
            weak: stage.weak.len(),
            fit,
            positives: pos.len(),
            negatives: neg.len(),
            acceptance_before: acceptance,
        });
        cascade.push_stage(stage, &pool);
        kept_neg = neg;
    }
    Ok((cascade, reports))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 12 × 6 windows: positives have a dark left half, negatives are random texture.
    fn toy() -> (Vec<u8>, Vec<u8>) {
        let (w, h) = (12, 6);
        let mut pos = Vec::new();
        let mut neg = Vec::new();
        let mut s: u32 = 7;
        let mut rnd = || {
            s = s.wrapping_mul(1_103_515_245).wrapping_add(12345);
            ((s >> 16) % 256) as u8
        };
        for _ in 0..40 {
            for _y in 0..h {
                for x in 0..w {
                    pos.push(if x < w / 2 {
                        20 + rnd() / 16
                    } else {
                        200 + rnd() / 16
                    });
                }
            }
        }
        for _ in 0..400 {
            for _ in 0..w * h {
                neg.push(rnd());
            }
        }
        (pos, neg)
    }

    #[test]
    fn cascade_separates_toy_windows() {
        let (pos, neg) = toy();
        let (w, h) = (12, 6);
        let params = TrainParams {
            min_hit_rate: 0.99,
            max_false_alarm: 0.5,
            max_weak: 10,
            max_stages: 4,
            negatives_per_stage: 100,
            feature_step: 2,
            target_false_alarm: 1e-3,
        };
        let p = Windows {
            pixels: &pos,
            width: w,
            height: h,
        };
        let n = Windows {
            pixels: &neg,
            width: w,
            height: h,
        };
        let (c, reports) = train_cascade(&p, &n, &params).unwrap();
        assert!(!reports.is_empty());
        let hits = (0..40).filter(|&i| c.accepts(&p.integral(i), 0, 0)).count();
        let fas = (0..400)
            .filter(|&i| c.accepts(&n.integral(i), 0, 0))
            .count();
        assert!(hits >= 38, "hits {hits}");
        assert!(fas <= 20, "false alarms {fas}");
        let mut c2 = c.clone();
        let r = add_stage(&mut c2, &p, &n, &params).unwrap();
        assert_eq!(c2.stages.len(), c.stages.len() + 1);
        assert!(r.fit.hit_rate >= 0.99);
        let bad = TrainParams {
            min_hit_rate: 1.5,
            ..params
        };
        assert!(train_cascade(&p, &n, &bad).is_err());
    }
}
