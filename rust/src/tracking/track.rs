//! Tracks and their history (the deleters that end them are in [`super::deleters`]).

use nalgebra::{DMatrix, DVector};

/// Everything appended to a track at one scan, flat and row-major (numpy-ready).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct History {
    /// Time of each entry, seconds.
    pub times: Vec<f64>,
    /// States `(k, ndim)`.
    pub states: Vec<f64>,
    /// Covariances `(k, ndim, ndim)`.
    pub covariances: Vec<f64>,
    /// Whether the entry is an update with a detection (Stone Soup `Update`) or a prediction.
    pub is_update: Vec<bool>,
    /// Scan counter (0-based, counting every accepted `step`) of each entry.
    pub scan: Vec<i64>,
    /// Sensor of the most probable detection of an update, −1 otherwise.
    pub sensor: Vec<i64>,
    /// Row in its scan of the most probable detection of an update, −1 otherwise.
    pub detection: Vec<i64>,
    /// Normalised innovation squared of that detection, NaN otherwise.
    pub nis: Vec<f64>,
    /// Probability that the track was not detected at this scan (NaN for initial states).
    pub missed_probability: Vec<f64>,
    /// CSR offsets into `assoc_detection`/`assoc_probability`, length `k + 1`.
    pub assoc_offsets: Vec<usize>,
    /// Detections (rows of their scan) hypothesised for the track at each entry.
    pub assoc_detection: Vec<i64>,
    /// Their association probabilities (JPDA marginals; 1/0 under GNN).
    pub assoc_probability: Vec<f64>,
}

/// One appended entry (see [`History`] for the fields).
#[derive(Debug, Clone)]
pub struct Entry {
    pub time: f64,
    pub is_update: bool,
    pub scan: i64,
    pub sensor: i64,
    pub detection: i64,
    pub nis: f64,
    pub missed_probability: f64,
    pub assoc: Vec<(i64, f64)>,
}

impl History {
    /// Number of entries.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// True when there is no entry.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// Reserves room for `k` more entries of an `n`-state track.
    pub fn reserve(&mut self, k: usize, n: usize) {
        self.times.reserve(k);
        self.states.reserve(k * n);
        self.covariances.reserve(k * n * n);
        self.is_update.reserve(k);
        self.scan.reserve(k);
        self.sensor.reserve(k);
        self.detection.reserve(k);
        self.nis.reserve(k);
        self.missed_probability.reserve(k);
        self.assoc_offsets.reserve(k);
        self.assoc_detection.reserve(4 * k);
        self.assoc_probability.reserve(4 * k);
    }

    fn push(&mut self, e: &Entry, x: &DVector<f64>, p: &DMatrix<f64>) {
        if self.assoc_offsets.is_empty() {
            self.assoc_offsets.push(0);
        }
        self.times.push(e.time);
        self.states.extend(x.iter());
        let n = x.len();
        for i in 0..n {
            for j in 0..n {
                self.covariances.push(p[(i, j)]);
            }
        }
        self.is_update.push(e.is_update);
        self.scan.push(e.scan);
        self.sensor.push(e.sensor);
        self.detection.push(e.detection);
        self.nis.push(e.nis);
        self.missed_probability.push(e.missed_probability);
        for &(d, pr) in &e.assoc {
            self.assoc_detection.push(d);
            self.assoc_probability.push(pr);
        }
        self.assoc_offsets.push(self.assoc_detection.len());
    }

    /// Removes every entry, keeping the buffers' capacity.
    pub fn clear(&mut self) {
        self.times.clear();
        self.states.clear();
        self.covariances.clear();
        self.is_update.clear();
        self.scan.clear();
        self.sensor.clear();
        self.detection.clear();
        self.nis.clear();
        self.missed_probability.clear();
        self.assoc_offsets.clear();
        self.assoc_detection.clear();
        self.assoc_probability.clear();
    }

    fn pop(&mut self, n: usize) {
        if self.times.pop().is_none() {
            return;
        }
        self.states.truncate(self.states.len() - n);
        self.covariances.truncate(self.covariances.len() - n * n);
        self.is_update.pop();
        self.scan.pop();
        self.sensor.pop();
        self.detection.pop();
        self.nis.pop();
        self.missed_probability.pop();
        self.assoc_offsets.pop();
        let k = *self.assoc_offsets.last().unwrap_or(&0);
        self.assoc_detection.truncate(k);
        self.assoc_probability.truncate(k);
    }
}

/// A track: current Gaussian state and its full history.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Track {
    /// Stable id (confirmed tracks count 0, 1, 2, ... in order of confirmation; tentative
    /// tracks have their own counter).
    pub id: u64,
    /// Current state (state units, e.g. `[n, v_n, e, v_e]` in m, m/s).
    pub x: DVector<f64>,
    /// Current covariance.
    pub p: DMatrix<f64>,
    /// Time of the current state, seconds.
    pub t: f64,
    /// All states so far, including the tentative phase.
    pub history: History,
    /// Time of confirmation (NaN while tentative).
    pub confirmed_time: f64,
    /// Scan time at which the track was deleted (NaN while alive).
    pub deleted_time: f64,
    /// Mode probabilities and mode-conditioned states under an IMM (`None` without one, or
    /// until the first IMM prediction).
    pub imm: Option<crate::tracking::imm::ImmState>,
    /// Existence and visibility probabilities `(r, v)` (`None` without an existence model, or
    /// until the first scan as a confirmed track).
    pub existence: Option<(f64, f64)>,
}

impl Track {
    /// A track whose first entry is `(x, p)` at `entry.time`.
    pub fn new(id: u64, x: DVector<f64>, p: DMatrix<f64>, entry: Entry) -> Self {
        Self::new_in(id, x, p, entry, History::default())
    }

    /// [`Track::new`] reusing the buffers of `history` (emptied first; its capacity is kept).
    pub fn new_in(
        id: u64,
        x: DVector<f64>,
        p: DMatrix<f64>,
        entry: Entry,
        mut history: History,
    ) -> Self {
        history.clear();
        let mut t = Track {
            id,
            t: entry.time,
            x,
            p,
            history,
            confirmed_time: f64::NAN,
            deleted_time: f64::NAN,
            imm: None,
            existence: None,
        };
        // Room for a few scans up front: growing 12 vectors one by one dominated the cost of
        // appending.
        t.history.reserve(8, t.x.len());
        t.history.push(&entry, &t.x, &t.p);
        t
    }

    /// Appends a state given as slices (`x` `(ndim,)`, `p` column-major `(ndim, ndim)`)
    /// copied into the track's buffers (no allocation), and makes it current.
    pub fn append_slices(&mut self, x: &[f64], p: &[f64], entry: &Entry) {
        self.t = entry.time;
        self.x.copy_from_slice(x);
        self.p.copy_from_slice(p);
        self.history.push(entry, &self.x, &self.p);
    }

    /// Removes the last history entry if it is a prediction (Stone Soup's `delete_last_pred`).
    pub fn drop_last_prediction(&mut self) {
        if self.history.is_update.last() == Some(&false) && self.history.len() > 1 {
            self.history.pop(self.x.len());
        }
    }

    /// Number of update entries.
    pub fn n_updates(&self) -> usize {
        self.history.is_update.iter().filter(|u| **u).count()
    }
}

pub use super::deleters::Deleter;

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(time: f64, is_update: bool) -> Entry {
        Entry {
            time,
            is_update,
            scan: 0,
            sensor: -1,
            detection: -1,
            nis: f64::NAN,
            missed_probability: f64::NAN,
            assoc: vec![],
        }
    }

    #[test]
    fn steps_since_update_counts_distinct_times() {
        let x = DVector::zeros(2);
        let p = DMatrix::identity(2, 2);
        let mut t = Track::new(0, x.clone(), p.clone(), entry(0.0, true));
        let d = Deleter::StepsSinceUpdate(2);
        t.append_slices(x.as_slice(), p.as_slice(), &entry(1.0, false));
        assert!(!d.check(&t));
        t.append_slices(x.as_slice(), p.as_slice(), &entry(1.0, false));
        assert!(!d.check(&t));
        t.append_slices(x.as_slice(), p.as_slice(), &entry(2.0, false));
        assert!(d.check(&t));
        let trace = Deleter::CovarianceTrace {
            threshold: 1.5,
            mapping: None,
        };
        assert!(trace.check(&t));
        let both = Deleter::Composite {
            deleters: vec![d, Deleter::TimeSinceUpdate(5.0)],
            intersect: true,
        };
        assert!(!both.check(&t));
        t.drop_last_prediction();
        assert_eq!(t.history.len(), 3);
    }

    #[test]
    fn time_since_update_compares_whole_microseconds_like_stonesoup() {
        // Scans at k · 0.1 s, last update at 1.3 s, 5 s deleter: 63 · 0.1 − 13 · 0.1 is
        // 5.000000000000001 in floats but exactly 5 s for Stone Soup's datetimes (kept);
        // deleted at 6.4 s.
        let (x, p) = (DVector::zeros(2), DMatrix::identity(2, 2));
        let d = Deleter::TimeSinceUpdate(5.0);
        let mut t = Track::new(0, x.clone(), p.clone(), entry(13.0 * 0.1, true));
        for k in 14..=63 {
            t.append_slices(x.as_slice(), p.as_slice(), &entry(k as f64 * 0.1, false));
            assert!(!d.check(&t), "deleted at scan {k}");
        }
        t.append_slices(x.as_slice(), p.as_slice(), &entry(64.0 * 0.1, false));
        assert!(d.check(&t));
    }
}
