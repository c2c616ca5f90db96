//! Per-scan kernels of the tracker: prediction of all tracks, innovations, gating of
//! (track, detection) pairs through the spatial grid, and the spatial ordering of JPDA clusters
//! for EHM. GNN association lives in [`super::gnn`].

pub(crate) use super::gnn::gnn_step;

use crate::error::{Error, Result};
use crate::models::MotionModel;
use crate::tracking::config::Sensor;
use crate::tracking::gating::CandidateGrid;
use crate::tracking::track::Track;
use nalgebra::allocator::Allocator;
use nalgebra::{Cholesky, DefaultAllocator, Dim, OMatrix, OVector, U1};

/// The allocator bounds of the per-scan kernels, generic over the state dimension `N` and the
/// measurement dimension `M` (static `U4`/`U2` for the common 2-D case: no heap allocation
/// per track; `Dyn` for any other size).
pub(crate) trait Alloc<N: Dim, M: Dim>:
    Allocator<N, N>
    + Allocator<N>
    + Allocator<U1, N>
    + Allocator<M, M>
    + Allocator<M>
    + Allocator<M, N>
    + Allocator<N, M>
{
}

impl<N: Dim, M: Dim> Alloc<N, M> for DefaultAllocator where
    DefaultAllocator: Allocator<N, N>
        + Allocator<N>
        + Allocator<U1, N>
        + Allocator<M, M>
        + Allocator<M>
        + Allocator<M, N>
        + Allocator<N, M>
{
}

/// A sensor's `H`, `R` in the kernel's dimensions.
pub(crate) struct SensorT<N: Dim, M: Dim>
where
    DefaultAllocator: Alloc<N, M>,
{
    pub h: OMatrix<f64, M, N>,
    pub r: OMatrix<f64, M, M>,
    /// A range–bearing sensor (its `h` then only selects the mapped positions).
    pub polar: Option<crate::tracking::polar::Polar>,
}

/// The configured sensors converted to the kernel's dimensions (once per scan).
pub(crate) fn sensors_t<N: Dim, M: Dim>(sensors: &[Sensor], n: N, m: M) -> Vec<SensorT<N, M>>
where
    DefaultAllocator: Alloc<N, M>,
{
    sensors
        .iter()
        .map(|s| SensorT {
            h: OMatrix::from_iterator_generic(m, n, s.h.iter().copied()),
            r: OMatrix::from_iterator_generic(m, m, s.r.iter().copied()),
            polar: s.polar,
        })
        .collect()
}

/// A predicted state `(x⁻, P⁻)`.
pub(crate) type Pred<N> = (OVector<f64, N>, OMatrix<f64, N, N>);

/// Per (track, sensor) quantities of a prediction, or per (track, detection) when the
/// detection carries its own noise covariance.
pub(crate) struct Innovation<N: Dim, M: Dim>
where
    DefaultAllocator: Alloc<N, M>,
{
    pub zhat: OVector<f64, M>,
    /// `H P⁻ Hᵀ` (the innovation covariance without the measurement noise).
    pub hph: OMatrix<f64, M, M>,
    /// `P⁻ Hᵀ`.
    pub pht: OMatrix<f64, N, M>,
    pub s: OMatrix<f64, M, M>,
    pub chol: Cholesky<f64, M>,
    pub ln_det: f64,
    /// Kalman gain `P⁻ Hᵀ S⁻¹`.
    pub k: OMatrix<f64, N, M>,
    /// The detection's own noise covariance (`None`: the sensor's `R`).
    pub r: Option<OMatrix<f64, M, M>>,
    /// The linearised measurement matrix (extended Kalman; `None`: the sensor's `H`, or an
    /// unscented innovation).
    pub h: Option<OMatrix<f64, M, N>>,
    /// The first measurement component is an angle: residuals are wrapped to `[−π, π)`.
    pub angle: bool,
}

impl<N: Dim, M: Dim> Innovation<N, M>
where
    DefaultAllocator: Alloc<N, M>,
{
    /// The residual `z − ẑ` of a detection `z` (its angle wrapped).
    pub fn residual(&self, z: &[f64]) -> OVector<f64, M> {
        let (m, _) = self.zhat.shape_generic();
        let mut y = OVector::<f64, M>::from_column_slice_generic(m, U1, z) - &self.zhat;
        if self.angle {
            y[0] = crate::tracking::polar::wrap(y[0]);
        }
        y
    }
}

fn not_pd() -> Error {
    Error::NotPositiveDefinite {
        arg: "innovation covariance".into(),
        reason: "H P Hᵀ + R of a track is not positive definite: the track covariance P has \
                 lost positive definiteness (rounding asymmetry of P − K S Kᵀ grows through \
                 long predictions, fastest with constant-acceleration models); set \
                 symmetric_covariance (Stone Soup: force_symmetric_covariance) or \
                 use_joseph_cov"
            .into(),
    }
}

/// `S = hph + R`, its Cholesky factor, `ln det S` and the gain `pht S⁻¹`. `own`: the
/// detection's own R, kept on the innovation; `h`: the linearised measurement matrix of a
/// non-linear sensor; `angle`: the innovation's first component is an angle (wrapped).
pub(crate) fn finish<N: Dim, M: Dim>(
    zhat: OVector<f64, M>,
    hph: OMatrix<f64, M, M>,
    pht: OMatrix<f64, N, M>,
    r: &OMatrix<f64, M, M>,
    own: Option<OMatrix<f64, M, M>>,
    h: Option<OMatrix<f64, M, N>>,
    angle: bool,
) -> Result<Innovation<N, M>>
where
    DefaultAllocator: Alloc<N, M>,
{
    let crate::kalman::Gain { s, chol, ln_det, k } =
        crate::kalman::gain(&hph, &pht, r).ok_or_else(not_pd)?;
    Ok(Innovation {
        zhat,
        hph,
        pht,
        s,
        chol,
        ln_det,
        k,
        r: own,
        h,
        angle,
    })
}

pub(crate) fn innovation<N: Dim, M: Dim>(
    x: &OVector<f64, N>,
    p: &OMatrix<f64, N, N>,
    sensor: &SensorT<N, M>,
) -> Result<Innovation<N, M>>
where
    DefaultAllocator: Alloc<N, M>,
{
    let h = &sensor.h;
    let pht = p * h.transpose();
    let hph = h * &pht;
    finish(h * x, hph, pht, &sensor.r, None, None, false)
}

/// The innovation of one detection with its own noise covariance `r`, from the track's
/// per-sensor innovation `base` (same `H P⁻ Hᵀ`, `P⁻ Hᵀ`; `S = H P⁻ Hᵀ + r`).
pub(crate) fn own_innovation<N: Dim, M: Dim>(
    base: &Innovation<N, M>,
    r: &OMatrix<f64, M, M>,
) -> Result<Innovation<N, M>>
where
    DefaultAllocator: Alloc<N, M>,
{
    finish(
        base.zhat.clone(),
        base.hph.clone(),
        base.pht.clone(),
        r,
        Some(r.clone()),
        None,
        false,
    )
}

/// The innovations of one scan's gated pairs: per (track, sensor) with the sensor's `R`, and
/// per (track, detection) for detections with their own covariance.
/// The error of a pair whose innovation was never computed (an internal invariant).
pub(crate) fn missing_innovation() -> Error {
    Error::param("tracker", "internal error: a gated pair has no innovation")
}

pub(crate) struct Innovations<N: Dim, M: Dim>
where
    DefaultAllocator: Alloc<N, M>,
{
    ns: usize,
    shared: Vec<Option<Innovation<N, M>>>,
    own: Vec<Innovation<N, M>>,
}

impl<N: Dim, M: Dim> Innovations<N, M>
where
    DefaultAllocator: Alloc<N, M>,
{
    /// Room for `n_tracks` tracks seen by `ns` sensors.
    pub fn new(n_tracks: usize, ns: usize) -> Self {
        Self {
            ns,
            shared: (0..n_tracks * ns).map(|_| None).collect(),
            own: Vec::new(),
        }
    }

    /// The innovation of a gated pair (`gate_pairs` computes it for every pair it returns;
    /// an [`Error::InvalidParameter`] naming `tracker` should that invariant ever break).
    pub fn of(&self, pair: &Pair, sensor: usize) -> Result<&Innovation<N, M>> {
        let inn = if pair.own == NO_OWN {
            self.shared
                .get(pair.t * self.ns + sensor)
                .and_then(|i| i.as_ref())
        } else {
            self.own.get(pair.own as usize)
        };
        inn.ok_or_else(missing_innovation)
    }
}

/// A gated (track, detection) pair: indices, squared Mahalanobis distance `d2`, and the index
/// of its own innovation ([`NO_OWN`] when the detection uses its sensor's `R`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pair {
    pub t: usize,
    pub d: usize,
    pub d2: f64,
    pub own: u32,
}

/// [`Pair::own`] of a detection without its own covariance.
pub(crate) const NO_OWN: u32 = u32::MAX;

/// How an updater forms the posterior covariance (Stone Soup `KalmanUpdater` flags).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct CovForm {
    /// Joseph form `(I − K H) P (I − K H)ᵀ + K R Kᵀ` instead of `P − K S Kᵀ`.
    pub joseph: bool,
    /// Replace the result by `(P + Pᵀ) / 2` (`force_symmetric_covariance`).
    pub symmetric: bool,
}

/// Posterior covariance of a Kalman update (same for every detection of a sensor unless the
/// detection has its own covariance).
pub(crate) fn posterior_cov<N: Dim, M: Dim>(
    p: &OMatrix<f64, N, N>,
    inn: &Innovation<N, M>,
    sensor: &SensorT<N, M>,
    form: CovForm,
) -> OMatrix<f64, N, N>
where
    DefaultAllocator: Alloc<N, M>,
{
    let h = inn.h.as_ref().unwrap_or(&sensor.h);
    let r = inn.r.as_ref().unwrap_or(&sensor.r);
    crate::kalman::posterior_covariance(p, &inn.k, &inn.s, h, r, form.joseph, form.symmetric)
}

/// Predicts every track to `t` (`x⁻ = F x`, `P⁻ = F P Fᵀ + Q`), computing `F`, `Q` once per
/// distinct time step.
pub(crate) fn predict_all<N: Dim>(
    model: &MotionModel,
    tracks: &[Track],
    t: f64,
    n: N,
) -> Vec<Pred<N>>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N>,
{
    let fq = |dt: f64| {
        let mut f = OMatrix::<f64, N, N>::zeros_generic(n, n);
        let mut q = OMatrix::<f64, N, N>::zeros_generic(n, n);
        model.fill(dt, &mut f, &mut q);
        (f, q)
    };
    // (dt bits, F, Fᵀ, Q)
    type Step<N> = (
        u64,
        OMatrix<f64, N, N>,
        OMatrix<f64, N, N>,
        OMatrix<f64, N, N>,
    );
    let mut cache: Vec<Step<N>> = Vec::new();
    tracks
        .iter()
        .map(|tr| {
            let x = OVector::<f64, N>::from_column_slice_generic(n, U1, tr.x.as_slice());
            let p = OMatrix::<f64, N, N>::from_column_slice_generic(n, n, tr.p.as_slice());
            let dt = t - tr.t;
            let key = dt.to_bits();
            let k = match cache.iter().position(|c| c.0 == key) {
                Some(k) => k,
                None if cache.len() >= 8 => {
                    // Many distinct steps (tracks at scattered times): no caching.
                    let (f, q) = fq(dt);
                    return (&f * &x, &f * &p * f.transpose() + q);
                }
                None => {
                    let (f, q) = fq(dt);
                    let ft = f.transpose();
                    cache.push((key, f, ft, q));
                    cache.len() - 1
                }
            };
            let (_, f, ft, q) = &cache[k];
            (f * &x, f * &p * ft + q)
        })
        .collect()
}

/// One scan's detections as the kernels see them.
pub(crate) struct Dets<'a, M: Dim>
where
    DefaultAllocator: Allocator<M, M>,
{
    /// Measurements `(k, m)` row-major.
    pub z: &'a [f64],
    /// Sensor of each detection `(k,)`.
    pub sensor: &'a [usize],
    /// Each detection's own noise covariance (`None`: its sensor's `R`).
    pub covs: Option<&'a [OMatrix<f64, M, M>]>,
    /// Sensor position `(k, 2)` of each detection (used by polar sensors; `None`: the
    /// origin).
    pub origins: Option<&'a [f64]>,
}

impl<M: Dim> Dets<'_, M>
where
    DefaultAllocator: Allocator<M, M>,
{
    /// Number of detections.
    pub fn len(&self) -> usize {
        self.sensor.len()
    }

    /// Measurement row `d`.
    pub fn row(&self, d: usize, m: usize) -> &[f64] {
        &self.z[d * m..(d + 1) * m]
    }

    /// Sensor position of detection `d`.
    pub fn origin(&self, d: usize) -> [f64; 2] {
        self.origins
            .map_or([0.0, 0.0], |o| [o[2 * d], o[2 * d + 1]])
    }
}

/// Up to this many (track, detection) pairs of one sensor, [`gate_pairs`] tests every pair's
/// gate box directly instead of building the spatial grid.
const SMALL_SCAN_PAIRS: usize = 64;

/// Candidate pairs within `gate` (squared Mahalanobis) for predictions `preds[t] = (x⁻, P⁻)` and
/// the detections `which` of `dets`, sorted by (track, detection). The per-(track, sensor)
/// innovations of `innov` are filled lazily for linear sensors; a detection with its own noise
/// covariance, and every detection of a polar sensor (its innovation depends on the
/// detection's sensor position), gets its own innovation. Polar sensors test every
/// (track, detection) pair.
#[allow(clippy::too_many_arguments)]
pub(crate) fn gate_pairs<N: Dim, M: Dim>(
    preds: &[Pred<N>],
    sensors: &[SensorT<N, M>],
    m: M,
    dets: &Dets<'_, M>,
    which: &[usize],
    gate: f64,
    innov: &mut Innovations<N, M>,
) -> Result<Vec<Pair>>
where
    DefaultAllocator: Alloc<N, M>,
{
    let mut pairs = Vec::new();
    if preds.is_empty() || which.is_empty() {
        return Ok(pairs);
    }
    let ns = sensors.len();
    let md = m.value();
    let covs = dets.covs;
    for (s, sensor) in sensors.iter().enumerate() {
        let ids: Vec<usize> = which
            .iter()
            .copied()
            .filter(|&d| dets.sensor[d] == s)
            .collect();
        if ids.is_empty() {
            continue;
        }
        if let Some(pol) = &sensor.polar {
            for (t, (x, p)) in preds.iter().enumerate() {
                for &d in &ids {
                    let r = covs.map_or(&sensor.r, |c| &c[d]);
                    let o = pol.innovation(x, p, r, dets.origin(d))?;
                    let y = o.residual(dets.row(d, md));
                    let d2 = y.dot(&o.chol.solve(&y));
                    if d2 <= gate {
                        pairs.push(Pair {
                            t,
                            d,
                            d2,
                            own: innov.own.len() as u32,
                        });
                        innov.own.push(o);
                    }
                }
            }
            continue;
        }
        for (t, (x, p)) in preds.iter().enumerate() {
            if innov.shared[t * ns + s].is_none() {
                innov.shared[t * ns + s] = Some(innovation(x, p, sensor)?);
            }
        }
        // With per-detection covariances the gate boxes use the largest noise variance of
        // this sensor's detections on each axis (a superset of every detection's gate).
        let rmax: Option<Vec<f64>> = covs.map(|c| {
            (0..md)
                .map(|i| ids.iter().map(|&d| c[d][(i, i)]).fold(0.0, f64::max))
                .collect()
        });
        let var = |inn: &Innovation<N, M>, i: usize| match &rmax {
            Some(r) => inn.hph[(i, i)] + r[i],
            None => inn.s[(i, i)],
        };
        let mut err: Option<Error> = None;
        let Innovations { shared, own, .. } = innov;
        // Tests detection `ids[k]` against the track whose innovation is `inn`.
        let mut visit = |t: usize, inn: &Innovation<N, M>, k: usize, err: &mut Option<Error>| {
            if err.is_some() {
                return;
            }
            let d = ids[k];
            let y = inn.residual(dets.row(d, md));
            match covs {
                None => {
                    let d2 = y.dot(&inn.chol.solve(&y));
                    if d2 <= gate {
                        pairs.push(Pair {
                            t,
                            d,
                            d2,
                            own: NO_OWN,
                        });
                    }
                }
                Some(c) => match own_innovation(inn, &c[d]) {
                    Ok(o) => {
                        let d2 = y.dot(&o.chol.solve(&y));
                        if d2 <= gate {
                            pairs.push(Pair {
                                t,
                                d,
                                d2,
                                own: own.len() as u32,
                            });
                            own.push(o);
                        }
                    }
                    Err(e) => *err = Some(e),
                },
            }
        };
        if preds.len() * ids.len() <= SMALL_SCAN_PAIRS {
            // A small scan: every detection inside the track's gate box is tested, as the grid
            // below finds them (building the grid costs more than it saves here).
            let half = |inn: &Innovation<N, M>, i: usize| {
                let h = (gate * var(inn, i)).sqrt();
                if h.is_nan() {
                    f64::INFINITY
                } else {
                    h
                }
            };
            for t in 0..preds.len() {
                let inn = shared[t * ns + s].as_ref().ok_or_else(missing_innovation)?;
                for (k, &d) in ids.iter().enumerate() {
                    let z = dets.row(d, md);
                    if (0..md).all(|i| (z[i] - inn.zhat[i]).abs() <= half(inn, i)) {
                        visit(t, inn, k, &mut err);
                    }
                }
                if let Some(e) = err.take() {
                    return Err(e);
                }
            }
            continue;
        }
        let pts: Vec<f64> = ids
            .iter()
            .flat_map(|&d| dets.row(d, md).iter().copied())
            .collect();
        // Cell side: median gate box width over tracks.
        let mut widths: Vec<f64> = (0..preds.len())
            .map(|t| {
                let inn = shared[t * ns + s].as_ref().ok_or_else(missing_innovation)?;
                let w = (0..md.min(2)).map(|i| var(inn, i)).fold(0.0, f64::max);
                Ok(2.0 * (gate * w).sqrt())
            })
            .collect::<Result<_>>()?;
        let cell = if gate.is_finite() {
            let mid = widths.len() / 2;
            *widths.select_nth_unstable_by(mid, |a, b| a.total_cmp(b)).1
        } else {
            f64::INFINITY
        };
        let local: Vec<usize> = (0..ids.len()).collect();
        let grid = CandidateGrid::new(&pts, md, &local, cell);
        let mut half = vec![0.0; md];
        for t in 0..preds.len() {
            let inn = shared[t * ns + s].as_ref().ok_or_else(missing_innovation)?;
            for (i, h) in half.iter_mut().enumerate() {
                *h = (gate * var(inn, i)).sqrt();
                if h.is_nan() {
                    *h = f64::INFINITY;
                }
            }
            grid.query(inn.zhat.as_slice(), &half, |k| visit(t, inn, k, &mut err));
            if let Some(e) = err.take() {
                return Err(e);
            }
        }
    }
    pairs.sort_unstable_by_key(|p| (p.t, p.d));
    Ok(pairs)
}

/// Orders a cluster's tracks along the axis of largest spread of their predicted states, so
/// that EHM's sets of pending detections stay small.
pub(crate) fn order_cluster<N: Dim>(c: &[usize], preds: &[Pred<N>]) -> Vec<usize>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N>,
{
    let mut out = c.to_vec();
    let n = preds[c[0]].0.len();
    let spread = |i: usize| {
        let v: Vec<f64> = c.iter().map(|&t| preds[t].0[i]).collect();
        let lo = v.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        hi - lo
    };
    let axis = (0..n)
        .max_by(|&a, &b| spread(a).total_cmp(&spread(b)))
        .unwrap_or(0);
    out.sort_by(|&a, &b| preds[a].0[axis].total_cmp(&preds[b].0[axis]));
    out
}

/// The cluster sorted along each state axis (both directions): candidate EHM orders.
pub(crate) fn axis_orders<N: Dim>(c: &[usize], preds: &[Pred<N>]) -> Vec<Vec<usize>>
where
    DefaultAllocator: Allocator<N, N> + Allocator<N>,
{
    let n = preds[c[0]].0.len();
    let mut out = Vec::with_capacity(2 * n);
    for axis in 0..n {
        let mut o = c.to_vec();
        o.sort_by(|&a, &b| preds[a].0[axis].total_cmp(&preds[b].0[axis]));
        let r: Vec<usize> = o.iter().rev().copied().collect();
        out.push(o);
        out.push(r);
    }
    out
}

/// The innovation of detection `d` of `dets` for the prediction `(x, p)` with its sensor's
/// model (linear or polar; the detection's own covariance when it has one).
pub(crate) fn pair_innovation<N: Dim, M: Dim>(
    x: &OVector<f64, N>,
    p: &OMatrix<f64, N, N>,
    sensor: &SensorT<N, M>,
    dets: &Dets<'_, M>,
    d: usize,
) -> Result<Innovation<N, M>>
where
    DefaultAllocator: Alloc<N, M>,
{
    if let Some(pol) = &sensor.polar {
        let r = dets.covs.map_or(&sensor.r, |c| &c[d]);
        return pol.innovation(x, p, r, dets.origin(d));
    }
    let base = innovation(x, p, sensor)?;
    match dets.covs {
        Some(c) => own_innovation(&base, &c[d]),
        None => Ok(base),
    }
}
