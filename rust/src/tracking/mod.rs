//! Multi-target tracking, organised by Stone Soup role:
//!
//! | role | module | Stone Soup |
//! |---|---|---|
//! | predict / update | [`crate::kalman`], [`hypothesise`] (innovations, posterior covariance), [`imm`], [`imm_scan`], [`turn`], [`polar`], [`unscented`] | `KalmanPredictor`, `Extended/UnscentedKalmanPredictor`, `KalmanUpdater`, `Extended/UnscentedKalmanUpdater` |
//! | gating | [`gating`] (χ² gate, spatial grid), [`hypothesise`] (`gate_pairs`) | `PDAHypothesiser` / `DistanceHypothesiser` gates |
//! | clustering | [`clustering`] | `JPDA` clusters |
//! | JPDA | [`jpda`] (EHM, brute force, belief propagation past a budget), [`kbest`] (Murty k-best) | `JPDA`, `JPDAwithEHM` |
//! | existence | [`config::Existence`] (IPDA per track), [`jipda`] (JIPDA: joint existence and visibility) | — |
//! | GNN | [`gnn`], [`assign`] | `GNNWith2DAssignment` |
//! | initiator | [`initiator`] | `MultiMeasurementInitiator` |
//! | deleters | [`deleters`] | `UpdateTimeStepsDeleter`, `CovarianceBasedDeleter`, ... |
//! | the tracker | [`tracker`] (one scan), [`run`] (a whole recording), [`config`], [`track`] | `MultiTargetMixtureTracker`, `MultiTargetTracker` |

pub mod assign;
pub mod clustering;
pub mod config;
pub mod deleters;
pub mod gating;
pub mod gnn;
pub mod hypothesise;
pub mod imm;
pub(crate) mod imm_scan;
mod initiator;
pub mod jipda;
pub mod jpda;
pub mod kbest;
pub mod polar;
pub mod run;
pub mod track;
pub mod tracker;
pub mod turn;
pub mod unscented;
