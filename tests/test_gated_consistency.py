"""ANIS of gated innovations: a tracker reports the NIS only of detections inside its gate, so a
consistent filter's NIS is χ² truncated at the gate. The truncated moments against numerical
integration and sampling, the band's coverage, our JPDA tracker's own NIS, and the files."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.stats import chi2

from usvfast import tracking as T
from usvfast.kalman import constant_velocity_2d, transition_matrices
from usvfast.metrics.consistency import average_consistency, chi2_band, gated_chi2_moments
from usvfast.metrics.tables import read_innovations


@pytest.mark.parametrize("dof", [1, 2, 3, 4])
@pytest.mark.parametrize("gate", [0.9, 0.99, 0.999])
def test_truncated_moments_equal_numerical_integration(dof, gate):
    g = chi2.ppf(gate, dof)
    m1 = quad(lambda x: x * chi2.pdf(x, dof), 0, g)[0] / gate
    m2 = quad(lambda x: x * x * chi2.pdf(x, dof), 0, g)[0] / gate
    mean, var = gated_chi2_moments(dof, gate)
    np.testing.assert_allclose([mean, var], [m1, m2 - m1 * m1], rtol=1e-9)


def test_no_gate_is_the_chi2_law():
    mean, var = gated_chi2_moments([1, 2, 5], 1.0)
    np.testing.assert_allclose(mean, [1, 2, 5])
    np.testing.assert_allclose(var, [2, 4, 10])
    # the gamma law with the sum's moments is the exact χ²(Σd) band when nothing is truncated
    np.testing.assert_allclose(chi2_band(2, 300, gate=1.0), chi2_band(2, 300), rtol=1e-12)
    dof = np.array([2, 2, 3, 1, 2])
    np.testing.assert_allclose(chi2_band(dof, gate=np.ones(5)), chi2_band(dof), rtol=1e-12)


def test_gated_band_is_the_quantiles_of_the_sampled_mean():
    rng = np.random.default_rng(3)
    n, gate = 400, 0.99  # the gamma law is an approximation: within 0.01 at n = 40
    x = rng.chisquare(2, 8_000_000)
    x = x[x <= chi2.ppf(gate, 2)]
    means = x[: (len(x) // n) * n].reshape(-1, n).mean(axis=1)
    lo, hi = chi2_band(2, n, gate=gate)
    np.testing.assert_allclose([lo, hi], np.quantile(means, [0.025, 0.975]), atol=0.004)


def test_gated_band_covers_a_consistent_filter_and_the_plain_band_does_not():
    rng = np.random.default_rng(11)
    n, reps, gate = 2000, 400, 0.99
    x = rng.chisquare(2, int(n * reps * 1.02))
    x = x[x <= chi2.ppf(gate, 2)][: n * reps].reshape(reps, n)
    gated = [average_consistency(r, 2, gate=gate).inside for r in x]
    plain = [average_consistency(r, 2).inside for r in x]
    assert 0.92 <= np.mean(gated) <= 0.98
    assert np.mean(plain) < 0.6  # the plain band calls a consistent filter under-confident


def test_consistency_reports_expected_and_gate():
    v = np.full(10, 1.9)
    c = average_consistency(v, 2, gate=np.r_[np.full(7, 0.99), np.full(3, np.nan)])
    assert c.gate == 0.99
    assert c.expected == pytest.approx((7 * gated_chi2_moments(2, 0.99)[0] + 3 * 2.0) / 10)
    plain = average_consistency(v, 2, gate=np.full(10, np.nan))
    assert plain.gate is None and plain.expected == 2.0
    assert average_consistency(v, 2).as_dict()["expected"] == 2.0


@pytest.mark.parametrize("gate", [0.0, -0.1, 1.5])
def test_bad_gate_is_named(gate):
    with pytest.raises(ValueError, match="gate"):
        average_consistency(np.ones(4), 2, gate=gate)


def test_gate_of_wrong_length_is_named():
    with pytest.raises(ValueError, match="gate"):
        chi2_band(np.full(4, 2), gate=np.full(3, 0.99))


def test_tracker_nis_is_gated():
    """Our JPDA tracker on targets that move exactly as its model says, detected every scan
    with its R. The NIS of an update that follows an update averages 2·c(P_G) = 1.907, inside
    the gated band. An update right after a detection fell outside the gate is larger (the
    coasting track's error exceeds its covariance): it lifts the pooled ANIS a little, which
    still lies far below the plain χ² band."""
    rng = np.random.default_rng(5)
    q, sd, dt, gate = 0.05, 0.3, 1.0, 0.99
    model = constant_velocity_2d(q)
    f, qq = transition_matrices(model, dt)
    tr = T.Tracker(
        motion_model=model,
        sensors=[T.Sensor.position(sd)],
        association=T.JPDA(prob_detect=0.99, prob_gate=gate, clutter_density=1e-9),
        deleter=T.StepsSinceUpdate(1000),
        initiator=T.MultiMeasurementInitiator(
            np.zeros(4), np.diag([0.0, 1.0, 0.0, 1.0]), missed_distance=3.0
        ),
    )
    k, scans, burn = 40, 600, 30
    x = np.zeros((k, 4))
    x[:, 0] = np.arange(k) * 500.0  # far apart: one target per cluster
    x[:, [1, 3]] = rng.normal(0, 0.5, (k, 2))
    for i in range(k):
        tr.add_track(x[i], np.diag([sd**2, 1.0, sd**2, 1.0]), 0.0)
    chol = np.linalg.cholesky(qq)
    steady, after_miss, pooled = [], [], []
    last_update: dict[int, int] = dict.fromkeys(range(k), 0)
    for s in range(1, scans + 1):
        x = x @ f.T + rng.standard_normal((k, 4)) @ chol.T
        z = x[:, [0, 2]] + rng.normal(0, sd, (k, 2))
        got = tr.step(s * dt, z)
        for tid, dof, v in zip(got.ids.tolist(), got.nis_dof, got.nis, strict=True):
            if dof == 0:
                continue
            if s > burn:
                pooled.append(v)
                if tid < k:  # the targets' own tracks (ids 0..k-1), not those born later
                    (steady if last_update[tid] == s - 1 else after_miss).append(v)
            last_update[tid] = s
    assert max(pooled) <= chi2.ppf(gate, 2) + 1e-9
    c = average_consistency(np.array(steady), 2, gate=gate)
    assert c.n > 10_000 and c.expected == pytest.approx(1.907, abs=5e-4)
    assert c.inside, c
    assert np.mean(after_miss) > 3.0
    assert np.mean(pooled) < chi2_band(2, len(pooled))[0]


def test_innovations_file_gate_column(tmp_path):
    p = tmp_path / "innovations.csv"
    p.write_text(
        "time,track_id,sensor,nis,dof,gate\n1.0,0,lidar,1.5,2,0.99\n1.1,0,camera,2.5,2,nan\n"
    )
    inn = read_innovations(p)
    np.testing.assert_array_equal(inn.gate, [0.99, np.nan])
    old = tmp_path / "old.csv"
    old.write_text("time,track_id,sensor,nis,dof\n1.0,0,lidar,1.5,2\n")
    assert read_innovations(old).gate is None
    bad = tmp_path / "bad.csv"
    bad.write_text("time,track_id,sensor,nis,dof,gate\n1.0,0,lidar,1.5,2,1.2\n")
    with pytest.raises(ValueError, match="gate"):
        read_innovations(bad)
