"""usvfast.radar.bearing_bias_deg: the radar's bearing bias calibrated against a reference
track, checked on synthetic plots turned about a moving radar by a known angle, against
SciPy's solution of Wahba's problem (Rotation.align_vectors), by its invariances, and on bad
input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from usvfast.radar import bearing_bias_deg
from usvfast.trackcmd import Plots, corrected_plots


def turn(rel: np.ndarray, deg: float) -> np.ndarray:
    """Vectors (n, 2) north/east with deg added to their compass bearing."""
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.stack([c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1]], axis=1)


def scene(bias_deg: float, noise_m: float, seed: int = 0, n: int = 80, clutter: bool = True):
    """A boat seen by a radar on a moving own ship for n scans: the boat's plot turned by
    bias_deg about the radar plus noise, and (if `clutter`) 0-3 clutter plots a scan at least
    200 m from the boat. Returns (plots, scan_index, origins, reference, the boat's plot
    rows)."""
    rng = np.random.default_rng(seed)
    k = np.arange(n)
    own = np.stack([2.0 * k, 30.0 + 1.5 * k], axis=1)
    boat = np.stack([400.0 + 250.0 * np.cos(k / 15.0), -300.0 + 350.0 * np.sin(k / 20.0)], 1)
    plots, si, origins, boat_rows = [], [], [], []
    for i in k:
        m = int(rng.integers(0, 4)) if clutter else 0
        spur = boat[i] + rng.uniform(200.0, 900.0, (m, 1)) * np.stack(
            [np.cos(a := rng.uniform(0, 2 * np.pi, m)), np.sin(a)], axis=1
        )
        p = own[i] + turn((boat[i] - own[i])[None], bias_deg)[0] + rng.normal(0, noise_m, 2)
        rows = [*spur[: m // 2], p, *spur[m // 2 :]]
        boat_rows.append(len(plots) + m // 2)
        plots += rows
        si += [i] * len(rows)
        origins += [own[i]] * len(rows)
    return np.array(plots), np.array(si), np.array(origins), boat, np.array(boat_rows)


@pytest.mark.parametrize("bias", [-1.85, 0.0, 3.0, -0.5])
def test_recovers_a_synthetic_rotation_exactly(bias):
    p, si, o, ref, _ = scene(bias, noise_m=0.0)
    assert bearing_bias_deg(p, si, o, ref) == pytest.approx(bias, abs=1e-10)
    # A turn too large for the 60 m gate (at 120-800 m) needs a wider one (and no clutter).
    p, si, o, ref, _ = scene(bias * 4, noise_m=0.0, clutter=False)
    assert bearing_bias_deg(p, si, o, ref, gate_m=1e4) == pytest.approx(bias * 4, abs=1e-10)


def test_equals_scipy_wahba_solution_on_noisy_plots():
    # SciPy's Kabsch / SVD solution of Wahba's problem on the same pairs (3-D vectors in the
    # z = 0 plane): the rotation that best maps the reference onto the plots, about the radar.
    p, si, o, ref, rows = scene(-2.0, noise_m=12.0, seed=3)
    rel_t = ref[si[rows]] - o[rows]
    rel_p = p[rows] - o[rows]
    pad = np.zeros((len(rows), 1))
    rot, _ = Rotation.align_vectors(np.hstack([rel_p, pad]), np.hstack([rel_t, pad]))
    expected = np.degrees(rot.as_rotvec()[2])
    got = bearing_bias_deg(p, si, o, ref)
    assert got == pytest.approx(expected, abs=1e-9)
    assert abs(got + 2.0) < 0.5  # the noise moves it, but not far


def test_the_correction_removes_the_bias():
    # bearing_correction_deg = -bias turns the plots back: the calibration of the corrected
    # plots is zero, and the boat's plots land on the reference.
    p, si, o, ref, rows = scene(4.0, noise_m=0.0, seed=5)
    bias = bearing_bias_deg(p, si, o, ref)
    fixed = corrected_plots({"bearing_correction_deg": -bias}, Plots(ref, p, si, si, origins=o))
    assert bearing_bias_deg(fixed, si, o, ref) == pytest.approx(0.0, abs=1e-10)
    np.testing.assert_allclose(fixed[rows], ref[si[rows]], atol=1e-9)


def test_scans_gate_and_missing_reference():
    p, si, o, ref, rows = scene(-3.0, noise_m=8.0, seed=7)
    # Calibrating on a window equals calibrating the plots of that window alone.
    keep = si < 40
    assert bearing_bias_deg(p, si, o, ref, scans=range(40)) == pytest.approx(
        bearing_bias_deg(p[keep], si[keep], o[keep], ref[:40]), abs=1e-12
    )
    # Scans without a reference fix (NaN) are skipped, like scans outside `scans`.
    ref_nan = ref.copy()
    ref_nan[40:] = np.nan
    assert bearing_bias_deg(p, si, o, ref_nan) == pytest.approx(
        bearing_bias_deg(p, si, o, ref, scans=np.arange(40)), abs=1e-12
    )
    # A plot beyond the gate is not paired: move one boat plot 500 m off.
    far = p.copy()
    far[rows[0]] += 500.0
    assert bearing_bias_deg(far, si, o, ref) == pytest.approx(
        bearing_bias_deg(p, si, o, ref, scans=np.arange(1, len(ref))), abs=1e-12
    )


@settings(max_examples=60, deadline=None)
@given(
    bias=st.floats(-30.0, 30.0),
    extra=st.floats(-60.0, 60.0),
    shift=st.tuples(st.floats(-1e4, 1e4), st.floats(-1e4, 1e4)),
    seed=st.integers(0, 1000),
)
def test_turning_the_plots_adds_to_the_bias_and_moving_the_plane_changes_nothing(
    bias, extra, shift, seed
):
    p, si, o, ref, _ = scene(bias, noise_m=5.0, seed=seed, n=30, clutter=False)
    b0 = bearing_bias_deg(p, si, o, ref, gate_m=1e4)
    turned = o + turn(p - o, extra)
    assert bearing_bias_deg(turned, si, o, ref, gate_m=1e4) == pytest.approx(b0 + extra, abs=1e-7)
    d = np.array(shift)
    assert bearing_bias_deg(p + d, si, o + d, ref + d, gate_m=1e4) == pytest.approx(b0, abs=1e-7)


def test_bad_input_names_the_argument():
    p, si, o, ref, _ = scene(1.0, noise_m=1.0, n=20)
    cases = [
        ((p[:, :1], si, o, ref), {}, ValueError, "plots"),
        ((p, si[:-1], o, ref), {}, ValueError, "scan_index"),
        ((p, si.astype(float), o, ref), {}, TypeError, "scan_index"),
        ((p, si, o[:-1], ref), {}, ValueError, "origins"),
        ((p, si, o, ref[:, 0]), {}, ValueError, "reference"),
        ((np.where(p > 0, np.nan, p), si, o, ref), {}, ValueError, "finite"),
        ((p, si, o, ref[:10]), {}, ValueError, "scan_index"),
        ((p, si, o, ref), {"scans": [0, 25]}, ValueError, "scans"),
        ((p, si, o, ref), {"scans": [0.5]}, TypeError, "scans"),
        ((p, si, o, ref), {"gate_m": 0.0}, ValueError, "gate_m"),
        ((p, si, o, ref), {"gate_m": float("nan")}, ValueError, "gate_m"),
        ((p, si, o, ref), {"min_pairs": 0}, ValueError, "min_pairs"),
        ((p, si, o, ref), {"scans": range(5)}, ValueError, "min_pairs=10"),
        ((p, si, o, np.full_like(ref, np.nan)), {}, ValueError, "reference"),
        ((p * 1e160, si, o * 1e160, ref * 1e160), {"gate_m": 1e300}, ValueError, "overflow"),
    ]
    for args, kw, err, word in cases:
        with pytest.raises(err, match=word):
            bearing_bias_deg(*args, **kw)
