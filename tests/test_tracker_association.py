"""Association kernels: optimal assignment vs scipy, EHM vs brute force, chi-square gates."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment as scipy_lsa
from scipy.stats import chi2

from usvfast import _core


@st.composite
def cost_matrices(draw):
    nr = draw(st.integers(1, 7))
    nc = draw(st.integers(nr, nr + 4))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    cost = rng.uniform(-10, 10, (nr, nc))
    cost[rng.random((nr, nc)) < draw(st.sampled_from([0.0, 0.3]))] = np.inf
    return cost


@given(cost_matrices())
def test_assignment_is_optimal_like_scipy(cost):
    finite = np.where(np.isinf(cost), 1e9, cost)
    rows, cols = scipy_lsa(finite)
    best = finite[rows, cols].sum()
    if best >= 5e8:
        with pytest.raises(ValueError):
            _core.linear_sum_assignment(cost)
        return
    ours = _core.linear_sum_assignment(cost)
    assert len(set(ours.tolist())) == len(ours)
    assert cost[np.arange(len(ours)), ours].sum() == pytest.approx(best, abs=1e-9)


def test_assignment_rejects_more_rows_than_columns():
    with pytest.raises(_core.DimensionError):
        _core.linear_sum_assignment(np.zeros((3, 2)))


def brute_marginals(lik: np.ndarray) -> np.ndarray:
    """Joint-hypothesis enumeration written independently of the Rust code."""
    nt, nc = lik.shape
    options = [[0] + [j for j in range(1, nc) if lik[t, j] > 0] for t in range(nt)]
    out = np.zeros_like(lik)
    for combo in itertools.product(*options):
        used = [j for j in combo if j]
        if len(used) != len(set(used)):
            continue
        w = np.prod([lik[t, j] for t, j in enumerate(combo)])
        for t, j in enumerate(combo):
            out[t, j] += w
    return out / out[0].sum()


@st.composite
def clusters(draw):
    nt = draw(st.integers(1, 6))
    nd = draw(st.integers(0, 6))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    lik = rng.uniform(0.01, 5.0, (nt, nd + 1))
    lik[:, 1:][rng.random((nt, nd)) < draw(st.sampled_from([0.2, 0.5, 0.8]))] = 0.0
    return lik


@given(clusters())
def test_ehm_equals_brute_force_and_probabilities_sum_to_one(lik):
    ehm = _core.jpda_marginals(lik, "ehm")
    brute = _core.jpda_marginals(lik, "brute_force")
    np.testing.assert_allclose(ehm, brute, rtol=1e-11, atol=1e-14)
    np.testing.assert_allclose(ehm, brute_marginals(lik), rtol=1e-11, atol=1e-14)
    np.testing.assert_allclose(ehm.sum(axis=1), 1.0, rtol=1e-12)
    # A detection is used at most once across the cluster.
    assert np.all(ehm[:, 1:].sum(axis=0) <= 1.0 + 1e-12)


def test_ehm_handles_twenty_tracks_sharing_gates():
    # 20 tracks in a row, each gating its own and its neighbours' detections: brute force
    # would enumerate ~10^9 joint hypotheses.
    n = 20
    lik = np.zeros((n, n + 1))
    lik[:, 0] = 0.2
    for t in range(n):
        for d in range(max(0, t - 1), min(n, t + 2)):
            lik[t, d + 1] = 5.0 if d == t else 1.0
    m = _core.jpda_marginals(lik, "ehm")
    np.testing.assert_allclose(m.sum(axis=1), 1.0)
    # Symmetric ends, and the own detection dominates.
    assert m[0, 1] == pytest.approx(m[-1, n])
    assert np.all(np.argmax(m[:, 1:], axis=1) == np.arange(n))


@pytest.mark.parametrize("dof", [1, 2, 3, 4, 6])
@pytest.mark.parametrize("p", [0.5, 0.9, 0.95, 0.99, 0.999])
def test_chi2_gate_matches_scipy(p, dof):
    assert _core.chi2_gate(p, dof) == pytest.approx(chi2.ppf(p, dof), rel=1e-10)


def test_bad_likelihoods_and_gates():
    with pytest.raises(ValueError):
        _core.jpda_marginals(np.array([[np.inf, 1.0]]))
    with pytest.raises(ValueError):
        _core.jpda_marginals(np.array([[-1.0, 1.0]]))
    with pytest.raises(ValueError):
        _core.chi2_gate(0.0, 2)
    with pytest.raises(ValueError):
        _core.chi2_gate(1.5, 2)
