//! The batch driver: a whole recording through [`Tracker::step_interruptible`] in one call,
//! with the confirmed tracks after every scan gathered into flat, row-major arrays.

use crate::error::{Error, Result};
use crate::tracking::tracker::{StepOutcome, Tracker};

/// A recording: detection rows `z` `(d, m)` row-major, each with its sensor, its scan
/// (index into `times`), and optionally its own noise covariance `(d, m, m)` and sensor
/// origin `(d, 2)` (see [`Tracker::step_with`]).
#[derive(Debug, Clone, Copy)]
pub struct RunInput<'a> {
    /// Scan times, seconds, `(s,)`.
    pub times: &'a [f64],
    pub z: &'a [f64],
    pub sensor_ids: &'a [usize],
    pub scan_index: &'a [usize],
    pub covariances: Option<&'a [f64]>,
    pub origins: Option<&'a [f64]>,
}

/// The confirmed tracks after every scan, one row per (scan, track), flat and row-major.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunOutput {
    /// Scan index of each row.
    pub scan: Vec<i64>,
    pub track_id: Vec<i64>,
    /// Time of the track's state, seconds.
    pub time: Vec<f64>,
    /// States `(rows, ndim)`.
    pub state: Vec<f64>,
    /// Covariances `(rows, ndim, ndim)`.
    pub covariance: Vec<f64>,
    /// Whether the state is an update with a detection.
    pub is_update: Vec<bool>,
    /// Scans dropped as out of order.
    pub dropped_scans: Vec<i64>,
    /// JPDA clusters approximated in each scan `(s,)` (0 for dropped scans).
    pub approximated_clusters: Vec<i64>,
}

impl RunInput<'_> {
    fn check(&self, m: usize) -> Result<()> {
        let nd = self.sensor_ids.len();
        if self.z.len() != nd * m {
            return Err(Error::dim(
                "measurements",
                format!("{nd} x {m} values (one row per sensor id)"),
                self.z.len(),
            ));
        }
        if self.scan_index.len() != nd {
            return Err(Error::dim(
                "scan_index",
                format!("{nd} entries, one per measurement row"),
                self.scan_index.len(),
            ));
        }
        if let Some(o) = self.origins {
            if o.len() != nd * 2 {
                return Err(Error::dim(
                    "origins",
                    format!("({nd}, 2) values, one sensor position per measurement row"),
                    o.len(),
                ));
            }
        }
        if let Some(c) = self.covariances {
            if c.len() != nd * m * m {
                return Err(Error::dim(
                    "covariances",
                    format!("({nd}, {m}, {m}) values, one matrix per measurement row"),
                    c.len(),
                ));
            }
        }
        if let Some(p) = self.scan_index.iter().position(|&s| s >= self.times.len()) {
            return Err(Error::param(
                "scan_index",
                format!(
                    "element {p} is {}, but there are {} scans",
                    self.scan_index[p],
                    self.times.len()
                ),
            ));
        }
        Ok(())
    }
}

impl Tracker {
    /// Runs a whole recording: scan `i` at `times[i]` holds the rows with `scan_index == i`
    /// (in their order). `interrupt` is called between scans and between JPDA clusters; when
    /// it returns true the run stops with [`Error::Interrupted`] (scans before it stay
    /// applied). Errors about a detection name its row of the whole run.
    pub fn run(
        &mut self,
        input: &RunInput<'_>,
        interrupt: &mut dyn FnMut() -> bool,
    ) -> Result<RunOutput> {
        let m = self.measurement_dim();
        input.check(m)?;
        let nd = input.sensor_ids.len();
        let mm = m * m;
        let mut order: Vec<usize> = (0..nd).collect();
        order.sort_by_key(|&i| input.scan_index[i]);
        let mut out = RunOutput::default();
        let (mut zs, mut ss, mut cs, mut os) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let mut p = 0;
        for (i, &ti) in input.times.iter().enumerate() {
            zs.clear();
            ss.clear();
            cs.clear();
            os.clear();
            let first_row = p;
            while p < nd && input.scan_index[order[p]] == i {
                let d = order[p];
                zs.extend_from_slice(&input.z[d * m..(d + 1) * m]);
                ss.push(input.sensor_ids[d]);
                if let Some(c) = input.covariances {
                    cs.extend_from_slice(&c[d * mm..(d + 1) * mm]);
                }
                if let Some(o) = input.origins {
                    os.extend_from_slice(&o[2 * d..2 * d + 2]);
                }
                p += 1;
            }
            let ci = input.covariances.map(|_| cs.as_slice());
            let oi = input.origins.map(|_| os.as_slice());
            if interrupt() {
                return Err(Error::Interrupted);
            }
            let rep = self
                .step_interruptible(ti, &zs, &ss, ci, oi, interrupt)
                .map_err(|e| whole_run_row(e, &order, first_row))?;
            out.approximated_clusters
                .push(rep.approximated_clusters as i64);
            if rep.outcome == StepOutcome::Dropped {
                out.dropped_scans.push(i as i64);
                continue;
            }
            for tr in &self.tracks {
                out.scan.push(i as i64);
                out.track_id.push(tr.id as i64);
                out.time.push(tr.t);
                out.state.extend(tr.x.iter());
                out.covariance.extend(tr.p.transpose().iter());
                out.is_update
                    .push(tr.history.is_update.last().copied().unwrap_or(false));
            }
        }
        Ok(out)
    }
}

/// Renames `covariances[r]` (row `r` of a scan starting at sorted position `first_row`) to the
/// row of the whole run.
fn whole_run_row(e: Error, order: &[usize], first_row: usize) -> Error {
    match e {
        Error::NotPositiveDefinite { arg, reason } => {
            let row = arg
                .strip_prefix("covariances[")
                .and_then(|r| r.strip_suffix(']'))
                .and_then(|r| r.parse::<usize>().ok())
                .and_then(|r| order.get(first_row + r));
            match row {
                Some(r) => Error::NotPositiveDefinite {
                    arg: format!("covariances[{r}]"),
                    reason,
                },
                None => Error::NotPositiveDefinite { arg, reason },
            }
        }
        e => e,
    }
}
