//! The sigma-point weights of the unscented transform, as Stone Soup's `gauss2sigma` makes
//! them (Julier and Uhlmann's scaled unscented transform): shared by the unscented radar
//! update ([`crate::tracking::polar`]) and the unscented turn prediction
//! ([`crate::tracking::turn`]).

/// Weights of the `2n + 1` sigma points `x`, `x ± √(n + λ) L_i` of an `n`-state Gaussian
/// (`L` its lower Cholesky factor), with `λ = α² (n + κ) − n`.
pub struct SigmaWeights {
    /// `√(n + λ)`: the spread of the points along each column of `L`.
    pub spread: f64,
    /// Weights of the mean: `λ / (n + λ)`, then `1 / (2 (n + λ))`.
    pub mean: Vec<f64>,
    /// Weights of the covariance: the mean's, the first plus `1 − α² + β`.
    pub covariance: Vec<f64>,
}

impl SigmaWeights {
    /// The weights for `n` states, spread `alpha`, `beta` (2 for Gaussian priors) and
    /// `kappa` (`None`: `3 − n`).
    pub fn new(n: usize, alpha: f64, beta: f64, kappa: Option<f64>) -> Self {
        let nf = n as f64;
        let kappa = kappa.unwrap_or(3.0 - nf);
        let alpha2 = alpha * alpha;
        let lamda = alpha2 * (nf + kappa) - nf;
        let c = nf + lamda;
        let mut mean = vec![0.5 / c; 2 * n + 1];
        mean[0] = lamda / c;
        let mut covariance = mean.clone();
        covariance[0] = lamda / c + (1.0 - alpha2 + beta);
        Self {
            spread: c.sqrt(),
            mean,
            covariance,
        }
    }
}
