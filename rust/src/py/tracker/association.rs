//! Bindings of the tracker's association kernels on their own: optimal assignment, exact JPDA
//! marginals of one cluster and the χ² gate.

use super::*;
use crate::tracking::gating::chi2_quantile;
use crate::tracking::jpda::{marginals, Method, TrackHypotheses};
use crate::tracking::kbest::marginals_kbest;

/// Optimal assignment of a `(nr, nc)` cost matrix (`nr <= nc`, `inf` forbidden): the column
/// of each row.
#[pyfunction]
pub(super) fn linear_sum_assignment<'py>(
    py: Python<'py>,
    cost: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyAny>> {
    let s = cost.shape();
    let (nr, nc) = (s[0], s[1]);
    let c = slice("cost", &cost)?;
    let sol = py
        .detach(|| crate::tracking::assign::linear_sum_assignment(c, nr, nc))
        .map_err(to_py_err)?;
    arr_i(py, sol.into_iter().map(|j| j as i64).collect(), &[nr])
}

/// JPDA marginals of one cluster: `likelihoods` is `(tracks, 1 + detections)`, column 0 the
/// missed-detection weight, a weight `<= 0` in another column meaning "not gated". `method`
/// "ehm", "brute_force", "lbp" or "kbest" (the `k_best` most likely joint hypotheses).
#[pyfunction]
#[pyo3(signature = (likelihoods, method="ehm", k_best=1000))]
pub(super) fn jpda_marginals<'py>(
    py: Python<'py>,
    likelihoods: PyReadonlyArray2<'py, f64>,
    method: &str,
    k_best: i64,
) -> PyResult<Bound<'py, PyAny>> {
    let kbest = method == "kbest";
    if kbest && k_best < 1 {
        return Err(to_py_err(Error::param(
            "k_best",
            format!("must be >= 1, got {k_best}"),
        )));
    }
    let meth = if kbest {
        Method::Ehm
    } else {
        crate::py::tracker_config::method(method)?
    };
    let s = likelihoods.shape();
    let (nt, nc) = (s[0], s[1]);
    if nc == 0 {
        return Err(to_py_err(Error::dim(
            "likelihoods",
            "at least one column",
            0,
        )));
    }
    let l = slice("likelihoods", &likelihoods)?;
    let cluster: Vec<TrackHypotheses> = (0..nt)
        .map(|t| TrackHypotheses {
            missed: l[t * nc],
            detections: (1..nc)
                .filter(|&j| l[t * nc + j] > 0.0 || l[t * nc + j].is_nan())
                .map(|j| (j - 1, l[t * nc + j]))
                .collect(),
        })
        .collect();
    let m = py
        .detach(|| {
            if kbest {
                let k = usize::try_from(k_best).unwrap_or(usize::MAX);
                marginals_kbest(&cluster, k).map(|r| r.marginals)
            } else {
                marginals(&cluster, meth)
            }
        })
        .map_err(to_py_err)?;
    let mut out = vec![0.0; nt * nc];
    for (t, (mm, h)) in m.iter().zip(&cluster).enumerate() {
        out[t * nc] = mm.missed;
        for (p, &(j, _)) in mm.detections.iter().zip(&h.detections) {
            out[t * nc + j + 1] = *p;
        }
    }
    arr_f(py, out, &[nt, nc])
}

/// The chi-square quantile `chi2.ppf(prob_gate, dof)`.
#[pyfunction]
pub(super) fn chi2_gate(prob_gate: f64, dof: i64) -> PyResult<f64> {
    if dof < 1 {
        return Err(to_py_err(crate::Error::param(
            "dof",
            format!("must be an integer >= 1, got {dof}"),
        )));
    }
    chi2_quantile(prob_gate, dof as usize).map_err(to_py_err)
}
