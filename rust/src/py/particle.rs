//! Bindings of the two-tier particle filter (`crate::particle`): conversions only.

use super::{slice, to_py_err};
use crate::error::{check_finite, Error};
use crate::particle::fuse::{fuse_mixtures, Component};
use crate::particle::kcluster::{kclusterize, Cluster, ClusterParams};
use crate::particle::params::TrackerParams;
use crate::particle::rng::Stream;
use crate::particle::sir::{gather, propagate, sample_around, systematic_resample, weights};
use crate::particle::tracker::{Frame, ParticleTracker as Core};
use crate::particle::DIM;
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

type Arr<'py> = Bound<'py, PyAny>;

fn array<'py>(py: Python<'py>, data: Vec<f64>, shape: &[usize]) -> PyResult<Arr<'py>> {
    Ok(PyArray1::from_vec(py, data).reshape(shape)?.into_any())
}

fn rows<'a>(name: &str, a: &'a PyReadonlyArray2<'_, f64>, width: usize) -> PyResult<&'a [f64]> {
    let s = a.shape();
    if s[1] != width {
        return Err(to_py_err(Error::dim(
            name,
            format!("(n, {width})"),
            format!("{s:?}"),
        )));
    }
    let v = slice(name, a)?;
    check_finite(name, v).map_err(to_py_err)?;
    Ok(v)
}

fn cluster_params(
    delta: f64,
    min_size: usize,
    min_kurtosis: f64,
    max_depth: usize,
) -> PyResult<ClusterParams> {
    if !(delta.is_finite() && delta > 0.0) {
        return Err(to_py_err(Error::param("delta", "must be finite and > 0")));
    }
    if min_size == 0 {
        return Err(to_py_err(Error::param("min_size", "must be ≥ 1")));
    }
    if !(min_kurtosis.is_finite() && min_kurtosis >= 0.0) || max_depth > 16 {
        return Err(to_py_err(Error::param(
            "min_kurtosis",
            "must be finite and ≥ 0 (and max_depth ≤ 16)",
        )));
    }
    Ok(ClusterParams {
        delta,
        min_size,
        min_kurtosis,
        max_depth,
    })
}

/// (weights (c,), means (c, 4), stds (c, 4), labels (n,) cluster of each particle or −1).
fn mixture_arrays<'py>(
    py: Python<'py>,
    c: &[Cluster],
    n: usize,
) -> PyResult<(Arr<'py>, Arr<'py>, Arr<'py>, Arr<'py>)> {
    let mut labels = vec![-1i64; n];
    for (k, cl) in c.iter().enumerate() {
        for &i in &cl.members {
            labels[i] = k as i64;
        }
    }
    Ok((
        array(py, c.iter().map(|x| x.weight).collect(), &[c.len()])?,
        array(py, c.iter().flat_map(|x| x.mean).collect(), &[c.len(), DIM])?,
        array(py, c.iter().flat_map(|x| x.std).collect(), &[c.len(), DIM])?,
        PyArray1::from_vec(py, labels).into_any(),
    ))
}

/// Words `start .. start + n` of the counter-based stream of `seed` as uniforms in [0, 1).
#[pyfunction]
fn particle_uniforms<'py>(py: Python<'py>, seed: u64, start: u64, n: usize) -> PyResult<Arr<'py>> {
    let mut s = Stream {
        seed,
        counter: start,
    };
    Ok(PyArray1::from_vec(py, (0..n).map(|_| s.uniform()).collect()).into_any())
}

/// Systematic resampling of `weights` (n,) ≥ 0 with positive sum into `count` indices,
/// using word `counter` of the stream of `seed`.
#[pyfunction]
#[pyo3(signature = (weights, count, *, seed, counter=0))]
fn particle_resample<'py>(
    py: Python<'py>,
    weights: PyReadonlyArray1<'py, f64>,
    count: usize,
    seed: u64,
    counter: u64,
) -> PyResult<Arr<'py>> {
    let w = slice("weights", &weights)?;
    check_finite("weights", w).map_err(to_py_err)?;
    if w.iter().any(|v| *v < 0.0) || w.iter().sum::<f64>() <= 0.0 {
        return Err(to_py_err(Error::param(
            "weights",
            "must be ≥ 0 with a positive sum",
        )));
    }
    let idx = systematic_resample(w, count, &mut Stream { seed, counter });
    Ok(PyArray1::from_vec(py, idx.into_iter().map(|i| i as i64).collect()).into_any())
}

/// KClusterize (Bloisi et al. Fig. 10) of `particles` (n, 4) `[u, v, du, dv]` with positive
/// `weights` (n,): (λ (c,), means (c, 4), stds (c, 4), labels (n,) with −1 for dropped).
#[pyfunction]
#[pyo3(signature = (particles, weights, *, delta, min_size=8, min_kurtosis=1.9, max_depth=3))]
fn particle_kclusterize<'py>(
    py: Python<'py>,
    particles: PyReadonlyArray2<'py, f64>,
    weights: PyReadonlyArray1<'py, f64>,
    delta: f64,
    min_size: usize,
    min_kurtosis: f64,
    max_depth: usize,
) -> PyResult<(Arr<'py>, Arr<'py>, Arr<'py>, Arr<'py>)> {
    let p = rows("particles", &particles, DIM)?;
    let w = slice("weights", &weights)?;
    let n = p.len() / DIM;
    if w.len() != n {
        return Err(to_py_err(Error::dim("weights", format!("({n},)"), w.len())));
    }
    check_finite("weights", w).map_err(to_py_err)?;
    if w.iter().any(|v| *v <= 0.0) {
        return Err(to_py_err(Error::param("weights", "must be > 0")));
    }
    let params = cluster_params(delta, min_size, min_kurtosis, max_depth)?;
    let c = py.detach(|| kclusterize(p, w, &params));
    mixture_arrays(py, &c, n)
}

/// One local-tier step of the particle filter without identities (Bloisi et al. Fig. 9):
/// propagate `particles` (n, 4) over `dt` frames with `accel_std`; append `count` proposal
/// particles per observation `obs` (k, 4) `[u, v, σ_u, σ_v]` moving with `velocities` (k, 2)
/// ± `vel_std`; weight by the observations (+ `clutter`); resample `n_out`; KClusterize.
/// Returns (resampled (n_out, 4), λ, means, stds, labels). Random words from `seed` in the
/// order propagate, proposals, resampling.
#[pyfunction]
#[pyo3(signature = (
    particles, obs, velocities, *, count, dt, accel_std, vel_std, clutter, n_out, delta,
    seed, min_size=8, min_kurtosis=1.9, max_depth=3
))]
#[allow(clippy::too_many_arguments)]
fn particle_local_step<'py>(
    py: Python<'py>,
    particles: PyReadonlyArray2<'py, f64>,
    obs: PyReadonlyArray2<'py, f64>,
    velocities: PyReadonlyArray2<'py, f64>,
    count: usize,
    dt: f64,
    accel_std: f64,
    vel_std: f64,
    clutter: f64,
    n_out: usize,
    delta: f64,
    seed: u64,
    min_size: usize,
    min_kurtosis: f64,
    max_depth: usize,
) -> PyResult<(Arr<'py>, Arr<'py>, Arr<'py>, Arr<'py>, Arr<'py>)> {
    let mut set = rows("particles", &particles, DIM)?.to_vec();
    let z = rows("obs", &obs, 4)?;
    let v = rows("velocities", &velocities, 2)?;
    let k = z.len() / 4;
    if v.len() != 2 * k {
        return Err(to_py_err(Error::dim(
            "velocities",
            format!("({k}, 2)"),
            v.len() / 2,
        )));
    }
    if z.chunks_exact(4).any(|o| o[2] <= 0.0 || o[3] <= 0.0) {
        return Err(to_py_err(Error::param("obs", "σ_u and σ_v must be > 0")));
    }
    for (name, x) in [
        ("dt", dt),
        ("accel_std", accel_std),
        ("vel_std", vel_std),
        ("clutter", clutter),
    ] {
        if !(x.is_finite() && x >= 0.0) {
            return Err(to_py_err(Error::param(name, "must be finite and ≥ 0")));
        }
    }
    if clutter <= 0.0 && k == 0 {
        return Err(to_py_err(Error::param(
            "clutter",
            "must be > 0 without observations",
        )));
    }
    let params = cluster_params(delta, min_size, min_kurtosis, max_depth)?;
    let (res, c) = py.detach(|| {
        let mut rng = Stream::new(seed);
        propagate(&mut set, dt, accel_std, &mut rng);
        let obs4: Vec<[f64; 4]> = z
            .chunks_exact(4)
            .map(|o| [o[0], o[1], o[2], o[3]])
            .collect();
        for (j, o) in obs4.iter().enumerate() {
            sample_around(
                &mut set,
                count,
                [o[0], o[1]],
                [o[2], o[3]],
                [v[2 * j], v[2 * j + 1]],
                vel_std,
                &mut rng,
            );
        }
        let w = weights(&set, &obs4, clutter);
        let idx = systematic_resample(&w, n_out, &mut rng);
        let res = gather(&set, &idx);
        let ones = vec![1.0; idx.len()];
        let c = kclusterize(&res, &ones, &params);
        (res, c)
    });
    let n = res.len() / DIM;
    let (lw, lm, ls, lab) = mixture_arrays(py, &c, n)?;
    Ok((array(py, res, &[n, DIM])?, lw, lm, ls, lab))
}

/// The global tier (Bloisi et al. Fig. 9): fuse the components (times (m,) s, weights (m,),
/// means (m, 4), stds (m, 4)) that arrived in `[now − window, now]` by drawing `count`
/// particles and KClusterizing them: (λ, means, stds, labels, particles (count, 4)).
#[pyfunction]
#[pyo3(signature = (
    times, weights, means, stds, *, now, window, count, delta, seed, min_size=8,
    min_kurtosis=1.9, max_depth=3
))]
#[allow(clippy::too_many_arguments)]
fn particle_fuse<'py>(
    py: Python<'py>,
    times: PyReadonlyArray1<'py, f64>,
    weights: PyReadonlyArray1<'py, f64>,
    means: PyReadonlyArray2<'py, f64>,
    stds: PyReadonlyArray2<'py, f64>,
    now: f64,
    window: f64,
    count: usize,
    delta: f64,
    seed: u64,
    min_size: usize,
    min_kurtosis: f64,
    max_depth: usize,
) -> PyResult<(Arr<'py>, Arr<'py>, Arr<'py>, Arr<'py>, Arr<'py>)> {
    let t = slice("times", &times)?;
    let w = slice("weights", &weights)?;
    let m = rows("means", &means, DIM)?;
    let s = rows("stds", &stds, DIM)?;
    let n = t.len();
    for (name, len) in [
        ("weights", w.len()),
        ("means", m.len() / DIM),
        ("stds", s.len() / DIM),
    ] {
        if len != n {
            return Err(to_py_err(Error::dim(name, format!("{n} rows"), len)));
        }
    }
    let comps: Vec<Component> = (0..n)
        .map(|i| Component {
            time: t[i],
            weight: w[i],
            mean: [m[4 * i], m[4 * i + 1], m[4 * i + 2], m[4 * i + 3]],
            std: [s[4 * i], s[4 * i + 1], s[4 * i + 2], s[4 * i + 3]],
        })
        .collect();
    let params = cluster_params(delta, min_size, min_kurtosis, max_depth)?;
    let (c, p) = py
        .detach(|| fuse_mixtures(&comps, now, window, count, &params, seed))
        .map_err(to_py_err)?;
    let np = p.len() / DIM;
    let (lw, lm, ls, lab) = mixture_arrays(py, &c, np)?;
    Ok((lw, lm, ls, lab, array(py, p, &[np, DIM])?))
}

/// The local tier of Bloisi et al.'s two-tier particle filter as a multi-target image
/// tracker (px, px/frame, frames); see `usvfast.shore.particle`.
#[pyclass(module = "usvfast._core")]
pub struct ParticleTracker {
    inner: Core,
}

#[pymethods]
impl ParticleTracker {
    #[new]
    #[pyo3(signature = (
        *, seed=0, particles=64, accel_std=0.01, meas_scale=0.15, birth_vel_std=1.0,
        track_vel_std=0.3, vel_gain=0.5, clutter=1e-9, delta=20.0, min_cluster=8,
        min_kurtosis=1.9, max_depth=3, gate=1.0, max_angle_deg=10.0, min_speed=0.5,
        speed_abs=1.0, speed_rel=0.5, appearance_weight=0.3, confirm_hits=2,
        confirm_window=3, max_age=3, group_iou=0.05, reid_distance=0.35, reid_radius=1.5,
        size_gain=0.6
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        seed: u64,
        particles: usize,
        accel_std: f64,
        meas_scale: f64,
        birth_vel_std: f64,
        track_vel_std: f64,
        vel_gain: f64,
        clutter: f64,
        delta: f64,
        min_cluster: usize,
        min_kurtosis: f64,
        max_depth: usize,
        gate: f64,
        max_angle_deg: f64,
        min_speed: f64,
        speed_abs: f64,
        speed_rel: f64,
        appearance_weight: f64,
        confirm_hits: u32,
        confirm_window: u32,
        max_age: u32,
        group_iou: f64,
        reid_distance: f64,
        reid_radius: f64,
        size_gain: f64,
    ) -> PyResult<Self> {
        let params = TrackerParams {
            particles,
            accel_std,
            meas_scale,
            birth_vel_std,
            track_vel_std,
            vel_gain,
            clutter,
            cluster: ClusterParams {
                delta,
                min_size: min_cluster,
                min_kurtosis,
                max_depth,
            },
            gate,
            max_angle_deg,
            min_speed,
            speed_abs,
            speed_rel,
            appearance_weight,
            confirm_hits,
            confirm_window,
            max_age,
            group_iou,
            reid_distance,
            reid_radius,
            size_gain,
        };
        Ok(Self {
            inner: Core::new(params, seed).map_err(to_py_err)?,
        })
    }

    /// One frame: boxes (k, 4) x, y, w, h px, scores (k,), optional colour histograms
    /// (k, b) ≥ 0, dt frames since the last step. Returns the confirmed tracks updated now:
    /// (ids (t,), boxes (t, 4) px, scores (t,)).
    #[pyo3(signature = (boxes, scores, hists=None, dt=1.0))]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        boxes: PyReadonlyArray2<'py, f64>,
        scores: PyReadonlyArray1<'py, f64>,
        hists: Option<PyReadonlyArray2<'py, f64>>,
        dt: f64,
    ) -> PyResult<(Arr<'py>, Arr<'py>, Arr<'py>)> {
        let b = rows("boxes", &boxes, 4)?;
        let s = slice("scores", &scores)?;
        let (h, hl) = match &hists {
            Some(a) => (slice("hists", a)?, a.shape()[1]),
            None => (&[][..], 0),
        };
        let frame = Frame {
            boxes: b,
            scores: s,
            hists: h,
            hist_len: hl,
        };
        let inner = &mut self.inner;
        let out = py.detach(|| inner.step(&frame, dt)).map_err(to_py_err)?;
        let tr = &self.inner.tracks;
        let ids: Vec<i64> = out.iter().map(|&i| tr[i].id as i64).collect();
        let bx: Vec<f64> = out.iter().flat_map(|&i| tr[i].bbox()).collect();
        let sc: Vec<f64> = out.iter().map(|&i| tr[i].score).collect();
        Ok((
            PyArray1::from_vec(py, ids).into_any(),
            array(py, bx, &[out.len(), 4])?,
            PyArray1::from_vec(py, sc).into_any(),
        ))
    }

    /// The live tracks: (ids (t,), means (t, 4) [u, v, du, dv], stds (t, 4), boxes (t, 4),
    /// confirmed (t,), group (t,) with −1 for none, λ (t,)).
    #[allow(clippy::type_complexity)]
    fn tracks<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(
        Arr<'py>,
        Arr<'py>,
        Arr<'py>,
        Arr<'py>,
        Arr<'py>,
        Arr<'py>,
        Arr<'py>,
    )> {
        let tr = &self.inner.tracks;
        let n = tr.len();
        Ok((
            PyArray1::from_vec(py, tr.iter().map(|t| t.id as i64).collect()).into_any(),
            array(py, tr.iter().flat_map(|t| t.mean).collect(), &[n, DIM])?,
            array(py, tr.iter().flat_map(|t| t.std).collect(), &[n, DIM])?,
            array(py, tr.iter().flat_map(|t| t.bbox()).collect(), &[n, 4])?,
            PyArray1::from_vec(py, tr.iter().map(|t| t.confirmed).collect()).into_any(),
            PyArray1::from_vec(
                py,
                tr.iter()
                    .map(|t| t.group.map_or(-1, |g| g as i64))
                    .collect(),
            )
            .into_any(),
            PyArray1::from_vec(py, tr.iter().map(|t| t.weight).collect()).into_any(),
        ))
    }

    /// This step's local Gaussian mixture: (λ (c,), means (c, 4), stds (c, 4)).
    fn mixture<'py>(&self, py: Python<'py>) -> PyResult<(Arr<'py>, Arr<'py>, Arr<'py>)> {
        let c = &self.inner.mixture;
        let (w, m, s, _) = mixture_arrays(py, c, 0)?;
        Ok((w, m, s))
    }

    /// Steps run.
    #[getter]
    fn steps(&self) -> u64 {
        self.inner.steps
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(particle_uniforms, m)?)?;
    m.add_function(wrap_pyfunction!(particle_resample, m)?)?;
    m.add_function(wrap_pyfunction!(particle_kclusterize, m)?)?;
    m.add_function(wrap_pyfunction!(particle_local_step, m)?)?;
    m.add_function(wrap_pyfunction!(particle_fuse, m)?)?;
    m.add_class::<ParticleTracker>()?;
    Ok(())
}
