//! The particle image tracker's parameters (Bloisi et al. §V) and their checks.

use super::kcluster::ClusterParams;
use crate::error::{Error, Result};

/// Parameters of [`super::tracker::ParticleTracker`] (units: px, px/frame, frames).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackerParams {
    /// Particles drawn per detection and kept per track.
    pub particles: usize,
    /// Random acceleration std of the transition (px/frame²).
    pub accel_std: f64,
    /// Observation std as a share of the box's width and height.
    pub meas_scale: f64,
    /// Velocity std of proposal particles near no track (px/frame).
    pub birth_vel_std: f64,
    /// Velocity std of proposal particles near a track (px/frame).
    pub track_vel_std: f64,
    /// Proposal velocity near a track: its velocity plus this share of (detection − predicted
    /// centre) / dt.
    pub vel_gain: f64,
    /// Clutter density added to every weight (per px²).
    pub clutter: f64,
    /// KClusterize parameters (δ_model in px).
    pub cluster: ClusterParams,
    /// Proximity gate: predicted-centre distance in predicted-box diagonals.
    pub gate: f64,
    /// Largest angle between the velocities of a track and a cluster (degrees; Bloisi: 10°).
    pub max_angle_deg: f64,
    /// Speeds below this are not tested for direction (px/frame).
    pub min_speed: f64,
    /// Speed module test: |s₁ − s₂| ≤ speed_abs + speed_rel · max(s₁, s₂).
    pub speed_abs: f64,
    /// Relative part of the speed module test.
    pub speed_rel: f64,
    /// Share of the histogram distance in the association cost.
    pub appearance_weight: f64,
    /// M of M-of-N confirmation.
    pub confirm_hits: u32,
    /// N of M-of-N confirmation (≤ 32).
    pub confirm_window: u32,
    /// Consecutive misses after which a confirmed track is deleted.
    pub max_age: u32,
    /// IoU of two confirmed tracks' predicted boxes that makes them an occlusion group.
    pub group_iou: f64,
    /// Largest histogram distance of a re-identification.
    pub reid_distance: f64,
    /// Re-identification radius in predicted-box diagonals.
    pub reid_radius: f64,
    /// Share of a new box in the smoothed box size.
    pub size_gain: f64,
}

impl Default for TrackerParams {
    fn default() -> Self {
        Self {
            particles: 64,
            accel_std: 0.01,
            meas_scale: 0.15,
            birth_vel_std: 1.0,
            track_vel_std: 0.3,
            vel_gain: 0.5,
            clutter: 1e-9,
            cluster: ClusterParams::default(),
            gate: 1.0,
            max_angle_deg: 10.0,
            min_speed: 0.5,
            speed_abs: 1.0,
            speed_rel: 0.5,
            appearance_weight: 0.3,
            confirm_hits: 2,
            confirm_window: 3,
            max_age: 3,
            group_iou: 0.05,
            reid_distance: 0.35,
            reid_radius: 1.5,
            size_gain: 0.6,
        }
    }
}

impl TrackerParams {
    /// Fails with [`Error::InvalidParameter`] naming the first bad field.
    pub fn validate(&self) -> Result<()> {
        let pos = |name: &str, v: f64| -> Result<()> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(Error::param(
                    name,
                    format!("must be finite and > 0, got {v}"),
                ))
            }
        };
        let nonneg = |name: &str, v: f64| -> Result<()> {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(Error::param(
                    name,
                    format!("must be finite and ≥ 0, got {v}"),
                ))
            }
        };
        if self.particles == 0 || self.particles > 100_000 {
            return Err(Error::param("particles", "must be in 1..=100000"));
        }
        nonneg("accel_std", self.accel_std)?;
        pos("meas_scale", self.meas_scale)?;
        nonneg("birth_vel_std", self.birth_vel_std)?;
        nonneg("track_vel_std", self.track_vel_std)?;
        nonneg("vel_gain", self.vel_gain)?;
        pos("clutter", self.clutter)?;
        pos("delta", self.cluster.delta)?;
        if self.cluster.min_size == 0 || self.cluster.min_size > self.particles {
            return Err(Error::param("min_cluster", "must be in 1..=particles"));
        }
        nonneg("min_kurtosis", self.cluster.min_kurtosis)?;
        if self.cluster.max_depth > 16 {
            return Err(Error::param("max_depth", "must be ≤ 16"));
        }
        pos("gate", self.gate)?;
        nonneg("max_angle_deg", self.max_angle_deg)?;
        nonneg("min_speed", self.min_speed)?;
        nonneg("speed_abs", self.speed_abs)?;
        nonneg("speed_rel", self.speed_rel)?;
        nonneg("appearance_weight", self.appearance_weight)?;
        if self.confirm_window == 0 || self.confirm_window > 32 {
            return Err(Error::param("confirm_window", "must be in 1..=32"));
        }
        if self.confirm_hits == 0 || self.confirm_hits > self.confirm_window {
            return Err(Error::param(
                "confirm_hits",
                "must be in 1..=confirm_window",
            ));
        }
        nonneg("group_iou", self.group_iou)?;
        nonneg("reid_distance", self.reid_distance)?;
        nonneg("reid_radius", self.reid_radius)?;
        if !(self.size_gain > 0.0 && self.size_gain <= 1.0) {
            return Err(Error::param("size_gain", "must be in (0, 1]"));
        }
        Ok(())
    }
}
