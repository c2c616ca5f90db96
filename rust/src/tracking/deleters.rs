//! Deleters of tracks (Stone Soup's `UpdateTimeStepsDeleter`, `UpdateTimeDeleter`,
//! `CovarianceBasedDeleter`, `CompositeDeleter`).

use crate::error::{Error, Result};
use crate::tracking::track::Track;

/// When a track is deleted.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Deleter {
    /// Delete when more than `steps` distinct timestamps go back from the newest state without
    /// meeting an update (`UpdateTimeStepsDeleter(time_steps_since_update=steps)`).
    StepsSinceUpdate(usize),
    /// Delete when no update has a timestamp within `seconds` of the newest state
    /// (`UpdateTimeDeleter(time_since_update=seconds)`).
    TimeSinceUpdate(f64),
    /// Delete when the trace of the covariance (or of the `mapping` diagonal entries) exceeds
    /// the threshold (`CovarianceBasedDeleter`).
    CovarianceTrace {
        threshold: f64,
        mapping: Option<Vec<usize>>,
    },
    /// Delete when any (`intersect = false`) or all (`intersect = true`) delete
    /// (`CompositeDeleter`).
    Composite {
        deleters: Vec<Deleter>,
        intersect: bool,
    },
    /// Never delete.
    Never,
}

impl Deleter {
    /// Checks parameters against the state dimension `ndim`.
    pub fn validate(&self, ndim: usize, arg: &str) -> Result<()> {
        match self {
            Deleter::StepsSinceUpdate(_) | Deleter::Never => Ok(()),
            Deleter::TimeSinceUpdate(s) if s.is_finite() && *s >= 0.0 => Ok(()),
            Deleter::TimeSinceUpdate(s) => Err(Error::param(
                arg,
                format!("time since update must be finite and >= 0, got {s}"),
            )),
            Deleter::CovarianceTrace { threshold, mapping } => {
                if threshold.is_nan() {
                    return Err(Error::param(arg, "covariance trace threshold is NaN"));
                }
                if let Some(m) = mapping {
                    if let Some(&bad) = m.iter().find(|&&i| i >= ndim) {
                        return Err(Error::param(
                            arg,
                            format!("mapping index {bad} is outside the {ndim}-D state"),
                        ));
                    }
                }
                Ok(())
            }
            Deleter::Composite { deleters, .. } => {
                if deleters.is_empty() {
                    return Err(Error::param(arg, "a composite deleter needs deleters"));
                }
                deleters.iter().try_for_each(|d| d.validate(ndim, arg))
            }
        }
    }

    /// Whether `track` should be deleted now.
    pub fn check(&self, track: &Track) -> bool {
        let h = &track.history;
        match self {
            Deleter::Never => false,
            Deleter::StepsSinceUpdate(steps) => {
                let mut distinct = 0usize;
                let mut last = f64::NAN;
                for k in (0..h.len()).rev() {
                    if h.times[k] != last {
                        distinct += 1;
                        last = h.times[k];
                    }
                    if distinct > *steps {
                        return true;
                    }
                    if h.is_update[k] {
                        return false;
                    }
                }
                false
            }
            Deleter::TimeSinceUpdate(s) => {
                // In whole microseconds, as Stone Soup compares datetimes: 7.6 s − 2.6 s is
                // 5 s exactly there (5.000000000000001 in floats).
                let us = |t: f64| (t * 1e6).round();
                let (now, limit) = (us(track.t), us(*s));
                !(0..h.len())
                    .rev()
                    .take_while(|&k| now - us(h.times[k]) <= limit)
                    .any(|k| h.is_update[k])
            }
            Deleter::CovarianceTrace { threshold, mapping } => {
                let trace: f64 = match mapping {
                    Some(m) if !m.is_empty() => m.iter().map(|&i| track.p[(i, i)]).sum(),
                    _ => track.p.diagonal().sum(),
                };
                trace > *threshold
            }
            Deleter::Composite {
                deleters,
                intersect,
            } => {
                if *intersect {
                    deleters.iter().all(|d| d.check(track))
                } else {
                    deleters.iter().any(|d| d.check(track))
                }
            }
        }
    }
}
