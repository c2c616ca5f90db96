//! Rigid-body frames: the ZYX roll–pitch–yaw rotation of the thesis (eq. 3.9), SE(3)
//! transforms (eq. 3.10), and batch transforms of sensor points into the local NED frame.
//!
//! Conventions: angles in radians; `R = Rz(yaw) · Ry(pitch) · Rx(roll)` maps vectors from the
//! rotated frame (body, sensor) to the reference frame (NED, body); body frame FRD. A
//! transform `T_a_b` maps points in frame b to frame a: `p_a = R p_b + t`.

use crate::error::{check_finite, Error, Result};
use nalgebra::{Matrix3, Vector3};

/// `Rz(yaw) · Ry(pitch) · Rx(roll)` (thesis eq. 3.9; Fossen's zyx convention).
#[must_use]
pub fn rotation_zyx(roll: f64, pitch: f64, yaw: f64) -> Matrix3<f64> {
    let (sf, cf) = roll.sin_cos();
    let (st, ct) = pitch.sin_cos();
    let (sp, cp) = yaw.sin_cos();
    // Eq. 3.10's upper-left block.
    Matrix3::new(
        ct * cp,
        sf * st * cp - cf * sp,
        cf * st * cp + sf * sp,
        ct * sp,
        sf * st * sp + cf * cp,
        cf * st * sp - sf * cp,
        -st,
        sf * ct,
        cf * ct,
    )
}

/// The (roll, pitch, yaw) of a rotation matrix, inverse of [`rotation_zyx`]; pitch in
/// [-π/2, π/2], roll and yaw in (-π, π]. At pitch = ±π/2 (gimbal lock) roll is set to 0.
#[must_use]
pub fn euler_zyx(r: &Matrix3<f64>) -> (f64, f64, f64) {
    let pitch = (-r[(2, 0)]).clamp(-1.0, 1.0).asin();
    if r[(2, 0)].abs() < 1.0 - 1e-12 {
        (
            r[(2, 1)].atan2(r[(2, 2)]),
            pitch,
            r[(1, 0)].atan2(r[(0, 0)]),
        )
    } else {
        // cos(pitch) = 0: only yaw ∓ roll is defined; report it as yaw.
        (0.0, pitch, (-r[(0, 1)]).atan2(r[(1, 1)]))
    }
}

/// A rigid transform `p_a = rotation · p_b + translation` (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Se3 {
    /// Rotation from frame b to frame a.
    pub rotation: Matrix3<f64>,
    /// Origin of frame b expressed in frame a (metres).
    pub translation: Vector3<f64>,
}

impl Se3 {
    /// From ZYX angles (radians) and a translation (metres).
    #[must_use]
    pub fn from_rpy(roll: f64, pitch: f64, yaw: f64, translation: [f64; 3]) -> Self {
        Se3 {
            rotation: rotation_zyx(roll, pitch, yaw),
            translation: Vector3::from(translation),
        }
    }

    /// `self ∘ other`: first `other`, then `self`.
    #[must_use]
    pub fn compose(&self, other: &Se3) -> Se3 {
        Se3 {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// The inverse transform.
    #[must_use]
    pub fn inverse(&self) -> Se3 {
        let rt = self.rotation.transpose();
        Se3 {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }

    /// Applies the transform to one point.
    #[must_use]
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        (self.rotation * Vector3::from(p) + self.translation).into()
    }
}

/// Sensor points → NED: `p_ned = T_ned_body(pose_i) · T_body_sensor · p_sensor`.
///
/// `points`: row-major (n, 3) in the sensor frame (metres). `mount`: body ← sensor. Vessel
/// pose arrays `roll`, `pitch`, `yaw` (radians) and `position` (row-major (m, 3), NED metres of
/// the body origin) each have m = 1 (one pose for all points) or m = n (a pose per point).
/// Returns row-major (n, 3) NED metres (empty for n = 0). Fails on wrong lengths or non-finite
/// values (in the points, the pose or the mount).
pub fn sensor_to_ned(
    points: &[f64],
    mount: &Se3,
    roll: &[f64],
    pitch: &[f64],
    yaw: &[f64],
    position: &[f64],
) -> Result<Vec<f64>> {
    if points.len() % 3 != 0 {
        return Err(Error::dim(
            "points",
            "shape (n, 3)",
            format!("{} values", points.len()),
        ));
    }
    let n = points.len() / 3;
    for (name, s, per) in [
        ("roll", roll, 1),
        ("pitch", pitch, 1),
        ("yaw", yaw, 1),
        ("position", position, 3),
    ] {
        if s.len() != per && s.len() != per * n {
            return Err(Error::dim(
                name,
                format!("{} or {} values", per, per * n),
                format!("{} values", s.len()),
            ));
        }
        check_finite(name, s)?;
    }
    check_finite("points", points)?;
    check_finite("mount.rotation", mount.rotation.as_slice())?;
    check_finite("mount.translation", mount.translation.as_slice())?;
    if n == 0 {
        return Ok(Vec::new());
    }
    let pick = |s: &[f64], i: usize| if s.len() == 1 { s[0] } else { s[i] };
    let single = roll.len() == 1 && pitch.len() == 1 && yaw.len() == 1 && position.len() == 3;
    let pose_at = |i: usize| {
        let j = if position.len() == 3 { 0 } else { i };
        Se3::from_rpy(
            pick(roll, i),
            pick(pitch, i),
            pick(yaw, i),
            [position[3 * j], position[3 * j + 1], position[3 * j + 2]],
        )
        .compose(mount)
    };
    let fixed = pose_at(0);
    let mut out = Vec::with_capacity(3 * n);
    for i in 0..n {
        let t = if single { fixed } else { pose_at(i) };
        out.extend_from_slice(&t.apply([points[3 * i], points[3 * i + 1], points[3 * i + 2]]));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::FRAC_PI_2;

    fn rx(a: f64) -> Matrix3<f64> {
        Matrix3::new(1.0, 0.0, 0.0, 0.0, a.cos(), -a.sin(), 0.0, a.sin(), a.cos())
    }
    fn ry(a: f64) -> Matrix3<f64> {
        Matrix3::new(a.cos(), 0.0, a.sin(), 0.0, 1.0, 0.0, -a.sin(), 0.0, a.cos())
    }
    fn rz(a: f64) -> Matrix3<f64> {
        Matrix3::new(a.cos(), -a.sin(), 0.0, a.sin(), a.cos(), 0.0, 0.0, 0.0, 1.0)
    }

    proptest! {
        #[test]
        fn closed_form_is_the_product_and_round_trips(
            roll in -3.1..3.1f64, pitch in -1.5..1.5f64, yaw in -3.1..3.1f64,
        ) {
            let r = rotation_zyx(roll, pitch, yaw);
            prop_assert!((r - rz(yaw) * ry(pitch) * rx(roll)).abs().max() < 1e-14);
            prop_assert!((r * r.transpose() - Matrix3::identity()).abs().max() < 1e-14);
            let (a, b, c) = euler_zyx(&r);
            prop_assert!((a - roll).abs() < 1e-9 && (b - pitch).abs() < 1e-9 && (c - yaw).abs() < 1e-9);
        }

        #[test]
        fn inverse_and_compose(
            roll in -3.0..3.0f64, pitch in -1.5..1.5f64, yaw in -3.0..3.0f64,
            x in -10.0..10.0f64, y in -10.0..10.0f64,
        ) {
            let t = Se3::from_rpy(roll, pitch, yaw, [x, y, 1.0]);
            let id = t.compose(&t.inverse());
            prop_assert!((id.rotation - Matrix3::identity()).abs().max() < 1e-12);
            prop_assert!(id.translation.norm() < 1e-12);
            let p = [1.0, -2.0, 3.0];
            let back = t.inverse().apply(t.apply(p));
            prop_assert!((back[0] - 1.0).abs() < 1e-12 && (back[2] - 3.0).abs() < 1e-12);
        }
    }

    #[test]
    fn no_points_give_no_output() {
        let mount = Se3::from_rpy(0.0, 0.0, 0.0, [0.0; 3]);
        assert_eq!(sensor_to_ned(&[], &mount, &[], &[], &[], &[]), Ok(vec![]));
        assert_eq!(
            sensor_to_ned(&[], &mount, &[0.1], &[0.0], &[0.2], &[1.0, 2.0, 3.0]),
            Ok(vec![])
        );
        // n > 0 with empty pose arrays is a shape error, not a panic.
        assert!(matches!(
            sensor_to_ned(&[1.0, 2.0, 3.0], &mount, &[], &[], &[], &[]),
            Err(Error::Dimension { .. })
        ));
    }

    #[test]
    fn non_finite_mount_is_an_error() {
        let mount = Se3::from_rpy(f64::NAN, 0.0, 0.0, [0.0; 3]);
        let got = sensor_to_ned(&[1.0, 2.0, 3.0], &mount, &[0.0], &[0.0], &[0.0], &[0.0; 3]);
        assert!(matches!(got, Err(Error::NonFinite { arg, .. }) if arg == "mount.rotation"));
        let mount = Se3::from_rpy(0.0, 0.0, 0.0, [0.0, f64::INFINITY, 0.0]);
        let got = sensor_to_ned(&[1.0, 2.0, 3.0], &mount, &[0.0], &[0.0], &[0.0], &[0.0; 3]);
        assert!(matches!(got, Err(Error::NonFinite { arg, .. }) if arg == "mount.translation"));
    }

    #[test]
    fn gimbal_lock_keeps_the_rotation() {
        let r = rotation_zyx(0.3, FRAC_PI_2, 0.5);
        let (a, b, c) = euler_zyx(&r);
        assert!((rotation_zyx(a, b, c) - r).abs().max() < 1e-9);
    }

    #[test]
    fn sensor_points_follow_mount_and_pose() {
        // Sensor 2 m forward, 1 m up (z down: -1) on the body, looking forward; vessel heading
        // east (yaw 90°) at NED (100, 50, 0). A point 10 m ahead of the sensor is 12 m east.
        let mount = Se3::from_rpy(0.0, 0.0, 0.0, [2.0, 0.0, -1.0]);
        let out = sensor_to_ned(
            &[10.0, 0.0, 0.0],
            &mount,
            &[0.0],
            &[0.0],
            &[FRAC_PI_2],
            &[100.0, 50.0, 0.0],
        )
        .unwrap();
        assert!(
            (out[0] - 100.0).abs() < 1e-12
                && (out[1] - 62.0).abs() < 1e-12
                && (out[2] + 1.0).abs() < 1e-12
        );
        // Per-point poses equal one pose at a time.
        let pts = [1.0, 2.0, 3.0, -4.0, 5.0, 6.0];
        let many = sensor_to_ned(
            &pts,
            &mount,
            &[0.1, 0.2],
            &[0.0],
            &[1.0, 2.0],
            &[0.0, 0.0, 0.0],
        )
        .unwrap();
        let one =
            sensor_to_ned(&pts[3..], &mount, &[0.2], &[0.0], &[2.0], &[0.0, 0.0, 0.0]).unwrap();
        assert_eq!(&many[3..], &one[..]);
        assert!(sensor_to_ned(&pts, &mount, &[0.0; 3], &[0.0], &[0.0], &[0.0; 3]).is_err());
        assert!(sensor_to_ned(&pts[..4], &mount, &[0.0], &[0.0], &[0.0], &[0.0; 3]).is_err());
    }
}
