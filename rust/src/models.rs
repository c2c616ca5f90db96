//! Linear-Gaussian motion models, discretised exactly as Stone Soup does.
//!
//! A [`MotionModel`] is a block-diagonal combination of per-axis components (Stone Soup's
//! `CombinedLinearGaussianTransitionModel`). The 2-D constant-velocity model of the tracker
//! is `[ConstantVelocity(q), ConstantVelocity(q)]` with state `[n, v_n, e, v_e]`.

use crate::error::{Error, Result};
use nalgebra::{Dim, OMatrix};

/// One axis of a motion model; `q` is the noise diffusion coefficient (Stone Soup's
/// `noise_diff_coeff`), in (state unit)² per second^(2k-1).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum Component {
    /// Position only: `F = [1]`, `Q = [q·dt]`.
    RandomWalk { q: f64 },
    /// Discretised Wiener velocity, state `[x, ẋ]`:
    /// `F = [[1, dt], [0, 1]]`, `Q = q·[[dt³/3, dt²/2], [dt²/2, dt]]`.
    ConstantVelocity { q: f64 },
    /// Discretised Wiener acceleration, state `[x, ẋ, ẍ]`.
    ConstantAcceleration { q: f64 },
}

impl Component {
    /// Number of state entries of this component.
    pub fn ndim(&self) -> usize {
        match self {
            Component::RandomWalk { .. } => 1,
            Component::ConstantVelocity { .. } => 2,
            Component::ConstantAcceleration { .. } => 3,
        }
    }

    fn q(&self) -> f64 {
        match *self {
            Component::RandomWalk { q }
            | Component::ConstantVelocity { q }
            | Component::ConstantAcceleration { q } => q,
        }
    }
}

/// A block-diagonal combination of [`Component`]s.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MotionModel {
    components: Vec<Component>,
    ndim: usize,
}

impl MotionModel {
    /// Builds a model; every `q` must be finite and non-negative and the list non-empty.
    pub fn new(components: Vec<Component>) -> Result<Self> {
        if components.is_empty() {
            return Err(Error::param("motion_model", "needs at least one component"));
        }
        for c in &components {
            if !(c.q().is_finite() && c.q() >= 0.0) {
                return Err(Error::param(
                    "motion_model",
                    format!("noise coefficient must be finite and >= 0, got {}", c.q()),
                ));
            }
        }
        let ndim = components.iter().map(Component::ndim).sum();
        Ok(Self { components, ndim })
    }

    /// The 2-D constant-velocity model `[n, v_n, e, v_e]` with the same `q` on both axes.
    pub fn constant_velocity_2d(q: f64) -> Result<Self> {
        Self::new(vec![Component::ConstantVelocity { q }; 2])
    }

    /// State dimension.
    pub fn ndim(&self) -> usize {
        self.ndim
    }

    /// The components, in state order.
    pub fn components(&self) -> &[Component] {
        &self.components
    }

    /// Writes the transition matrix `F(dt)` and process noise `Q(dt)` into `f` and `q`,
    /// which must be `ndim × ndim` (all entries are overwritten). `dt` in seconds; a
    /// negative `dt` is the caller's responsibility (it is a valid backward model).
    pub fn fill<N: Dim>(&self, dt: f64, f: &mut OMatrix<f64, N, N>, q: &mut OMatrix<f64, N, N>)
    where
        nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<N, N>,
    {
        f.fill(0.0);
        q.fill(0.0);
        self.fill_blocks(dt, f, q);
    }

    /// Like [`MotionModel::fill`], but writes only the diagonal blocks: for matrices that
    /// were zeroed once and are only ever written by this model (the hot loops).
    #[inline]
    pub(crate) fn fill_blocks<N: Dim>(
        &self,
        dt: f64,
        f: &mut OMatrix<f64, N, N>,
        q: &mut OMatrix<f64, N, N>,
    ) where
        nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<N, N>,
    {
        let mut o = 0;
        for c in &self.components {
            match *c {
                Component::RandomWalk { q: k } => {
                    f[(o, o)] = 1.0;
                    q[(o, o)] = k * dt;
                }
                Component::ConstantVelocity { q: k } => {
                    let (dt2, dt3) = (dt * dt, dt * dt * dt);
                    f[(o, o)] = 1.0;
                    f[(o, o + 1)] = dt;
                    f[(o + 1, o + 1)] = 1.0;
                    q[(o, o)] = k * dt3 / 3.0;
                    q[(o, o + 1)] = k * dt2 / 2.0;
                    q[(o + 1, o)] = k * dt2 / 2.0;
                    q[(o + 1, o + 1)] = k * dt;
                }
                Component::ConstantAcceleration { q: k } => {
                    let dt2 = dt * dt;
                    let dt3 = dt2 * dt;
                    let dt4 = dt3 * dt;
                    let dt5 = dt4 * dt;
                    let fb = [[1.0, dt, dt2 / 2.0], [0.0, 1.0, dt], [0.0, 0.0, 1.0]];
                    let qb = [
                        [dt5 / 20.0, dt4 / 8.0, dt3 / 6.0],
                        [dt4 / 8.0, dt3 / 3.0, dt2 / 2.0],
                        [dt3 / 6.0, dt2 / 2.0, dt],
                    ];
                    for i in 0..3 {
                        for j in 0..3 {
                            f[(o + i, o + j)] = fb[i][j];
                            q[(o + i, o + j)] = k * qb[i][j];
                        }
                    }
                }
            }
            o += c.ndim();
        }
    }

    /// `F(dt)` and `Q(dt)` as dynamic matrices.
    pub fn matrices(&self, dt: f64) -> (nalgebra::DMatrix<f64>, nalgebra::DMatrix<f64>) {
        let mut f = nalgebra::DMatrix::zeros(self.ndim, self.ndim);
        let mut q = nalgebra::DMatrix::zeros(self.ndim, self.ndim);
        self.fill(dt, &mut f, &mut q);
        (f, q)
    }
}

/// A source of the transition matrix `F` and process noise `Q` of each prediction step of a
/// batch run: step `i` predicts from the previous time to measurement `i`, over `dt` seconds.
pub trait Transition {
    /// State dimension.
    fn ndim(&self) -> usize;

    /// Writes `F` and `Q` of step `step` (over `dt` seconds) into `f` and `q`, which must be
    /// `ndim × ndim` and zeroed once before the first call; every entry this source ever sets
    /// is overwritten at each call.
    fn fill_step<N: Dim>(
        &self,
        step: usize,
        dt: f64,
        f: &mut OMatrix<f64, N, N>,
        q: &mut OMatrix<f64, N, N>,
    ) where
        nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<N, N>;
}

impl Transition for MotionModel {
    fn ndim(&self) -> usize {
        self.ndim
    }

    #[inline]
    fn fill_step<N: Dim>(
        &self,
        _step: usize,
        dt: f64,
        f: &mut OMatrix<f64, N, N>,
        q: &mut OMatrix<f64, N, N>,
    ) where
        nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<N, N>,
    {
        self.fill_blocks(dt, f, q);
    }
}

/// A general linear-Gaussian transition given by its matrices (filterpy's `F` and `Q`):
/// either one fixed pair used at every step whatever `dt`, or one pair per prediction step
/// (for a model that is a function of `dt`, evaluated by the caller at each step's `dt`).
#[derive(Debug, Clone, PartialEq)]
pub struct LinearModel {
    ndim: usize,
    steps: usize,
    f: Vec<f64>,
    q: Vec<f64>,
}

impl LinearModel {
    /// Builds a model from `steps` row-major `ndim × ndim` transition matrices `f` and process
    /// noises `q` (`steps` = `f.len() / ndim²`, 1 for a fixed model). Fails unless the sizes
    /// agree, every value is finite and each `Q` is symmetric positive semi-definite.
    pub fn new(ndim: usize, f: Vec<f64>, q: Vec<f64>) -> Result<Self> {
        let nn = ndim * ndim;
        if ndim == 0 || f.is_empty() || f.len() % nn != 0 {
            return Err(Error::dim(
                "transition_matrix",
                format!("shape (k, {ndim}, {ndim}) with k >= 1"),
                format!("{} values", f.len()),
            ));
        }
        if q.len() != f.len() {
            return Err(Error::dim(
                "process_noise",
                format!("{} values (as many as transition_matrix)", f.len()),
                q.len(),
            ));
        }
        crate::error::check_finite("transition_matrix", &f)?;
        for (i, qi) in q.chunks(nn).enumerate() {
            crate::kalman::check_covariance(&format!("process_noise[{i}]"), qi, ndim, false)?;
        }
        Ok(Self {
            ndim,
            steps: f.len() / nn,
            f,
            q,
        })
    }

    /// Number of matrix pairs: 1 for a fixed model, else one per prediction step.
    pub fn steps(&self) -> usize {
        self.steps
    }
}

impl Transition for LinearModel {
    fn ndim(&self) -> usize {
        self.ndim
    }

    fn fill_step<N: Dim>(
        &self,
        step: usize,
        _dt: f64,
        f: &mut OMatrix<f64, N, N>,
        q: &mut OMatrix<f64, N, N>,
    ) where
        nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<N, N>,
    {
        let n = self.ndim;
        let k = if self.steps == 1 { 0 } else { step };
        let (fs, qs) = (&self.f[k * n * n..], &self.q[k * n * n..]);
        for i in 0..n {
            for j in 0..n {
                f[(i, j)] = fs[i * n + j];
                q[(i, j)] = qs[i * n + j];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wiener_velocity_matches_closed_form() {
        let m = MotionModel::new(vec![Component::ConstantVelocity { q: 2.0 }]).unwrap();
        let (f, q) = m.matrices(0.5);
        assert_eq!(f[(0, 1)], 0.5);
        assert!((q[(0, 0)] - 2.0 * 0.125 / 3.0).abs() < 1e-15);
        assert!((q[(0, 1)] - 2.0 * 0.25 / 2.0).abs() < 1e-15);
        assert!((q[(1, 1)] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn combined_is_block_diagonal() {
        let m = MotionModel::new(vec![
            Component::ConstantVelocity { q: 1.0 },
            Component::RandomWalk { q: 3.0 },
        ])
        .unwrap();
        assert_eq!(m.ndim(), 3);
        let (f, q) = m.matrices(2.0);
        assert_eq!(f[(0, 2)], 0.0);
        assert_eq!(f[(2, 2)], 1.0);
        assert_eq!(q[(2, 2)], 6.0);
        assert_eq!(q[(0, 2)], 0.0);
    }

    #[test]
    fn linear_model_checks_and_fills() {
        let f = vec![1.0, 1.0, 0.0, 1.0];
        let q = vec![1.0, 0.0, 0.0, 1.0];
        let m = LinearModel::new(2, f.clone(), q.clone()).unwrap();
        assert_eq!(m.steps(), 1);
        let mut fm = nalgebra::DMatrix::zeros(2, 2);
        let mut qm = nalgebra::DMatrix::zeros(2, 2);
        m.fill_step(7, 0.3, &mut fm, &mut qm);
        assert_eq!(fm[(0, 1)], 1.0);
        assert_eq!(qm[(1, 1)], 1.0);
        assert!(LinearModel::new(2, f.clone(), vec![-1.0, 0.0, 0.0, 1.0]).is_err());
        assert!(LinearModel::new(2, vec![1.0; 3], q.clone()).is_err());
        assert!(LinearModel::new(2, vec![f64::NAN; 4], q).is_err());
    }

    #[test]
    fn rejects_negative_noise() {
        assert!(MotionModel::new(vec![Component::RandomWalk { q: -1.0 }]).is_err());
        assert!(MotionModel::new(vec![]).is_err());
    }
}
