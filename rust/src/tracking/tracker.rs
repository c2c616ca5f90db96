//! The multi-target tracker: Stone Soup's `MultiTargetMixtureTracker` (JPDA) and
//! `MultiTargetTracker` (GNN) with a `MultiMeasurementInitiator`, reproduced step for step.
//!
//! One [`Tracker::step`] at scan time `t` with detections `z_k` (each from a sensor with its
//! own `H`, `R`) does, in Stone Soup's order:
//! 1. predict every confirmed track to `t` (`F P Fᵀ + Q`);
//! 2. JPDA: PDA hypotheses per track — missed weight `1 − P_D P_G`, detection weight
//!    `N(z; H x⁻, S) P_D / λ` for detections with `yᵀ S⁻¹ y ≤ χ²_m(P_G)` — then exact JPDA
//!    marginals per cluster and a moment-matched Gaussian mixture of the prediction and the
//!    Kalman updates; the new state is an update if some detection's marginal exceeds the
//!    missed one, else a prediction. Detections whose marginal exceeds a track's missed
//!    marginal are "associated". With joint existence (JIPDA, [`crate::tracking::jipda`])
//!    the weights are scaled by each track's predicted existence and visibility, and the
//!    marginals conditioned on existence take their place in all of the above. GNN: distance
//!    hypotheses (`d < missed_distance`), optimal assignment, Kalman update or prediction;
//! 3. delete confirmed tracks by the deleter;
//! 4. the initiator takes the unassociated detections: its tentative tracks are predicted,
//!    GNN-associated with its own distance gate and updated, confirmed once they hold
//!    `min_points` updates, deleted by their own deleter; every detection left starts a new
//!    tentative track (`x = H⁺ z` on the mapped axes, prior elsewhere).
//!
//! All detections of a scan share the scan time. Time must not go backwards.
//!
//! Configuration types live in [`crate::tracking::config`] (re-exported here), the per-scan
//! kernels (prediction, gating, GNN) in [`crate::tracking::hypothesise`].

use crate::error::{check_finite, Error, Result};
use crate::kalman::check_covariance;
pub use crate::tracking::config::{
    Association, Confirmation, GnnParams, InitiatorConfig, JpdaParams, Measure, OutOfOrder, Sensor,
    TrackerConfig,
};
use crate::tracking::gating::chi2_quantile;
use crate::tracking::hypothesise::{gnn_step, sensors_t, Alloc, CovForm, Dets};
use crate::tracking::jpda::{clusters, Method};
use crate::tracking::track::{Entry, Track};
use nalgebra::{DMatrix, DVector, DefaultAllocator, Dim, Dyn, OMatrix, U2, U4, U6};

mod jpda_scan;

/// `ln(2π)`.
const LN_2PI: f64 = 1.837_877_066_409_345_5;

/// Result of one [`Tracker::step`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepOutcome {
    Processed,
    /// The scan was older than the previous one and [`OutOfOrder::Drop`] is set.
    Dropped,
}

/// What one [`Tracker::step`] did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepReport {
    pub outcome: StepOutcome,
    /// JPDA clusters of confirmed tracks (tracks sharing gated detections) in the scan.
    pub clusters: usize,
    /// Clusters whose marginals were approximated (belief propagation: over the
    /// `max_hypotheses` budget, or asked for by [`Method::Lbp`]).
    pub approximated_clusters: usize,
    /// Tracks in the largest cluster.
    pub largest_cluster: usize,
}

impl StepReport {
    fn of(outcome: StepOutcome, c: ClusterStats) -> Self {
        Self {
            outcome,
            clusters: c.clusters,
            approximated_clusters: c.approximated,
            largest_cluster: c.largest,
        }
    }
}

/// Cluster counts of one JPDA scan.
#[derive(Debug, Clone, Copy, Default)]
struct ClusterStats {
    clusters: usize,
    approximated: usize,
    largest: usize,
}

/// The tracker state between scans.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Tracker {
    pub(super) cfg: TrackerConfig,
    pub(super) m: usize,
    /// Confirmed, alive tracks.
    pub tracks: Vec<Track>,
    /// Tentative tracks held by the initiator.
    pub tentative: Vec<Track>,
    /// Deleted confirmed tracks, in order of deletion.
    pub deleted: Vec<Track>,
    pub(super) next_id: u64,
    pub(super) next_tentative_id: u64,
    pub(super) last_time: Option<f64>,
    pub(super) scan: i64,
    /// Number of scans dropped for being out of order.
    pub dropped_scans: usize,
    /// Detections that started no tentative track because of `max_new_tentative`.
    pub capped_detections: usize,
    /// JPDA clusters approximated so far (see [`StepReport::approximated_clusters`]).
    pub approximated_clusters: usize,
    pub(super) gate: f64,
    /// Per-scan work kept between scans (not saved: rebuilt on demand).
    #[serde(skip)]
    pub(super) scratch: crate::tracking::initiator::Scratch,
}

impl Tracker {
    /// Checks the configuration and builds an empty tracker.
    pub fn new(cfg: TrackerConfig) -> Result<Self> {
        cfg.validate()?;
        let m = cfg.sensors[0].m();
        let gate = match &cfg.association {
            Association::Jpda(j) => chi2_quantile(j.prob_gate, m)?,
            Association::Gnn(_) => f64::INFINITY,
        };
        Ok(Self {
            cfg,
            m,
            tracks: Vec::new(),
            tentative: Vec::new(),
            deleted: Vec::new(),
            next_id: 0,
            next_tentative_id: 0,
            last_time: None,
            scan: 0,
            dropped_scans: 0,
            capped_detections: 0,
            approximated_clusters: 0,
            gate,
            scratch: Default::default(),
        })
    }

    /// The whole tracker (configuration, tracks with their histories, counters) as bytes
    /// (CBOR; floats bit-exact), for [`Tracker::from_bytes`].
    pub fn to_bytes(&self) -> Result<Vec<u8>> {
        let mut out = Vec::new();
        ciborium::into_writer(self, &mut out).map_err(|e| Error::param("tracker", e))?;
        Ok(out)
    }

    /// A tracker from [`Tracker::to_bytes`]; it continues exactly as the one saved. Bytes that
    /// are not such a tracker, or whose configuration does not validate, are an
    /// `InvalidParameter` error naming `state`.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        let t: Self = ciborium::from_reader(bytes)
            .map_err(|e| Error::param("state", format!("not a saved tracker ({e})")))?;
        t.cfg.validate()?;
        Ok(t)
    }

    /// Removes and returns the deleted confirmed tracks kept so far (their histories are then
    /// the caller's; memory stays bounded in long runs).
    pub fn drain_deleted(&mut self) -> Vec<Track> {
        std::mem::take(&mut self.deleted)
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.cfg
    }

    /// Reserves room for `entries` more history entries on every track (clones shrink
    /// capacity to fit; benchmarks of one scan on a cloned tracker use this).
    pub fn reserve_history(&mut self, entries: usize) {
        for t in self.tracks.iter_mut().chain(self.tentative.iter_mut()) {
            t.history.reserve(entries, t.x.len());
        }
    }

    /// Measurement dimension shared by all sensors.
    pub fn measurement_dim(&self) -> usize {
        self.m
    }

    /// Time of the last processed scan.
    pub fn last_time(&self) -> Option<f64> {
        self.last_time
    }

    /// Registers one more sensor between scans (its detections use index
    /// `self.config().sensors.len()` before the call); tracks are untouched. The sensor must
    /// fit the state dimension (see [`Sensor::new`]) and share the measurement dimension of
    /// the configured sensors. Returns the new sensor's index.
    pub fn add_sensor(&mut self, sensor: Sensor) -> Result<usize> {
        let n = self.cfg.motion_model.ndim();
        let i = self.cfg.sensors.len();
        if sensor.h.ncols() != n {
            return Err(Error::dim(
                "measurement_matrix",
                format!("{n} columns (state dimension)"),
                sensor.h.ncols(),
            ));
        }
        if sensor.m() != self.m {
            return Err(Error::dim(
                "measurement_matrix",
                format!(
                    "{} rows (all sensors share one measurement dimension)",
                    self.m
                ),
                sensor.m(),
            ));
        }
        self.cfg.sensors.push(sensor);
        if let Err(e) = self.cfg.validate_polar() {
            self.cfg.sensors.pop();
            return Err(e);
        }
        Ok(i)
    }

    /// Adds a confirmed track with state `x`, covariance `p` at time `t` (its first state is a
    /// prior, not an update). Returns its id.
    pub fn add_track(&mut self, x: &[f64], p: &[f64], t: f64) -> Result<u64> {
        self.add_track_with(x, p, t, None)
    }

    /// [`Tracker::add_track`] with the track's existence and visibility probabilities
    /// `(r, v)` (`r` in (0, 1], `v` in [0, 1]; needs an existence model). `None`: the model's
    /// `initial` existence, visible.
    pub fn add_track_with(
        &mut self,
        x: &[f64],
        p: &[f64],
        t: f64,
        existence: Option<(f64, f64)>,
    ) -> Result<u64> {
        if let Some((r, v)) = existence {
            if self.cfg.existence.is_none() {
                return Err(Error::param(
                    "existence",
                    "needs a tracker with an existence model",
                ));
            }
            if !(r > 0.0 && r <= 1.0) {
                return Err(Error::param(
                    "existence",
                    format!("must be in (0, 1], got {r}"),
                ));
            }
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::param(
                    "visibility",
                    format!("must be in [0, 1], got {v}"),
                ));
            }
        }
        let n = self.cfg.motion_model.ndim();
        if x.len() != n {
            return Err(Error::dim("state", n, x.len()));
        }
        if p.len() != n * n {
            return Err(Error::dim("covariance", format!("({n}, {n})"), p.len()));
        }
        check_finite("state", x)?;
        check_finite("time", &[t])?;
        check_covariance("covariance", p, n, false)?;
        let id = self.next_id;
        self.next_id += 1;
        let mut tr = Track::new(
            id,
            DVector::from_column_slice(x),
            DMatrix::from_row_slice(n, n, p),
            Entry {
                time: t,
                is_update: false,
                scan: self.scan - 1,
                sensor: -1,
                detection: -1,
                nis: f64::NAN,
                missed_probability: f64::NAN,
                assoc: vec![],
            },
        );
        tr.confirmed_time = t;
        tr.existence = existence;
        self.tracks.push(tr);
        Ok(id)
    }

    /// Processes one scan: detections `z` (`(k, m)` row-major) from sensors `sensor_ids`
    /// (`(k,)`) at time `t` seconds, each with its sensor's noise `R`. An empty scan only
    /// predicts.
    pub fn step(&mut self, t: f64, z: &[f64], sensor_ids: &[usize]) -> Result<StepReport> {
        self.step_with(t, z, sensor_ids, None, None)
    }

    /// [`Tracker::step`] with a measurement noise covariance per detection: `covariances`
    /// `(k, m, m)` row-major (measurement units squared), symmetric positive definite, in place
    /// of the sensor's `R` for gating, the PDA/distance hypotheses, the Kalman updates of
    /// confirmed and tentative tracks, and the start of a tentative track (unless the sensor has
    /// its own initiation noise; Stone Soup: a detection's own `measurement_model` is used by
    /// every component, `SimpleMeasurementInitiator` included). `None`: the sensors' `R`.
    ///
    /// `origins` `(k, 2)` row-major: the position of the sensor that made each detection, in
    /// the state's mapped position coordinates (e.g. own-ship north, east in metres), used by
    /// range–bearing sensors (ignored for linear ones); `None`: every sensor at `(0, 0)`.
    pub fn step_with(
        &mut self,
        t: f64,
        z: &[f64],
        sensor_ids: &[usize],
        covariances: Option<&[f64]>,
        origins: Option<&[f64]>,
    ) -> Result<StepReport> {
        self.step_interruptible(t, z, sensor_ids, covariances, origins, &mut || false)
    }

    /// [`Tracker::step_with`] that calls `interrupt` between JPDA clusters and stops with
    /// [`Error::Interrupted`] when it returns true; the tracker is then left as it was before
    /// the scan (association computes before any track changes).
    pub fn step_interruptible(
        &mut self,
        t: f64,
        z: &[f64],
        sensor_ids: &[usize],
        covariances: Option<&[f64]>,
        origins: Option<&[f64]>,
        interrupt: &mut dyn FnMut() -> bool,
    ) -> Result<StepReport> {
        let m = self.m;
        check_finite("t", &[t])?;
        if z.len() != sensor_ids.len() * m {
            return Err(Error::dim(
                "measurements",
                format!("{} x {m} values (one row per sensor id)", sensor_ids.len()),
                z.len(),
            ));
        }
        check_finite("measurements", z)?;
        if let Some(c) = covariances {
            let k = sensor_ids.len();
            if c.len() != k * m * m {
                return Err(Error::dim(
                    "covariances",
                    format!("({k}, {m}, {m}) values (one matrix per measurement row)"),
                    c.len(),
                ));
            }
            for (i, ci) in c.chunks(m * m).enumerate() {
                check_covariance(&format!("covariances[{i}]"), ci, m, true)?;
            }
        }
        if let Some(o) = origins {
            if o.len() != 2 * sensor_ids.len() {
                return Err(Error::dim(
                    "origins",
                    format!("({}, 2) values (one per measurement row)", sensor_ids.len()),
                    o.len(),
                ));
            }
            check_finite("origins", o)?;
        }
        if let Some(pos) = sensor_ids.iter().position(|&s| s >= self.cfg.sensors.len()) {
            return Err(Error::param(
                "sensor_ids",
                format!(
                    "element {pos} is {}, but only {} sensors are configured",
                    sensor_ids[pos],
                    self.cfg.sensors.len()
                ),
            ));
        }
        if let Some(lt) = self.last_time {
            if t < lt {
                return match self.cfg.out_of_order {
                    OutOfOrder::Drop => {
                        self.dropped_scans += 1;
                        Ok(StepReport::of(
                            StepOutcome::Dropped,
                            ClusterStats::default(),
                        ))
                    }
                    OutOfOrder::Raise => Err(Error::Order {
                        arg: "t".into(),
                        reason: format!("scan time {t} is before the previous scan time {lt}"),
                    }),
                };
            }
        }
        let nd = self.cfg.motion_model.ndim();
        let (zc, i) = ((z, covariances, origins), interrupt);
        let stats = match (nd, m) {
            (4, 2) => self.step_dims((U4, U2), t, sensor_ids, zc, i)?,
            (6, 2) => self.step_dims((U6, U2), t, sensor_ids, zc, i)?,
            _ => self.step_dims((Dyn(nd), Dyn(m)), t, sensor_ids, zc, i)?,
        };
        self.approximated_clusters += stats.approximated;
        self.last_time = Some(t);
        self.scan += 1;
        Ok(StepReport::of(StepOutcome::Processed, stats))
    }

    /// The scan in the kernels' dimensions (state `N`, measurement `M`).
    fn step_dims<N: Dim, M: Dim>(
        &mut self,
        dims: (N, M),
        t: f64,
        sensor_ids: &[usize],
        (z, covariances, origins): (&[f64], Option<&[f64]>, Option<&[f64]>),
        interrupt: &mut dyn FnMut() -> bool,
    ) -> Result<ClusterStats>
    where
        DefaultAllocator: Alloc<N, M>,
    {
        let k = sensor_ids.len();
        let all: Vec<usize> = (0..k).collect();
        let sensors = sensors_t(&self.cfg.sensors, dims.0, dims.1);
        let md = dims.1;
        let covs: Option<Vec<OMatrix<f64, M, M>>> = covariances.map(|c| {
            c.chunks(self.m * self.m)
                .map(|ci| OMatrix::<f64, M, M>::from_row_slice_generic(md, md, ci))
                .collect()
        });
        let dets = Dets {
            z,
            sensor: sensor_ids,
            covs: covs.as_deref(),
            origins,
        };
        let mut stats = ClusterStats::default();
        let associated = match self.cfg.association {
            Association::Jpda(j) => {
                let (a, s) = self.step_jpda(t, &dets, &all, &j, &sensors, dims, interrupt)?;
                stats = s;
                a
            }
            Association::Gnn(g) => {
                let model = self.cfg.motion_model.clone();
                let assoc = gnn_step(
                    &mut self.tracks,
                    &model,
                    &sensors,
                    &g,
                    CovForm {
                        joseph: self.cfg.use_joseph_cov,
                        symmetric: self.cfg.symmetric_covariance,
                    },
                    t,
                    &dets,
                    dims,
                    &all,
                    self.scan,
                    self.cfg.imm.as_ref(),
                    None,
                )?;
                let mut associated = vec![false; k];
                for d in assoc.into_iter().flatten() {
                    associated[d] = true;
                }
                associated
            }
        };
        // Delete confirmed tracks (in place: surviving tracks are not moved unless a track
        // before them is deleted).
        let mut i = 0;
        while i < self.tracks.len() {
            let gone = match (&self.cfg.existence, self.tracks[i].existence) {
                (Some(e), Some((r, _))) => r < e.delete,
                _ => false,
            };
            if gone || self.cfg.deleter.check(&self.tracks[i]) {
                let mut tr = self.tracks.remove(i);
                if self.cfg.delete_last_prediction {
                    tr.drop_last_prediction();
                }
                tr.deleted_time = t;
                self.deleted.push(tr);
                if let Some(cap) = self.cfg.max_deleted {
                    if self.deleted.len() > cap {
                        let extra = self.deleted.len() - cap;
                        self.deleted.drain(..extra);
                    }
                }
            } else {
                i += 1;
            }
        }
        let free: Vec<usize> = (0..k).filter(|&d| !associated[d]).collect();
        self.initiate(t, &dets, &free, &sensors, dims)?;
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::MotionModel;
    use crate::tracking::track::Deleter;

    /// Code 5.7 with faster targets: q = 0.01, σ = 0.5 m, prior velocity variance 1, a 3σ
    /// initiation gate, tentative tracks deleted after 2 steps, 3 steps for confirmed ones.
    fn config(assoc: Association) -> TrackerConfig {
        let mut c = TrackerConfig::code_5_7();
        c.motion_model = MotionModel::constant_velocity_2d(0.01).unwrap();
        c.sensors[0].r = DMatrix::identity(2, 2) * 0.25;
        c.sensors[0].init.1 = c.sensors[0].r.clone();
        c.association = assoc;
        c.deleter = Deleter::StepsSinceUpdate(3);
        let init = &mut c.initiator;
        init.prior_covariance =
            DMatrix::from_diagonal(&DVector::from_vec(vec![0.0, 1.0, 0.0, 1.0]));
        init.deleter = Deleter::StepsSinceUpdate(2);
        init.gnn.missed_distance = 3.0;
        c
    }

    fn run(assoc: Association) -> Tracker {
        let mut tr = Tracker::new(config(assoc)).unwrap();
        for k in 0..20 {
            let t = k as f64;
            let z = [t, 0.0, t, 50.0, 100.0 - t, 20.0];
            tr.step(t, &z, &[0, 0, 0]).unwrap();
        }
        tr
    }

    #[test]
    fn jpda_and_gnn_track_three_targets() {
        let jpda = Association::Jpda(JpdaParams {
            prob_detect: 0.9,
            prob_gate: 0.99,
            clutter_density: Some(1e-3),
            include_all: false,
            method: Method::Ehm,
            max_hypotheses: None,
        });
        let gnn = Association::Gnn(GnnParams {
            measure: Measure::Mahalanobis,
            missed_distance: 5.0,
            include_all: false,
        });
        for a in [jpda, gnn] {
            let tr = run(a);
            assert_eq!(tr.tracks.len(), 3);
            assert!(tr.tentative.is_empty());
            for t in &tr.tracks {
                assert!((t.x[1].abs() - 1.0).abs() < 0.1 || t.x[1].abs() < 0.1);
            }
        }
    }

    #[test]
    fn time_backwards_is_an_error_or_dropped() {
        let gnn = Association::Gnn(GnnParams {
            measure: Measure::Mahalanobis,
            missed_distance: 5.0,
            include_all: false,
        });
        let mut tr = Tracker::new(config(gnn)).unwrap();
        tr.step(1.0, &[], &[]).unwrap();
        assert!(matches!(tr.step(0.5, &[], &[]), Err(Error::Order { .. })));
        let mut c = config(gnn);
        c.out_of_order = OutOfOrder::Drop;
        let mut tr = Tracker::new(c).unwrap();
        tr.step(1.0, &[], &[]).unwrap();
        assert_eq!(
            tr.step(0.5, &[], &[]).unwrap().outcome,
            StepOutcome::Dropped
        );
        assert_eq!(tr.dropped_scans, 1);
    }
}
