//! Georeferencing of camera detections onto the water plane, with first-order uncertainty.
//!
//! Frames (see `docs/design.md`): the camera frame is OpenCV's (x right, y down, z forward); the
//! body frame is FRD at the vessel reference point; the *level* frame is the body frame with
//! the vessel's roll and pitch removed (x forward-horizontal along the heading, y starboard,
//! z down), its origin at the reference point, the water surface the plane `z = h` below the
//! camera. NED output rotates the level frame by the heading and adds the vessel position.
//!
//! For each detection the ray through the undistorted normalised image point
//! `d_C = (x_n, y_n, 1)` is rotated into the level frame, `d = R_y(pitch) R_x(roll) R_BC d_C`,
//! and intersected with the water: `p = c + (h / d_z) d`, where `c` is the camera position in
//! the level frame and `h` the camera height above the water (thesis eqs. 3.14–3.17).
//! The 2×2 covariance of `p` is `J Σ Jᵀ` over the pixel coordinates, roll, pitch, height and
//! (for NED output) heading, `J` the analytic Jacobian of the intersection.

use crate::error::{check_finite, Error, Result};
use nalgebra::{Matrix2, Matrix2x3, Matrix3, Vector2, Vector3};

/// The detection was georeferenced.
pub const STATUS_OK: u8 = 0;
/// The ray does not reach the water: at or above the horizon (or less steep than the
/// configured minimum depression angle).
pub const STATUS_ABOVE_HORIZON: u8 = 1;

/// Standard deviations of the error sources propagated into each covariance.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct GeorefNoise {
    /// Pixel noise of the contact point along image x and y (pixels).
    pub sigma_px: [f64; 2],
    /// Roll and pitch noise of the camera attitude (radians).
    pub sigma_roll_pitch: [f64; 2],
    /// Camera height noise (metres).
    pub sigma_height: f64,
    /// Heading noise (radians); used only for NED output.
    pub sigma_heading: f64,
}

/// Inputs of [`georeference`]; every per-detection slice has length `n`.
#[derive(Debug, Clone, Copy)]
pub struct GeorefInput<'a> {
    /// Undistorted normalised image coordinates `x_n = X/Z`, `y_n = Y/Z` (camera frame), `(n, 2)`.
    pub normalized: &'a [f64],
    /// `d(x_n, y_n) / d(u, v)` per detection, row-major `(n, 2, 2)` (1/pixels).
    pub jacobian: &'a [f64],
    /// Vessel roll per detection (radians, FRD, positive starboard down).
    pub roll: &'a [f64],
    /// Vessel pitch per detection (radians, FRD, positive bow up).
    pub pitch: &'a [f64],
    /// Camera height above the water per detection (metres, > 0).
    pub height: &'a [f64],
    /// Rotation body <- camera, row-major 3×3 (maps OpenCV camera axes to FRD).
    pub r_body_cam: [f64; 9],
    /// Camera position in the body frame (FRD metres); only its horizontal part moves the
    /// result, the height above water is `height`.
    pub cam_position: [f64; 3],
    /// Heading per detection (radians clockwise from north) for NED output, `None` for the
    /// level frame.
    pub heading: Option<&'a [f64]>,
    /// Vessel reference point (north, east) per detection, `(n, 2)`, NED metres; NED output only.
    pub vessel_ne: Option<&'a [f64]>,
    /// Rays less than this far below the horizontal (radians, >= 0) are rejected.
    pub min_depression: f64,
    /// Error sources for the covariance.
    pub noise: GeorefNoise,
}

/// Result of [`georeference`]: rejected detections hold NaN positions and covariances.
#[derive(Debug, Clone, PartialEq)]
pub struct GeorefOutput {
    /// `(n, 2)` positions: (forward, starboard) in the level frame or (north, east) in NED, metres.
    pub positions: Vec<f64>,
    /// `(n, 2, 2)` covariances in the same frame, m².
    pub covariances: Vec<f64>,
    /// `(n,)` status codes: [`STATUS_OK`] or [`STATUS_ABOVE_HORIZON`].
    pub status: Vec<u8>,
}

fn rx(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}
fn drx(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(0.0, 0.0, 0.0, 0.0, -s, -c, 0.0, c, -s)
}
fn ry(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c)
}
fn dry(a: f64) -> Matrix3<f64> {
    let (s, c) = a.sin_cos();
    Matrix3::new(-s, 0.0, c, 0.0, 0.0, 0.0, -c, 0.0, -s)
}

/// Rotation matrix from intrinsic z-y-x (yaw, pitch, roll) angles in radians:
/// `R = R_z(yaw) R_y(pitch) R_x(roll)` (Fossen's zyx convention, thesis eq. 3.9), row-major.
#[must_use]
pub fn rotation_zyx(yaw: f64, pitch: f64, roll: f64) -> [f64; 9] {
    let (s, c) = yaw.sin_cos();
    let rz = Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0);
    let r = rz * ry(pitch) * rx(roll);
    let mut out = [0.0; 9];
    for i in 0..3 {
        for j in 0..3 {
            out[3 * i + j] = r[(i, j)];
        }
    }
    out
}

fn check(input: &GeorefInput) -> Result<usize> {
    if input.normalized.len() % 2 != 0 {
        return Err(Error::dim(
            "normalized",
            "shape (n, 2)",
            format!("{} values", input.normalized.len()),
        ));
    }
    let n = input.normalized.len() / 2;
    let lens = [
        ("jacobian", input.jacobian.len(), 4 * n),
        ("roll", input.roll.len(), n),
        ("pitch", input.pitch.len(), n),
        ("height", input.height.len(), n),
        ("heading", input.heading.map_or(n, <[f64]>::len), n),
        (
            "vessel_ne",
            input.vessel_ne.map_or(2 * n, <[f64]>::len),
            2 * n,
        ),
    ];
    for (arg, got, want) in lens {
        if got != want {
            return Err(Error::dim(arg, format!("{want} values"), got));
        }
    }
    check_finite("normalized", input.normalized)?;
    check_finite("jacobian", input.jacobian)?;
    check_finite("roll", input.roll)?;
    check_finite("pitch", input.pitch)?;
    check_finite("height", input.height)?;
    check_finite("r_body_cam", &input.r_body_cam)?;
    check_finite("cam_position", &input.cam_position)?;
    if let Some(h) = input.heading {
        check_finite("heading", h)?;
    }
    if let Some(v) = input.vessel_ne {
        check_finite("vessel_ne", v)?;
    }
    if let Some(i) = input.height.iter().position(|&h| h <= 0.0) {
        return Err(Error::param(
            "height",
            format!(
                "must be > 0 (camera above the water), element {i} is {}",
                input.height[i]
            ),
        ));
    }
    let r = Matrix3::from_row_slice(&input.r_body_cam);
    let err = (r.transpose() * r - Matrix3::identity()).abs().max();
    if err > 1e-6 || r.determinant() < 0.0 {
        return Err(Error::param(
            "r_body_cam",
            format!("must be a rotation matrix (orthonormal, det +1); |RᵀR - I| = {err:.2e}"),
        ));
    }
    let z = input.noise;
    let sig = [
        z.sigma_px[0],
        z.sigma_px[1],
        z.sigma_roll_pitch[0],
        z.sigma_roll_pitch[1],
        z.sigma_height,
        z.sigma_heading,
        input.min_depression,
    ];
    if sig.iter().any(|s| !(s.is_finite() && *s >= 0.0)) {
        return Err(Error::param(
            "noise",
            format!("standard deviations and min_depression must be finite and >= 0, got {sig:?}"),
        ));
    }
    Ok(input.normalized.len() / 2)
}

/// Georeferences `n` detections onto the water plane and propagates their covariance.
///
/// See the module documentation for frames and maths. Fails on shape mismatches, non-finite
/// input, a non-positive height, a non-rotation `r_body_cam` or negative standard deviations.
/// Detections whose ray does not descend at least `min_depression` below the horizontal get
/// [`STATUS_ABOVE_HORIZON`] and NaN outputs instead of huge numbers.
pub fn georeference(input: &GeorefInput) -> Result<GeorefOutput> {
    let n = check(input)?;
    let r_bc = Matrix3::from_row_slice(&input.r_body_cam);
    let t_b = Vector3::from_column_slice(&input.cam_position);
    let noise = input.noise;
    let sin_min = input.min_depression.sin();
    let mut out = GeorefOutput {
        positions: vec![f64::NAN; 2 * n],
        covariances: vec![f64::NAN; 4 * n],
        status: vec![STATUS_ABOVE_HORIZON; n],
    };
    for i in 0..n {
        let (roll, pitch, h) = (input.roll[i], input.pitch[i], input.height[i]);
        let (rx_, ry_) = (rx(roll), ry(pitch));
        let r_lb = ry_ * rx_;
        let r_lc = r_lb * r_bc;
        let d_c = Vector3::new(input.normalized[2 * i], input.normalized[2 * i + 1], 1.0);
        let d_b = r_bc * d_c;
        let d = r_lb * d_b;
        // Reject rays at or above the horizon (or shallower than the minimum depression); the
        // 1e-9 floor keeps round-off at the horizon (d_z ~ 1e-17) from giving ~1e17 m positions.
        if d.z <= sin_min.max(1e-9) * d.norm() {
            continue;
        }
        let c = r_lb * t_b;
        let s = h / d.z;
        // p = c_xy + (h / d_z) d_xy  (thesis eqs. 3.16–3.17)
        let mut p = Vector2::new(c.x + s * d.x, c.y + s * d.y);
        // G = dp/dd (2x3)
        let g = Matrix2x3::new(s, 0.0, -s * d.x / d.z, 0.0, s, -s * d.y / d.z);
        // Pixel term: dp/d(u,v) = G R_LC[:, :2] d(x_n, y_n)/d(u, v)
        let ju = Matrix2::new(
            input.jacobian[4 * i],
            input.jacobian[4 * i + 1],
            input.jacobian[4 * i + 2],
            input.jacobian[4 * i + 3],
        );
        let j_px = g * r_lc.fixed_view::<3, 2>(0, 0) * ju;
        // Attitude terms: d(c + s d)/d(angle), c and d both rotate with the vessel.
        let dr_roll = ry_ * drx(roll);
        let dr_pitch = dry(pitch) * rx_;
        let j_roll = (dr_roll * t_b).xy() + g * (dr_roll * d_b);
        let j_pitch = (dr_pitch * t_b).xy() + g * (dr_pitch * d_b);
        let j_h = Vector2::new(d.x / d.z, d.y / d.z);
        let s_px = Matrix2::new(
            noise.sigma_px[0] * noise.sigma_px[0],
            0.0,
            0.0,
            noise.sigma_px[1] * noise.sigma_px[1],
        );
        let mut cov = j_px * s_px * j_px.transpose()
            + j_roll * j_roll.transpose() * noise.sigma_roll_pitch[0].powi(2)
            + j_pitch * j_pitch.transpose() * noise.sigma_roll_pitch[1].powi(2)
            + j_h * j_h.transpose() * noise.sigma_height.powi(2);
        if let Some(headings) = input.heading {
            // NED: p_N = R_z(psi) p + vessel_ne ; heading noise through dR_z/dpsi p.
            let (sp, cp) = headings[i].sin_cos();
            let rz = Matrix2::new(cp, -sp, sp, cp);
            let j_psi = Matrix2::new(-sp, -cp, cp, -sp) * p;
            cov =
                rz * cov * rz.transpose() + j_psi * j_psi.transpose() * noise.sigma_heading.powi(2);
            p = rz * p;
            if let Some(ne) = input.vessel_ne {
                p += Vector2::new(ne[2 * i], ne[2 * i + 1]);
            }
        }
        // Symmetrise against round-off.
        let cov = (cov + cov.transpose()) * 0.5;
        // Overflow (e.g. an enormous height) is reported like a ray above the horizon.
        if !(p.iter().all(|v| v.is_finite()) && cov.iter().all(|v| v.is_finite())) {
            continue;
        }
        out.positions[2 * i] = p.x;
        out.positions[2 * i + 1] = p.y;
        out.covariances[4 * i] = cov[(0, 0)];
        out.covariances[4 * i + 1] = cov[(0, 1)];
        out.covariances[4 * i + 2] = cov[(1, 0)];
        out.covariances[4 * i + 3] = cov[(1, 1)];
        out.status[i] = STATUS_OK;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Camera looking straight ahead: cam z -> body x, cam x -> body y, cam y -> body z.
    const R0: [f64; 9] = [0., 0., 1., 1., 0., 0., 0., 1., 0.];

    fn one(xn: f64, yn: f64, roll: f64, pitch: f64, h: f64, t: [f64; 3]) -> GeorefOutput {
        georeference(&GeorefInput {
            normalized: &[xn, yn],
            jacobian: &[1.0, 0.0, 0.0, 1.0],
            roll: &[roll],
            pitch: &[pitch],
            height: &[h],
            r_body_cam: R0,
            cam_position: t,
            heading: None,
            vessel_ne: None,
            min_depression: 0.0,
            noise: GeorefNoise {
                sigma_px: [1.0, 1.0],
                sigma_roll_pitch: [0.01, 0.02],
                sigma_height: 0.05,
                sigma_heading: 0.0,
            },
        })
        .unwrap()
    }

    #[test]
    fn flat_camera_matches_similar_triangles() {
        // Ray (1, 0.5, 0.1) in body from 2 m: hits 20 m ahead, 10 m to starboard.
        let o = one(0.5, 0.1, 0.0, 0.0, 2.0, [1.0, -0.5, -2.0]);
        assert_eq!(o.status, vec![STATUS_OK]);
        assert!((o.positions[0] - 21.0).abs() < 1e-12);
        assert!((o.positions[1] - 9.5).abs() < 1e-12);
    }

    #[test]
    fn round_off_at_the_horizon_and_overflow_are_rejected() {
        // Rolled 90 degrees: a ray below the image centre is horizontal up to round-off.
        let o = one(0.0, 0.2, std::f64::consts::FRAC_PI_2, 0.0, 2.0, [0.0; 3]);
        assert_eq!(o.status, vec![STATUS_ABOVE_HORIZON]);
        assert!(o.positions.iter().all(|v| v.is_nan()));
        // An enormous height overflows to inf: not OK either.
        let o = one(0.0, 0.5, 0.0, 0.0, 1e308, [0.0; 3]);
        assert_eq!(o.status, vec![STATUS_ABOVE_HORIZON]);
        assert!(o.covariances.iter().all(|v| v.is_nan()));
    }

    #[test]
    fn horizon_is_rejected_not_huge() {
        let o = one(0.0, 0.0, 0.0, 0.0, 2.0, [0.0; 3]);
        assert_eq!(o.status, vec![STATUS_ABOVE_HORIZON]);
        assert!(o.positions[0].is_nan());
        let o = one(0.0, -0.1, 0.0, 0.0, 2.0, [0.0; 3]);
        assert_eq!(o.status, vec![STATUS_ABOVE_HORIZON]);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let (xn, yn, r, p, h) = (0.3, 0.2, 0.05, -0.03, 1.5);
        let t = [0.5, 0.2, -1.0];
        let f = |xn: f64, yn: f64, r: f64, p: f64, h: f64| {
            let o = one(xn, yn, r, p, h, t);
            Vector2::new(o.positions[0], o.positions[1])
        };
        let e = 1e-6;
        let cols = [
            (f(xn + e, yn, r, p, h) - f(xn - e, yn, r, p, h)) / (2.0 * e),
            (f(xn, yn + e, r, p, h) - f(xn, yn - e, r, p, h)) / (2.0 * e),
            (f(xn, yn, r + e, p, h) - f(xn, yn, r - e, p, h)) / (2.0 * e),
            (f(xn, yn, r, p + e, h) - f(xn, yn, r, p - e, h)) / (2.0 * e),
            (f(xn, yn, r, p, h + e) - f(xn, yn, r, p, h - e)) / (2.0 * e),
        ];
        let sig = [1.0, 1.0, 0.01, 0.02, 0.05];
        let mut want = Matrix2::zeros();
        for (c, s) in cols.iter().zip(sig) {
            want += c * c.transpose() * s * s;
        }
        let o = one(xn, yn, r, p, h, t);
        let got = Matrix2::from_row_slice(&o.covariances);
        assert!(
            (got - want).abs().max() < 1e-6 * want.abs().max(),
            "{got} vs {want}"
        );
    }

    #[test]
    fn rejects_bad_input() {
        let mut inp = GeorefInput {
            normalized: &[0.0, 0.1],
            jacobian: &[1.0, 0.0, 0.0, 1.0],
            roll: &[0.0],
            pitch: &[0.0],
            height: &[-1.0],
            r_body_cam: R0,
            cam_position: [0.0; 3],
            heading: None,
            vessel_ne: None,
            min_depression: 0.0,
            noise: GeorefNoise::default(),
        };
        assert!(georeference(&inp).is_err());
        inp.height = &[1.0];
        inp.r_body_cam = [2.0, 0., 0., 0., 1., 0., 0., 0., 1.];
        assert!(georeference(&inp).is_err());
        inp.r_body_cam = R0;
        inp.roll = &[];
        assert!(georeference(&inp).is_err());
    }
}
