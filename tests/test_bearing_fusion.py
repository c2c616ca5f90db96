"""Bearing fusion (KF + RTS, Wiener velocity): parity with filterpy built from the paper's
eq. (4), wrap-around astern, fusion beating single cameras, RMSE, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter, rts_smoother
from hypothesis import given
from hypothesis import strategies as st

import usvfast
from usvfast.bearing import (
    THERMAL,
    VISIBLE,
    bearing_rmse_table,
    fuse_bearings,
    pixel_to_bearing,
    reference_bearing_deg,
    rmse_deg,
    unwrap_deg,
    wrap_deg,
)
from usvfast.bearing.sample import generate_encounter


def stream(seed: int, n: int = 300, start: float = -60.0, rate: float = -0.1):
    """Interleaved visible/thermal samples of a bearing drifting at `rate` deg/s."""
    rng = np.random.default_rng(seed)
    t = 1.6e9 + np.sort(rng.uniform(0.0, 120.0, n))
    src = rng.choice([VISIBLE, THERMAL], n)
    truth = start + rate * (t - t[0]) + 0.5 * np.sin((t - t[0]) / 20.0)
    noise = np.where(src == VISIBLE, 0.4, 0.3) * rng.normal(size=n)
    return src, t, truth + noise, truth


def filterpy_reference(src, t, z, q, stds, rate_std):
    """KF + RTS with filterpy, F and Q written from eq. (4) of the paper."""
    kf = KalmanFilter(dim_x=2, dim_z=1)
    r0 = stds[int(src[0])] ** 2
    kf.x = np.array([[z[0]], [0.0]])
    kf.P = np.diag([100.0 * r0, rate_std**2])
    kf.H = np.array([[1.0, 0.0]])
    xs, ps, fs, qs = [], [], [], []
    for i in range(len(t)):
        dt = t[i] - t[i - 1] if i else 0.0
        # eq. (4): A = [[1, ΔT], [0, 1]], Q = q [[ΔT³/3, ΔT²/2], [ΔT²/2, ΔT]]
        kf.F = np.array([[1.0, dt], [0.0, 1.0]])
        kf.Q = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
        kf.predict()
        kf.R = np.array([[stds[int(src[i])] ** 2]])
        kf.update(np.array([[z[i]]]))
        xs.append(kf.x.ravel().copy())
        ps.append(kf.P.copy())
        fs.append(kf.F.copy())
        qs.append(kf.Q.copy())
    fs_next = np.array([*fs[1:], np.eye(2)])
    qs_next = np.array([*qs[1:], np.zeros((2, 2))])
    xs_s, ps_s, _, _ = rts_smoother(np.array(xs), np.array(ps), fs_next, qs_next)
    return np.array(xs), xs_s, ps_s


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_matches_filterpy_with_paper_defaults(seed):
    src, t, z, _ = stream(seed)
    t[10] = t[9]  # simultaneous visible and thermal frames
    fused = fuse_bearings(src, t, z)
    xf, xs, ps = filterpy_reference(src, t, z, 0.01**2, {VISIBLE: 0.7, THERMAL: 1.0}, 5.0)
    np.testing.assert_allclose(fused.bearing_deg, xs[:, 0], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(fused.bearing_rate_deg_s, xs[:, 1], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(fused.bearing_std_deg**2, ps[:, 0, 0], rtol=1e-9)
    np.testing.assert_allclose(fused.bearing_rate_std_deg_s**2, ps[:, 1, 1], rtol=1e-9)
    np.testing.assert_allclose(fused.filtered_bearing_deg, xf[:, 0], rtol=1e-9, atol=1e-9)


def test_custom_noise_and_sources():
    src, t, z, _ = stream(5)
    src = np.where(src == VISIBLE, 7, 9)
    stds = {7: 0.3, 9: 2.0}
    fused = fuse_bearings(src, t, z, measurement_std_deg=stds, noise_diff_coeff_deg2=0.05**2)
    _, xs, _ = filterpy_reference(src, t, z, 0.05**2, stds, 5.0)
    np.testing.assert_allclose(fused.bearing_deg, xs[:, 0], rtol=1e-9, atol=1e-9)


def test_target_crossing_astern_does_not_jump():
    # bearing passes +180 -> -180 (dead astern, moving to port side aft)
    src, t, z, truth = stream(3, n=400, start=170.0, rate=0.2)
    wrapped = wrap_deg(z)
    assert wrapped.max() > 175 and wrapped.min() < -175  # the stream really crosses ±180
    fused = fuse_bearings(src, t, wrapped)
    # estimates stay in (-180, 180] and follow the truth everywhere (wrapped error small)
    assert np.all((fused.bearing_deg > -180) & (fused.bearing_deg <= 180))
    assert np.max(np.abs(wrap_deg(fused.bearing_deg - truth))) < 0.5
    # the continuous estimate has no 360° jump and its rate stays near the truth's
    assert np.max(np.abs(np.diff(fused.bearing_unwrapped_deg))) < 1.0
    assert np.max(np.abs(fused.bearing_rate_deg_s - 0.2)) < 0.1
    # rotation invariance: the same stream turned by 180° (no wrap) gives the same answer
    turned = fuse_bearings(src, t, wrapped - 180.0)
    np.testing.assert_allclose(wrap_deg(turned.bearing_deg + 180.0), fused.bearing_deg, atol=1e-9)
    np.testing.assert_allclose(turned.bearing_rate_deg_s, fused.bearing_rate_deg_s, atol=1e-12)
    np.testing.assert_allclose(turned.bearing_std_deg, fused.bearing_std_deg, rtol=1e-12)


@given(offset=st.floats(-720.0, 720.0), seed=st.integers(0, 2**16))
def test_any_branch_of_the_input_gives_the_same_fusion(offset, seed):
    src, t, z, _ = stream(seed, n=60)
    base = fuse_bearings(src, t, z)
    k = np.random.default_rng(seed).integers(-2, 3, len(z))  # each sample on its own branch
    moved = fuse_bearings(src, t, z + offset + 360.0 * k)
    assert np.max(np.abs(wrap_deg(moved.bearing_deg - offset - base.bearing_deg))) < 1e-6
    np.testing.assert_allclose(moved.bearing_rate_deg_s, base.bearing_rate_deg_s, atol=1e-9)


def test_unwrap_deg():
    np.testing.assert_allclose(unwrap_deg([179.0, -179.0, -170.0, 175.0]), [179, 181, 190, 175])
    assert unwrap_deg([]).shape == (0,)


def bundled_fusion_rmse(seed: int):
    s = generate_encounter(seed, duration_s=150.0)
    b = np.empty(len(s.times))
    for sid, cam in s.cameras.items():
        m = s.source == sid
        b[m] = pixel_to_bearing(s.x_px[m], s.y_px[m], cam, pan_deg=s.pan_deg[m]).bearing_deg
    fused = fuse_bearings(s.source, s.times, b, s.confidence)
    ref = reference_bearing_deg(s.times, s.own, s.target_ais)
    return s, b, fused, ref, {r.label: r for r in bearing_rmse_table(fused, ref)}


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_fusion_beats_each_single_camera(seed):
    s, _, _, ref, rows = bundled_fusion_rmse(seed)
    vis, ir = rows["visible (unfused)"], rows["thermal (unfused)"]
    assert rows["fused KF + RTS"].rmse_deg < 0.5 * min(vis.rmse_deg, ir.rmse_deg)
    assert rows["fused KF + RTS"].rmse_deg <= rows["fused KF"].rmse_deg
    # single-camera RMSEs are what the pixel noise implies (0.36° and 0.27° white + wander)
    assert 0.25 < vis.rmse_deg < 0.55 and 0.18 < ir.rmse_deg < 0.40
    assert vis.count + ir.count == rows["fused KF + RTS"].count == len(s.times)
    # the AIS reference (10 s reports, linear in time) is far closer to the truth than that
    assert rmse_deg(ref, s.true_bearing_deg)[0] < 0.01


def test_rmse_table_rows_are_plain_rmse_per_source():
    s, b, fused, ref, rows = bundled_fusion_rmse(4)
    for sid, label in ((VISIBLE, "visible (unfused)"), (THERMAL, "thermal (unfused)")):
        m = s.source == sid
        err = b[m] - ref[m]  # no wrap needed here: bearings are near -60°
        assert rows[label].rmse_deg == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-12)
        assert rows[label].count == m.sum()
    err = fused.bearing_deg - ref
    assert rows["fused KF + RTS"].rmse_deg == pytest.approx(np.sqrt(np.mean(err**2)), rel=1e-12)


def test_rmse_wraps_and_ignores_uncovered():
    rmse, n = rmse_deg([179.0, -179.0, 10.0, 5.0], [-179.0, 179.0, 12.0, np.nan])
    assert n == 3
    assert rmse == pytest.approx(2.0)
    assert np.isnan(rmse_deg([1.0], [np.nan])[0])


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        ({"source": [1, 3, 2]}, ValueError, r"source: unknown source id\(s\) \[3\]"),
        ({"source": [1.0, np.nan, 2.0]}, ValueError, "source"),
        ({"source": ["a", "b", "c"]}, TypeError, "source"),
        ({"source": [1, 2]}, usvfast.DimensionError, "source"),
        ({"times": [0.0, 2.0, 1.0]}, usvfast.TimeOrderError, "times"),
        ({"times": [0.0, np.nan, 1.0]}, usvfast.NonFiniteError, "times"),
        ({"bearing_deg": [1.0, np.inf, 2.0]}, usvfast.NonFiniteError, "bearing_deg"),
        ({"bearing_deg": [1.0, 2.0]}, usvfast.DimensionError, "bearing_deg"),
        ({"confidence": [0.5, np.nan, 0.5]}, usvfast.NonFiniteError, "confidence"),
        ({"confidence": [0.5, 1.5, 0.5]}, ValueError, "confidence"),
        ({"measurement_std_deg": {1: 0.7, 2: 0.0}}, ValueError, "measurement_std_deg"),
        ({"noise_diff_coeff_deg2": np.nan}, ValueError, "noise_diff_coeff_deg2"),
        ({"prior_rate_std_deg_s": 0.0}, ValueError, "prior_rate_std_deg_s"),
    ],
)
def test_bad_input_names_the_argument(kwargs, exc, match):
    args = {"source": [1, 2, 1], "times": [0.0, 1.0, 2.0], "bearing_deg": [1.0, 2.0, 3.0]}
    args.update(kwargs)
    with pytest.raises(exc, match=match):
        fuse_bearings(**args)


def test_empty_stream_is_rejected():
    with pytest.raises(ValueError, match="times: no samples"):
        fuse_bearings([], [], [])


def test_single_sample_and_simultaneous_samples():
    one = fuse_bearings([THERMAL], [5.0], [-70.0])
    assert one.bearing_deg[0] == pytest.approx(-70.0)
    same = fuse_bearings([VISIBLE, THERMAL], [5.0, 5.0], [-70.0, -69.0])
    # both frames at one time: the estimate is the inverse-variance mean (diffuse prior)
    w = np.array([1 / 0.49, 1.0])
    assert same.bearing_deg[1] == pytest.approx((w @ [-70.0, -69.0]) / w.sum(), abs=0.01)
