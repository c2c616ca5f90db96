//! Haar-feature boosted cascades (Viola–Jones, as Bloisi et al. train their boat detector):
//! integral images, the Haar feature pool of a detection window, Gentle AdaBoost stumps per
//! stage with hit-rate and false-alarm targets, negative bootstrapping, and OpenCV's cascade
//! XML so that `cv2.CascadeClassifier` runs what was trained here.

pub mod boost;
pub mod haar;
pub mod integral;
pub mod train;
pub mod xml;

use haar::HaarFeature;
use integral::IntegralImage;

/// A decision stump: `left` when the normalised feature value is below `threshold`, else
/// `right` (OpenCV's stump semantics).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stump {
    /// Index into the owning cascade's (or trainer's) feature list.
    pub feature: usize,
    pub threshold: f64,
    pub left: f64,
    pub right: f64,
}

/// One stage: a window passes when the sum of its stumps' outputs is at least `threshold`.
#[derive(Debug, Clone, PartialEq)]
pub struct Stage {
    pub weak: Vec<Stump>,
    pub threshold: f64,
}

/// A trained cascade of a `width × height` window.
#[derive(Debug, Clone, PartialEq)]
pub struct Cascade {
    pub width: usize,
    pub height: usize,
    /// The features the stumps use (only those).
    pub features: Vec<HaarFeature>,
    pub stages: Vec<Stage>,
}

impl Cascade {
    /// An empty cascade (accepts every window).
    pub fn new(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            features: Vec::new(),
            stages: Vec::new(),
        }
    }

    /// Stage sum of the window at `(x, y)` of `ii` with normalisation factor `nf`.
    fn stage_sum(&self, stage: &Stage, ii: &IntegralImage, x: usize, y: usize, nf: f64) -> f64 {
        stage
            .weak
            .iter()
            .map(|s| {
                let v = self.features[s.feature].value(ii, x, y) / nf;
                if v < s.threshold {
                    s.left
                } else {
                    s.right
                }
            })
            .sum()
    }

    /// How many stages the window at `(x, y)` passes (all of them: accepted).
    pub fn stages_passed(&self, ii: &IntegralImage, x: usize, y: usize) -> usize {
        let nf = ii.norm_factor(x, y, self.width, self.height);
        for (k, st) in self.stages.iter().enumerate() {
            if self.stage_sum(st, ii, x, y, nf) < st.threshold {
                return k;
            }
        }
        self.stages.len()
    }

    /// Whether the window at `(x, y)` passes every stage.
    pub fn accepts(&self, ii: &IntegralImage, x: usize, y: usize) -> bool {
        self.stages_passed(ii, x, y) == self.stages.len()
    }

    /// Top-left corners of the accepted windows of an image at one scale, on a grid of `step`
    /// pixels.
    pub fn scan(&self, ii: &IntegralImage, step: usize) -> Vec<(usize, usize)> {
        let step = step.max(1);
        let mut out = Vec::new();
        if ii.width() < self.width || ii.height() < self.height {
            return out;
        }
        let mut y = 0;
        while y + self.height <= ii.height() {
            let mut x = 0;
            while x + self.width <= ii.width() {
                if self.accepts(ii, x, y) {
                    out.push((x, y));
                }
                x += step;
            }
            y += step;
        }
        out
    }

    /// Appends a stage whose stumps index `pool`, copying the features it uses (once each).
    pub fn push_stage(&mut self, stage: Stage, pool: &[HaarFeature]) {
        let weak = stage
            .weak
            .into_iter()
            .map(|mut s| {
                let f = &pool[s.feature];
                s.feature = match self.features.iter().position(|g| g == f) {
                    Some(i) => i,
                    None => {
                        self.features.push(f.clone());
                        self.features.len() - 1
                    }
                };
                s
            })
            .collect();
        self.stages.push(Stage {
            weak,
            threshold: stage.threshold,
        });
    }
}
