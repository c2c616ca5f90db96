//! One boosted stage: Gentle AdaBoost of decision stumps on precomputed normalised feature
//! values, stopped when the stage's false-alarm rate at the required hit rate is reached.

use super::{Stage, Stump};

/// Targets of one stage.
#[derive(Debug, Clone, Copy)]
pub struct StageTargets {
    /// Share of positives the stage must pass (e.g. 0.995).
    pub min_hit_rate: f64,
    /// Largest share of negatives the stage may pass (e.g. 0.5).
    pub max_false_alarm: f64,
    /// Most stumps in the stage.
    pub max_weak: usize,
}

/// What a trained stage achieves on its training samples.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StageFit {
    pub hit_rate: f64,
    pub false_alarm: f64,
}

/// Trains a stage on `n = n_pos + n_neg` samples (positives first) whose normalised feature
/// values are `values[f * n + i]` for feature `f` of `n_features`. Stumps index the features.
pub fn train_stage(
    values: &[f32],
    n_features: usize,
    n_pos: usize,
    n_neg: usize,
    targets: StageTargets,
) -> (Stage, StageFit) {
    let n = n_pos + n_neg;
    let y: Vec<f64> = (0..n).map(|i| if i < n_pos { 1.0 } else { -1.0 }).collect();
    let mut w: Vec<f64> = (0..n)
        .map(|i| {
            if i < n_pos {
                0.5 / n_pos as f64
            } else {
                0.5 / n_neg as f64
            }
        })
        .collect();
    // each feature's samples in increasing value
    let mut order: Vec<u32> = Vec::with_capacity(n_features * n);
    for f in 0..n_features {
        let v = &values[f * n..(f + 1) * n];
        let mut idx: Vec<u32> = (0..n as u32).collect();
        idx.sort_unstable_by(|&a, &b| v[a as usize].total_cmp(&v[b as usize]));
        order.extend(idx);
    }
    let mut score = vec![0.0f64; n];
    let mut weak = Vec::new();
    let mut threshold = f64::NEG_INFINITY;
    let mut fit = StageFit {
        hit_rate: 1.0,
        false_alarm: 1.0,
    };
    for _ in 0..targets.max_weak.max(1) {
        let Some(stump) = best_stump(values, &order, n_features, n, &w, &y) else {
            break;
        };
        let v = &values[stump.feature * n..(stump.feature + 1) * n];
        let mut total = 0.0;
        for i in 0..n {
            let out = if f64::from(v[i]) < stump.threshold {
                stump.left
            } else {
                stump.right
            };
            score[i] += out;
            // Gentle AdaBoost: w ← w · exp(−y f(x)), normalised
            w[i] *= (-y[i] * out).exp();
            total += w[i];
        }
        w.iter_mut().for_each(|wi| *wi /= total);
        weak.push(stump);
        let (thr, f) = stage_threshold(&score, n_pos, targets.min_hit_rate);
        threshold = thr;
        fit = f;
        if fit.false_alarm <= targets.max_false_alarm {
            break;
        }
    }
    (Stage { weak, threshold }, fit)
}

/// The threshold that passes at least `min_hit_rate` of the positives, and the rates.
fn stage_threshold(score: &[f64], n_pos: usize, min_hit_rate: f64) -> (f64, StageFit) {
    let mut pos: Vec<f64> = score[..n_pos].to_vec();
    pos.sort_unstable_by(f64::total_cmp);
    let k = (((1.0 - min_hit_rate) * n_pos as f64).floor() as usize).min(n_pos - 1);
    let thr = pos[k] - 1e-6 * pos[k].abs().max(1e-3);
    let hits = pos.iter().filter(|&&s| s >= thr).count();
    let fas = score[n_pos..].iter().filter(|&&s| s >= thr).count();
    let n_neg = score.len() - n_pos;
    (
        thr,
        StageFit {
            hit_rate: hits as f64 / n_pos as f64,
            false_alarm: if n_neg == 0 {
                0.0
            } else {
                fas as f64 / n_neg as f64
            },
        },
    )
}

/// The stump of least weighted squared error over all features and split points:
/// maximises `S_l² / W_l + S_r² / W_r` (S: weighted label sums, W: weight sums); its leaf
/// values are `S_l / W_l` and `S_r / W_r`.
fn best_stump(
    values: &[f32],
    order: &[u32],
    n_features: usize,
    n: usize,
    w: &[f64],
    y: &[f64],
) -> Option<Stump> {
    let (w_all, s_all): (f64, f64) = (w.iter().sum(), w.iter().zip(y).map(|(a, b)| a * b).sum());
    let eps = 1e-12;
    let mut best: Option<(f64, Stump)> = None;
    for f in 0..n_features {
        let v = &values[f * n..(f + 1) * n];
        let ord = &order[f * n..(f + 1) * n];
        let (mut wl, mut sl) = (0.0, 0.0);
        for k in 0..n - 1 {
            let i = ord[k] as usize;
            wl += w[i];
            sl += w[i] * y[i];
            let (a, b) = (v[i], v[ord[k + 1] as usize]);
            if a == b {
                continue;
            }
            let (wr, sr) = (w_all - wl, s_all - sl);
            if wl < eps || wr < eps {
                continue;
            }
            let gain = sl * sl / wl + sr * sr / wr;
            if best.as_ref().is_none_or(|(g, _)| gain > *g) {
                best = Some((
                    gain,
                    Stump {
                        feature: f,
                        threshold: 0.5 * (f64::from(a) + f64::from(b)),
                        left: sl / wl,
                        right: sr / wr,
                    },
                ));
            }
        }
    }
    best.map(|(_, s)| s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn separable_samples_give_one_clean_stump() {
        // feature 0 separates (pos high), feature 1 is noise
        let (p, q) = (20, 30);
        let n = p + q;
        let mut values = vec![0.0f32; 2 * n];
        for i in 0..n {
            values[i] = if i < p {
                1.0 + i as f32
            } else {
                -1.0 - i as f32
            };
            values[n + i] = ((i * 7919) % 13) as f32;
        }
        let (stage, fit) = train_stage(
            &values,
            2,
            p,
            q,
            StageTargets {
                min_hit_rate: 1.0,
                max_false_alarm: 0.0,
                max_weak: 5,
            },
        );
        assert_eq!(stage.weak.len(), 1);
        assert_eq!(stage.weak[0].feature, 0);
        assert_eq!(fit.hit_rate, 1.0);
        assert_eq!(fit.false_alarm, 0.0);
        assert!(stage.weak[0].left < 0.0 && stage.weak[0].right > 0.0);
    }
}
