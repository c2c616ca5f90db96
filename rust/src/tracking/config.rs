//! Configuration of the multi-target tracker: sensors, association (JPDA / GNN), initiator,
//! deleters and policies, with their validation. See [`crate::tracking::tracker`] for the step.

use crate::error::{check_finite, Error, Result};
use crate::kalman::check_covariance;
use crate::models::MotionModel;
use crate::tracking::jpda::Method;
use crate::tracking::track::Deleter;
use nalgebra::{DMatrix, DVector};

/// A sensor's linear-Gaussian measurement model `z = H x + w`, `w ~ N(0, R)`.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct Sensor {
    /// `H`, `(m, ndim)`.
    pub h: DMatrix<f64>,
    /// `R`, `(m, m)`, positive definite.
    pub r: DMatrix<f64>,
    /// The model the initiator uses to start tentative tracks from this sensor's detections
    /// (`H`, `R`); defaults to `(h, r)`.
    pub init: (DMatrix<f64>, DMatrix<f64>),
    /// Whether the initiation noise was given (then it starts tracks even from detections with
    /// their own covariance).
    pub init_noise_given: bool,
    /// A range–bearing sensor: measurements `(φ, ρ)` (rad, m) of the mapped positions, `r` in
    /// rad², m²; `h` (and the initiation `H`) then only select the mapped positions. `None`:
    /// linear `z = H x + w`.
    pub polar: Option<crate::tracking::polar::Polar>,
    /// Whether this sensor's detections left over after association start tentative tracks
    /// (`true`, Stone Soup's initiator). `false`: they only update existing tracks, tentative
    /// ones included (e.g. a detector's low-score boxes beside its high-score ones, the
    /// two-threshold association of ByteTrack, Zhang et al. 2022).
    #[serde(default = "starts_tracks_default")]
    pub starts_tracks: bool,
}

fn starts_tracks_default() -> bool {
    true
}

impl Sensor {
    /// Builds and checks a sensor for an `ndim`-state model; the initiation model's `H` and
    /// `R` default to `h` and `r`.
    pub fn new(
        h: DMatrix<f64>,
        r: DMatrix<f64>,
        init_h: Option<DMatrix<f64>>,
        init_r: Option<DMatrix<f64>>,
        ndim: usize,
        arg: &str,
    ) -> Result<Self> {
        let check = |h: &DMatrix<f64>, r: &DMatrix<f64>, what: &str| -> Result<()> {
            if h.ncols() != ndim || h.nrows() == 0 {
                return Err(Error::dim(
                    &format!("{arg}.{what}measurement_matrix"),
                    format!("shape (m, {ndim})"),
                    format!("({}, {})", h.nrows(), h.ncols()),
                ));
            }
            let m = h.nrows();
            if r.shape() != (m, m) {
                return Err(Error::dim(
                    &format!("{arg}.{what}measurement_noise"),
                    format!("shape ({m}, {m})"),
                    format!("({}, {})", r.nrows(), r.ncols()),
                ));
            }
            check_finite(&format!("{arg}.{what}measurement_matrix"), h.as_slice())?;
            let rm: Vec<f64> = r.transpose().as_slice().to_vec();
            check_covariance(&format!("{arg}.{what}measurement_noise"), &rm, m, true)
        };
        check(&h, &r, "")?;
        let init_noise_given = init_r.is_some();
        let init = (
            init_h.unwrap_or_else(|| h.clone()),
            init_r.unwrap_or_else(|| r.clone()),
        );
        check(&init.0, &init.1, "initiation_")?;
        if init.0.nrows() != h.nrows() {
            return Err(Error::dim(
                &format!("{arg}.initiation_measurement_matrix"),
                format!("{} rows like measurement_matrix", h.nrows()),
                init.0.nrows(),
            ));
        }
        Ok(Self {
            h,
            r,
            init,
            init_noise_given,
            polar: None,
            starts_tracks: true,
        })
    }

    /// A range–bearing sensor observing state positions `mapping` of an `ndim`-state model
    /// with noise `r` (rad², m²; Stone Soup's `CartesianToBearingRange` with `noise_covar`)
    /// and the initiation noise `init_r` (default `r`).
    pub fn polar(
        polar: crate::tracking::polar::Polar,
        r: DMatrix<f64>,
        init_r: Option<DMatrix<f64>>,
        ndim: usize,
        arg: &str,
    ) -> Result<Self> {
        let [i, j] = polar.mapping;
        if i >= ndim || j >= ndim || i == j {
            return Err(Error::param(
                &format!("{arg}.mapping"),
                format!("needs two distinct state indices < {ndim}, got ({i}, {j})"),
            ));
        }
        if let crate::tracking::polar::PolarUpdate::Unscented { alpha, beta, kappa } = polar.update
        {
            if !(alpha > 0.0 && alpha.is_finite() && beta.is_finite())
                || kappa.is_some_and(|k| !k.is_finite() || ndim as f64 + k <= 0.0)
            {
                return Err(Error::param(
                    &format!("{arg}.update"),
                    format!(
                        "unscented parameters need alpha > 0, finite beta and ndim + kappa > 0, \
                         got alpha={alpha}, beta={beta}, kappa={kappa:?}"
                    ),
                ));
            }
        }
        let mut h = DMatrix::zeros(2, ndim);
        h[(0, i)] = 1.0;
        h[(1, j)] = 1.0;
        let mut s = Self::new(h, r, None, init_r, ndim, arg)?;
        s.polar = Some(polar);
        Ok(s)
    }

    /// Measurement dimension `m`.
    pub fn m(&self) -> usize {
        self.h.nrows()
    }
}

/// How a distance hypothesiser scores a detection (Stone Soup measures).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Measure {
    /// `sqrt(yᵀ S⁻¹ y)`.
    Mahalanobis,
    /// `yᵀ S⁻¹ y`.
    SquaredMahalanobis,
}

/// Distance hypotheses + GNN (`DistanceHypothesiser` + `GNNWith2DAssignment`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GnnParams {
    pub measure: Measure,
    /// Detections at `distance >= missed_distance` are not hypothesised; a missed detection
    /// costs `missed_distance` in the assignment. May be `+inf`.
    pub missed_distance: f64,
    /// Hypothesise every detection whatever its distance.
    pub include_all: bool,
}

/// PDA hypotheses + JPDA (`PDAHypothesiser` + `JPDA`/`JPDAwithEHM`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JpdaParams {
    /// `P_D` in (0, 1].
    pub prob_detect: f64,
    /// `P_G` in (0, 1].
    pub prob_gate: f64,
    /// Clutter spatial density `λ` (per measurement-space unit volume); `None`: Stone Soup's
    /// estimate from the validation-region volume and the number of gated detections.
    pub clutter_density: Option<f64>,
    /// Keep detections outside the gate (needs `clutter_density`).
    pub include_all: bool,
    pub method: Method,
    /// Per-cluster budget of the exact method (EHM: edges of its net, i.e. single-track
    /// hypotheses summed over its levels, times the 64-bit words of a node key, one per 64
    /// detections of the cluster — its memory and work; brute force: joint hypotheses). A cluster past it gets belief-propagation marginals
    /// ([`crate::tracking::jpda::marginals_lbp`]) and is counted in [`crate::tracking::tracker::StepReport`].
    /// `None`: always exact (unbounded).
    pub max_hypotheses: Option<usize>,
}

/// The association of confirmed tracks.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Association {
    Jpda(JpdaParams),
    Gnn(GnnParams),
}

/// How tentative tracks are confirmed.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Confirmation {
    /// Confirmed once the track holds `min_points` updates (or states when `updates_only` is
    /// false); dropped by the initiator's deleter (Stone Soup's `MultiMeasurementInitiator`).
    MinPoints {
        min_points: usize,
        updates_only: bool,
    },
    /// Confirmed once `m` of its first `n` states are updates; dropped after `n` states
    /// without confirmation.
    MOfN { m: usize, n: usize },
}

/// The multi-measurement initiator.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct InitiatorConfig {
    /// Prior state `(ndim,)`; its mapped entries are replaced by `H⁺ z`.
    pub prior_state: DVector<f64>,
    /// Prior covariance; mapped rows/columns are replaced by `H⁺ R H⁺ᵀ`.
    pub prior_covariance: DMatrix<f64>,
    /// Added to the diagonal of new covariances.
    pub diag_load: f64,
    pub confirmation: Confirmation,
    /// Deleter of tentative tracks (ignored under M-of-N).
    pub deleter: Deleter,
    /// Gate and assignment of tentative tracks.
    pub gnn: GnnParams,
    /// Motion model of tentative tracks (`None`: the tracker's).
    pub motion_model: Option<MotionModel>,
    /// Joseph-form covariance in the initiator's updater.
    pub use_joseph_cov: bool,
    /// Symmetrise the initiator updater's posterior covariances.
    pub symmetric_covariance: bool,
    /// At most this many new tentative tracks per scan (the first free detections in scan
    /// order; the others are counted in `Tracker::capped_detections`): a clutter burst then
    /// costs O(plots) and leaves no flood of tentative tracks. `None`: no cap.
    pub max_new_tentative: Option<usize>,
    /// Run the tracker's IMM bank ([`TrackerConfig::imm`], which it needs) on the tentative
    /// tracks too: each starts every mode at its initiation Gaussian (prior and `H⁺ z`) with
    /// the bank's `initial` probabilities, and every scan mixes, predicts each mode, updates
    /// it with the track's GNN detection (mode likelihoods `N(z; ẑ_j, S_j)`; a missed scan
    /// keeps `μ = c̄`) and combines; gating and the GNN use the combined prediction. A
    /// confirmed track keeps its modes and probabilities. `false`: tentative tracks use
    /// `motion_model` (or the tracker's) and a confirmed track starts every mode at its state.
    #[serde(default)]
    pub imm: bool,
}

/// Track existence with visibility for confirmed JPDA tracks (IPDA of Mušicki, Evans and
/// Stanković 1994, with the visibility chain of the VIMMJIPDA of Brekke and co-workers): per
/// track the probability `r` that the target exists and `v` that it is visible (detectable)
/// given it exists. Each scan: `r⁻ = survival · r`, `v⁻ = v·vis_stay + (1 − v)(1 − invis_stay)`;
/// with the scan's likelihood ratio `L = 1 − P_D P_G + Σ_i P_D N(z_i; ẑ, S) / λ` over the
/// track's gated detections, `r⁺ ∝ r⁻ (v⁻ L + 1 − v⁻)` against `1 − r⁻`, and
/// `v⁺ = v⁻ L / (v⁻ L + 1 − v⁻)`. A confirmed track starts at `initial` (visible) and is deleted
/// when `r < delete` (besides the deleter). Per track (IPDA) unless `joint`.
///
/// With `joint` (JIPDA, [`crate::tracking::jipda`]): the JPDA association of confirmed tracks
/// weights each track by `r⁻v⁻` (missed `1 − P_D P_G r⁻v⁻`, detection `r⁻v⁻ P_D N(z; ẑ, S)/λ`),
/// and `r⁺`, `v⁺` and the state (given existence) follow from the cluster's joint marginals;
/// a track alone in its cluster gets the same `r⁺`, `v⁺` as without `joint`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Existence {
    pub survival: f64,
    pub initial: f64,
    pub delete: f64,
    pub vis_stay: f64,
    pub invis_stay: f64,
    /// Confirmation by existence: a tentative track (starting at `birth`, updated with its
    /// single GNN detection, `L = 1 − P_D P_G + P_D N(z)/λ`) is confirmed once the initiator
    /// would confirm it and `r ≥ confirm`, and dropped once `r < delete`; it keeps its `r`.
    pub confirm: Option<f64>,
    pub birth: f64,
    /// Joint existence (JIPDA) for confirmed tracks; `false`: per track (IPDA). Tentative
    /// tracks (GNN) always use the per-track update.
    #[serde(default)]
    pub joint: bool,
}

impl Existence {
    /// The prediction `(r⁻, v⁻)` of `(r, v)` over one scan: `r⁻ = survival · r`,
    /// `v⁻ = v · vis_stay + (1 − v)(1 − invis_stay)`.
    pub fn predict(&self, (r, v): (f64, f64)) -> (f64, f64) {
        let r0 = self.survival * r;
        let v0 = v * self.vis_stay + (1.0 - v) * (1.0 - self.invis_stay);
        (r0, v0)
    }

    /// One scan of the existence/visibility recursion from `(r, v)` with the scan's
    /// log-likelihood ratio `ln L` (computed in the log domain).
    pub fn update(&self, rv: (f64, f64), ln_l: f64) -> (f64, f64) {
        let (r0, v0) = self.predict(rv);
        let a = v0.ln() + ln_l; // ln(v0 L)
        let b = (1.0 - v0).ln(); // ln(1 − v0)
        let m2 = a.max(b);
        let ln_ev = m2 + ((a - m2).exp() + (b - m2).exp()).ln(); // ln(v0 L + 1 − v0)
        let num = r0.ln() + ln_ev;
        let other = (1.0 - r0).ln();
        let m3 = num.max(other);
        let r1 = (num - m3).exp() / ((num - m3).exp() + (other - m3).exp());
        let v1 = (a - ln_ev).exp();
        (r1.clamp(0.0, 1.0), v1.clamp(0.0, 1.0))
    }
}

/// What to do with a scan older than the previous one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum OutOfOrder {
    /// Fail with [`Error::Order`].
    Raise,
    /// Ignore the scan and count it.
    Drop,
}

/// The whole tracker configuration.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TrackerConfig {
    pub motion_model: MotionModel,
    pub sensors: Vec<Sensor>,
    pub association: Association,
    /// Joseph-form covariance in the updater (Stone Soup's `use_joseph_cov`; default form is
    /// `P − K S Kᵀ`).
    pub use_joseph_cov: bool,
    /// Replace every updated covariance `P` by `(P + Pᵀ) / 2` (Stone Soup's
    /// `force_symmetric_covariance`). Without it the rounding asymmetry of `P − K S Kᵀ` is
    /// never removed and grows through the prediction `F P Fᵀ` — polynomially in the coasting
    /// time for constant-acceleration models, until `P` is indefinite after a few hundred
    /// seconds (Joyride with a CA model fails at t ≈ 400 s).
    pub symmetric_covariance: bool,
    pub deleter: Deleter,
    /// Drop the last state of a deleted track if it is a prediction (`delete_last_pred`).
    pub delete_last_prediction: bool,
    pub initiator: InitiatorConfig,
    pub out_of_order: OutOfOrder,
    /// An IMM bank for the confirmed tracks (`None`: `motion_model` alone). Tentative tracks
    /// use the initiator's model and a confirmed track starts every mode at its state, unless
    /// [`InitiatorConfig::imm`] runs the bank in the initiator too.
    pub imm: Option<crate::tracking::imm::ImmConfig>,
    /// Existence and visibility of confirmed tracks (JPDA only; `None`: not modelled).
    pub existence: Option<Existence>,
    /// Keep at most this many deleted tracks (the oldest are dropped; take them earlier with
    /// `Tracker::drain_deleted`). `None`: keep all.
    pub max_deleted: Option<usize>,
    /// Stone Soup passes detections to the initiator unless some track's marginal for them
    /// exceeds its missed marginal (`true`). With `false` (native option against duplicate
    /// tracks on one target): detections inside any confirmed track's gate are withheld too,
    /// and a tentative track about to be confirmed is dropped when its position lies inside the
    /// gate of a confirmed track or of a track confirmed before it in the same scan.
    pub initiate_in_gates: bool,
}

impl TrackerConfig {
    /// The thesis's Code 5.7 tracker (the Stone Soup multi-target JPDA example it follows):
    /// constant velocity `q = 0.001` m² s⁻³ on `[n, v_n, e, v_e]`; one position sensor
    /// `σ = 0.25` m (`R = 0.0625 I`, m²); JPDA with `P_D = 0.85`, `P_G = 0.95`,
    /// `λ = 0.125` m⁻², exact EHM marginals (no budget); confirmed tracks deleted when the
    /// covariance trace exceeds 1.5 or after 35 steps without an update; a multi-measurement
    /// initiator with prior `diag(0, 0.3, 0, 0.3)`, confirmation after 2 updates, tentative
    /// tracks deleted after 3 steps without one, GNN gate `missed_distance = 0.3`
    /// (Mahalanobis). Stone Soup's other defaults: `P − K S Kᵀ` updates without
    /// symmetrisation, detections in confirmed tracks' gates offered to the initiator, scans
    /// out of time order an error, no IMM, no existence, every deleted track kept.
    pub fn code_5_7() -> Self {
        let mut h = DMatrix::zeros(2, 4);
        h[(0, 0)] = 1.0;
        h[(1, 2)] = 1.0;
        let r = DMatrix::identity(2, 2) * 0.0625;
        let sensor = Sensor {
            init: (h.clone(), r.clone()),
            h,
            r,
            init_noise_given: false,
            polar: None,
            starts_tracks: true,
        };
        let no_symmetry = false;
        Self {
            motion_model: MotionModel::constant_velocity_2d(0.001)
                .unwrap_or_else(|_| unreachable!("q = 0.001 is a valid noise coefficient")),
            sensors: vec![sensor],
            association: Association::Jpda(JpdaParams {
                prob_detect: 0.85,
                prob_gate: 0.95,
                clutter_density: Some(0.125),
                include_all: false,
                method: Method::Ehm,
                max_hypotheses: None,
            }),
            use_joseph_cov: false,
            symmetric_covariance: no_symmetry,
            deleter: Deleter::Composite {
                deleters: vec![
                    Deleter::CovarianceTrace {
                        threshold: 1.5,
                        mapping: None,
                    },
                    Deleter::StepsSinceUpdate(35),
                ],
                intersect: false,
            },
            delete_last_prediction: false,
            initiator: InitiatorConfig {
                prior_state: DVector::zeros(4),
                prior_covariance: DMatrix::from_diagonal(&DVector::from_vec(vec![
                    0.0, 0.3, 0.0, 0.3,
                ])),
                diag_load: 0.0,
                confirmation: Confirmation::MinPoints {
                    min_points: 2,
                    updates_only: true,
                },
                deleter: Deleter::StepsSinceUpdate(3),
                gnn: GnnParams {
                    measure: Measure::Mahalanobis,
                    missed_distance: 0.3,
                    include_all: false,
                },
                motion_model: None,
                use_joseph_cov: false,
                symmetric_covariance: no_symmetry,
                max_new_tentative: None,
                imm: false,
            },
            out_of_order: OutOfOrder::Raise,
            initiate_in_gates: true,
            imm: None,
            existence: None,
            max_deleted: None,
        }
    }

    /// Options the range–bearing sensors do not support.
    pub(crate) fn validate_polar(&self) -> Result<()> {
        for (i, s) in self.sensors.iter().enumerate() {
            let Some(p) = &s.polar else { continue };
            if !self.initiate_in_gates {
                return Err(Error::param(
                    "initiate_in_gates",
                    format!(
                        "False is not supported with the range–bearing sensors[{i}] (its \
                         duplicate test compares positions with linear sensors only)"
                    ),
                ));
            }
            let joseph = self.use_joseph_cov || self.initiator.use_joseph_cov;
            if joseph
                && matches!(
                    p.update,
                    crate::tracking::polar::PolarUpdate::Unscented { .. }
                )
            {
                return Err(Error::param(
                    "use_joseph_cov",
                    format!(
                        "the Joseph form needs a measurement matrix, which the unscented \
                         sensors[{i}] has not"
                    ),
                ));
            }
        }
        Ok(())
    }

    pub(crate) fn validate(&self) -> Result<()> {
        self.validate_polar()?;
        if let Some(imm) = &self.imm {
            imm.validate(self.motion_model.ndim())?;
        }
        if let Some(e) = &self.existence {
            if !matches!(self.association, Association::Jpda(_)) {
                return Err(Error::param(
                    "existence",
                    "needs JPDA association (its clutter density gives the likelihood ratio)",
                ));
            }
            let p = |v: f64| (0.0..=1.0).contains(&v);
            let open = |v: f64| v > 0.0 && v <= 1.0;
            let ok = p(e.survival)
                && p(e.delete)
                && p(e.vis_stay)
                && p(e.invis_stay)
                && open(e.initial)
                && open(e.birth)
                && e.confirm.is_none_or(p);
            if !ok {
                return Err(Error::param(
                    "existence",
                    "survival, delete, confirm and visibility probabilities must be in [0, 1], \
                     initial and birth in (0, 1]",
                ));
            }
        }
        let n = self.motion_model.ndim();
        if self.sensors.is_empty() {
            return Err(Error::param("sensors", "at least one sensor is needed"));
        }
        let m = self.sensors[0].m();
        for (i, s) in self.sensors.iter().enumerate() {
            if s.h.ncols() != n {
                return Err(Error::dim(
                    &format!("sensors[{i}].measurement_matrix"),
                    format!("{n} columns (state dimension)"),
                    s.h.ncols(),
                ));
            }
            if s.m() != m {
                return Err(Error::dim(
                    &format!("sensors[{i}].measurement_matrix"),
                    format!("{m} rows (all sensors share one measurement dimension)"),
                    s.m(),
                ));
            }
        }
        let prob = |v: f64, arg: &str| -> Result<()> {
            if v > 0.0 && v <= 1.0 {
                Ok(())
            } else {
                Err(Error::param(arg, format!("must be in (0, 1], got {v}")))
            }
        };
        let gnn = |g: &GnnParams, arg: &str| -> Result<()> {
            if g.missed_distance.is_nan() || g.missed_distance < 0.0 {
                return Err(Error::param(
                    arg,
                    format!("missed_distance must be >= 0, got {}", g.missed_distance),
                ));
            }
            Ok(())
        };
        match &self.association {
            Association::Jpda(j) => {
                prob(j.prob_detect, "prob_detect")?;
                prob(j.prob_gate, "prob_gate")?;
                if j.prob_detect * j.prob_gate >= 1.0 {
                    return Err(Error::param(
                        "prob_detect",
                        format!(
                            "prob_detect * prob_gate must be < 1 (a scan without detections \
                             would have zero probability), got prob_detect={} and prob_gate={}",
                            j.prob_detect, j.prob_gate
                        ),
                    ));
                }
                if j.clutter_density.is_none() && j.prob_gate >= 1.0 {
                    return Err(Error::param(
                        "prob_gate",
                        "must be < 1 when clutter_density is None (the clutter density is \
                         estimated from the gate volume, which is infinite at prob_gate=1)",
                    ));
                }
                if j.max_hypotheses == Some(0) {
                    return Err(Error::param("max_hypotheses", "must be >= 1 or None"));
                }
                if let Some(l) = j.clutter_density {
                    if !(l > 0.0 && l.is_finite()) {
                        return Err(Error::param(
                            "clutter_density",
                            format!("must be finite and > 0, got {l}"),
                        ));
                    }
                } else if j.include_all {
                    return Err(Error::param(
                        "clutter_density",
                        "is required when include_all is set",
                    ));
                }
            }
            Association::Gnn(g) => gnn(g, "association")?,
        }
        self.deleter.validate(n, "deleter")?;
        let init = &self.initiator;
        if init.prior_state.len() != n {
            return Err(Error::dim("prior_state", n, init.prior_state.len()));
        }
        if init.prior_covariance.shape() != (n, n) {
            return Err(Error::dim(
                "prior_covariance",
                format!("({n}, {n})"),
                format!("{:?}", init.prior_covariance.shape()),
            ));
        }
        check_finite("prior_state", init.prior_state.as_slice())?;
        let pc: Vec<f64> = init.prior_covariance.transpose().as_slice().to_vec();
        check_covariance("prior_covariance", &pc, n, false)?;
        if !(init.diag_load >= 0.0 && init.diag_load.is_finite()) {
            return Err(Error::param("diag_load", "must be finite and >= 0"));
        }
        match init.confirmation {
            Confirmation::MinPoints { min_points: 0, .. } => {
                return Err(Error::param("min_points", "must be >= 1"));
            }
            Confirmation::MOfN { m, n } if m == 0 || n < m => {
                return Err(Error::param(
                    "confirmation",
                    format!("M-of-N needs 1 <= M <= N, got {m} of {n}"),
                ));
            }
            _ => {}
        }
        init.deleter.validate(n, "initiator.deleter")?;
        gnn(&init.gnn, "initiator")?;
        if let Some(mm) = &init.motion_model {
            if mm.ndim() != n {
                return Err(Error::dim("initiator.motion_model", n, mm.ndim()));
            }
        }
        if init.imm {
            if self.imm.is_none() {
                return Err(Error::param(
                    "initiator.imm",
                    "needs the tracker's IMM bank (imm), which it runs on tentative tracks",
                ));
            }
            if init.motion_model.is_some() {
                return Err(Error::param(
                    "initiator.imm",
                    "the IMM bank replaces the initiator's motion_model: give one or the other",
                ));
            }
        }
        Ok(())
    }
}
