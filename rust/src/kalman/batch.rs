//! Batch Kalman filtering of a whole measurement sequence, many states at once, and the
//! Rauch–Tung–Striebel smoother (fixed-size 2-, 4- and 6-state fast paths, dynamic otherwise).

use super::*;
use crate::error::check_non_decreasing;
use crate::models::{LinearModel, MotionModel, Transition};
use nalgebra::{Dyn, U1, U2, U3, U4, U6};

/// Inputs of a batch run: flat row-major arrays, as they come from numpy.
#[derive(Debug, Clone, Copy)]
pub struct BatchInput<'a> {
    /// Measurement times `(n,)`, seconds, non-decreasing.
    pub times: &'a [f64],
    /// Measurements `(n, m)`.
    pub measurements: &'a [f64],
    /// Measurement dimension `m`.
    pub measurement_dim: usize,
    /// Measurement matrix `H`, `(m, ndim)`.
    pub measurement_matrix: &'a [f64],
    /// A stack of measurement noise covariances `(k, m, m)`.
    pub measurement_noise: &'a [f64],
    /// For each measurement, which of the `k` covariances applies (`None`: all use the first).
    pub noise_index: Option<&'a [usize]>,
    /// Prior state `(ndim,)` at `prior_time`.
    pub prior_state: &'a [f64],
    /// Prior covariance `(ndim, ndim)`.
    pub prior_covariance: &'a [f64],
    /// Time of the prior; must not be after `times[0]`.
    pub prior_time: f64,
}

/// Outputs of a batch run: flat row-major arrays of `n` states `(n, ndim)` and covariances
/// `(n, ndim, ndim)`; the smoothed ones are empty when smoothing was not asked for.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BatchOutput {
    pub predicted_states: Vec<f64>,
    pub predicted_covariances: Vec<f64>,
    pub filtered_states: Vec<f64>,
    pub filtered_covariances: Vec<f64>,
    pub smoothed_states: Vec<f64>,
    pub smoothed_covariances: Vec<f64>,
    /// Normalised innovation squared per measurement.
    pub nis: Vec<f64>,
    /// Log-likelihood per measurement.
    pub log_likelihood: Vec<f64>,
}

impl BatchInput<'_> {
    /// Checks shapes, finiteness, time order and covariances; returns `(n, k)`.
    fn validate(&self, ndim: usize) -> Result<(usize, usize)> {
        let n = self.times.len();
        let m = self.measurement_dim;
        if m == 0 {
            return Err(Error::dim("measurements", "at least one column", 0));
        }
        if self.measurements.len() != n * m {
            return Err(Error::dim(
                "measurements",
                format!("{n} x {m} values (one row per time)"),
                self.measurements.len(),
            ));
        }
        if self.measurement_matrix.len() != m * ndim {
            return Err(Error::dim(
                "measurement_matrix",
                format!("shape ({m}, {ndim})"),
                format!("{} values", self.measurement_matrix.len()),
            ));
        }
        if self.prior_state.len() != ndim {
            return Err(Error::dim("prior_state", ndim, self.prior_state.len()));
        }
        if self.prior_covariance.len() != ndim * ndim {
            return Err(Error::dim(
                "prior_covariance",
                format!("shape ({ndim}, {ndim})"),
                format!("{} values", self.prior_covariance.len()),
            ));
        }
        if self.measurement_noise.is_empty() || self.measurement_noise.len() % (m * m) != 0 {
            return Err(Error::dim(
                "measurement_noise",
                format!("shape (k, {m}, {m})"),
                format!("{} values", self.measurement_noise.len()),
            ));
        }
        let k = self.measurement_noise.len() / (m * m);
        check_finite("times", self.times)?;
        check_finite("measurements", self.measurements)?;
        check_finite("measurement_matrix", self.measurement_matrix)?;
        check_finite("prior_state", self.prior_state)?;
        check_finite("prior_time", &[self.prior_time])?;
        check_non_decreasing("times", self.times)?;
        if n > 0 && self.prior_time > self.times[0] {
            return Err(Error::Order {
                arg: "prior_time".into(),
                reason: format!(
                    "{} is after the first measurement time {}",
                    self.prior_time, self.times[0]
                ),
            });
        }
        check_covariance("prior_covariance", self.prior_covariance, ndim, false)?;
        for (i, r) in self.measurement_noise.chunks(m * m).enumerate() {
            let name = if k == 1 {
                "measurement_noise".to_string()
            } else {
                format!("measurement_noise[{i}]")
            };
            check_covariance(&name, r, m, true)?;
        }
        if let Some(idx) = self.noise_index {
            if idx.len() != n {
                return Err(Error::dim("sensor_index", n, idx.len()));
            }
            if let Some(pos) = idx.iter().position(|&s| s >= k) {
                return Err(Error::param(
                    "sensor_index",
                    format!(
                        "element {pos} is {}, but only {k} measurement noise matrices were given",
                        idx[pos]
                    ),
                ));
            }
        }
        Ok((n, k))
    }
}

/// Filters (and optionally RTS-smooths) a whole sequence in one call.
///
/// Each measurement is preceded by a prediction over `dt = t_i − t_{i−1}` (the first from
/// `prior_time`). Fast fixed-size paths serve 2-state/1-D, 4-state/2-D and 6-state/3-D
/// problems; any other size runs on dynamic matrices with the same code.
pub fn run_batch(model: &MotionModel, input: &BatchInput, smooth: bool) -> Result<BatchOutput> {
    let ndim = model.ndim();
    input.validate(ndim)?;
    match (ndim, input.measurement_dim) {
        (2, 1) => run_generic::<U2, U1, _>(model, input, smooth),
        (4, 2) => run_generic::<U4, U2, _>(model, input, smooth),
        (6, 3) => run_generic::<U6, U3, _>(model, input, smooth),
        _ => run_generic::<Dyn, Dyn, _>(model, input, smooth),
    }
}

/// [`run_batch`] with a general [`LinearModel`]: its fixed `F`, `Q` at every step, or its
/// pair `i` before measurement `i` (then the model needs exactly one pair per measurement).
pub fn run_batch_linear(
    model: &LinearModel,
    input: &BatchInput,
    smooth: bool,
) -> Result<BatchOutput> {
    let ndim = model.ndim();
    input.validate(ndim)?;
    let n = input.times.len();
    if model.steps() != 1 && model.steps() != n {
        return Err(Error::dim(
            "transition_matrix",
            format!("1 or {n} matrices (one per measurement)"),
            model.steps(),
        ));
    }
    match (ndim, input.measurement_dim) {
        (2, 1) => run_generic::<U2, U1, _>(model, input, smooth),
        (4, 2) => run_generic::<U4, U2, _>(model, input, smooth),
        (6, 3) => run_generic::<U6, U3, _>(model, input, smooth),
        _ => run_generic::<Dyn, Dyn, _>(model, input, smooth),
    }
}

/// Predicts `k` independent states at once with one `F`, `Q`: `states` `(k, n)` and
/// `covariances` `(k, n, n)` flat row-major, `f` and `q` `(n, n)`. Returns the predicted
/// states and covariances in the same layout. Fails on mismatched sizes or non-finite values.
pub fn predict_many(
    states: &[f64],
    covariances: &[f64],
    ndim: usize,
    f: &[f64],
    q: &[f64],
) -> Result<(Vec<f64>, Vec<f64>)> {
    let k = check_many(states, covariances, ndim)?;
    let nn = ndim * ndim;
    if f.len() != nn {
        return Err(Error::dim(
            "transition_matrix",
            format!("shape ({ndim}, {ndim})"),
            f.len(),
        ));
    }
    if q.len() != nn {
        return Err(Error::dim(
            "process_noise",
            format!("shape ({ndim}, {ndim})"),
            q.len(),
        ));
    }
    check_finite("transition_matrix", f)?;
    check_covariance("process_noise", q, ndim, false)?;
    let fm = nalgebra::DMatrix::from_row_slice(ndim, ndim, f);
    let qm = nalgebra::DMatrix::from_row_slice(ndim, ndim, q);
    let mut xs = Vec::with_capacity(k * ndim);
    let mut ps = Vec::with_capacity(k * nn);
    for i in 0..k {
        let x = nalgebra::DVector::from_row_slice(&states[i * ndim..(i + 1) * ndim]);
        let p = nalgebra::DMatrix::from_row_slice(ndim, ndim, &covariances[i * nn..(i + 1) * nn]);
        let (xp, pp) = predict(&x, &p, &fm, &qm);
        push_matrix(&mut xs, &xp);
        push_matrix(&mut ps, &pp);
    }
    Ok((xs, ps))
}

/// Updates `k` independent states at once, state `i` with measurement row `i`: `states`
/// `(k, n)`, `covariances` `(k, n, n)`, `measurements` `(k, m)`, `h` `(m, n)`, `r` `(m, m)`, all
/// flat row-major. Returns posterior states, covariances (Joseph form) and the NIS `(k,)`.
/// Fails on mismatched sizes, non-finite values or a non-positive-definite `r`.
pub fn update_many(
    states: &[f64],
    covariances: &[f64],
    ndim: usize,
    measurements: &[f64],
    h: &[f64],
    r: &[f64],
) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let k = check_many(states, covariances, ndim)?;
    if ndim == 0 || h.is_empty() || h.len() % ndim != 0 {
        return Err(Error::dim(
            "measurement_matrix",
            format!("shape (m, {ndim})"),
            h.len(),
        ));
    }
    let m = h.len() / ndim;
    if measurements.len() != k * m {
        return Err(Error::dim(
            "measurements",
            format!("shape ({k}, {m})"),
            measurements.len(),
        ));
    }
    if r.len() != m * m {
        return Err(Error::dim(
            "measurement_noise",
            format!("shape ({m}, {m})"),
            r.len(),
        ));
    }
    check_finite("measurements", measurements)?;
    check_finite("measurement_matrix", h)?;
    check_covariance("measurement_noise", r, m, true)?;
    let nn = ndim * ndim;
    let hm = nalgebra::DMatrix::from_row_slice(m, ndim, h);
    let rm = nalgebra::DMatrix::from_row_slice(m, m, r);
    let mut xs = Vec::with_capacity(k * ndim);
    let mut ps = Vec::with_capacity(k * nn);
    let mut nis = Vec::with_capacity(k);
    for i in 0..k {
        let x = nalgebra::DVector::from_row_slice(&states[i * ndim..(i + 1) * ndim]);
        let p = nalgebra::DMatrix::from_row_slice(ndim, ndim, &covariances[i * nn..(i + 1) * nn]);
        let z = nalgebra::DVector::from_row_slice(&measurements[i * m..(i + 1) * m]);
        let u = update(&x, &p, &z, &hm, &rm).map_err(|e| match e {
            Error::NotPositiveDefinite { reason, .. } => Error::NotPositiveDefinite {
                arg: format!("innovation covariance of state {i}"),
                reason,
            },
            other => other,
        })?;
        push_matrix(&mut xs, &u.x);
        push_matrix(&mut ps, &u.p);
        nis.push(u.nis);
    }
    Ok((xs, ps, nis))
}

/// Checks a stack of `k` states `(k, n)` and covariances `(k, n, n)`; returns `k`.
fn check_many(states: &[f64], covariances: &[f64], ndim: usize) -> Result<usize> {
    if ndim == 0 || states.len() % ndim != 0 {
        return Err(Error::dim(
            "states",
            format!("shape (k, {ndim})"),
            states.len(),
        ));
    }
    let k = states.len() / ndim;
    if covariances.len() != k * ndim * ndim {
        return Err(Error::dim(
            "covariances",
            format!("shape ({k}, {ndim}, {ndim})"),
            covariances.len(),
        ));
    }
    check_finite("states", states)?;
    check_finite("covariances", covariances)?;
    Ok(k)
}

/// Appends a matrix or vector to a flat row-major output.
fn push_matrix<R: Dim, C: Dim>(out: &mut Vec<f64>, m: &OMatrix<f64, R, C>)
where
    DefaultAllocator: Allocator<R, C>,
{
    for i in 0..m.nrows() {
        for j in 0..m.ncols() {
            out.push(m[(i, j)]);
        }
    }
}

pub(super) fn run_generic<N: Dim, M: Dim, T: Transition>(
    model: &T,
    input: &BatchInput,
    smooth: bool,
) -> Result<BatchOutput>
where
    DefaultAllocator: Allocator<N, N>
        + Allocator<N>
        + Allocator<M, M>
        + Allocator<M>
        + Allocator<M, N>
        + Allocator<N, M>,
{
    let ndim = model.ndim();
    let m = input.measurement_dim;
    let n_meas = input.times.len();
    let (nd, md) = (N::from_usize(ndim), M::from_usize(m));
    let h = OMatrix::<f64, M, N>::from_row_slice_generic(md, nd, input.measurement_matrix);
    let noises: Vec<OMatrix<f64, M, M>> = input
        .measurement_noise
        .chunks(m * m)
        .map(|r| OMatrix::<f64, M, M>::from_row_slice_generic(md, md, r))
        .collect();
    let mut x = OVector::<f64, N>::from_row_slice_generic(nd, U1, input.prior_state);
    let mut p = OMatrix::<f64, N, N>::from_row_slice_generic(nd, nd, input.prior_covariance);
    let mut f = OMatrix::<f64, N, N>::zeros_generic(nd, nd);
    let mut q = OMatrix::<f64, N, N>::zeros_generic(nd, nd);

    let mut out = BatchOutput {
        predicted_states: Vec::with_capacity(n_meas * ndim),
        predicted_covariances: Vec::with_capacity(n_meas * ndim * ndim),
        filtered_states: Vec::with_capacity(n_meas * ndim),
        filtered_covariances: Vec::with_capacity(n_meas * ndim * ndim),
        nis: Vec::with_capacity(n_meas),
        log_likelihood: Vec::with_capacity(n_meas),
        ..Default::default()
    };
    let mut t_prev = input.prior_time;
    for (i, &t) in input.times.iter().enumerate() {
        model.fill_step(i, t - t_prev, &mut f, &mut q);
        t_prev = t;
        let (xp, pp) = predict(&x, &p, &f, &q);
        let z = OVector::<f64, M>::from_row_slice_generic(
            md,
            U1,
            &input.measurements[i * m..(i + 1) * m],
        );
        let r = &noises[input.noise_index.map_or(0, |idx| idx[i])];
        let u = update(&xp, &pp, &z, &h, r).map_err(|e| match e {
            Error::NotPositiveDefinite { reason, .. } => Error::NotPositiveDefinite {
                arg: format!("innovation covariance at measurement {i}"),
                reason,
            },
            other => other,
        })?;
        push_matrix(&mut out.predicted_states, &xp);
        push_matrix(&mut out.predicted_covariances, &pp);
        push_matrix(&mut out.filtered_states, &u.x);
        push_matrix(&mut out.filtered_covariances, &u.p);
        out.nis.push(u.nis);
        out.log_likelihood.push(u.log_likelihood);
        x = u.x;
        p = u.p;
    }
    if smooth {
        rts_smooth_flat::<N, T>(model, input.times, &mut out)?;
    }
    Ok(out)
}

/// Rauch–Tung–Striebel smoother over flat batch outputs (fills the smoothed fields):
/// `C_k = P_k Fᵀ (P⁻_{k+1})⁻¹`, `x̂_k = x_k + C_k (x̂_{k+1} − x⁻_{k+1})`,
/// `P̂_k = P_k + C_k (P̂_{k+1} − P⁻_{k+1}) C_kᵀ`.
fn rts_smooth_flat<N: Dim, T: Transition>(
    model: &T,
    times: &[f64],
    out: &mut BatchOutput,
) -> Result<()>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N>,
{
    let ndim = model.ndim();
    let n = times.len();
    let nd = N::from_usize(ndim);
    let (s2, s1) = (ndim * ndim, ndim);
    out.smoothed_states = out.filtered_states.clone();
    out.smoothed_covariances = out.filtered_covariances.clone();
    if n < 2 {
        return Ok(());
    }
    let mut f = OMatrix::<f64, N, N>::zeros_generic(nd, nd);
    let mut q = OMatrix::<f64, N, N>::zeros_generic(nd, nd);
    let vec_at = |v: &[f64], k: usize| {
        OVector::<f64, N>::from_row_slice_generic(nd, U1, &v[k * s1..(k + 1) * s1])
    };
    let mat_at = |v: &[f64], k: usize| {
        OMatrix::<f64, N, N>::from_row_slice_generic(nd, nd, &v[k * s2..(k + 1) * s2])
    };
    let mut xs_next = vec_at(&out.smoothed_states, n - 1);
    let mut ps_next = mat_at(&out.smoothed_covariances, n - 1);
    for k in (0..n - 1).rev() {
        model.fill_step(k + 1, times[k + 1] - times[k], &mut f, &mut q);
        let xf = vec_at(&out.filtered_states, k);
        let pf = mat_at(&out.filtered_covariances, k);
        let xp = vec_at(&out.predicted_states, k + 1);
        let pp = mat_at(&out.predicted_covariances, k + 1);
        // C = P_k Fᵀ (P⁻)⁻¹ = ((P⁻)⁻¹ F P_k)ᵀ
        let fp = &f * &pf;
        let c = match Cholesky::new(pp.clone()) {
            Some(ch) => ch.solve(&fp).transpose(),
            None => pp
                .clone()
                .try_inverse()
                .map(|inv| (inv * fp).transpose())
                .ok_or_else(|| Error::NotPositiveDefinite {
                    arg: format!("predicted covariance at measurement {}", k + 1),
                    reason: "is singular, the RTS smoother cannot invert it".into(),
                })?,
        };
        let xs = &xf + &c * (&xs_next - &xp);
        let mut ps = &pf + &c * (&ps_next - &pp) * c.transpose();
        symmetrise(&mut ps);
        out.smoothed_states[k * s1..(k + 1) * s1].copy_from_slice(xs.as_slice());
        for i in 0..ndim {
            for j in 0..ndim {
                out.smoothed_covariances[k * s2 + i * ndim + j] = ps[(i, j)];
            }
        }
        xs_next = xs;
        ps_next = ps;
    }
    Ok(())
}
